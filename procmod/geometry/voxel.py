"""Voxelizing 3D parts into a fixed grid, incrementally, counting overlaps.

A voxel is covered by a part when its centre lies inside the part: exact for boxes and
cylinders (a point-in-solid test in the part's local frame) and for closed meshes (ray
parity along z). The numba kernels visit only the voxels of a part's bounding box, keep
a per-voxel hit count (so voxels hit more than once — self-intersections — are counted),
count covered lattice cells that fall outside the grid, and accumulate a per-voxel gain
for the first hit, which is how volume scores stay O(voxels changed) per part. Parts can
also be removed again (:meth:`VoxelScene.remove`, the exact inverse of ``add`` while no
count has saturated), which lets the GA derive an offspring's scene from its parent's.
"""

from __future__ import annotations

from typing import NamedTuple

import numba
import numpy as np

from ..core.errors import InvalidArgumentError
from ..core.kernels import once_per_process
from .solid import Box, Cylinder, Mesh, part_bounds, part_triangles, transform_values, with_positive_length


class VoxelGrid(NamedTuple):
    """A regular grid: ``origin`` is the min corner, ``size`` the voxel edge, ``shape`` (nx, ny, nz)."""

    origin: tuple
    size: float
    shape: tuple

    @property
    def upper(self) -> np.ndarray:
        return np.asarray(self.origin, dtype=np.float64) + self.size * np.asarray(self.shape)

    def centres(self) -> np.ndarray:
        """Voxel centres, shape (nx, ny, nz, 3)."""
        axes = [self.origin[a] + self.size * (np.arange(self.shape[a]) + 0.5) for a in range(3)]
        return np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1)

    @classmethod
    def around(cls, lo, hi, size: float, margin: float = 0.0) -> "VoxelGrid":
        """The grid of voxel edge ``size`` covering the box [lo, hi] grown by ``margin``."""
        lo = np.asarray(lo, dtype=np.float64) - margin
        hi = np.asarray(hi, dtype=np.float64) + margin
        shape = tuple(int(max(1, np.ceil((hi[a] - lo[a]) / size))) for a in range(3))
        return cls(tuple(float(v) for v in lo), float(size), shape)


# Lattice cells a part's bounding box may span: the voxel kernels visit each (about 10 ns a
# cell), so this bounds one part's voxelization to about a second.
MAX_PART_CELLS = 1e8


@numba.njit(cache=True, inline="always")
def _too_many_cells(lo, hi, h, state) -> bool:
    """Whether the box ``[lo, hi]`` spans more than :data:`MAX_PART_CELLS` lattice cells
    (with a cell's margin round it); if so the count goes to ``state[6]`` and the kernel
    visits none of them (checked here, in floats, before any index is made an integer)."""
    n = 1.0
    for a in range(3):
        n *= max((hi[a] - lo[a]) / h + 3.0, 1.0)
    if n <= MAX_PART_CELLS:
        return False
    state[6] = n
    return True


@numba.njit(cache=True, inline="always")
def _hit(counts, nx, ny, nz, i, j, k, gain, state, record):
    # state: [new voxels, overlaps, outside] as floats, gain sum at index 3, at index 4
    # the number of voxel indices written to ``record`` (when it is not empty), and at
    # index 5 a flag set when a saturated count (255) could not be incremented
    if i < 0 or j < 0 or k < 0 or i >= nx or j >= ny or k >= nz:
        state[2] += 1
        return
    v = (i * ny + j) * nz + k
    if record.shape[0] > 0:
        record[int(state[4])] = v
        state[4] += 1
    _count(counts, v, gain, state)


@numba.njit(cache=True, inline="always")
def _count(counts, v, gain, state):
    """One more hit of in-grid voxel ``v``: a new voxel (and its gain) or an overlap."""
    c = counts[v]
    if c == 0:
        state[0] += 1
        if gain.shape[0] > 0:
            state[3] += gain[v]
    else:
        state[1] += 1
    if c < 255:
        counts[v] = c + 1
    else:
        state[5] = 1.0


@numba.njit(cache=True)
def _remove_voxels(counts, voxels, gain, state):
    """Take one hit of each voxel in ``voxels`` off the counts: state[0] counts voxels
    left uncovered, state[1] removed overlaps, state[3] the gain of the uncovered ones."""
    for v in voxels:
        c = counts[v]
        if c == 1:
            state[0] += 1
            if gain.shape[0] > 0:
                state[3] += gain[v]
        elif c > 1:
            state[1] += 1
        if c > 0:
            counts[v] = c - 1


@numba.njit(cache=True)
def _voxelize_solid(counts, shape, origin, h, inv, kind, p0, p1, p2, lo, hi, gain, state, record):
    """kind 0: box with half extents (p0, p1, p2); kind 1: frustum r0=p0, r1=p1, length=p2."""
    if _too_many_cells(lo, hi, h, state):
        return
    nx, ny, nz = shape[0], shape[1], shape[2]
    i0 = int(np.floor((lo[0] - origin[0]) / h - 0.5)) + 1
    i1 = int(np.floor((hi[0] - origin[0]) / h - 0.5))
    j0 = int(np.floor((lo[1] - origin[1]) / h - 0.5)) + 1
    j1 = int(np.floor((hi[1] - origin[1]) / h - 0.5))
    k0 = int(np.floor((lo[2] - origin[2]) / h - 0.5)) + 1
    k1 = int(np.floor((hi[2] - origin[2]) / h - 0.5))
    for i in range(i0 - 1, i1 + 2):
        x = origin[0] + (i + 0.5) * h
        for j in range(j0 - 1, j1 + 2):
            y = origin[1] + (j + 0.5) * h
            for k in range(k0 - 1, k1 + 2):
                z = origin[2] + (k + 0.5) * h
                lx = inv[0, 0] * x + inv[0, 1] * y + inv[0, 2] * z + inv[0, 3]
                ly = inv[1, 0] * x + inv[1, 1] * y + inv[1, 2] * z + inv[1, 3]
                lz = inv[2, 0] * x + inv[2, 1] * y + inv[2, 2] * z + inv[2, 3]
                if kind == 0:
                    inside = abs(lx) <= p0 and abs(ly) <= p1 and abs(lz) <= p2
                else:
                    inside = False
                    if 0.0 <= lz <= p2:
                        r = p0 + (p1 - p0) * (lz / p2 if p2 > 0 else 0.0)
                        inside = lx * lx + ly * ly <= r * r
                if inside:
                    _hit(counts, nx, ny, nz, i, j, k, gain, state, record)


@numba.njit(cache=True, inline="always")
def _edge(px, py, qx, qy, x, y):
    """Which side of the line p -> q the point (x, y) lies (positive: to the left), computed
    from the edge's lower endpoint (x, then y) whichever way the triangle runs it: the two
    triangles sharing an edge get the same number, of opposite sign, to the last bit."""
    if px < qx or (px == qx and py < qy):
        return (qx - px) * (y - py) - (qy - py) * (x - px)
    return -((px - qx) * (y - qy) - (py - qy) * (x - qx))


@numba.njit(cache=True, inline="always")
def _owns(e, dx, dy):
    """Whether a triangle holds a point on its edge (edge function ``e`` zero) running
    ``(dx, dy)`` counter-clockwise: of the two triangles sharing an edge, exactly one (the
    edges run opposite ways)."""
    return e > 0.0 or (e == 0.0 and (dy > 0.0 or (dy == 0.0 and dx > 0.0)))


@numba.njit(cache=True)
def _voxelize_mesh(counts, shape, origin, h, tris, lo, hi, gain, state, record):
    """Ray parity along +z through every voxel column of the mesh's bounding box.

    A ray through an edge or a vertex two triangles share is counted by exactly one of
    them: each edge's side test is computed one way for both (:func:`_edge`) and a tie
    goes to one side (:func:`_owns`). Barycentric weights computed in each triangle's own
    vertex order had counted a ray along the diagonal of a grid-aligned cube's face twice
    or not at all, so the column's parity flipped: a Mesh cube lost 4 columns of 100."""
    if _too_many_cells(lo, hi, h, state):
        return
    nx, ny, nz = shape[0], shape[1], shape[2]
    i0 = int(np.floor((lo[0] - origin[0]) / h - 0.5))
    i1 = int(np.floor((hi[0] - origin[0]) / h - 0.5)) + 1
    j0 = int(np.floor((lo[1] - origin[1]) / h - 0.5))
    j1 = int(np.floor((hi[1] - origin[1]) / h - 0.5)) + 1
    zs = np.empty(tris.shape[0])
    for i in range(i0, i1 + 1):
        x = origin[0] + (i + 0.5) * h
        for j in range(j0, j1 + 1):
            y = origin[1] + (j + 0.5) * h
            n = 0
            for t in range(tris.shape[0]):
                ax, ay, az = tris[t, 0, 0], tris[t, 0, 1], tris[t, 0, 2]
                bx, by, bz = tris[t, 1, 0], tris[t, 1, 1], tris[t, 1, 2]
                cx, cy, cz = tris[t, 2, 0], tris[t, 2, 1], tris[t, 2, 2]
                d = (bx - ax) * (cy - ay) - (by - ay) * (cx - ax)  # twice the signed area seen from +z
                if d == 0.0:
                    continue  # edge-on: its neighbours hold the ray
                sign = 1.0 if d > 0.0 else -1.0  # counter-clockwise seen from +z, either way it faces
                ea = sign * _edge(bx, by, cx, cy, x, y)  # the edge opposite a, b -> c
                eb = sign * _edge(cx, cy, ax, ay, x, y)  # c -> a
                ec = sign * _edge(ax, ay, bx, by, x, y)  # a -> b
                if (_owns(ea, sign * (cx - bx), sign * (cy - by)) and _owns(eb, sign * (ax - cx), sign * (ay - cy))
                        and _owns(ec, sign * (bx - ax), sign * (by - ay))):
                    total = ea + eb + ec
                    if total > 0.0:  # weights first: e * z would cube the coordinates (inf past 1e102)
                        zs[n] = (ea / total) * az + (eb / total) * bz + (ec / total) * cz
                        n += 1
            if n < 2:
                continue
            zz = np.sort(zs[:n])
            for p in range(0, n - 1, 2):
                k_lo = int(np.ceil((zz[p] - origin[2]) / h - 0.5))
                k_hi = int(np.floor((zz[p + 1] - origin[2]) / h - 0.5))
                for k in range(k_lo, k_hi + 1):
                    _hit(counts, nx, ny, nz, i, j, k, gain, state, record)


@numba.njit(cache=True)
def _add_voxels(counts, voxels, gain, state):
    """Add a part already voxelized (its in-grid voxel indices) to the hit counts."""
    for v in voxels:
        _count(counts, v, gain, state)


def _inverse(t: tuple) -> np.ndarray:
    """Inverse of an affine 4x4 transform tuple (plain-Python 3x3 cofactors: faster than
    numpy's general inverse on one small matrix)."""
    a, b, c, tx, d, e, f, ty, g, h, i, tz = t[:12]
    A, B, C = e * i - f * h, -(d * i - f * g), d * h - e * g
    det = a * A + b * B + c * C
    if det == 0.0:
        raise ValueError("a part's transform is singular (scaled to zero along some axis): a volume target "
                         "cannot tell what it covers; scale it by more than 0, or leave the part out")
    r = 1.0 / det
    m00, m01, m02 = A * r, -(b * i - c * h) * r, (b * f - c * e) * r
    m10, m11, m12 = B * r, (a * i - c * g) * r, -(a * f - c * d) * r
    m20, m21, m22 = C * r, -(a * h - b * g) * r, (a * e - b * d) * r
    return np.array(((m00, m01, m02, -(m00 * tx + m01 * ty + m02 * tz)),
                     (m10, m11, m12, -(m10 * tx + m11 * ty + m12 * tz)),
                     (m20, m21, m22, -(m20 * tx + m21 * ty + m22 * tz)),
                     (0.0, 0.0, 0.0, 1.0)))


class PartCache:
    """Voxelized parts by value, for engines that replay whole derivations.

    MCMC proposals (and GA offspring when they are full replays: with an executor, or a
    target without exact removal) replay the full derivation, and most of their parts
    are the parent's, unchanged: an equal part (same shape, transform
    and tag) on the same grid covers the same voxels, so its voxel indices are looked up
    instead of voxelized again. Bounded: past ``max_voxels`` stored indices it starts over.
    """

    def __init__(self, max_voxels: int = 10_000_000):
        self.max_voxels = max_voxels
        self.entries = {}
        self.stored = 0
        self.hits = self.misses = 0

    def get(self, part):
        try:
            entry = self.entries.get(part)
        except TypeError:  # a Mesh a model gave numpy arrays (unhashable): never stored
            entry = None
        if entry is None:
            self.misses += 1
        else:
            self.hits += 1
        return entry

    def put(self, part, entry, size: int | None = None) -> None:
        """Store ``entry`` for ``part``; ``size`` (default ``len(entry[0])``) counts
        towards ``max_voxels``."""
        size = len(entry[0]) if size is None else int(size)
        try:
            hash(part)
        except TypeError:  # a Mesh of numpy arrays: voxelized each time instead
            return
        if self.stored + size > self.max_voxels:
            self.entries.clear()
            self.stored = 0
        self.entries[part] = entry
        self.stored += size


_PART_CACHES: dict = {}  # grid -> PartCache (one per process)
_NO_GAIN = np.zeros(0)
_NO_RECORD = np.zeros(0, dtype=np.int64)


_SCRATCH_COUNTS: dict = {}  # number of voxels -> an all-zero count grid (VoxelScene._entry)


class VoxelScene:
    """An output accumulator that voxelizes every part added to it.

    Attributes
    ----------
    counts : numpy.ndarray
        Flat ``uint8`` hit counts (saturating at 255), index ``(i * ny + j) * nz + k``.
    filled_count, overlaps, outside : int
        Voxels hit at least once; extra hits (self-intersection); covered lattice cells
        outside the grid.
    gain_total : float
        Sum of ``gain`` over voxels at their first hit (when a gain array is attached).
    extent : tuple or None
        World bounds (min xyz, max xyz) of everything added (not shrunk by ``remove``).
    saturated : bool
        True once a hit could not be counted because a voxel's count was already 255;
        from then on ``remove`` is no longer exact and refuses.
    """

    __slots__ = ("grid", "counts", "gain", "gain_total", "filled_count", "overlaps", "outside",
                 "extent", "n_parts", "_shape", "_origin", "_state", "part_cache", "saturated")

    # capabilities (procmod.core.protocols.Output): hits are counted, so remove is exact
    dimension = 3
    supports_removal = True
    supports_part_cache = True

    def __init__(self, grid: VoxelGrid, gain=None):
        self.grid = VoxelGrid(tuple(grid.origin), float(grid.size), tuple(int(n) for n in grid.shape))
        self.counts = np.zeros(int(np.prod(self.grid.shape)), dtype=np.uint8)
        self.gain = _NO_GAIN if gain is None else np.ascontiguousarray(gain, dtype=np.float64).ravel()
        if self.gain.shape[0] not in (0, self.counts.shape[0]):
            raise ValueError("gain must have one value per voxel")
        self.gain_total = 0.0
        self.filled_count = self.overlaps = self.outside = self.n_parts = 0
        self.extent = None
        self._shape = np.array(self.grid.shape, dtype=np.int64)
        self._origin = np.array(self.grid.origin, dtype=np.float64)
        self._state = np.zeros(7)
        self.part_cache = None
        self.saturated = False
        load_kernels()

    def use_part_cache(self) -> None:
        """Look parts up in this process's cache for the grid (see :class:`PartCache`)."""
        self.part_cache = _PART_CACHES.setdefault(self.grid, PartCache())

    def copy(self) -> "VoxelScene":
        other = type(self).__new__(type(self))
        for name in self.__slots__:
            setattr(other, name, getattr(self, name))
        other.counts = self.counts.copy()
        return other

    @property
    def occupancy(self) -> np.ndarray:
        """Boolean ``shape`` array of covered voxels."""
        return (self.counts > 0).reshape(self.grid.shape)

    def _voxelize(self, part, lo, hi, state, record, counts=None) -> None:
        """Count one more hit on the voxels ``part`` covers (in ``counts``, default this
        scene's); their indices go to ``record`` when it is not empty."""
        counts = self.counts if counts is None else counts
        h = self.grid.size
        if isinstance(part, (Box, Cylinder)):
            if isinstance(part, Cylinder):
                part = with_positive_length(part)
            inv = _inverse(transform_values(part))  # a 4x4 array too, as sampling and silhouettes read it
            if isinstance(part, Box):
                kind, p = 0, [0.5 * float(s) for s in part.size]
            else:
                top = part.radius if part.top_radius is None else part.top_radius
                kind, p = 1, [float(part.radius), float(top), float(part.length)]
            _voxelize_solid(counts, self._shape, self._origin, h, inv, kind, p[0], p[1], p[2],
                            lo, hi, self.gain, state, record)
        elif isinstance(part, Mesh):
            _voxelize_mesh(counts, self._shape, self._origin, h, part_triangles(part), lo, hi,
                           self.gain, state, record)
        else:
            raise TypeError(f"a voxel scene cannot add {part!r}")
        if state[6]:  # the kernel refused the part's span (see _too_many_cells)
            self._refuse_span(lo, hi, state[6])

    def add(self, part) -> int:
        """Voxelize one part; returns the number of newly covered voxels."""
        state = self._state
        state[:] = 0.0
        cache = self.part_cache
        entry = cache.get(part) if cache is not None else None
        if entry is not None:
            voxels, outside, lo, hi = entry
            _add_voxels(self.counts, voxels, self.gain, state)
            state[2] = outside
        else:
            lo, hi = part_bounds(part)
            record = self._record_for(lo, hi) if cache is not None else _NO_RECORD
            self._voxelize(part, lo, hi, state, record)
            if cache is not None:
                cache.put(part, (record[:int(state[4])].copy(), int(state[2]), lo, hi))
        n = int(state[0])
        self.filled_count += n
        self.overlaps += int(state[1])
        self.outside += int(state[2])
        self.gain_total += float(state[3])
        self.n_parts += 1
        if state[5]:
            self.saturated = True
        self.extent = (lo, hi) if self.extent is None else (np.minimum(self.extent[0], lo),
                                                          np.maximum(self.extent[1], hi))
        return n

    def _refuse_span(self, lo, hi, cells: float) -> None:
        """A part spanning ``cells`` > :data:`MAX_PART_CELLS` lattice cells: the kernels
        would visit every one, so a target far smaller than the model's parts (a 5 cm mesh
        at 1 mm voxels against a ship of metres) would run for hours, or its record buffer
        ask for terabytes."""
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            # a model's bug (a NaN or an infinity in a part's size or transform), not the
            # target's scale; ValueError: the runtime names the rule that emitted it
            raise ValueError("the part's position or size is not finite (NaN or infinity); find the rule's "
                             "arithmetic that makes it")
        size = max(float(hi[a]) - float(lo[a]) for a in range(3))
        raise InvalidArgumentError(
            f"a part of the model ({size:.3g} units across) spans about {cells:.2g} voxels of the target's "
            f"voxel_size {self.grid.size:.3g}: the target is far smaller than the model's parts; scale the target "
            f"to the model's size (its grid is {self.grid.shape[0]}x{self.grid.shape[1]}x{self.grid.shape[2]} "
            f"voxels from ({', '.join(f'{v:.3g}' for v in self.grid.origin)})), or give it a larger voxel_size")

    def _record_for(self, lo, hi) -> np.ndarray:
        """An index buffer with room for every in-grid voxel centre in the box ``[lo, hi]``:
        a part hits each in-grid voxel at most once, so never more than the grid holds."""
        h = self.grid.size  # plain floats: numpy's per-call overhead exceeds the arithmetic
        n = 1.0
        for a in range(3):
            n *= max((float(hi[a]) - float(lo[a])) / h + 3.0, 1.0)
        if not n <= MAX_PART_CELLS:
            self._refuse_span(lo, hi, n)
        return np.empty(int(min(n, self.counts.shape[0])) + 8, dtype=np.int64)

    def _entry(self, part):
        """``(voxel indices, outside count, lo, hi)`` of a part: from the part cache, or
        voxelized (and then cached when this scene has a cache).

        A miss voxelizes the part into a zeroed scratch count grid kept per grid shape (and
        zeroes the voxels it hit again), so no grid is allocated per removed part."""
        cache = self.part_cache
        entry = cache.get(part) if cache is not None else None
        if entry is None:
            lo, hi = part_bounds(part)
            record = self._record_for(lo, hi)
            scratch = _SCRATCH_COUNTS.get(self.counts.shape[0])
            if scratch is None:
                scratch = _SCRATCH_COUNTS[self.counts.shape[0]] = np.zeros_like(self.counts)
            state = self._state
            state[:] = 0.0
            self._voxelize(part, lo, hi, state, record, scratch)
            voxels = record[:int(state[4])].copy()
            scratch[voxels] = 0
            entry = (voxels, int(state[2]), lo, hi)
            if cache is not None:
                cache.put(part, entry)
        return entry

    def remove(self, part) -> int:
        """Take out one part added earlier (the exact inverse of :meth:`add`: counts,
        ``filled_count``, ``overlaps``, ``outside`` and ``gain_total`` are as if it had
        never been added; ``extent`` is left as it is). Returns the number of voxels
        left uncovered.

        Raises InvalidArgumentError when the scene is saturated (some count hit 255),
        where the counts no longer say how many parts cover a voxel.
        """
        if self.saturated:
            raise InvalidArgumentError("a saturated voxel scene (a count reached 255) cannot remove parts exactly")
        voxels, outside, _, _ = self._entry(part)
        state = self._state
        state[:] = 0.0
        _remove_voxels(self.counts, voxels, self.gain, state)
        n = int(state[0])
        self.filled_count -= n
        self.overlaps -= int(state[1])
        self.outside -= int(outside)
        self.gain_total -= float(state[3])
        self.n_parts -= 1
        return n


@once_per_process
def load_kernels() -> None:
    """Load the voxelizing kernels, with the argument types adding and removing parts
    pass; the first :class:`VoxelScene` a process makes calls it (see
    :mod:`procmod.core.kernels`)."""
    scene = VoxelScene(VoxelGrid((0.0, 0.0, 0.0), 1.0, (2, 2, 2)))
    tetrahedron = Mesh(((0.0, 0.0, 0.0), (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)),
                       ((0, 1, 2), (0, 1, 3), (0, 2, 3), (1, 2, 3)))
    parts = (Box((1.0, 1.0, 1.0)), Cylinder(0.5, 1.0), tetrahedron)
    for part in parts:
        scene.add(part)
    for part in parts:
        scene.remove(part)
    _add_voxels(scene.counts, _NO_RECORD, scene.gain, scene._state)  # a part cache's hit


def voxelize(parts, grid: VoxelGrid) -> np.ndarray:
    """Boolean occupancy of a list of parts on a grid."""
    scene = VoxelScene(grid)
    for part in parts:
        scene.add(part)
    return scene.occupancy
