"""Exact intersection tests between 3D parts, and an incremental count of intersecting pairs.

Two parts *intersect* when they share volume: their penetration depth (the length of the
shortest translation that separates them) exceeds ``rel_tol`` (default 1e-6) times the
smaller of their bounding-box diagonals. Parts that only touch — a face on a face, a
cylinder tangent to a box or to another cylinder, as the spaceship's segments, wings, fins
and clustered hulls do — do not intersect. The tolerance absorbs rounding (a segment whose
rear is computed as the previous one's front) and fcl's depth accuracy (about 1e-8).

* box-box: the separating-axis theorem for two parallelepipeds (any affine placement): the
  3 + 3 face normals and the 9 edge cross products. For two convex polytopes the
  penetration depth is the smallest overlap of their projections on these axes, so the
  test is exact.
* every other pair: python-fcl (GJK / EPA on convex solids) — ``fcl.Box``,
  ``fcl.Cylinder`` and ``fcl.Cone`` exactly when the transform is a rotation and
  translation; a frustum (fcl has none), or a cylinder or box under a transform with
  scaling or shear, is the convex prism inscribed in it with :data:`SIDES` sides (it is
  inside the part, so touching parts never count; overlaps shallower than 1 - cos(pi /
  SIDES) = 1.2e-3 of the radius are missed: 2e-4 units on the spaceship's gun tips, 2e-3
  on its noses, against a 0.25 voxel grid); a convex mesh is an ``fcl.Convex``. fcl
  builds a Convex in about 1 ms at 64 sides (quadratic in them), and only for parts
  whose bounding boxes overlap another's; the fcl forms are cached per part.
* a mesh that is not convex: fcl's triangle BVH, which tests surfaces, so touching
  surfaces count as intersecting there (a BVH gives no penetration depth), plus a
  point-in-mesh test for a part wholly inside the mesh.

:class:`PartIntersections` counts the intersecting pairs of a growing set of parts; a new
part is tested exactly only against earlier parts whose bounding boxes overlap it by more
than the tolerance (a penetration depth is at most the bounding boxes' overlap along any
axis, so the broad phase drops no intersecting pair).
"""

from __future__ import annotations

import math
from functools import lru_cache

import numpy as np

from .solid import Box, Cylinder, Mesh, matrix, part_bounds, with_positive_length

SIDES = 64  # sides of the prism that stands for a frustum or a non-rigidly placed cylinder
REL_TOL = 1e-6


def _rigid(m: np.ndarray) -> bool:
    """Whether the 3x3 ``m`` is orthonormal (a rotation, possibly with a reflection).
    Plain Python: np.allclose costs more than the test."""
    c = m.T.tolist()  # columns
    for i in range(3):
        for j in range(i, 3):
            dot = c[i][0] * c[j][0] + c[i][1] * c[j][1] + c[i][2] * c[j][2]
            if abs(dot - (1.0 if i == j else 0.0)) > 1e-9:
                return False
    return True


def _proper(m: np.ndarray) -> np.ndarray:
    """``m`` with its local x axis flipped when it reflects: boxes and cylinders are
    symmetric under that flip, and fcl takes rotations only."""
    if np.linalg.det(m) < 0:
        m = m.copy()
        m[:, 0] = -m[:, 0]
    return m


def _flat_faces(faces) -> np.ndarray:
    """fcl's face list: each face's vertex count, then its vertex indices."""
    return np.concatenate([[len(f), *f] for f in faces]).astype(np.int32)


def _convex(points: np.ndarray, faces, flat=None) -> object:
    """An ``fcl.Convex`` of world-space ``points`` and polygonal ``faces`` (``flat``:
    their :func:`_flat_faces`, when known)."""
    import fcl
    flat = _flat_faces(faces) if flat is None else flat
    return fcl.Convex(np.ascontiguousarray(points, dtype=np.float64), len(faces), flat)


@lru_cache(maxsize=4)
def _prism_topology(sides: int):
    a = np.linspace(0.0, 2.0 * math.pi, sides, endpoint=False)
    faces = [list(range(sides - 1, -1, -1)), list(range(sides, 2 * sides))]  # bottom (outward -z), top
    faces += [[i, (i + 1) % sides, sides + (i + 1) % sides, sides + i] for i in range(sides)]
    return np.cos(a), np.sin(a), faces, _flat_faces(faces)


def _frustum_points(part: Cylinder) -> tuple:
    """World vertices, faces and flat faces of the prism inscribed in a cylinder or frustum."""
    cos, sin, faces, flat = _prism_topology(SIDES)
    r0 = float(part.radius)
    r1 = r0 if part.top_radius is None else float(part.top_radius)
    local = np.empty((2 * SIDES, 3))
    local[:SIDES, 0], local[:SIDES, 1], local[:SIDES, 2] = r0 * cos, r0 * sin, 0.0
    local[SIDES:, 0], local[SIDES:, 1], local[SIDES:, 2] = r1 * cos, r1 * sin, float(part.length)
    m = matrix(part.transform)
    return local @ m[:3, :3].T + m[:3, 3], faces, flat


_BOX_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])
_BOX_POLYGONS = [[0, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]]


def _box_corners(part: Box) -> np.ndarray:
    m = matrix(part.transform)
    return (_BOX_CORNERS * np.asarray(part.size, dtype=np.float64)) @ m[:3, :3].T + m[:3, 3]


def _mesh_world(part: Mesh) -> tuple:
    m = matrix(part.transform)
    points = np.asarray(part.vertices, dtype=np.float64) @ m[:3, :3].T + m[:3, 3]
    return points, np.asarray(part.faces, dtype=np.int64)


def _is_convex(points: np.ndarray, faces: np.ndarray) -> bool:
    """Whether every vertex lies on the inner side of every face plane (orientation-free)."""
    tri = points[faces]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    lengths = np.linalg.norm(normals, axis=1)
    keep = lengths > 0
    if not keep.any():
        return False
    normals, tri = normals[keep] / lengths[keep, None], tri[keep]
    side = np.einsum("fk,fvk->fv", normals, points[None, :, :] - tri[:, None, 0, :])
    eps = 1e-9 * float(np.ptp(points, axis=0).max() or 1.0)
    return bool(np.all((side <= eps).all(axis=1) | (side >= -eps).all(axis=1)))


class _Solid:
    """What the exact tests need of one part: its fcl geometry and transform, whether that
    is a surface-only triangle BVH, and (for BVH meshes) the world triangles."""

    __slots__ = ("geometry", "rotation", "translation", "bvh", "triangles", "inner_point")

    def __init__(self, geometry, rotation, translation, bvh=False, triangles=None, inner_point=None):
        self.geometry, self.rotation, self.translation = geometry, rotation, translation
        self.bvh, self.triangles, self.inner_point = bvh, triangles, inner_point

    def fcl_object(self):
        import fcl
        return fcl.CollisionObject(self.geometry, fcl.Transform(self.rotation, self.translation))


_I3, _ZERO = np.eye(3), np.zeros(3)


def _solid_of(part) -> _Solid:
    """:func:`_solid`, cached where the part can be (a Mesh of numpy arrays cannot)."""
    try:
        return _solid(part)
    except TypeError as exc:
        if "unhashable" not in str(exc):
            raise
        return _solid.__wrapped__(part)


@lru_cache(maxsize=4096)
def _solid(part) -> _Solid:
    """The fcl form of a part (cached: parts are immutable values)."""
    import fcl
    if isinstance(part, Mesh):
        points, faces = _mesh_world(part)
        if _is_convex(points, faces):
            return _Solid(_convex(points, faces.tolist()), _I3, _ZERO, inner_point=points.mean(0))
        bvh = fcl.BVHModel()
        bvh.beginModel(len(points), len(faces))
        bvh.addSubModel(np.ascontiguousarray(points), np.ascontiguousarray(faces, dtype=np.int32))
        bvh.endModel()
        return _Solid(bvh, _I3, _ZERO, bvh=True, triangles=points[faces], inner_point=points[0])
    if isinstance(part, Cylinder):
        part = with_positive_length(part)
    m = matrix(part.transform)
    linear, origin = m[:3, :3], m[:3, 3]
    rigid = _rigid(linear)
    if isinstance(part, Box):
        if rigid:
            return _Solid(fcl.Box(*map(float, part.size)), _proper(linear), origin.copy(), inner_point=origin.copy())
        return _Solid(_convex(_box_corners(part), _BOX_POLYGONS), _I3, _ZERO, inner_point=origin.copy())
    if isinstance(part, Cylinder):
        r0, length = float(part.radius), float(part.length)
        top = r0 if part.top_radius is None else float(part.top_radius)
        centre = origin + linear[:, 2] * (0.5 * length)
        if rigid and top == r0:
            return _Solid(fcl.Cylinder(r0, length), _proper(linear), centre, inner_point=centre)
        if rigid and top == 0.0:
            return _Solid(fcl.Cone(r0, length), _proper(linear), centre, inner_point=centre)
        points, faces, flat = _frustum_points(part)
        return _Solid(_convex(points, faces, flat), _I3, _ZERO, inner_point=centre)
    raise TypeError(f"not a 3D part: {part!r}")


def _point_in_triangles(point: np.ndarray, triangles: np.ndarray) -> bool:
    """Ray parity: is ``point`` inside the closed triangle mesh ``triangles`` (n, 3, 3)?
    The ray direction is skewed so that it meets no edge of an axis-aligned mesh."""
    d = np.array([0.5773502691896258, 0.5773502691896257, 0.5773502691896258]) + np.array([1e-3, 2e-3, 0.0])
    d /= np.linalg.norm(d)
    v0, e1, e2 = triangles[:, 0], triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]
    p = np.cross(d, e2)
    det = np.einsum("ij,ij->i", e1, p)
    ok = np.abs(det) > 1e-14
    inv = np.where(ok, 1.0 / np.where(ok, det, 1.0), 0.0)
    s = point - v0
    u = np.einsum("ij,ij->i", s, p) * inv
    q = np.cross(s, e1)
    v = (q @ d) * inv
    t = np.einsum("ij,ij->i", e2, q) * inv
    hits = ok & (u >= 0) & (v >= 0) & (u + v <= 1) & (t > 0)
    return bool(np.count_nonzero(hits) % 2)


def _sat_depth(a: Box, b: Box) -> float:
    """Penetration depth of two boxes (parallelepipeds) by the separating-axis theorem
    (<= 0 when they are apart or touch)."""
    ca, cb = _box_corners(a), _box_corners(b)
    ea = matrix(a.transform)[:3, :3].T * np.asarray(a.size, dtype=np.float64)[:, None]  # rows: edge vectors
    eb = matrix(b.transform)[:3, :3].T * np.asarray(b.size, dtype=np.float64)[:, None]
    na = np.cross(ea[[1, 2, 0]], ea[[2, 0, 1]])
    nb = np.cross(eb[[1, 2, 0]], eb[[2, 0, 1]])
    axes = np.concatenate([na, nb, np.cross(ea[:, None, :], eb[None, :, :]).reshape(9, 3)])
    norms = np.linalg.norm(axes, axis=1)
    keep = norms > 1e-12 * norms.max()
    axes = axes[keep] / norms[keep, None]
    pa, pb = ca @ axes.T, cb @ axes.T
    overlap = np.minimum(pa.max(0), pb.max(0)) - np.maximum(pa.min(0), pb.min(0))
    return float(overlap.min())


def _axis_aligned(t: tuple) -> bool:
    """Whether a transform maps the local axes onto the world axes (each row of its linear
    part has one non-zero entry): a box placed so fills its bounding box."""
    return all((t[r] != 0.0) + (t[r + 1] != 0.0) + (t[r + 2] != 0.0) == 1 for r in (0, 4, 8))


def _diagonal(bounds) -> float:
    lo, hi = bounds
    return math.sqrt(sum((float(h) - float(l)) ** 2 for l, h in zip(lo, hi)))


def parts_intersect(a, b, rel_tol: float = REL_TOL, bounds_a=None, bounds_b=None) -> bool:
    """Whether parts ``a`` and ``b`` share volume deeper than ``rel_tol`` times the smaller
    of their bounding-box diagonals (see the module docstring); touching is not
    intersecting. ``bounds_a`` / ``bounds_b``: their :func:`part_bounds`, if known."""
    ba = part_bounds(a) if bounds_a is None else bounds_a
    bb = part_bounds(b) if bounds_b is None else bounds_b
    tol = rel_tol * min(_diagonal(ba), _diagonal(bb))
    for k in range(3):  # broad phase: the depth is at most the boxes' overlap on any axis
        if min(float(ba[1][k]), float(bb[1][k])) - max(float(ba[0][k]), float(bb[0][k])) <= tol:
            return False
    if isinstance(a, Box) and isinstance(b, Box):
        if _axis_aligned(a.transform) and _axis_aligned(b.transform):
            return True  # such boxes are their bounding boxes: the broad phase was exact
        return _sat_depth(a, b) > tol
    import fcl
    sa, sb = _solid_of(a), _solid_of(b)
    result = fcl.CollisionResult()
    request = fcl.CollisionRequest(num_max_contacts=1, enable_contact=True)
    if fcl.collide(sa.fcl_object(), sb.fcl_object(), request, result):
        if sa.bvh or sb.bvh:  # surfaces meet: no depth to compare with the tolerance
            return True
        return max(c.penetration_depth for c in result.contacts) > tol
    # fcl tests a BVH's surface only: a part wholly inside a mesh meets none of it
    if sa.bvh and _point_in_triangles(sb.inner_point, sa.triangles):
        return True
    return bool(sb.bvh and _point_in_triangles(sa.inner_point, sb.triangles))


class PartIntersections:
    """The number of intersecting pairs (:func:`parts_intersect`) among the parts added.

    ``add`` tests the new part exactly only against earlier parts whose bounding boxes
    overlap its own; ``remove`` is its exact inverse; ``copy`` is cheap (lists of the
    parts and their bounds; the fcl forms are cached per part, outside the object, so it
    pickles).
    """

    __slots__ = ("parts", "bounds", "count", "rel_tol")

    def __init__(self, rel_tol: float = REL_TOL):
        self.parts, self.bounds, self.count, self.rel_tol = [], [], 0, float(rel_tol)

    def copy(self) -> "PartIntersections":
        other = PartIntersections.__new__(PartIntersections)
        other.parts, other.bounds, other.count, other.rel_tol = list(self.parts), list(self.bounds), self.count, \
            self.rel_tol
        return other

    def _hits(self, part, bounds, skip: int = -1) -> int:
        lo, hi = bounds
        lo0, lo1, lo2 = float(lo[0]), float(lo[1]), float(lo[2])
        hi0, hi1, hi2 = float(hi[0]), float(hi[1]), float(hi[2])
        n = 0
        for i, (other, (olo, ohi)) in enumerate(zip(self.parts, self.bounds)):
            # cheap rejection first (plain floats): boxes apart or only touching on an axis
            if (i == skip or olo[0] >= hi0 or ohi[0] <= lo0 or olo[1] >= hi1 or ohi[1] <= lo1
                    or olo[2] >= hi2 or ohi[2] <= lo2):
                continue
            if parts_intersect(part, other, self.rel_tol, bounds, (olo, ohi)):
                n += 1
        return n

    def add(self, part) -> int:
        """Add a part; returns how many earlier parts it intersects."""
        lo, hi = part_bounds(part)
        bounds = (tuple(lo.tolist()), tuple(hi.tolist()))
        n = self._hits(part, bounds)
        self.parts.append(part)
        self.bounds.append(bounds)
        self.count += n
        return n

    def remove(self, part) -> int:
        """Take out a part added earlier (the last equal one); returns how many of the
        others it intersected."""
        for i in range(len(self.parts) - 1, -1, -1):
            if self.parts[i] == part:
                n = self._hits(part, self.bounds[i], skip=i)
                del self.parts[i], self.bounds[i]
                self.count -= n
                return n
        raise ValueError(f"{part!r} was not added")
