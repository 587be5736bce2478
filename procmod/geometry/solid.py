"""3D parts: oriented boxes, cylinders (and cone frusta) and triangle meshes, each placed
by a 4x4 affine transform.

Parts are immutable values: transforms are stored as tuples of 16 floats (row-major), so
parts compare and serialise like the 2D primitives. Helpers build transforms.
"""

from __future__ import annotations

import math
from functools import lru_cache
from typing import NamedTuple

import numpy as np

from ..core.errors import InvalidArgumentError, shown_value

IDENTITY = (1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0)


class Box(NamedTuple):
    """A box of full extents ``size`` = (sx, sy, sz), centred at its local origin."""

    size: tuple
    transform: tuple = IDENTITY
    tag: str = "box"


class Cylinder(NamedTuple):
    """A cylinder (or cone frustum) along its local +z axis from z = 0 to z = ``length``,
    radius ``radius`` at z = 0 and ``top_radius`` at the top (None: same radius)."""

    radius: float
    length: float
    transform: tuple = IDENTITY
    tag: str = "cylinder"
    top_radius: float | None = None


class Mesh(NamedTuple):
    """A triangle mesh in its local frame: vertices ((x, y, z), ...), faces ((i, j, k), ...)."""

    vertices: tuple
    faces: tuple
    transform: tuple = IDENTITY
    tag: str = "mesh"


def matrix(transform) -> np.ndarray:
    """A transform tuple (or array) as a 4x4 numpy array."""
    return np.asarray(transform, dtype=np.float64).reshape(4, 4)


def as_transform(m) -> tuple:
    """A 4x4 array as a transform tuple."""
    return tuple(float(v) for v in np.asarray(m, dtype=np.float64).reshape(16))


# The transform helpers run for every part a 3D model emits, so they work on plain tuples
# (numpy's per-call overhead on 4x4 arrays cost more than the voxelization of a part).

def translation(x: float, y: float, z: float) -> tuple:
    return (1.0, 0.0, 0.0, float(x), 0.0, 1.0, 0.0, float(y), 0.0, 0.0, 1.0, float(z), 0.0, 0.0, 0.0, 1.0)


def scaling(sx: float, sy: float, sz: float) -> tuple:
    return (float(sx), 0.0, 0.0, 0.0, 0.0, float(sy), 0.0, 0.0, 0.0, 0.0, float(sz), 0.0, 0.0, 0.0, 0.0, 1.0)


def rotation(axis: str, angle: float) -> tuple:
    """Rotation by ``angle`` radians about the x, y or z axis."""
    c, s = math.cos(angle), math.sin(angle)
    m = [1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0]
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[4 * i + i], m[4 * i + j], m[4 * j + i], m[4 * j + j] = c, -s, s, c
    return tuple(m)


def _affine_product(a: tuple, b: tuple) -> tuple:
    """``a @ b`` for affine 4x4 tuples (last rows 0 0 0 1), written out."""
    a0, a1, a2, a3, a4, a5, a6, a7, a8, a9, a10, a11 = a[:12]
    b0, b1, b2, b3, b4, b5, b6, b7, b8, b9, b10, b11 = b[:12]
    return (a0 * b0 + a1 * b4 + a2 * b8, a0 * b1 + a1 * b5 + a2 * b9, a0 * b2 + a1 * b6 + a2 * b10,
            a0 * b3 + a1 * b7 + a2 * b11 + a3,
            a4 * b0 + a5 * b4 + a6 * b8, a4 * b1 + a5 * b5 + a6 * b9, a4 * b2 + a5 * b6 + a6 * b10,
            a4 * b3 + a5 * b7 + a6 * b11 + a7,
            a8 * b0 + a9 * b4 + a10 * b8, a8 * b1 + a9 * b5 + a10 * b9, a8 * b2 + a9 * b6 + a10 * b10,
            a8 * b3 + a9 * b7 + a10 * b11 + a11,
            0.0, 0.0, 0.0, 1.0)


def compose(*transforms) -> tuple:
    """The product ``T1 @ T2 @ ...`` (apply the last one first) of affine transforms."""
    m = None
    for t in transforms:
        if not (isinstance(t, tuple) and len(t) == 16):
            t = as_transform(t)
        m = t if m is None else _affine_product(m, t)
    return IDENTITY if m is None else tuple(float(v) for v in m)


_BOX_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
_BOX_FACES = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                       (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)])


@lru_cache(maxsize=8)
def _cylinder_topology(segments: int):
    """Unit circle points and the face indices of a ``segments``-gon prism (cached)."""
    a = np.linspace(0, 2 * math.pi, segments, endpoint=False)
    faces = []
    cb, ct = 2 * segments, 2 * segments + 1
    for i in range(segments):
        j = (i + 1) % segments
        faces += [(i, j, segments + j), (i, segments + j, segments + i), (cb, j, i),
                  (ct, segments + i, segments + j)]
    return np.cos(a), np.sin(a), np.array(faces)


def with_positive_length(part: Cylinder) -> Cylinder:
    """The same solid as ``part`` with a length of at least 0. A cylinder of negative length
    points along -z from its origin (procmod draws it so): it is the frustum from z =
    ``length`` up to 0, i.e. one of length ``-length`` whose base is moved to z = ``length``,
    radii swapped. Volume targets had voxelized it as nothing (a model drawing one scored
    as if it were missing), and exports turned its faces inward."""
    if not part.length < 0:
        return part
    m = matrix(part.transform).copy()  # a view of a caller's 4x4 array: moved on every call
    m[:3, 3] += m[:3, 2] * float(part.length)
    top = part.radius if part.top_radius is None else part.top_radius
    return Cylinder(top, -part.length, tuple(m.reshape(-1).tolist()), part.tag,
                    None if part.top_radius is None else part.radius)


class MeshPartError(InvalidArgumentError, ValueError):
    """A :class:`Mesh` part whose vertices or faces are not a triangle mesh (none, ragged, not
    numbers, a face on a vertex it does not have). A ValueError too: an output refusing
    the part at an emit names the rule that emitted it (:mod:`procmod.core.runtime`)."""


def mesh_arrays(part: Mesh) -> tuple:
    """A Mesh part's ``(vertices (n, 3) float64, faces (m, 3) int64)``, checked: at least
    one face, three numbers a vertex, three whole vertex numbers a face, each naming a
    vertex the mesh has. Raises :class:`MeshPartError` naming what is wrong (numpy's
    "inhomogeneous shape", "cannot convert float NaN to integer" or a reduction over no
    faces had reached the user as they were)."""
    try:
        vertices = np.asarray(part.vertices, dtype=np.float64)
    except (TypeError, ValueError):
        raise MeshPartError(f"a Mesh's vertices must be rows of three numbers ((x, y, z), ...), got "
                            f"{shown_value(part.vertices)}") from None
    try:
        faces = np.asarray(part.faces)
        if faces.dtype.kind not in "iu":  # floats (3.0 is vertex 3) or objects: whole numbers checked below
            faces = faces.astype(np.float64)
    except (TypeError, ValueError):
        raise MeshPartError(f"a Mesh's faces must be rows of three vertex numbers ((i, j, k), ...), got "
                            f"{shown_value(part.faces)}") from None
    if vertices.size == 0 or faces.size == 0:
        raise MeshPartError(f"a Mesh needs at least one face (i, j, k) on its vertices (x, y, z), got "
                            f"{len(vertices) if vertices.ndim else 0} vertices and "
                            f"{len(faces) if faces.ndim else 0} faces")
    if vertices.ndim != 2 or vertices.shape[1:] != (3,) or faces.ndim != 2 or faces.shape[1:] != (3,):
        raise MeshPartError(f"a Mesh needs vertices ((x, y, z), ...) and faces ((i, j, k), ...: triangles), got "
                            f"arrays of shapes {vertices.shape} and {faces.shape}")
    if faces.dtype.kind == "f" and not (np.isfinite(faces).all() and (faces == np.round(faces)).all()):
        bad = faces[~(np.isfinite(faces) & (faces == np.round(faces)))][0]
        raise MeshPartError(f"a Mesh's faces must hold whole vertex numbers, got {shown_value(float(bad))}")
    if faces.min() < 0 or faces.max() >= len(vertices):
        bad = int(faces.max()) if faces.max() >= len(vertices) else int(faces.min())
        raise MeshPartError(f"a Mesh's face refers to vertex {bad}, but it has vertices 0 to {len(vertices) - 1}")
    return vertices, faces.astype(np.int64)


def part_triangles(part, segments: int = 24) -> np.ndarray:
    """World-space triangles ``(n, 3, 3)`` of a part (cylinders as ``segments``-gon prisms)."""
    if isinstance(part, Cylinder):
        part = with_positive_length(part)
    if isinstance(part, Box):
        local, tris = _BOX_CORNERS * np.asarray(part.size, dtype=np.float64), _BOX_FACES
    elif isinstance(part, Cylinder):
        r0 = float(part.radius)
        r1 = r0 if part.top_radius is None else float(part.top_radius)
        cos, sin, tris = _cylinder_topology(segments)
        local = np.empty((2 * segments + 2, 3))
        local[:segments, 0], local[:segments, 1], local[:segments, 2] = r0 * cos, r0 * sin, 0.0
        local[segments:2 * segments, 0], local[segments:2 * segments, 1] = r1 * cos, r1 * sin
        local[segments:2 * segments, 2] = float(part.length)
        local[2 * segments] = (0.0, 0.0, 0.0)
        local[2 * segments + 1] = (0.0, 0.0, float(part.length))
    elif isinstance(part, Mesh):
        local, tris = mesh_arrays(part)
    else:
        raise TypeError(_not_3d(part))
    m = matrix(part.transform)
    world = local @ m[:3, :3].T + m[:3, 3]
    a = m[:3, :3]
    det = (a[0, 0] * (a[1, 1] * a[2, 2] - a[1, 2] * a[2, 1]) - a[0, 1] * (a[1, 0] * a[2, 2] - a[1, 2] * a[2, 0])
           + a[0, 2] * (a[1, 0] * a[2, 1] - a[1, 1] * a[2, 0]))
    if det < 0:  # a mirror turns the faces inward: each turned back (exports had mirrored parts inside out)
        tris = tris[:, ::-1]
    return world[tris]


def part_bounds(part) -> tuple:
    """World-space axis-aligned bounds ``(min xyz, max xyz)`` of a part, as numpy arrays.

    Exact for boxes and cylinders (plain-Python arithmetic on the transform: this runs
    for every part drawn, where numpy's per-call overhead would dominate).
    """
    if isinstance(part, Mesh):
        tris = part_triangles(part)
        lo, hi = tris.reshape(-1, 3).min(0), tris.reshape(-1, 3).max(0)
        if not (np.isfinite(lo).all() and np.isfinite(hi).all()):
            raise ValueError(_NOT_FINITE)
        return lo, hi
    if isinstance(part, Box):
        t = transform_values(part)
        sx, sy, sz = part.size
        if not (sx >= 0 and sy >= 0 and sz >= 0):  # also NaN
            raise ValueError(f"a Box's size must be three sizes of at least 0, got {part.size}")
        lo, hi = [], []
        for row in range(3):
            a, b, c, d = t[4 * row:4 * row + 4]
            half = 0.5 * (abs(a) * sx + abs(b) * sy + abs(c) * sz)
            lo.append(d - half)
            hi.append(d + half)
        return _finite_bounds(lo, hi)
    if isinstance(part, Cylinder):
        t = transform_values(part)
        r0 = part.radius
        r1 = r0 if part.top_radius is None else part.top_radius
        if not (r0 >= 0 and r1 >= 0):  # also NaN
            raise ValueError(f"a Cylinder's radii must be at least 0, got {r0} and {r1}")
        lo, hi = [], []
        for row in range(3):
            a, b, c, d = t[4 * row:4 * row + 4]
            spread = math.sqrt(a * a + b * b)
            top = d + c * part.length
            lo.append(min(d - r0 * spread, top - r1 * spread))
            hi.append(max(d + r0 * spread, top + r1 * spread))
        return _finite_bounds(lo, hi)
    raise TypeError(_not_3d(part))


_NOT_FINITE = "the part's position or size is not finite (NaN or infinity); find the rule's arithmetic that makes it"


def _finite_bounds(lo: list, hi: list) -> tuple:
    """``lo``, ``hi`` as arrays; a ValueError when one is NaN or infinite (a sum of floats
    is finite only when each one is: the cheap test of a hot path)."""
    if not math.isfinite(lo[0] + lo[1] + lo[2] + hi[0] + hi[1] + hi[2]):
        raise ValueError(_NOT_FINITE)
    return np.array(lo), np.array(hi)


def transform_values(part):
    """A part's transform as its 16 numbers, row by row: as given, or read from a 4x4 array."""
    t = part.transform
    if len(t) != 16:
        if np.shape(t) == (4, 4):  # a 4x4 array, as matrix() reads it too
            return np.asarray(t, dtype=np.float64).reshape(16)
        raise ValueError(f"a part's transform must be 16 numbers (a 4x4 matrix, row by row, as "
                         f"procmod.geometry.solid.translation and compose make), got {len(t)}")
    return t


def _not_3d(part) -> str:
    return (f"a 3D output draws Box, Cylinder and Mesh parts, not {type(part).__name__}"
            + (" (a 2D primitive: is this rule from a 2D model?)" if hasattr(part, "_fields") else ""))


class PartBounds:
    """The default output of a 3D model when nothing scores it: counts parts and keeps
    their world bounds (``extent``)."""

    __slots__ = ("extent", "n_parts")

    # capabilities (procmod.core.protocols.Output)
    dimension = 3
    supports_removal = False
    supports_part_cache = False

    def __init__(self):
        self.extent = None
        self.n_parts = 0

    def copy(self) -> "PartBounds":
        other = PartBounds()
        other.extent, other.n_parts = self.extent, self.n_parts
        return other

    def add(self, part) -> int:
        lo, hi = part_bounds(part)
        self.extent = (lo, hi) if self.extent is None else (np.minimum(self.extent[0], lo),
                                                          np.maximum(self.extent[1], hi))
        self.n_parts += 1
        return 0


def new_part_bounds(params=None) -> PartBounds:
    """Output factory of 3D models (a named function, so models pickle for process pools)."""
    return PartBounds()


def scene_bounds(parts) -> tuple:
    """World bounds (min xyz, max xyz) of a list of parts (a unit box if there are none)."""
    if not parts:
        return -np.ones(3), np.ones(3)
    boxes = [part_bounds(p) for p in parts]
    return np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
