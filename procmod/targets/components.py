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
def _union_parts(mask):
    """Union-find over the pixels of ``mask``, 8-connected: each pixel's parent (a pixel's
    part is its root), int32 (8 bytes a pixel in all: pictures may be large)."""
    h, w = mask.shape
    parent = np.arange(h * w, dtype=np.int32)
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
    return parent


@numba.njit(cache=True)
def _without_specks(mask, share):
    h, w = mask.shape
    parent = _union_parts(mask)
    sizes = np.zeros(h * w, dtype=np.int32)  # by root
    largest = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                r = _root(parent, y * w + x)
                sizes[r] += 1
                largest = max(largest, sizes[r])
    keep = np.zeros((h, w), dtype=np.bool_)
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                keep[y, x] = sizes[_root(parent, y * w + x)] >= share * largest
    return keep


@numba.njit(cache=True)
def _part_count(mask):
    h, w = mask.shape
    parent = _union_parts(mask)
    count = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x] and _root(parent, y * w + x) == y * w + x:
                count += 1
    return count


def part_count(mask: np.ndarray) -> int:
    """How many 8-connected parts ``mask`` has (``scipy.ndimage.label``'s count with a 3x3
    structure, without importing scipy.ndimage)."""
    return int(_part_count(np.ascontiguousarray(np.asarray(mask, dtype=np.bool_))))


def without_specks(mask: np.ndarray, share: float) -> np.ndarray:
    """``mask`` without its 8-connected parts smaller than ``share`` of the largest."""
    mask = np.asarray(mask, dtype=np.bool_)
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    out = np.zeros(mask.shape, dtype=np.bool_)
    if len(rows):  # only the box around the foreground is labelled: a drawing rarely fills its page
        box = (slice(rows[0], rows[-1] + 1), slice(cols[0], cols[-1] + 1))
        out[box] = _without_specks(np.ascontiguousarray(mask[box]), float(share))
    return out


@numba.njit(cache=True)
def _labels(mask):
    h, w = mask.shape
    parent = _union_parts(mask)
    out = np.zeros((h, w), dtype=np.int32)
    number = np.zeros(h * w, dtype=np.int32)  # by root
    count = 0
    for y in range(h):
        for x in range(w):
            if mask[y, x]:
                r = _root(parent, y * w + x)
                if number[r] == 0:
                    count += 1
                    number[r] = count
                out[y, x] = number[r]
    return out, count


def labels(mask: np.ndarray) -> tuple:
    """``(labels, count)``: ``mask``'s 8-connected parts numbered 1 to ``count`` in the
    order their first pixels come in rows, 0 off the mask (``scipy.ndimage.label`` with a
    3x3 structure, without importing scipy.ndimage)."""
    out, count = _labels(np.ascontiguousarray(np.asarray(mask, dtype=np.bool_)))
    return out, int(count)
