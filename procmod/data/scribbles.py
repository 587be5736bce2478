"""Scribble targets: procedurally drawn thick brush strokes (seed 004's Scribbles, made
at run time instead of drawn in Photoshop).

A scribble is one continuous stroke: a path whose curvature wanders (an
Ornstein-Uhlenbeck process with occasional sharp bends) and whose brush width varies
smoothly between thin and thick, steered back when it nears the frame, so it has thick
and thin parts, high and low curvature and, often, self-intersections. Scribble ``k`` is
a fixed function of ``k``. Its start point and direction are the stroke's own.
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from ..core import InvalidArgumentError
from ..geometry import Canvas, Segment
from ..targets import TargetImage

RESOLUTION = 100
_SALT = 0x5C41B
MIN_FILL, MAX_FILL = 0.06, 0.35


def _stroke(rng: np.random.Generator):
    """Points and widths (pixel units) of one stroke."""
    n = int(rng.integers(45, 110))
    x = rng.uniform(0.3, 0.7) * RESOLUTION
    y = rng.uniform(0.65, 0.85) * RESOLUTION
    heading = -math.pi / 2 + rng.normal(0, 0.5)
    curvature = 0.0
    phase, rate = rng.uniform(0, 2 * math.pi), rng.uniform(0.03, 0.12)
    thin, thick = rng.uniform(2.0, 3.5), rng.uniform(5.0, 9.0)
    points, widths = [(x, y)], []
    margin = 0.12 * RESOLUTION
    for i in range(n):
        curvature = 0.9 * curvature + rng.normal(0, 0.025)
        if rng.random() < 0.03:  # a sharp bend now and then
            curvature += rng.choice([-1, 1]) * rng.uniform(0.25, 0.6)
        heading += curvature
        # Steer back towards the centre near the frame.
        if not (margin < x < RESOLUTION - margin and margin < y < RESOLUTION - margin):
            to_centre = math.atan2(RESOLUTION / 2 - y, RESOLUTION / 2 - x)
            turn = math.atan2(math.sin(to_centre - heading), math.cos(to_centre - heading))
            heading += 0.35 * turn
        x += 2.0 * math.cos(heading)
        y += 2.0 * math.sin(heading)
        points.append((x, y))
        widths.append(thin + (thick - thin) * 0.5 * (1 + math.sin(phase + rate * i)))
    return points, widths


@lru_cache(maxsize=256)
def _scribble(index: int) -> TargetImage:
    for attempt in range(100):
        rng = np.random.default_rng([_SALT, index, attempt])
        points, widths = _stroke(rng)
        canvas = Canvas((0, RESOLUTION, 0, RESOLUTION), RESOLUTION)
        for (x0, y0), (x1, y1), w in zip(points, points[1:], widths):
            canvas.add(Segment(x0, y0, x1, y1, w))
        mask = canvas.filled
        if MIN_FILL <= mask.mean() <= MAX_FILL:
            (x0, y0), (x1, y1) = points[0], points[3]
            start = (min(max(x0 / RESOLUTION, 0.0), 1.0), min(max(y0 / RESOLUTION, 0.0), 1.0))
            return TargetImage(f"scribble:{index}", mask, start, (x1 - x0, y1 - y0))
    raise RuntimeError(f"could not draw scribble {index}")  # pragma: no cover - never seen


def scribble_target(index: int) -> TargetImage:
    """Scribble number ``index`` (any non-negative integer)."""
    if isinstance(index, bool) or not isinstance(index, int) or index < 0:
        raise InvalidArgumentError(f"a scribble number is a non-negative integer, got {index!r}")
    return _scribble(index)


def scribble_set(count: int, first: int = 0, mirror: bool = False) -> list:
    """Scribbles ``first .. first + count - 1`` (plus mirrored copies if asked)."""
    out = []
    for index in range(first, first + count):
        target = scribble_target(index)
        out.append(target)
        if mirror:
            out.append(target.mirrored())
    return out
