"""Helpers shared by the benchmark scripts (run them as ``python bench/NAME.py``)."""

from __future__ import annotations

import math


def improvements(history) -> list:
    """An anytime curve reduced to the points where the best score improves (and the last)."""
    out = []
    for row in history:
        if not out or row.best_score > out[-1][1]:
            out.append([round(row.seconds, 4), row.best_score])
    if history:
        out.append([round(history[-1].seconds, 4), history[-1].best_score])
    return out


def best_by(curve, t: float, before_any: float = -math.inf) -> float:
    """Best score of a reduced curve by time ``t`` (``before_any`` until the first point)."""
    best = before_any
    for seconds, score in curve:
        if seconds > t:
            break
        best = max(best, score)
    return best
