"""Triangles of a mesh file's polygon faces, right for concave ones.

OBJ, PLY and OFF files hold faces of any number of corners, and tools write them so:
Blender's and Maya's exporters keep n-gons unless told to triangulate. trimesh splits
each into a fan from its first corner, which covers a convex face only: an L-shaped
floor's six-cornered face gained a triangle across its inner corner (a silhouette target
of an L-shaped prism had 1621 pixels to hit instead of 1280, with no word). Here a convex
face keeps the fan (what trimesh made of it), and a concave one is ear-clipped (mapbox's
earcut, the triangulation trimesh itself uses for 2D polygons) in its own plane.
"""

from __future__ import annotations

import numpy as np


def newell_normals(points: np.ndarray) -> np.ndarray:
    """Newell's normals of polygons ``points`` (``(g, k, 3)``, corners in order): twice
    the area vector of each, right for non-planar and concave polygons alike."""
    following = np.roll(points, -1, axis=1)
    return np.cross(points, following).sum(axis=1)


CONCAVE_TURN = 1e-3
"""A corner turns against its polygon (is concave) when the sine of its turn, measured
against the polygon's normal, is below minus this: ~0.06 degrees. Corners straight to
within that (a grid's hexagon on a gently curved surface, not quite planar) keep the
fan, as trimesh made it."""


def convex_faces(points: np.ndarray) -> np.ndarray:
    """Whether each polygon of ``points`` (``(g, k, 3)``) turns the same way at every
    corner (a straight corner counts as either, :data:`CONCAVE_TURN`), so that a fan from
    its first corner covers it. Each corner is judged by its own angle: a notch of short
    edges in a long face (a letter's inner curve, 7.5 degrees a corner) is concave however
    long the face's other edges are."""
    normals = newell_normals(points)
    normals /= np.maximum(np.linalg.norm(normals, axis=1), 1e-300)[:, None]
    edges = np.roll(points, -1, axis=1) - points
    following = np.roll(edges, -1, axis=1)
    turns = np.einsum("gkc,gc->gk", np.cross(edges, following), normals)
    lengths = np.linalg.norm(edges, axis=2) * np.linalg.norm(following, axis=2)
    return (turns >= -CONCAVE_TURN * lengths).all(axis=1)


def fan_covers(points: np.ndarray) -> np.ndarray:
    """Whether a fan from its first corner covers each polygon of ``points`` (``(g, k,
    3)``): it is convex and writes no corner twice in a row (a repeated corner hides the
    turn across it, so such a face takes the full path, :func:`polygon_triangles`)."""
    repeats = (points == np.roll(points, 1, axis=1)).all(axis=2).any(axis=1)
    return convex_faces(points) & ~repeats


def fan(k: int) -> np.ndarray:
    """The fan triangles of a ``k``-cornered polygon: ``(0, i, i + 1)``."""
    i = np.arange(1, k - 1)
    return np.stack([np.zeros_like(i), i, i + 1], axis=1)


def polygon_triangles(points: np.ndarray) -> np.ndarray:
    """Triangles (corner indices, wound as the polygon is) covering the polygon ``points``
    (``(k, 3)``, corners in order), ear-clipped in its plane: ``k - 2`` of them, fewer
    where a corner repeats the one before it (as some exporters close a face with its
    first corner again); the fan where the polygon has no area or crosses itself (earcut
    then covers less of it)."""
    repeated = np.all(points == np.roll(points, 1, axis=0), axis=1)
    if repeated.any() and not repeated.all():
        kept = np.flatnonzero(~repeated)
        return kept[polygon_triangles(points[kept])] if len(kept) >= 3 else np.zeros((0, 3), dtype=np.int64)
    return _ear_clipped(points)


def _ear_clipped(points: np.ndarray) -> np.ndarray:
    import mapbox_earcut

    k = len(points)
    normal = newell_normals(points[None])[0]
    length = float(np.linalg.norm(normal))
    if k == 3 or not length > 0:
        return fan(k)
    normal /= length
    # a basis (u, v) of the plane with u x v = normal: counter-clockwise in (u, v) is the
    # polygon's own winding
    u = np.cross(normal, np.eye(3)[int(np.argmin(np.abs(normal)))])
    u /= np.linalg.norm(u)
    v = np.cross(normal, u)
    flat = np.stack([points @ u, points @ v], axis=1)
    flat -= flat.mean(axis=0)
    triangles = np.asarray(mapbox_earcut.triangulate_float64(flat, np.array([k], dtype=np.uint32)),
                           dtype=np.int64).reshape(-1, 3)
    if len(triangles) != k - 2 and not np.isclose(_area(points, triangles), 0.5 * length, rtol=1e-9):
        return fan(k)  # earcut covered less than the polygon (it crosses itself); a spike's empty triangle is no loss
    a, b, c = (flat[triangles[:, j]] for j in range(3))
    clockwise = (b[:, 0] - a[:, 0]) * (c[:, 1] - a[:, 1]) - (b[:, 1] - a[:, 1]) * (c[:, 0] - a[:, 0]) < 0
    triangles[clockwise] = triangles[clockwise][:, ::-1]
    return triangles


def _area(points: np.ndarray, triangles: np.ndarray) -> float:
    a, b, c = (points[triangles[:, j]] for j in range(3))
    return 0.5 * float(np.linalg.norm(np.cross(b - a, c - a), axis=1).sum())


def triangulate_faces(vertices: np.ndarray, faces) -> np.ndarray:
    """Triangles (``(m, 3)`` vertex indices) of ``faces``, a sequence of vertex-index
    sequences of three or more corners (faces of fewer are left out; a 2D array for faces
    of one size, an object array of index arrays for mixed ones): a convex face as a fan
    from its first corner, a concave one ear-clipped (module docstring). Raises
    ValueError for a face naming a vertex that ``vertices`` lacks."""
    vertices = np.asarray(vertices, dtype=np.float64)
    if isinstance(faces, np.ndarray) and faces.dtype != object and faces.ndim == 2:
        by_size = {faces.shape[1]: faces} if faces.shape[1] >= 3 else {}  # one size: no grouping
    elif isinstance(faces, np.ndarray):  # an object array of index arrays (plyfile's faces of mixed sizes)
        sizes = np.fromiter((len(face) for face in faces), dtype=np.int64, count=len(faces))
        by_size = {int(k): np.stack(faces[sizes == k]) for k in np.unique(sizes) if k >= 3}
    else:
        by_size = {}
        for face in faces:
            if len(face) >= 3:
                by_size.setdefault(len(face), []).append(face)
    out = []
    for k, group in sorted(by_size.items()):
        group = np.asarray(group, dtype=np.int64)
        if len(group) == 0:
            continue
        if group.min() < 0 or group.max() >= len(vertices):
            bad = int(group.max() if group.max() >= len(vertices) else group.min())
            raise ValueError(f"a face refers to vertex {bad} (counting from 0), but the file has "
                             f"{len(vertices)} vertices")
        if k == 3:
            out.append(group)
            continue
        points = vertices[group]
        convex = fan_covers(points)
        out.append(group[convex][:, fan(k)].reshape(-1, 3))
        for face, corners in zip(group[~convex], points[~convex]):
            out.append(face[polygon_triangles(corners)])
    return np.concatenate(out) if out else np.zeros((0, 3), dtype=np.int64)


__all__ = ["convex_faces", "fan_covers", "newell_normals", "polygon_triangles", "triangulate_faces"]
