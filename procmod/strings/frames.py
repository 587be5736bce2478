"""Part frames and whole-shape symmetries (seed 001, section 6).

**Local frames** by the extremal-point ("diagonal") method: the vertex ``v`` farthest from
the centre of gravity, the vertex ``w`` farthest from ``v``, the vertex ``u`` farthest from
the line ``vw``; tied vertices are averaged, and when the average collapses (a box's
corners all tie) the tied vertex listed first in the part library is taken, which keeps
the frame attached to the part however it is placed. A symmetric part's frame is then
turned by its own symmetry to the equivalent frame closest to the world axes
(:func:`canonical_frame`), so one pose has one frame.

**World symmetries**: the turns about the vertical axis and mirrors of a whole shape,
which a string cannot tell apart (:func:`symmetric_copies`). Which ones a set has is
estimated from its shapes (:func:`estimate_world_symmetries`: the turns and mirrors that
map the horizontal directions between neighbouring parts onto themselves: quarter turns on
a square grid, 30-degree turns on a triangular lattice of 12-sided posts);
:func:`world_symmetries` (quarter turns, mirrors) is the default for sets without any.
"""

from __future__ import annotations

import numpy as np

from ..geometry.solid import matrix, rotation
from .contacts import part_points
from .shapes import Shape, ShapeSet


def _extreme(points: np.ndarray, dist: np.ndarray, eps: float) -> np.ndarray:
    """The average of the points at maximal ``dist``; the first of them if they average out."""
    top = np.nonzero(dist >= dist.max() - eps)[0]
    return points[top].mean(0), points[top[0]]


def local_frame(points: np.ndarray, eps_rel: float = 1e-5) -> np.ndarray:
    """A rigid 4x4 frame (origin = vertex mean) from a part's world vertices, by the
    extremal-point method (see the module docstring)."""
    p = np.asarray(points, dtype=np.float64)
    c = p.mean(0)
    scale = max(float(np.linalg.norm(p - c, axis=1).max()), 1e-12)
    eps = eps_rel * scale
    avg, first = _extreme(p, np.linalg.norm(p - c, axis=1), eps)
    v = avg if np.linalg.norm(avg - c) > 1e-3 * scale else first
    avg, first = _extreme(p, np.linalg.norm(p - v, axis=1), eps)
    w = avg if np.linalg.norm(avg - v) > 1e-3 * scale else first
    a1 = (w - v) / max(np.linalg.norm(w - v), 1e-12)
    rel = p - v
    foot = v + np.outer(rel @ a1, a1)
    off = np.linalg.norm(p - foot, axis=1)
    avg, first = _extreme(p, off, eps)
    u = avg if np.linalg.norm(avg - (v + ((avg - v) @ a1) * a1)) > 1e-3 * scale else first
    a2 = u - (v + ((u - v) @ a1) * a1)
    if np.linalg.norm(a2) < 1e-9 * scale:  # all points on one line: any perpendicular
        a2 = np.cross(a1, [1.0, 0.0, 0.0] if abs(a1[0]) < 0.9 else [0.0, 1.0, 0.0])
    a2 /= np.linalg.norm(a2)
    a3 = np.cross(a1, a2)
    f = np.eye(4)
    f[:3, 0], f[:3, 1], f[:3, 2], f[:3, 3] = a1, a2, a3, c
    return f


def _candidate_rotations() -> list[np.ndarray]:
    """The 24 rotations of the cube, each also composed with turns by multiples of 30 and
    of 45 degrees about the library x, y and z axes: the symmetries :func:`symmetry_group`
    looks for (boxes, prisms and cylinders of 4, 6, 8 or 12 sides, whichever axis a mesh
    was modelled along: glTF meshes stand along y)."""
    mats = []
    for perm in ((0, 1, 2), (1, 2, 0), (2, 0, 1), (1, 0, 2), (0, 2, 1), (2, 1, 0)):
        for signs in np.ndindex(2, 2, 2):
            m = np.zeros((3, 3))
            for r, c in enumerate(perm):
                m[r, c] = 1 - 2 * signs[r]
            if np.linalg.det(m) > 0:
                mats.append(m)
    angles = sorted({k * np.pi / 6 for k in range(12)} | {k * np.pi / 4 for k in range(8)})
    turns = [matrix(rotation(axis, a))[:3, :3] for axis in "zxy" for a in angles]
    out, keys = [], set()
    for t in turns:
        for m in mats:
            r = t @ m
            key = tuple(np.round(r, 6).reshape(9).tolist())
            if key not in keys:
                keys.add(key)
                out.append(r)
    return out


_CANDIDATES = None


def symmetry_group(local_points: np.ndarray, rel_tol: float = 1e-4) -> list[np.ndarray]:
    """Rotations (about the vertex mean, in the part's library frame) that map its vertex
    set onto itself, among :func:`_candidate_rotations` (boxes, prisms, cylinders)."""
    from scipy.spatial import cKDTree

    global _CANDIDATES
    if _CANDIDATES is None:
        _CANDIDATES = _candidate_rotations()
    p = np.asarray(local_points, dtype=np.float64)
    p = p - p.mean(0)
    tol = rel_tol * max(float(np.linalg.norm(p, axis=1).max()), 1e-12)
    cov = p.T @ p / len(p)
    scale = max(float(np.abs(cov).max()), 1e-300)
    tree = cKDTree(p)
    group = []
    for r in _CANDIDATES:
        # a symmetry keeps the second moments: a cheap test before the point query
        if np.abs(r @ cov @ r.T - cov).max() > 1e-3 * scale:
            continue
        dist, _ = tree.query(p @ r.T, distance_upper_bound=2 * tol + 1e-300)
        if np.all(dist <= tol):
            group.append(r)
    return group


def canonical_frame(library: dict, name: str, transform: np.ndarray, groups: dict) -> np.ndarray:
    """The extremal-point frame of a placed part, turned by the part's own symmetry to the
    equivalent frame closest to the world axes (so a symmetric part gets the same frame
    however it was turned into place). ``groups`` caches each part's symmetries."""
    f = local_frame(part_points(library, name, transform))
    group = groups.get(name)
    if group is None:
        local = part_points(library, name, np.eye(4))
        r_local = local_frame(local)[:3, :3]
        # A symmetry S of the part turns its frame R_L into S R_L: in frame terms R_L^T S R_L.
        group = groups[name] = [r_local.T @ sym @ r_local for sym in symmetry_group(local)] or [np.eye(3)]
    # The closest to the world axes (largest trace); ties broken by the rounded entries, so
    # the choice depends only on the set of equivalent frames, not on how the part was turned.
    best, best_score = f, None
    for g in group:
        rot = _orthonormal(f[:3, :3] @ g)
        score = (round(float(np.trace(rot)), 6), tuple(np.round(rot, 6).reshape(9).tolist()))
        if best_score is None or score > best_score:
            best_score = score
            best = f.copy()
            best[:3, :3] = rot
    return best


def rigid_inverse(f: np.ndarray) -> np.ndarray:
    """The inverse of a rigid 4x4 transform (rotation transposed, translation turned back)."""
    out = np.eye(4)
    out[:3, :3] = f[:3, :3].T
    out[:3, 3] = -f[:3, :3].T @ f[:3, 3]
    return out


def _orthonormal(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def world_symmetries() -> list[np.ndarray]:
    """The 8 quarter turns of a whole shape about the vertical (z) axis, with and without a
    mirror in x: moves a string cannot tell apart (mirrors apply to shapes whose parts are
    mirror-symmetric, see :func:`proper_placement`)."""
    out = []
    for mirror in (1.0, -1.0):
        for k in range(4):
            c, s_ = [(1, 0), (0, 1), (-1, 0), (0, -1)][k]
            m = np.eye(4)
            m[:2, :2] = [[c, -s_], [s_, c]]
            out.append(m @ np.diag([mirror, 1.0, 1.0, 1.0]))
    return out


_MIRROR = np.diag([-1.0, 1.0, 1.0, 1.0])

# part geometry (its library-frame vertices) -> the part's own mirror about its vertex mean
# (a 4x4), or None when the part is not mirror-symmetric. Keyed by the points, not the part
# name: two libraries may give one name different parts.
_OWN_MIRROR: dict[bytes, np.ndarray | None] = {}


def _own_mirror(library: dict, name: str) -> np.ndarray | None:
    """The part's mirror in its own x about its vertex mean (4x4, in library coordinates)
    when that maps its vertices onto themselves, else None; remembered per geometry."""
    p = part_points(library, name, np.eye(4))
    key = p.tobytes()
    if key not in _OWN_MIRROR:
        c = p.mean(0)
        q = (p - c) * [-1.0, 1.0, 1.0] + c
        scale = max(float(np.linalg.norm(p - c, axis=1).max()), 1e-12)
        mirror = None
        if np.linalg.norm(q[:, None] - p[None], axis=2).min(1).max() <= 1e-6 * scale:
            about, back = np.eye(4), np.eye(4)
            about[:3, 3], back[:3, 3] = c, -c
            mirror = about @ _MIRROR @ back
        _OWN_MIRROR[key] = mirror
    return _OWN_MIRROR[key]


def proper_placement(library: dict, name: str, m: np.ndarray) -> np.ndarray | None:
    """``m`` if it turns without mirroring; else the proper transform that puts the part's
    points in the same place (``m`` times a mirror of the part in its own x), when the part
    is mirror-symmetric; None when it is not (a mirrored copy would need a mirrored part)."""
    if np.linalg.det(m[:3, :3]) > 0:
        return m
    mirror = _own_mirror(library, name)
    return None if mirror is None else m @ mirror


def turn_about_z(degrees: float) -> np.ndarray:
    """The 4x4 turn by ``degrees`` about the vertical (z) axis."""
    return matrix(rotation("z", np.radians(degrees)))


def mirror_across(degrees: float) -> np.ndarray:
    """The 4x4 mirror across the vertical plane through the origin at ``degrees`` from the
    x axis (a horizontal direction at angle t goes to 2 * degrees - t)."""
    return turn_about_z(2.0 * degrees) @ np.diag([1.0, -1.0, 1.0, 1.0])


def neighbour_directions(shape_set: ShapeSet, shapes, graphs, min_rel: float = 0.01) -> np.ndarray:
    """The distinct horizontal directions (degrees in [0, 360)) from a part's vertex mean to
    each neighbour's, over ``shapes`` (both ways round); offsets whose horizontal part is
    shorter than ``min_rel`` times the median part diagonal (a part on top of another) count
    for none."""
    lib = shape_set.library
    length = float(np.median([np.linalg.norm(np.subtract(*s.local_bounds()[::-1])) for s in lib.values()]))
    centre_of = {p: part_points(lib, p, np.eye(4)).mean(0) for p in lib}
    out = []
    for shape, g in zip(shapes, graphs):
        centres = [t[:3, :3] @ centre_of[p] + t[:3, 3] for p, t in zip(shape.parts, shape.transforms)]
        for a, b in g.edges:
            d = centres[b] - centres[a]
            if np.hypot(d[0], d[1]) >= min_rel * length:
                out += [np.degrees(np.arctan2(d[1], d[0])), np.degrees(np.arctan2(-d[1], -d[0]))]
    return np.unique(np.mod(np.round(np.mod(out, 360.0), 6), 360.0))


def _angle_gap(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Circular distance in degrees between every angle of ``a`` and every angle of ``b``."""
    d = np.abs(np.mod(a[:, None] - b[None, :], 360.0))
    return np.minimum(d, 360.0 - d)


def estimate_world_symmetries(shape_set: ShapeSet, shapes, graphs, steps: int = 120,
                              tol_degrees: float = 0.25) -> list[np.ndarray]:
    """The whole-shape symmetries a set's shapes show (4x4, about the origin; the identity
    first, then the other turns, then the mirrors): the turns about the vertical by a
    multiple of ``360 / steps`` degrees and the mirrors across vertical planes (at an
    observed direction plus a multiple of ``180 / steps`` degrees) that map the set of
    horizontal directions between neighbours (:func:`neighbour_directions`) onto itself,
    within ``tol_degrees``. A square grid gives the quarter turns and their 4 mirrors, a
    triangular lattice of 12-sided posts the 12 turns by 30 degrees and 12 mirrors, at
    whatever angle the lattice is turned. Without horizontal contacts:
    :func:`world_symmetries`. The default ``steps`` (3-degree turns) covers turns of order
    2, 3, 4, 5, 6, 8, 10, 12, 24, ...; tolerances are angles, so independent of part size."""
    dirs = neighbour_directions(shape_set, shapes, graphs)
    if len(dirs) == 0:
        return world_symmetries()

    def keeps(images: np.ndarray) -> bool:
        return bool(_angle_gap(images, dirs).min(1).max() <= tol_degrees)

    # mirrors as a turn after the mirror across the plane square to the first direction
    # (on a square grid: the mirror in x), in the order of world_symmetries
    base = dirs[0] + 90.0
    angles = [360.0 * k / steps for k in range(steps)]
    turns = [turn_about_z(a) for a in angles if keeps(dirs + a)]
    mirrors = [turn_about_z(a) @ mirror_across(base) for a in angles if keeps(2 * base - dirs + a)]
    # exact zeros and ones where a turn is a quarter turn (cos 90 degrees is 6e-17 in floats)
    return [np.round(m, 12) + 0.0 for m in turns + mirrors]


def symmetric_copies(shape: Shape, library: dict | None = None,
                     symmetries: list[np.ndarray] | None = None) -> list[Shape | None]:
    """A shape moved by each of ``symmetries`` (default :func:`world_symmetries`; about its
    centroid); None for a mirror when a part is not mirror-symmetric (needs ``library``;
    without it mirrors are None)."""
    centre = np.mean([t[:3, 3] for t in shape.transforms], axis=0)
    to, back = np.eye(4), np.eye(4)
    to[:3, 3], back[:3, 3] = -centre, centre
    out = []
    for g in world_symmetries() if symmetries is None else symmetries:
        moved = [back @ g @ to @ t for t in shape.transforms]
        if np.linalg.det(g[:3, :3]) < 0:
            if library is None:
                out.append(None)
                continue
            moved = [proper_placement(library, p, m) for p, m in zip(shape.parts, moved)]
            if any(m is None for m in moved):
                out.append(None)
                continue
        out.append(Shape.of(shape.parts, moved))
    return out
