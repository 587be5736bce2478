"""Contact geometry (seed 001, section 3): which parts of a shape touch.

Two parts are neighbours iff their surfaces intersect, within a tolerance
(:func:`shape_graph`; default :func:`tolerance_for` the library): an exact separating-axis
test for two boxes, python-fcl on triangle meshes otherwise, after an axis-aligned
bounding-box pre-filter.
"""

from __future__ import annotations

import math

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError
from ..geometry.part_library import PartShape
from .shapes import Shape, ShapeSet

DEFAULT_TOLERANCE = 1e-3  # times the median part diagonal


_BOX_CORNERS = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)])


def part_points(library: dict, name: str, transform: np.ndarray) -> np.ndarray:
    """World-space vertices of a part (a box's 8 corners, a mesh's vertices), in library order."""
    shape: PartShape = library[name]
    local = _BOX_CORNERS * np.asarray(shape.size) if shape.kind == "box" else np.asarray(shape.vertices)
    return local @ transform[:3, :3].T + transform[:3, 3]


def _box_axes(t: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Face normals and edge directions of a (possibly sheared) box placed by ``t``."""
    edges = t[:3, :3].T  # rows: images of the local x, y, z axes
    normals = np.array([np.cross(edges[1], edges[2]), np.cross(edges[2], edges[0]), np.cross(edges[0], edges[1])])
    return normals, edges


def boxes_touch(corners_a, t_a, corners_b, t_b, tol: float) -> bool:
    """Exact separating-axis test: do two boxes (parallelepipeds) intersect or lie within ``tol``?"""
    na, ea = _box_axes(t_a)
    nb, eb = _box_axes(t_b)
    cross = np.cross(ea[:, None, :], eb[None, :, :]).reshape(9, 3)
    axes = np.concatenate([na, nb, cross])
    norms = np.linalg.norm(axes, axis=1)
    keep = norms > 1e-9 * max(norms.max(), 1e-300)
    axes = axes[keep] / norms[keep, None]
    pa, pb = corners_a @ axes.T, corners_b @ axes.T
    gap = np.maximum(pb.min(0) - pa.max(0), pa.min(0) - pb.max(0))
    return bool(np.all(gap <= tol))


def _fcl_object(points: np.ndarray, faces: np.ndarray):
    import fcl
    model = fcl.BVHModel()
    model.beginModel(len(points), len(faces))
    model.addSubModel(np.ascontiguousarray(points, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int32))
    model.endModel()
    return fcl.CollisionObject(model, fcl.Transform())


_BOX_FACES = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                       (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)])


_LOCAL_MODELS: dict[int, tuple] = {}  # id(PartShape) -> (the PartShape, its fcl BVH in its own frame)


def _local_model(shape: PartShape):
    """The fcl BVH of a library part in its own frame (built once per part object)."""
    import fcl
    held = _LOCAL_MODELS.get(id(shape))
    if held is None or held[0] is not shape:
        local = _BOX_CORNERS * np.asarray(shape.size) if shape.kind == "box" else np.asarray(shape.vertices)
        faces = _BOX_FACES if shape.kind == "box" else np.asarray(shape.faces)
        model = fcl.BVHModel()
        model.beginModel(len(local), len(faces))
        model.addSubModel(np.ascontiguousarray(local, dtype=np.float64), np.ascontiguousarray(faces, dtype=np.int32))
        model.endModel()
        if len(_LOCAL_MODELS) > 256:
            _LOCAL_MODELS.clear()
        held = _LOCAL_MODELS[id(shape)] = (shape, model)
    return held[1]


def meshes_touch(obj_a, obj_b, tol: float) -> bool:
    """Do two fcl triangle meshes' surfaces intersect or come within ``tol``?"""
    import fcl
    if fcl.collide(obj_a, obj_b, fcl.CollisionRequest(), fcl.CollisionResult()):
        return True
    return fcl.distance(obj_a, obj_b, fcl.DistanceRequest(), fcl.DistanceResult()) <= tol


def contact_tolerance(shape_set: ShapeSet) -> float:
    """The set's contact tolerance: the one it was given (``ShapeSet.tolerance``), else
    :func:`tolerance_for` its library."""
    return shape_set.tolerance if shape_set.tolerance is not None else tolerance_for(shape_set.library)


def median_part_size(library: dict) -> float:
    """The median of the library's parts' bounding-box diagonals."""
    return float(np.median([float(np.linalg.norm(np.subtract(*s.local_bounds()[::-1]))) for s in library.values()]))


def tolerance_for(library: dict) -> float:
    """The default contact tolerance: :data:`DEFAULT_TOLERANCE` times the median part diagonal."""
    return DEFAULT_TOLERANCE * median_part_size(library)


def contact_pairs(library: dict, parts, transforms, tol: float, pairs_of=None) -> list[tuple[int, int]]:
    """Pairs ``(i, j)``, ``i < j``, of parts whose surfaces intersect (within ``tol``).

    ``pairs_of`` optionally restricts the test to the given candidate pairs.
    """
    points = [part_points(library, p, t) for p, t in zip(parts, transforms)]
    lo = np.array([q.min(0) for q in points]) - tol
    hi = np.array([q.max(0) for q in points]) + tol
    if pairs_of is None:
        overlap = np.all((lo[:, None, :] <= hi[None, :, :]) & (lo[None, :, :] <= hi[:, None, :]), axis=2)
        ii, jj = np.nonzero(np.triu(overlap, 1))
        candidates = zip(ii.tolist(), jj.tolist())
    else:
        candidates = [(i, j) for i, j in pairs_of if np.all(lo[i] <= hi[j]) and np.all(lo[j] <= hi[i])]
    fcl_objects: dict[int, object] = {}

    def obj(k):
        if k not in fcl_objects:
            shape = library[parts[k]]
            t = np.asarray(transforms[k], dtype=np.float64)
            r = t[:3, :3]
            if np.abs(r @ r.T - np.eye(3)).max() <= 1e-9 and np.linalg.det(r) > 0:
                # a rigid placement: the part's own BVH, built once, placed by fcl
                import fcl
                fcl_objects[k] = fcl.CollisionObject(_local_model(shape), fcl.Transform(r, t[:3, 3]))
            else:
                faces = _BOX_FACES if shape.kind == "box" else np.asarray(shape.faces)
                fcl_objects[k] = _fcl_object(points[k], faces)
        return fcl_objects[k]

    out = []
    for i, j in candidates:
        if library[parts[i]].kind == "box" and library[parts[j]].kind == "box":
            hit = boxes_touch(points[i], transforms[i], points[j], transforms[j], tol)
        else:
            hit = meshes_touch(obj(i), obj(j), tol)
        if hit:
            out.append((min(i, j), max(i, j)))
    return sorted(out)


def shape_graph(shape_set: ShapeSet, shape: Shape, tol: float | None = None) -> nx.Graph:
    """The shape graph: one node per part (``type`` = its letter, ``part`` = its name),
    an edge per pair of parts whose surfaces intersect within ``tol`` (default
    :func:`tolerance_for` the library)."""
    if tol is not None:
        try:
            value = float(tol)  # numpy numbers too
        except (TypeError, ValueError):
            value = math.nan
        if isinstance(tol, (bool, np.bool_, str)) or not 0 <= value < math.inf:
            raise InvalidArgumentError(f"tol must be a finite distance of at least 0 (or None for the library's "
                                       f"own), got {tol!r:.40}")
        tol = value
    tol = contact_tolerance(shape_set) if tol is None else tol
    g = nx.Graph()
    for k, name in enumerate(shape.parts):
        g.add_node(k, type=shape_set.letters[name], part=name)
    g.add_edges_from(contact_pairs(shape_set.library, shape.parts, shape.transforms, tol))
    return g


def centroids(shape_set: ShapeSet, shape: Shape) -> np.ndarray:
    """Centroid (vertex mean) of each part, ``(n, 3)``."""
    return np.array([part_points(shape_set.library, p, t).mean(0) for p, t in zip(shape.parts, shape.transforms)])


def loose_parts(g, pieces, index: int, inputs, letters: dict, tolerance: float | None = None) -> str:
    """Which parts of shape ``index`` touch nothing of its largest piece (for messages;
    ``letters``: part name -> type letter), and within what ``tolerance`` (a gap a part
    placed by eye leaves is found only within it)."""
    name_of = {letter: name for name, letter in letters.items()}
    loose = sorted(name_of.get(g.nodes[v]["type"], g.nodes[v]["type"]) for piece in pieces[1:] for v in piece)
    shown = ", ".join(loose[:8]) + (f" and {len(loose) - 8} more" if len(loose) > 8 else "")
    source = f" ({inputs[index]})" if inputs else ""
    within = f" within {tolerance:.3g}" if tolerance is not None else ""
    if all(len(piece) == 1 for piece in pieces[1:]):
        return (f"shape {index}{source} is in {len(pieces)} pieces: {shown} touch{'es' if len(loose) == 1 else ''} "
                f"no other part{within}")
    # pieces of several parts: those parts touch each other, only not the largest piece
    sizes = ", ".join(str(len(piece)) for piece in pieces[:6]) + (", ..." if len(pieces) > 6 else "")
    return (f"shape {index}{source} is in {len(pieces)} pieces of {sizes} parts: {shown} touch nothing of the "
            f"largest piece{within}")
