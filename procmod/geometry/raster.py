"""A raster canvas that draws 2D primitives incrementally and reports what changed.

The per-pixel work is in small numba kernels that touch only the pixels of a primitive's
bounding box: this is the hot path of every 2D engine (SMC draws one primitive per
particle per step), so it must cost about a microsecond, not a numpy call per pixel row.

A pixel is covered when its centre lies inside the primitive. Strokes and discs are
never drawn thinner than one pixel (radius >= 0.5 px), as a rasterised line of width 1
would be, so thin branches do not vanish at low resolution.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from ..core.errors import InvalidArgumentError
from ..core.kernels import once_per_process
from ..core.limits import check_memory
from .primitives import Disc, Ellipse, Polygon, Segment, Viewport, bounds

MIN_RADIUS_PX = 0.5


@numba.njit(cache=True, nogil=True)
def _cover(pixels, k, value, gain, changed, n_new, gain_sum):
    if pixels[k] == 0:
        changed[n_new] = k
        n_new += 1
        if gain.shape[0] > 0:
            gain_sum += gain[k]
    pixels[k] = value
    return n_new, gain_sum


@numba.njit(cache=True, nogil=True, inline="always")
def _pixel_range(lo, hi, n):
    """Pixel indices floor(lo) .. ceil(hi) clipped to 0 .. n - 1, as (first, last); last <
    first when none. Clipped before the conversion to int: a finite coordinate past 9.2e18
    pixels (a growth factor typed 1.9 for 0.9) overflowed int64, and the loops then ran
    out of bounds (a segfault) or for ever (SIGTERM unheeded)."""
    first = max(np.floor(lo), 0.0)
    last = min(np.ceil(hi), n - 1.0)
    if not first <= last:  # also NaN
        return 0, -1
    return int(first), int(last)


@numba.njit(cache=True, nogil=True)
def _draw_capsule(pixels, width, height, value, x0, y0, x1, y1, r, gain, changed):
    n_new = 0
    gain_sum = 0.0
    i_lo, i_hi = _pixel_range(min(x0, x1) - r, max(x0, x1) + r, width)
    j_lo, j_hi = _pixel_range(min(y0, y1) - r, max(y0, y1) + r, height)
    dx = x1 - x0
    dy = y1 - y0
    length2 = dx * dx + dy * dy
    r2 = r * r
    if length2 == np.inf:  # a segment past 1e154 pixels: its squared length overflows, so
        length = np.hypot(dx, dy)  # project on the unit direction (along it, in pixels) instead
        ux, uy = dx / length, dy / length
    for j in range(j_lo, j_hi + 1):
        py = j + 0.5
        for i in range(i_lo, i_hi + 1):
            px = i + 0.5
            t = 0.0
            if length2 == np.inf:
                along = min(length, max(0.0, (px - x0) * ux + (py - y0) * uy))
                ex = px - (x0 + along * ux)
                ey = py - (y0 + along * uy)
            else:
                if length2 > 0.0:
                    t = ((px - x0) * dx + (py - y0) * dy) / length2
                    t = min(1.0, max(0.0, t))
                ex = px - (x0 + t * dx)
                ey = py - (y0 + t * dy)
            if ex * ex + ey * ey <= r2:
                n_new, gain_sum = _cover(pixels, j * width + i, value, gain, changed, n_new, gain_sum)
    return n_new, gain_sum


@numba.njit(cache=True, nogil=True)
def _draw_ellipse(pixels, width, height, value, cx, cy, ux, uy, a, b, gain, changed):
    # (ux, uy): unit vector of the ``a`` axis, in pixel space.
    n_new = 0
    gain_sum = 0.0
    hx = np.sqrt((a * ux) ** 2 + (b * uy) ** 2)
    hy = np.sqrt((a * uy) ** 2 + (b * ux) ** 2)
    i_lo, i_hi = _pixel_range(cx - hx, cx + hx, width)
    j_lo, j_hi = _pixel_range(cy - hy, cy + hy, height)
    ia2 = 1.0 / (a * a)
    ib2 = 1.0 / (b * b)
    for j in range(j_lo, j_hi + 1):
        dy = j + 0.5 - cy
        for i in range(i_lo, i_hi + 1):
            dx = i + 0.5 - cx
            u = dx * ux + dy * uy
            v = -dx * uy + dy * ux
            if u * u * ia2 + v * v * ib2 <= 1.0:
                n_new, gain_sum = _cover(pixels, j * width + i, value, gain, changed, n_new, gain_sum)
    return n_new, gain_sum


@numba.njit(cache=True, nogil=True)
def _draw_polygon(pixels, width, height, value, xs, ys, gain, changed):
    n_new = 0
    gain_sum = 0.0
    n = xs.shape[0]
    i_lo, i_hi = _pixel_range(xs.min(), xs.max(), width)
    j_lo, j_hi = _pixel_range(ys.min(), ys.max(), height)
    for j in range(j_lo, j_hi + 1):
        py = j + 0.5
        for i in range(i_lo, i_hi + 1):
            px = i + 0.5
            inside = False
            a = n - 1
            for b in range(n):
                if (ys[b] > py) != (ys[a] > py):
                    x_cross = xs[b] + (py - ys[b]) * (xs[a] - xs[b]) / (ys[a] - ys[b])
                    if px < x_cross:
                        inside = not inside
                a = b
            if inside:
                n_new, gain_sum = _cover(pixels, j * width + i, value, gain, changed, n_new, gain_sum)
    return n_new, gain_sum


_NO_GAIN = np.zeros(0, dtype=np.float64)


class Canvas:
    """A ``height x width`` raster of a world viewport, drawn into incrementally.

    ``pixels`` is a flat ``uint8`` array (row-major); 0 is empty; ``filled_count`` counts
    the non-empty pixels. :meth:`add` draws a
    primitive and returns how many pixels became non-empty; their flat indices are in
    :attr:`last_changed` until the next draw. If a ``gain`` array is attached (one float
    per pixel), :attr:`gain_total` accumulates ``gain`` over newly filled pixels — the
    O(changed pixels) update an image target's score needs. :attr:`extent` is the world
    bounding box of everything drawn, to penalise geometry outside the viewport.
    """

    __slots__ = ("viewport", "width", "height", "pixels", "gain", "gain_total", "extent",
                 "_scale_x", "_scale_y", "_changed", "_n_changed", "value", "filled_count", "min_radius_px",
                 "_ox", "_oy", "_xmax", "_ymax", "_outside")

    # capabilities (procmod.core.protocols.Output)
    dimension = 2
    supports_removal = False  # pixels are covered or not: a drawn primitive cannot be taken back
    supports_part_cache = False

    def __init__(self, viewport, width: int, height: int | None = None, gain=None, value: int = 1,
                 min_radius_px: float = MIN_RADIUS_PX):
        self.viewport = Viewport(*viewport)
        self.width = int(width)
        self.height = int(width if height is None else height)
        if self.width < 1 or self.height < 1:
            raise InvalidArgumentError(f"canvas size must be positive, got {self.width}x{self.height}")
        # pixels, scratch indices and a gain: refused before numpy's raw MemoryError
        check_memory(f"a {self.width}x{self.height} canvas", self.width * self.height * 17.0,
                     "use a smaller canvas size")
        vp = self.viewport
        if not (np.isfinite(vp).all() and vp.xmin < vp.xmax and vp.ymin < vp.ymax):
            # (12, -12, ...) drew nothing at all, without a word: every part fell "outside"
            raise InvalidArgumentError(f"the canvas viewport is (xmin, xmax, ymin, ymax) with xmin < xmax and ymin "
                                       f"< ymax, finite; got {tuple(float(v) for v in vp)}")
        self.pixels = np.zeros(self.width * self.height, dtype=np.uint8)
        self.gain = _NO_GAIN if gain is None else np.ascontiguousarray(gain, dtype=np.float64).ravel()
        if self.gain.shape[0] not in (0, self.pixels.shape[0]):
            raise InvalidArgumentError(f"gain must have one value per pixel ({self.pixels.shape[0]}), got "
                                       f"{self.gain.shape[0]}")
        self.gain_total = 0.0
        self.extent = None
        vp = self.viewport
        self._scale_x = self.width / (vp.xmax - vp.xmin)
        self._scale_y = self.height / (vp.ymax - vp.ymin)
        self._changed = np.empty(self.pixels.shape[0], dtype=np.int64)  # shared scratch
        self._n_changed = 0
        self.value = value
        self.filled_count = 0
        self.min_radius_px = float(min_radius_px)
        self._ox, self._oy, self._xmax, self._ymax = vp.xmin, vp.ymin, vp.xmax, vp.ymax
        self._outside = False  # has anything been drawn beyond the viewport?
        load_kernels()

    def copy(self) -> "Canvas":
        """A copy with its own pixels; the gain array and scratch buffer are shared."""
        other = type(self).__new__(type(self))
        other.viewport = self.viewport
        other.width = self.width
        other.height = self.height
        other.pixels = self.pixels.copy()
        other.gain = self.gain
        other.gain_total = self.gain_total
        other.extent = self.extent
        other._scale_x = self._scale_x
        other._scale_y = self._scale_y
        other._changed = self._changed
        other._n_changed = 0
        other.value = self.value
        other.filled_count = self.filled_count
        other.min_radius_px = self.min_radius_px
        other._ox, other._oy, other._xmax, other._ymax = self._ox, self._oy, self._xmax, self._ymax
        other._outside = self._outside
        return other

    @property
    def last_changed(self) -> np.ndarray:
        """Flat indices of the pixels the last :meth:`add` filled (valid until the next)."""
        return self._changed[: self._n_changed]

    @property
    def filled(self) -> np.ndarray:
        """Boolean ``(height, width)`` image of the non-empty pixels."""
        return (self.pixels != 0).reshape(self.height, self.width)

    def add(self, geometry) -> int:
        """Draw one primitive; returns the number of newly filled pixels."""
        # The hot path of every 2D engine: plain floats in locals, no namedtuple lookups.
        ox, oy = self._ox, self._oy
        sx, sy = self._scale_x, self._scale_y
        least = self.min_radius_px
        cls = type(geometry)
        if cls is Segment:
            x0, y0, x1, y1, w = geometry[:5]
            # refused before the kernels see it: a NaN would draw nothing, or garbage. A sum
            # is NaN or infinite when a term is, and t - t is 0 only for a finite t; a
            # comparison with NaN is false, so w >= 0 also refuses a NaN width
            total = 0.25 * x0 + 0.25 * y0 + 0.25 * x1 + 0.25 * y1  # quarters: no overflow of finite ones
            if not (w >= 0.0 and total - total == 0.0):
                raise ValueError(_BAD_NUMBERS.format("width"))
            r = 0.25 * w * (sx + sy)
            n, g = _draw_capsule(self.pixels, self.width, self.height, self.value,
                                 (x0 - ox) * sx, (y0 - oy) * sy, (x1 - ox) * sx, (y1 - oy) * sy,
                                 r if r > least else least, self.gain, self._changed)
            w *= 0.5
            if x0 < x1:
                bx0, bx1 = x0 - w, x1 + w
            else:
                bx0, bx1 = x1 - w, x0 + w
            if y0 < y1:
                by0, by1 = y0 - w, y1 + w
            else:
                by0, by1 = y1 - w, y0 + w
        elif cls is Disc:
            x, y, radius = geometry[:3]
            total = 0.5 * x + 0.5 * y
            if not (radius >= 0.0 and total - total == 0.0):
                raise ValueError(_BAD_NUMBERS.format("radius"))
            r = 0.5 * radius * (sx + sy)
            px, py = (x - ox) * sx, (y - oy) * sy
            n, g = _draw_capsule(self.pixels, self.width, self.height, self.value, px, py, px, py,
                                 r if r > least else least, self.gain, self._changed)
            bx0, bx1, by0, by1 = x - radius, x + radius, y - radius, y + radius
        elif cls is Ellipse:
            x, y, angle, length, width = geometry[:5]
            total = 0.25 * x + 0.25 * y + 0.25 * angle
            if not (length >= 0.0 and width >= 0.0 and total - total == 0.0):
                raise ValueError(_BAD_NUMBERS.format("length and width"))
            s = 0.5 * (sx + sy)  # viewports are assumed to have square pixels here
            ha, hb = 0.5 * length, 0.5 * width
            a, b = ha * s, hb * s
            ca, sa = math.cos(angle), math.sin(angle)
            n, g = _draw_ellipse(self.pixels, self.width, self.height, self.value,
                                 (x - ox) * sx, (y - oy) * sy, ca, sa,
                                 a if a > least else least, b if b > least else least,
                                 self.gain, self._changed)
            hx, hy = math.hypot(ha * ca, hb * sa), math.hypot(ha * sa, hb * ca)  # as bounds()
            bx0, bx1, by0, by1 = x - hx, x + hx, y - hy, y + hy
        elif cls is Polygon:
            pts = np.asarray(geometry.points, dtype=np.float64)
            if pts.ndim != 2 or pts.shape[0] < 3 or pts.shape[1] != 2:
                raise ValueError("a Polygon needs at least three (x, y) points")
            if not np.isfinite(pts).all():
                raise ValueError("a Polygon's points must be finite numbers (not NaN or infinity); find the rule's "
                                 "arithmetic that makes them")
            n, g = _draw_polygon(self.pixels, self.width, self.height, self.value,
                                 (pts[:, 0] - ox) * sx, (pts[:, 1] - oy) * sy, self.gain, self._changed)
            bx0, bx1, by0, by1 = bounds(geometry)
        else:
            raise TypeError(f"a 2D canvas cannot draw {geometry!r}")
        e = self.extent
        if e is None:
            self.extent = (bx0, bx1, by0, by1)
        elif bx0 < e[0] or bx1 > e[1] or by0 < e[2] or by1 > e[3]:
            self.extent = (min(e[0], bx0), max(e[1], bx1), min(e[2], by0), max(e[3], by1))
        if bx0 < ox or bx1 > self._xmax or by0 < oy or by1 > self._ymax:
            self._outside = True
        self._n_changed = n
        self.gain_total += g
        self.filled_count += n
        return n

    def out_of_bounds(self) -> tuple:
        """How far the drawn geometry extends beyond the viewport, as fractions (ex, ey)."""
        if not self._outside:
            return 0.0, 0.0
        vp = self.viewport
        x0, x1, y0, y1 = self.extent
        ex = (max(vp.xmin - x0, 0.0) + max(x1 - vp.xmax, 0.0)) / (vp.xmax - vp.xmin)
        ey = (max(vp.ymin - y0, 0.0) + max(y1 - vp.ymax, 0.0)) / (vp.ymax - vp.ymin)
        return ex, ey


_BAD_NUMBERS = ("its coordinates must be finite numbers (not NaN or infinity) and its {} at least 0; find the "
                "rule's arithmetic that makes it")


@once_per_process
def load_kernels() -> None:
    """Load the drawing kernels, with the argument types :meth:`Canvas.add` passes; the
    first :class:`Canvas` a process makes calls it (see :mod:`procmod.core.kernels`)."""
    scratch = Canvas(Viewport(0.0, 1.0, 0.0, 1.0), 1)
    for primitive in (Segment(0.2, 0.2, 0.8, 0.8, 0.5), Disc(0.5, 0.5, 0.5),
                      Ellipse(0.5, 0.5, 0.0, 1.0, 0.5), Polygon(((0.0, 0.0), (1.0, 0.0), (0.0, 1.0)))):
        scratch.add(primitive)


def rasterize(geometries, viewport, width: int, height: int | None = None) -> np.ndarray:
    """Boolean ``(height, width)`` mask of a list of primitives (same rules as :class:`Canvas`)."""
    canvas = Canvas(viewport, width, height)
    for geometry in geometries:
        canvas.add(geometry)
    return canvas.filled
