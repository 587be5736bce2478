"""Cameras, silhouette rasters and shaded previews of 3D parts.

Parts are triangulated (:func:`procmod.geometry.solid.part_triangles`) and rasterised by
numba kernels at pixel centres: a silhouette keeps which pixels any part covers (with a
per-pixel gain for incremental image scores, as the 2D canvas does); a preview keeps a
z-buffer and Lambert-shaded colours.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

import numba
import numpy as np

from ..core.errors import InvalidArgumentError
from ..core.kernels import once_per_process
from .solid import Box, part_bounds, part_triangles

SILHOUETTE_SEGMENTS = 12


class Camera(NamedTuple):
    """A camera looking from ``eye`` at ``look_at``.

    ``projection`` is "perspective" (``fov`` = vertical field of view in degrees) or
    "orthographic" (``fov`` = the height of the view in world units). Images have
    ``width`` x ``height`` pixels, row 0 at the top.
    """

    eye: tuple
    look_at: tuple
    up: tuple = (0.0, 1.0, 0.0)
    projection: str = "perspective"
    fov: float = 40.0
    width: int = 64
    height: int = 64

    def basis(self):
        """Eye position and the right, up and forward unit vectors (cached per camera)."""
        return _basis(self)

    def _compute_basis(self):
        eye = np.asarray(self.eye, dtype=np.float64)
        forward = np.asarray(self.look_at, dtype=np.float64) - eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up, dtype=np.float64))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        return eye, right, up, forward

    def project(self, points: np.ndarray) -> np.ndarray:
        """Pixel x, pixel y and depth of world points ``(..., 3)``; depth <= 0 is behind."""
        linear = _linear_projection(self)  # rows: (x, y, depth) as affine maps of the point
        q = np.asarray(points, dtype=np.float64) @ linear[:, :3].T + linear[:, 3]
        if self.projection == "perspective":
            depth = q[..., 2:3]
            q[..., :2] = 0.5 * np.array([self.width, self.height]) + q[..., :2] / np.where(depth > 1e-9, depth, 1e-9)
        else:
            q[..., :2] += 0.5 * np.array([self.width, self.height])
        return q


@lru_cache(maxsize=64)
def _basis(camera: Camera):
    return camera._compute_basis()


@lru_cache(maxsize=64)
def _linear_projection(camera: Camera) -> np.ndarray:
    """3x4 affine map from world points to (scaled x, scaled y, depth) for ``camera``.

    Orthographic: x and y are already pixel offsets from the image centre. Perspective:
    x and y still need dividing by the depth. Image y grows downwards.
    """
    eye, right, up, forward = camera.basis()
    if camera.projection == "perspective":
        scale = 0.5 * camera.height / math.tan(math.radians(camera.fov) / 2)
    elif camera.projection == "orthographic":
        scale = camera.height / camera.fov
    else:
        raise ValueError(f"projection must be 'perspective' or 'orthographic', got {camera.projection!r}")
    rows = np.array([scale * right, -scale * up, forward])
    return np.hstack([rows, -(rows @ eye)[:, None]])


NEAR = 1e-4
"""A perspective camera's near plane, as a fraction of its eye's distance to look_at."""


def clip_to_near(tris: np.ndarray, camera: Camera) -> np.ndarray:
    """World triangles ``(n, 3, 3)`` cut at a camera's near plane (depth
    :data:`NEAR` x the eye's distance to look_at): those wholly in front as they are, those
    wholly behind dropped, and those across it as the one or two triangles of their part
    in front. (Skipping every triangle with a corner behind the camera lost most of a
    coarse mesh running under it: 16 pixels of a wall's 918.)"""
    eye, _, _, forward = camera.basis()
    near = NEAR * float(np.linalg.norm(np.subtract(camera.look_at, camera.eye)))
    depth = (tris - eye) @ forward - near  # per corner: >= 0 in front
    front = depth >= 0
    count = front.sum(axis=1)
    if count.min() == 3:
        return tris
    out = [tris[count == 3]]
    for inside, cut in ((1, _clip_one_in_front), (2, _clip_two_in_front)):
        chosen = count == inside
        if chosen.any():
            out.append(cut(tris[chosen], depth[chosen], front[chosen]))
    return np.concatenate(out)


def _rolled(tris, depth, first):
    """Each triangle's corners turned cyclically so that corner ``first[i]`` comes first
    (the winding is kept)."""
    order = (first[:, None] + np.arange(3)) % 3
    rows = np.arange(len(tris))[:, None]
    return tris[rows, order], depth[rows, order]


def _on_plane(a, b, da, db):
    """The point where edge a-b crosses the plane (signed distances da >= 0 > db)."""
    t = (da / (da - db))[:, None]
    return a + t * (b - a)


def _clip_one_in_front(tris, depth, front):
    t, d = _rolled(tris, depth, np.argmax(front, axis=1))  # the corner in front first
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    return np.stack([a, _on_plane(a, b, d[:, 0], d[:, 1]), _on_plane(a, c, d[:, 0], d[:, 2])], axis=1)


def _clip_two_in_front(tris, depth, front):
    t, d = _rolled(tris, depth, (np.argmin(front, axis=1) + 1) % 3)  # the corner behind last
    a, b, c = t[:, 0], t[:, 1], t[:, 2]
    bc, ac = _on_plane(b, c, d[:, 1], d[:, 2]), _on_plane(a, c, d[:, 0], d[:, 2])
    return np.concatenate([np.stack([a, b, bc], axis=1), np.stack([a, bc, ac], axis=1)])


@numba.njit(cache=True, inline="always")
def _pixel_box(ax, ay, bx, by, cx, cy, width, height):
    """Pixel index range (i0, i1, j0, j1) of a triangle's bounding box, clipped to the image."""
    # clipped before the conversion to int: a coordinate past 9.2e18 pixels overflows int64
    # (a part flung far by a model's typo, or a corner just in front of the near plane)
    i0, i1 = max(np.floor(min(ax, bx, cx)), 0.0), min(np.ceil(max(ax, bx, cx)), width - 1.0)
    j0, j1 = max(np.floor(min(ay, by, cy)), 0.0), min(np.ceil(max(ay, by, cy)), height - 1.0)
    if not (i0 <= i1 and j0 <= j1):  # off the image (or NaN)
        return 0, -1, 0, -1
    return int(i0), int(i1), int(j0), int(j1)


@numba.njit(cache=True)
def _raster_part(counts, mark, width, height, tri2d, gain, state, out):
    """Count one more hit on every pixel whose centre is inside any of a part's triangles.

    Each pixel counts once per part (``mark``, all zero on entry and on return, dedupes
    pixels shared by several triangles); their indices go to ``out``. state = [new
    pixels, gain sum, saturated flag]. Returns how many indices were written.
    """
    n = 0
    for t in range(tri2d.shape[0]):
        ax, ay = tri2d[t, 0, 0], tri2d[t, 0, 1]
        bx, by = tri2d[t, 1, 0], tri2d[t, 1, 1]
        cx, cy = tri2d[t, 2, 0], tri2d[t, 2, 1]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0:
            continue
        i0, i1, j0, j1 = _pixel_box(ax, ay, bx, by, cx, cy, width, height)
        for j in range(j0, j1 + 1):
            py = j + 0.5
            for i in range(i0, i1 + 1):
                px = i + 0.5
                e0 = ((bx - ax) * (py - ay) - (by - ay) * (px - ax)) * area
                e1 = ((cx - bx) * (py - by) - (cy - by) * (px - bx)) * area
                e2 = ((ax - cx) * (py - cy) - (ay - cy) * (px - cx)) * area
                if e0 >= 0 and e1 >= 0 and e2 >= 0:
                    k = j * width + i
                    if mark[k] == 0:
                        mark[k] = 1
                        out[n] = k
                        n += 1
    for q in range(n):
        mark[out[q]] = 0
    _count_pixels(counts, out[:n], gain, state)
    return n


@numba.njit(cache=True)
def _count_pixels(counts, pixels, gain, state):
    """One more hit on each pixel index (state as in :func:`_raster_part`)."""
    for k in pixels:
        c = counts[k]
        if c == 0:
            state[0] += 1
            if gain.shape[0] > 0:
                state[1] += gain[k]
        if c < 65535:
            counts[k] = c + 1
        else:
            state[2] = 1.0


@numba.njit(cache=True)
def _uncount_pixels(counts, pixels, gain, state):
    """One hit less on each pixel index: state[0] counts pixels left uncovered, state[1]
    their gain."""
    for k in pixels:
        c = counts[k]
        if c == 1:
            state[0] += 1
            if gain.shape[0] > 0:
                state[1] += gain[k]
        if c > 0:
            counts[k] = c - 1


_NO_GAIN = np.zeros(0)


class Silhouettes:
    """An output accumulator: one silhouette raster per camera, drawn incrementally.

    ``pixels[c]`` is camera ``c``'s flat ``uint16`` raster of per-pixel part counts (how
    many parts cover the pixel; 0 = empty); ``gains[c]`` an optional per-pixel gain;
    ``gain_total`` sums the gains of covered pixels over all views. Because pixels are
    counted, :meth:`remove` is the exact inverse of :meth:`add` (until a count saturates,
    see ``saturated``). Triangles across a camera's near plane are cut there
    (:func:`clip_to_near`); what lies behind it is not seen, through an orthographic camera
    too (as in Blender: it saw through its eye what lay behind it, which the placement note
    called unseen). With :meth:`use_part_cache`, the pixels a
    part covers are looked up by value instead of projected and rasterised again (full
    replays re-add mostly the same parts).
    """

    __slots__ = ("cameras", "pixels", "gains", "gain_total", "filled_count", "extent", "n_parts", "_state",
                 "_scratch", "part_cache", "saturated")

    # capabilities (procmod.core.protocols.Output): pixels are counted, so remove is exact
    dimension = 3
    supports_removal = True
    supports_part_cache = True

    def __init__(self, cameras, gains=None):
        self.cameras = tuple(cameras)
        self.pixels = [np.zeros(c.width * c.height, dtype=np.uint16) for c in self.cameras]
        self.gains = [(_NO_GAIN if g is None else np.ascontiguousarray(g, dtype=np.float64).ravel())
                      for g in (gains or [None] * len(self.cameras))]
        self.gain_total = 0.0
        self.filled_count = 0
        self.extent = None
        self.n_parts = 0
        self._state = np.zeros(3)
        # per-camera (mark, index buffer) work arrays, shared by copies (kernels hold the GIL)
        self._scratch = [(np.zeros(c.width * c.height, dtype=np.uint8), np.empty(c.width * c.height, dtype=np.int64))
                         for c in self.cameras]
        self.part_cache = None
        self.saturated = False
        load_kernels()

    def copy(self) -> "Silhouettes":
        other = type(self).__new__(type(self))
        for name in self.__slots__:
            setattr(other, name, getattr(self, name))
        other.pixels = [p.copy() for p in self.pixels]
        return other

    def use_part_cache(self) -> None:
        """Look parts' pixels up in this process's cache for these cameras."""
        from .voxel import PartCache
        self.part_cache = _PIXEL_CACHES.setdefault(self.cameras, PartCache())

    def image(self, index: int = 0) -> np.ndarray:
        """Boolean ``(height, width)`` silhouette of camera ``index``."""
        c = self.cameras[index]
        return (self.pixels[index] != 0).reshape(c.height, c.width)

    def _rasterise(self, part, cache):
        """Draw a part (one more count on each pixel it covers); returns its per-camera
        pixel indices when ``cache`` wants them, else None."""
        # 12-gon cylinders: silhouette rasters are coarse, and triangles dominate the cost.
        tris = part_triangles(part, SILHOUETTE_SEGMENTS)
        state = self._state
        entry = [] if cache else None
        for camera, pixels, gain, (mark, out) in zip(self.cameras, self.pixels, self.gains, self._scratch):
            projected = camera.project(clip_to_near(tris, camera))
            n = _raster_part(pixels, mark, camera.width, camera.height,
                             np.ascontiguousarray(projected[:, :, :2]), gain, state, out)
            if entry is not None:
                entry.append(out[:n].copy())
        return entry

    def add(self, part) -> int:
        lo, hi = part_bounds(part)
        self.extent = (lo, hi) if self.extent is None else (np.minimum(self.extent[0], lo),
                                                          np.maximum(self.extent[1], hi))
        self.n_parts += 1
        state = self._state
        state[:] = 0.0
        cache = self.part_cache
        entry = cache.get(part) if cache is not None else None
        if entry is not None:
            for pixels, gain, idx in zip(self.pixels, self.gains, entry):
                _count_pixels(pixels, idx, gain, state)
        else:
            entry = self._rasterise(part, cache is not None)
            if cache is not None:
                cache.put(part, tuple(entry), sum(len(e) for e in entry) + 1)
        new = int(state[0])
        self.gain_total += float(state[1])
        if state[2]:
            self.saturated = True
        self.filled_count += new
        return new

    def remove(self, part) -> int:
        """Take out one part added earlier (the exact inverse of :meth:`add`, except that
        ``extent`` is left as it is). Returns the number of pixels left uncovered.

        Raises InvalidArgumentError once the rasters are saturated (a count hit 65535).
        """
        if self.saturated:
            raise InvalidArgumentError("saturated silhouettes (a count reached 65535) cannot remove parts exactly")
        cache = self.part_cache
        entry = cache.get(part) if cache is not None else None
        state = self._state
        if entry is None:
            # Learn the part's pixels by drawing it once more into these rasters and taking
            # that count off again (no scratch rasters to allocate per removed part).
            state[:] = 0.0
            entry = self._rasterise(part, True)
            for pixels, gain, idx in zip(self.pixels, self.gains, entry):
                _uncount_pixels(pixels, idx, gain, state)
            if state[2]:  # a count was already at its limit: the rasters are no longer exact
                self.saturated = True
                raise InvalidArgumentError("saturated silhouettes (a count reached 65535) cannot remove parts exactly")
            if cache is not None:
                cache.put(part, tuple(entry), sum(len(e) for e in entry) + 1)
        state[:] = 0.0
        for pixels, gain, idx in zip(self.pixels, self.gains, entry):
            _uncount_pixels(pixels, idx, gain, state)
        gone = int(state[0])
        self.gain_total -= float(state[1])
        self.filled_count -= gone
        self.n_parts -= 1
        return gone


_PIXEL_CACHES: dict = {}  # cameras -> PartCache of per-camera pixel indices (one per process)


@once_per_process
def load_kernels() -> None:
    """Load the silhouette kernels, with the argument types adding and removing parts
    pass; the first :class:`Silhouettes` a process makes calls it (see
    :mod:`procmod.core.kernels`)."""
    scene = Silhouettes([Camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), projection="orthographic", fov=2.0,
                                width=4, height=4)])
    box = Box((1.0, 1.0, 1.0))
    scene.add(box)
    scene.remove(box)
    _count_pixels(scene.pixels[0], np.zeros(0, dtype=np.int64), scene.gains[0], scene._state)  # a part cache's hit


@numba.njit(cache=True)
def _shade_triangles(depth_buffer, colour_buffer, width, height, tri, shades, colours):
    for t in range(tri.shape[0]):
        ax, ay, az = tri[t, 0, 0], tri[t, 0, 1], tri[t, 0, 2]
        bx, by, bz = tri[t, 1, 0], tri[t, 1, 1], tri[t, 1, 2]
        cx, cy, cz = tri[t, 2, 0], tri[t, 2, 1], tri[t, 2, 2]
        area = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)
        if area == 0.0 or min(az, bz, cz) <= 1e-6:
            continue
        i0, i1, j0, j1 = _pixel_box(ax, ay, bx, by, cx, cy, width, height)
        for j in range(j0, j1 + 1):
            py = j + 0.5
            for i in range(i0, i1 + 1):
                px = i + 0.5
                w0 = ((bx - px) * (cy - py) - (by - py) * (cx - px)) / area
                w1 = ((cx - px) * (ay - py) - (cy - py) * (ax - px)) / area
                w2 = 1.0 - w0 - w1
                if w0 >= 0 and w1 >= 0 and w2 >= 0:
                    z = w0 * az + w1 * bz + w2 * cz
                    k = j * width + i
                    if z < depth_buffer[k]:
                        depth_buffer[k] = z
                        for ch in range(3):
                            colour_buffer[k, ch] = colours[t, ch] * shades[t]


def shaded_image(parts, camera: Camera, colour_of, background=(255, 255, 255), supersample: int = 2):
    """A Lambert-shaded RGB render (``uint8`` array) of parts seen from ``camera``."""
    w, h = camera.width * supersample, camera.height * supersample
    cam = camera._replace(width=w, height=h)
    tris, colours = [], []
    for part in parts:
        t = part_triangles(part)
        tris.append(t)
        colours.append(np.tile(np.asarray(colour_of(part.tag), dtype=np.float64), (len(t), 1)))
    depth = np.full(w * h, np.inf)
    rgb = np.tile(np.asarray(background, dtype=np.float64), (w * h, 1))
    if tris:
        world = np.concatenate(tris)
        normals = np.cross(world[:, 1] - world[:, 0], world[:, 2] - world[:, 0])
        normals /= np.maximum(np.linalg.norm(normals, axis=1, keepdims=True), 1e-12)
        light = np.array([0.4, 0.8, 0.45])
        light /= np.linalg.norm(light)
        shades = 0.35 + 0.65 * np.abs(normals @ light)  # two-sided: triangle winding varies
        _shade_triangles(depth, rgb, w, h, np.ascontiguousarray(cam.project(world)), shades,
                         np.concatenate(colours))
    image = rgb.reshape(camera.height, supersample, camera.width, supersample, 3).mean(axis=(1, 3))
    return np.round(image).astype(np.uint8)


def framing_camera(lo, hi, width: int = 256, height: int = 256, direction=(1.0, 0.8, 1.4),
                   up=(0.0, 1.0, 0.0), fov: float = 35.0) -> Camera:
    """A perspective camera that frames the box [lo, hi] from ``direction``."""
    lo, hi = np.asarray(lo, dtype=np.float64), np.asarray(hi, dtype=np.float64)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), 1e-6)
    d = np.asarray(direction, dtype=np.float64)
    d /= np.linalg.norm(d)
    distance = radius / math.sin(math.radians(fov) / 2) * 1.05
    return Camera(tuple(centre + distance * d), tuple(centre), tuple(up), "perspective", fov, width, height)
