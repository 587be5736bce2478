"""Part libraries and world-space part instances, as the ``procmod-examples/1`` and
``procmod-shapes/1`` file formats write them.

A library maps a part name to its shape in the part's own local frame:

- ``{"box": [sx, sy, sz]}`` — a box of those full extents centred at the local origin;
- ``{"mesh": "parts/wing.obj"}`` — a triangle mesh read from a path relative to the JSON
  file (anything trimesh reads: OBJ, STL, PLY, GLB, OFF).

An instance is a part name plus a 4x4 affine world transform (row-major, rotation with
possibly non-uniform or negative scale, then translation). Malformed input raises a
:class:`PartLibraryError` that names the JSON path of the problem, e.g.
``examples[3].children[1].transform``.
"""

from __future__ import annotations

import math
import os
from typing import NamedTuple

import numpy as np

from ..core.errors import ProcmodError, shown_value
from ..core.file_formats import conversion_hint
from ..core.limits import MAX_COORDINATE, MIN_LENGTH
from ..core.paths import UnsafePathError, named_file
from .mesh_files import load_mesh_file
from .solid import Box, Mesh, as_transform, matrix, part_triangles


class PartLibraryError(ProcmodError):
    """A part library or part transform that cannot be used; the message names where."""


class PartShape(NamedTuple):
    """One library entry: a box (``size``) or a mesh (``vertices``, ``faces``), local frame.

    ``source`` is what the file said (the box extents or the mesh path as written), so a
    library writes back exactly as it was read.
    """

    name: str
    kind: str  # "box" or "mesh"
    size: tuple | None = None
    vertices: tuple | None = None
    faces: tuple | None = None
    source: object = None

    def part(self, transform, tag: str | None = None):
        """The part placed by ``transform`` (a 4x4 array or a 16-tuple), tagged by name."""
        t = as_transform(transform) if not isinstance(transform, tuple) else transform
        tag = tag or self.name
        if self.kind == "box":
            return Box(self.size, t, tag)
        return Mesh(self.vertices, self.faces, t, tag)

    def local_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Lower and upper corner of the shape's local bounding box."""
        if self.kind == "box":
            half = np.asarray(self.size) / 2
            return -half, half
        v = np.asarray(self.vertices, dtype=np.float64)
        return v.min(axis=0), v.max(axis=0)

    def local_triangles(self) -> np.ndarray:
        """Triangles (n, 3, 3) of the shape in its local frame."""
        return part_triangles(self.part(np.eye(4)))

    def to_json(self):
        return {self.kind: self.source}


def _finite_numbers(value, count: int, where: str) -> list[float]:
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise PartLibraryError(f"{where}: expected a list of {count} numbers, got {shown_value(value, 80)}")
    out = []
    for i, v in enumerate(value):
        try:
            ok = not isinstance(v, bool) and isinstance(v, (int, float)) and math.isfinite(v)
        except OverflowError:  # an int too large for a float (10**400)
            ok = False
        if not ok:
            raise PartLibraryError(f"{where}[{i}]: expected a finite number, got {shown_value(v, 40)}")
        out.append(float(v))
    return out


def read_part_shape(name: str, spec, base_dir: str | os.PathLike, where: str) -> PartShape:
    """One library entry from its JSON value (``where`` is its JSON path, for errors)."""
    if not isinstance(spec, dict) or len(spec) != 1 or next(iter(spec)) not in ("box", "mesh"):
        raise PartLibraryError(f'{where}: a part is {{"box": [sx, sy, sz]}} or {{"mesh": "path"}}, '
                               f'got {shown_value(spec, 80)}')
    kind, value = next(iter(spec.items()))
    if kind == "box":
        size = _finite_numbers(value, 3, f"{where}.box")
        if min(size) <= 0:
            raise PartLibraryError(f"{where}.box: box extents must be positive, got {size}")
        if not (MIN_LENGTH <= min(size) and max(size) <= MAX_COORDINATE):
            raise PartLibraryError(f"{where}.box: box extents must lie in 1e-12..1e12, got {size}")
        return PartShape(name, "box", size=tuple(size), source=list(size))
    try:  # relative to the JSON file's folder, an existing regular file (see core.paths)
        path = named_file(base_dir, value, f"{where}.mesh", kind="mesh")
    except UnsafePathError as exc:
        raise PartLibraryError(str(exc)) from None
    try:
        mesh = load_mesh_file(path, force="mesh", process=False, skip_materials=True)  # geometry only
    except Exception as exc:  # trimesh raises many types for unreadable files
        hint = conversion_hint(path)
        raise PartLibraryError(f"{where}.mesh: cannot read {path} as a triangle mesh ({exc})"
                               + (f"; {hint}" if hint else "")) from None
    if len(getattr(mesh, "faces", ())) == 0:
        raise PartLibraryError(f"{where}.mesh: {path} holds no triangles")
    points, indices = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces)
    if indices.min() < 0 or indices.max() >= len(points):  # a glTF's index buffer is not checked by trimesh
        raise PartLibraryError(f"{where}.mesh: {path}: a triangle refers to a vertex that does not exist (index "
                               f"{int(indices.max() if indices.max() >= len(points) else indices.min())}, of "
                               f"{len(points)} vertices); fix or re-export the mesh")
    if not np.isfinite(points).all():
        raise PartLibraryError(f"{where}.mesh: {path} has vertices that are not finite numbers (nan or inf); "
                               "fix or re-export the mesh")
    if np.abs(points[np.unique(indices)]).max() > MAX_COORDINATE:
        raise PartLibraryError(f"{where}.mesh: {path} has vertices beyond +-1e12; scale the mesh down")
    if np.ptp(points[np.unique(indices)], axis=0).max() == 0.0:
        raise PartLibraryError(f"{where}.mesh: {path} has no extent (every face's vertices are one point)")
    vertices = tuple(tuple(float(c) for c in v) for v in points)
    faces = tuple(tuple(int(i) for i in f) for f in _wound_outward(points, indices))
    return PartShape(name, "mesh", vertices=vertices, faces=faces, source=value)


def _wound_outward(points: np.ndarray, indices: np.ndarray) -> np.ndarray:
    """``indices`` with the faces of each closed piece turned where
    :func:`procmod.geometry.inside.orient_faces` turns them (consistently and outward), on
    the mesh with its seams' split vertices merged; the vertices, their order and the
    faces' order are kept. A part mesh wound inward (the castles' towers and roofs as
    shipped) had been drawn inside out in every sample's OBJ and GLB: culled by three.js
    and game engines, shaded backwards. A piece that is not closed (every edge of two of
    its faces: an open sheet, a fin meeting a body along an edge of three faces, a face
    repeated in place) keeps the winding its author gave it: outward is no measure there,
    and a dish, or the inner band of a flanged ring, had been turned the wrong way."""
    from .inside import orient_faces

    indices = np.asarray(indices, dtype=np.int64).reshape(-1, 3)
    unique, merged = np.unique(points, axis=0, return_inverse=True)
    joined = merged.reshape(-1)[indices]
    oriented, piece = orient_faces(unique, joined)
    edges = np.sort(joined[:, [0, 1, 1, 2, 2, 0]].reshape(-1, 2), axis=1)
    _, edge_id, uses = np.unique(edges, axis=0, return_inverse=True, return_counts=True)
    face_closed = (uses[edge_id.reshape(-1)] == 2).reshape(-1, 3).all(axis=1)
    closed = np.ones(int(piece.max()) + 1 if len(piece) else 0, dtype=bool)
    np.logical_and.at(closed, piece, face_closed)  # a piece is closed when every face of it is
    turned = (oriented != joined).any(axis=1) & closed[piece]
    out = indices.copy()
    out[turned] = out[turned][:, ::-1]
    return out


def read_part_library(parts, base_dir: str | os.PathLike, where: str = "parts") -> dict[str, PartShape]:
    """The ``"parts"`` object of an examples or shapes file, as name -> :class:`PartShape`."""
    if not isinstance(parts, dict) or not parts:
        raise PartLibraryError(f"{where}: expected an object mapping part names to shapes, "
                               f"got {shown_value(parts, 80)}")
    library = {}
    for name, spec in parts.items():
        if not isinstance(name, str) or not name:
            raise PartLibraryError(f"{where}: part names must be non-empty strings, got {shown_value(name)}")
        library[name] = read_part_shape(name, spec, base_dir, f"{where}.{name}")
    return library


def part_library_to_json(library: dict[str, PartShape]) -> dict:
    """The ``"parts"`` object for a library (as it was read)."""
    return {name: shape.to_json() for name, shape in library.items()}


def read_transform(value, where: str) -> np.ndarray:
    """A 4x4 row-major affine world transform from JSON, checked.

    Rejects anything that is not 4 rows of 4 finite numbers, whose last row is not
    (0, 0, 0, 1) (not affine), or whose linear part is singular (not invertible).
    """
    if not isinstance(value, (list, tuple)) or len(value) != 4:
        raise PartLibraryError(f"{where}: expected a 4x4 matrix as 4 rows of 4 numbers, got {shown_value(value, 80)}")
    m = np.array([_finite_numbers(row, 4, f"{where}[{i}]") for i, row in enumerate(value)])
    if not np.allclose(m[3], (0, 0, 0, 1), atol=1e-9):
        raise PartLibraryError(f"{where}: not an affine transform (last row is {m[3].tolist()}, must be [0, 0, 0, 1])")
    if np.abs(m).max() > MAX_COORDINATE:
        # squares of such numbers overflow: the learner's SVDs spun on NaN matrices, deaf to SIGTERM
        raise PartLibraryError(f"{where}: a number beyond {MAX_COORDINATE:g} ({float(np.abs(m).max()):g}); the "
                               "examples' placements and scales must be ordinary lengths: check the file's units")
    if is_singular(m[:3, :3]):
        raise PartLibraryError(f"{where}: the transform is not invertible (its 3x3 part is singular)")
    return m


def is_singular(linear) -> bool:
    """Whether a 3x3 linear map flattens space: an axis scaled to zero, or axes (nearly)
    parallel. Each column is measured against its own length, so a very unequal scale
    (1 along x, 1e11 along z) is not taken for a flat one, as the determinant over the
    largest entry took it."""
    linear = np.asarray(linear, dtype=np.float64)
    lengths = np.linalg.norm(linear, axis=0)
    if not lengths.min() > 0:
        return True
    return abs(float(np.linalg.det(linear / lengths))) < 1e-9


def transform_to_json(m) -> list[list[float]]:
    """A 4x4 transform (array or 16-tuple) as JSON rows."""
    return [[float(v) for v in row] for row in matrix(m)]


def surface_samples(shape: PartShape, count: int) -> np.ndarray:
    """``count`` points (count, 3) on the shape's surface, in its local frame.

    Area-weighted: triangles are drawn in proportion to their area (stratified: the
    i-th point uses the quantile (i + 1/2) / count of the cumulative area), and each
    point's barycentric coordinates come from a generator with a fixed seed, so the same
    shape always gets the same points. They spread over the whole surface, whatever the
    order of a mesh's vertices; a degenerate (zero-area) shape gets its vertices.
    """
    tris = shape.local_triangles()
    area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
    total = float(area.sum())
    if not np.isfinite(total) or total <= 0:
        v = tris.reshape(-1, 3)
        return v[np.linspace(0, len(v) - 1, count).astype(int)]
    cum = np.cumsum(area) / total
    which = np.minimum(np.searchsorted(cum, (np.arange(count) + 0.5) / count), len(tris) - 1)
    rng = np.random.default_rng(0)
    u, v = rng.random(count), rng.random(count)
    flip = u + v > 1  # fold the unit square onto the triangle
    u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
    t = tris[which]
    return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0])


def flip_matrix(mask: int) -> np.ndarray:
    """The diagonal 3x3 flip of mask ``mask`` (bits 4, 2, 1: negate x, y, z)."""
    return np.diag([-1.0 if mask & 4 else 1.0, -1.0 if mask & 2 else 1.0, -1.0 if mask & 1 else 1.0])


def flip_deviations(shape: PartShape, count: int = 256, exact_below: float = 0.1) -> np.ndarray:
    """How far the shape is from its own image under each flip of its axes about its
    bounding-box centre (``out[mask]``, see :func:`flip_matrix`; ``out[0] = 0``): the
    largest distance of a flipped surface sample from the surface, as a fraction of the
    bounding-box diagonal (all 0 for a box).

    Distances are first taken to the nearest of 4096 surface samples (an upper bound);
    those below ``exact_below`` are then measured exactly, to the triangles."""
    out = np.zeros(8)
    if shape.kind == "box":
        return out
    from scipy.spatial import cKDTree
    lo, hi = shape.local_bounds()
    centre, diag = 0.5 * (lo + hi), max(float(np.linalg.norm(hi - lo)), 1e-300)
    local = surface_samples(shape, count) - centre
    flipped = [local @ flip_matrix(m) + centre for m in range(1, 8)]
    tree = cKDTree(surface_samples(shape, 4096))
    out[1:] = [float(tree.query(p)[0].max()) / diag for p in flipped]
    near = [m for m in range(1, 8) if out[m] < exact_below]
    if near:
        from trimesh import Trimesh
        from trimesh.proximity import closest_point
        mesh = Trimesh(np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces), process=False)
        pts = np.concatenate([flipped[m - 1] for m in near])
        gaps = np.linalg.norm(np.asarray(closest_point(mesh, pts)[0]) - pts, axis=1).reshape(len(near), count)
        out[near] = gaps.max(1) / diag
    return out


ROUND_TEST_ANGLES = (0.43, 1.05, 1.91)  # radians (about 25, 60, 110 degrees): no polygon's steps


def round_axes(shape: PartShape, tolerance: float, count: int = 256) -> tuple:
    """The local axes (0, 1, 2) about which the shape, turned by any angle about the line
    through its bounding-box centre, stays within ``tolerance`` of its bounding-box
    diagonal of itself (a cylinder or a cone about its axis, a sphere about all three; a
    box about none): tried at :data:`ROUND_TEST_ANGLES`, measured as
    :func:`flip_deviations` measures."""
    if shape.kind == "box":
        return ()
    from scipy.spatial import cKDTree
    from scipy.spatial.transform import Rotation

    lo, hi = shape.local_bounds()
    centre, diag = 0.5 * (lo + hi), max(float(np.linalg.norm(hi - lo)), 1e-300)
    local = surface_samples(shape, count) - centre
    tree = None
    found = []
    for axis in range(3):
        turned = [local @ Rotation.from_rotvec(np.eye(3)[axis] * a).as_matrix().T + centre for a in ROUND_TEST_ANGLES]
        tree = tree or cKDTree(surface_samples(shape, 4096))
        if max(float(tree.query(p)[0].max()) for p in turned) / diag > tolerance:
            continue
        from trimesh import Trimesh
        from trimesh.proximity import closest_point
        mesh = Trimesh(np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces), process=False)
        points = np.concatenate(turned)
        if float(np.linalg.norm(np.asarray(closest_point(mesh, points)[0]) - points, axis=1).max()) / diag <= tolerance:
            found.append(axis)
    return tuple(found)


def world_bounds(shape: PartShape, transform) -> tuple[np.ndarray, np.ndarray]:
    """World-space axis-aligned bounds of ``shape`` placed by ``transform``."""
    lo, hi = shape.local_bounds()
    corners = np.array([[x, y, z, 1.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    world = corners @ matrix(transform).T
    return world[:, :3].min(axis=0), world[:, :3].max(axis=0)
