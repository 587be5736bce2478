"""Connected parts of a binary mask, for telling a target's shape from specks of noise.

A numba kernel rather than ``scipy.ndimage.label``: importing scipy.ndimage takes about a
quarter of a second, longer than a guided run's inference, and a target picture is read
at the start of every ``procmod infer``.
"""

from __future__ import annotations

import numba
import numpy as np


@numba.njit(cache=True)
def _root(parent, i):
    while parent[i] != i:
        parent[i] = parent[parent[i]]  # path halving
        i = parent[i]
    return i


@numba.njit(cache=True)
def _label(mask):
    h, w = mask.shape
    parent = np.arange(h * w)
    for y in range(h):
        for x in range(w):
            if not mask[y, x]:
                continue
            i = y * w + x
            # the neighbours already visited: west, north-west, north, north-east
            for dy, dx in ((0, -1), (-1, -1), (-1, 0), (-1, 1)):
                yy, xx = y + dy, x + dx
                if 0 <= yy and 0 <= xx < w and mask[yy, xx]:
                    a, b = _root(parent, i), _root(parent, yy * w + xx)
                    if a != b:
                        parent[max(a, b)] = min(a, b)
    labels = np.full((h, w), -1, dtype=np.int64)
    ids = np.full(h * w, -1, dtype=np.int64)
    sizes = np.zeros(h * w, dtype=np.int64)
    n = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                r = _root(parent, y * w + x)
                if ids[r] < 0:
                    ids[r] = n
                    n += 1
                labels[y, x] = ids[r]
                sizes[ids[r]] += 1
    return labels, sizes[:n]


def component_labels(mask: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(labels, sizes): each foreground pixel's 8-connected part (0, 1, ... in reading
    order of their first pixels; -1 for background) and each part's pixel count."""
    return _label(np.ascontiguousarray(mask, dtype=np.bool_))


def without_specks(mask: np.ndarray, share: float) -> np.ndarray:
    """``mask`` without its 8-connected parts smaller than ``share`` of the largest (a
    mask with no foreground is returned as it is)."""
    labels, sizes = component_labels(mask)
    if len(sizes) <= 1:
        return np.asarray(mask, dtype=bool)
    keep = np.append(sizes >= share * sizes.max(), False)  # index -1: background
    return keep[labels]
