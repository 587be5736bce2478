"""The bench's neutral judge of vines outputs: the original program's score on a 50x50 mask.

Written for the bench from shared/seeds/vines.md, with numpy only: it imports nothing of
procmod, so it judges procmod's and WebPPL's outputs alike rather than procmod's own
target code. An output is a list of primitives in world coordinates (the vines viewport,
x in [-12, 12], y in [-22, 2], image row 0 at y = -22):

    {"type": "segment", "x0", "y0", "x1", "y1", "width"}   a capsule of full width ``width``
    {"type": "ellipse", "x", "y", "angle", "length", "width"}
    {"type": "disc", "x", "y", "radius"}

A pixel is covered when its centre lies inside a primitive (no minimum stroke width). The
score is the weighted agreement of output and target masks — weight 1 where the target is
empty, ``flat + (1 - flat) * sobel`` on target pixels (``flat = 1/1.5``, ``sobel`` the
target's Sobel magnitude normalised to [0, 1]) — normalised against the empty image:
``(sim - sim_empty) / (1 - sim_empty)``.
"""

from __future__ import annotations

import numpy as np

VIEWPORT = (-12.0, 12.0, -22.0, 2.0)
FLAT = 1.0 / 1.5


def sobel_magnitude(mask: np.ndarray) -> np.ndarray:
    """Sobel gradient magnitude of a 0/1 image with replicated borders."""
    a = np.pad(np.asarray(mask, dtype=np.float64), 1, mode="edge")
    gx = (a[:-2, 2:] + 2 * a[1:-1, 2:] + a[2:, 2:]) - (a[:-2, :-2] + 2 * a[1:-1, :-2] + a[2:, :-2])
    gy = (a[2:, :-2] + 2 * a[2:, 1:-1] + a[2:, 2:]) - (a[:-2, :-2] + 2 * a[:-2, 1:-1] + a[:-2, 2:])
    return np.hypot(gx, gy)


def weights(target: np.ndarray) -> np.ndarray:
    """Per-pixel weights of the original program's score."""
    target = np.asarray(target, dtype=bool)
    sobel = sobel_magnitude(target)
    top = sobel.max()
    graded = sobel / top if top > 0 else sobel
    return np.where(target, FLAT + (1 - FLAT) * graded, 1.0)


def rasterize(geometry: list, width: int = 50, height: int = 50) -> np.ndarray:
    """Boolean ``(height, width)`` mask: pixels whose centre lies inside some primitive."""
    xmin, xmax, ymin, ymax = VIEWPORT
    px = xmin + (np.arange(width) + 0.5) * (xmax - xmin) / width
    py = ymin + (np.arange(height) + 0.5) * (ymax - ymin) / height
    x, y = np.meshgrid(px, py)
    mask = np.zeros((height, width), dtype=bool)
    for g in geometry:
        kind = g["type"]
        if kind == "segment":
            x0, y0, x1, y1, r = g["x0"], g["y0"], g["x1"], g["y1"], 0.5 * g["width"]
            dx, dy = x1 - x0, y1 - y0
            length2 = dx * dx + dy * dy
            t = np.zeros_like(x) if length2 == 0 else np.clip(((x - x0) * dx + (y - y0) * dy) / length2, 0, 1)
            mask |= (x - x0 - t * dx) ** 2 + (y - y0 - t * dy) ** 2 <= r * r
        elif kind == "ellipse":
            ca, sa = np.cos(g["angle"]), np.sin(g["angle"])
            u = (x - g["x"]) * ca + (y - g["y"]) * sa
            v = -(x - g["x"]) * sa + (y - g["y"]) * ca
            mask |= (u / (0.5 * g["length"])) ** 2 + (v / (0.5 * g["width"])) ** 2 <= 1
        elif kind == "disc":
            mask |= (x - g["x"]) ** 2 + (y - g["y"]) ** 2 <= g["radius"] ** 2
        else:
            raise ValueError(f"unknown primitive type {kind!r}")
    return mask


def similarity(output: np.ndarray, target: np.ndarray) -> float:
    """Normalised similarity of an output mask to a target mask (1 = equal, 0 = empty image)."""
    output, target = np.asarray(output, dtype=bool), np.asarray(target, dtype=bool)
    w = weights(target)
    total = w.sum()
    sim = w[output == target].sum() / total
    sim_empty = w[~target].sum() / total
    return float((sim - sim_empty) / (1 - sim_empty))


def score(geometry: list, target: np.ndarray) -> float:
    """The judge: similarity of ``geometry`` rasterised at the target's size."""
    target = np.asarray(target, dtype=bool)
    return similarity(rasterize(geometry, target.shape[1], target.shape[0]), target)
