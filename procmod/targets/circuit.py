"""``Circuit``: seed 004 eq. 4, a style likelihood with no target image.

``edge(I)`` is the mean per-pixel edge strength of the output and ``fill(I)`` the
fraction of filled pixels; the likelihood is ``N(edge * (1 - |fill - tau| / tau); 1,
sigma)`` with tau = 0.5 and sigma = 0.01, plus the out-of-bounds penalty of the shape
target (the paper penalises geometry outside the image to get a rectangular "die").

Edge strength of a pixel is its Sobel gradient magnitude on the binary image divided by
4 (the magnitude of a straight axis-aligned edge) and clipped to 1, so ``edge`` lies in
[0, 1]. It is kept incrementally: a draw changes the gradient only in the 3x3
neighbourhoods of the pixels it filled, and :class:`EdgeCanvas` updates the sum there.
"""

from __future__ import annotations

import numba
import numpy as np

from ..core import InvalidArgumentError
from ..core.kernels import once_per_process
from ..geometry import Canvas, Segment, Viewport
from .image import check_canvas, out_of_bounds_penalty


@numba.njit(cache=True, inline="always")
def _edge_at(pixels, mark, width, height, i, j, old):
    gx = 0.0
    gy = 0.0
    for dj in range(-1, 2):
        jj = min(max(j + dj, 0), height - 1)
        for di in range(-1, 2):
            ii = min(max(i + di, 0), width - 1)
            k = jj * width + ii
            v = 1.0 if pixels[k] != 0 and not (old and mark[k]) else 0.0
            if v != 0.0:
                wx = 2.0 if dj == 0 else 1.0
                wy = 2.0 if di == 0 else 1.0
                gx += di * wx * v
                gy += dj * wy * v
    return min(np.sqrt(gx * gx + gy * gy) / 4.0, 1.0)


@numba.njit(cache=True)
def _edge_delta(pixels, width, height, changed, n, mark, stamp, stamp_value):
    """Change of the summed edge strength caused by filling ``changed[:n]``."""
    for t in range(n):
        mark[changed[t]] = True
    delta = 0.0
    for t in range(n):
        k = changed[t]
        j0 = k // width
        i0 = k - j0 * width
        for dj in range(-1, 2):
            j = j0 + dj
            if j < 0 or j >= height:
                continue
            for di in range(-1, 2):
                i = i0 + di
                if i < 0 or i >= width:
                    continue
                q = j * width + i
                if stamp[q] == stamp_value:
                    continue
                stamp[q] = stamp_value
                delta += (_edge_at(pixels, mark, width, height, i, j, False)
                          - _edge_at(pixels, mark, width, height, i, j, True))
    for t in range(n):
        mark[changed[t]] = False
    return delta


@numba.njit(cache=True)
def edge_total(pixels, width, height):
    """Summed edge strength of a whole image (reference for the incremental update)."""
    mark = np.zeros(pixels.shape[0], dtype=np.bool_)
    total = 0.0
    for j in range(height):
        for i in range(width):
            total += _edge_at(pixels, mark, width, height, i, j, False)
    return total


@once_per_process
def _load_edge_kernel() -> None:
    """Load the edge kernel with the argument types :meth:`EdgeCanvas.add` passes; the
    first :class:`EdgeCanvas` a process makes calls it (see :mod:`procmod.core.kernels`)."""
    scratch = EdgeCanvas.wrap(Canvas(Viewport(0.0, 1.0, 0.0, 1.0), 1))
    scratch.add(Segment(0.2, 0.2, 0.8, 0.8, 0.5))


class EdgeCanvas(Canvas):
    """A canvas that also keeps the summed edge strength of its image up to date."""

    __slots__ = ("edge_sum", "_mark", "_stamp", "_counter")

    @classmethod
    def wrap(cls, canvas: Canvas) -> "EdgeCanvas":
        """An empty EdgeCanvas with ``canvas``'s viewport and size."""
        out = cls(canvas.viewport, canvas.width, canvas.height, min_radius_px=canvas.min_radius_px)
        out.edge_sum = 0.0
        out._mark = np.zeros(out.pixels.shape[0], dtype=np.bool_)
        out._stamp = np.zeros(out.pixels.shape[0], dtype=np.int64)
        out._counter = np.zeros(1, dtype=np.int64)  # shared by all copies: stamps stay unique
        _load_edge_kernel()
        return out

    def copy(self) -> "EdgeCanvas":
        other = super().copy()
        other.edge_sum = self.edge_sum
        other._mark = self._mark  # scratch, shared like the changed-pixel buffer
        other._stamp = self._stamp
        other._counter = self._counter
        return other

    def add(self, geometry) -> int:
        n = super().add(geometry)
        if n:
            self._counter[0] += 1
            self.edge_sum += _edge_delta(self.pixels, self.width, self.height, self._changed, n,
                                         self._mark, self._stamp, self._counter[0])
        return n


class Circuit:
    """The circuit-style likelihood of seed 004 eq. 4 (no target image).

    Parameters
    ----------
    tau : float
        Target fill fraction.
    sigma : float
        Standard deviation of the Gaussian around 1.
    oob_sigma : float or None
        Scale of the out-of-bounds penalty; ``None`` disables it.
    """

    name = "circuit"
    # capabilities (procmod.core.protocols.Target): no target image
    exact_removal = False
    has_mask = False
    has_overlay = False

    def __init__(self, tau: float = 0.5, sigma: float = 0.01, oob_sigma: float | None = 0.001):
        if not 0 < tau <= 1:
            raise InvalidArgumentError(f"tau must be in (0, 1], got {tau!r}")
        if not sigma > 0:
            raise InvalidArgumentError(f"sigma must be positive, got {sigma!r}")
        self.tau = tau
        self.sigma = sigma
        self.oob_sigma = oob_sigma

    def configure(self, model):
        """Circuits place no constraint on where the model starts."""
        return model

    def new_output(self, model) -> EdgeCanvas:
        """An empty edge-tracking canvas of ``model``'s size."""
        return EdgeCanvas.wrap(check_canvas(model.new_output(), "the circuit target"))

    def _edge(self, canvas) -> float:
        n = canvas.width * canvas.height
        if isinstance(canvas, EdgeCanvas):
            return canvas.edge_sum / n
        return edge_total(canvas.pixels, canvas.width, canvas.height) / n

    def score(self, canvas) -> float:
        """``edge * (1 - relative fill error)``: 1 is the ideal circuit."""
        fill = canvas.filled_count / canvas.pixels.shape[0]
        return self._edge(canvas) * (1.0 - abs(fill - self.tau) / self.tau)

    def log_likelihood(self, canvas) -> float:
        """Gaussian log-likelihood of the score around 1, plus the out-of-bounds penalty."""
        d = self.score(canvas) - 1.0
        ll = -0.5 * d * d / (self.sigma * self.sigma)
        return ll - out_of_bounds_penalty(canvas, self.oob_sigma)

    def display_mask(self, width: int):
        """No target picture."""
        return None
