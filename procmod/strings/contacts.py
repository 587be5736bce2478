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


NEAR_MISS = 0.02
"""Two parts apart by less than this share of the median part's size (or 4x the contact
tolerance, if more) without touching within the tolerance are named in a note
(:func:`near_misses`): a wall placed by eye 15 mm short of its tower dropped that one
contact without a word, the grammar learned that a wall may hang from one tower, and
augment built shapes with walls hanging off one (4 of 14; h139)."""

JOIN_REACH = 0.25
"""The largest contact tolerance, as a share of the median part's size, that
:func:`joining_tolerance` tries: past it parts touch their neighbours' neighbours."""


def _least_touching(library: dict, shape: Shape, lo: float, hi: float, touches) -> float | None:
    """The least contact tolerance in ``(lo, hi]`` at which ``touches(pairs)`` holds of the
    contacts found there (bisected to within 5%, then rounded up to two significant
    digits), or None where it does not hold at ``hi``."""
    def holds(tol):
        return touches(contact_pairs(library, shape.parts, shape.transforms, tol))

    if not holds(hi):
        return None
    for _ in range(40):
        if hi - lo <= 0.05 * hi:
            break
        mid = 0.5 * (lo + hi)
        lo, hi = (lo, mid) if holds(mid) else (mid, hi)
    digits = 10.0 ** (math.floor(math.log10(hi)) - 1)
    return math.ceil(hi / digits - 1e-9) * digits


def joining_tolerance(shape_set: ShapeSet, shape: Shape, tol: float) -> float | None:
    """The contact tolerance (up to :data:`JOIN_REACH` of the median part's size) at which a
    shape in pieces becomes one: what ``--tolerance`` to give for gaps left by hand. None
    when no tolerance in reach joins it (its pieces are apart, not placed by eye)."""
    count = len(shape.parts)

    def one_piece(pairs):
        g = nx.Graph()
        g.add_nodes_from(range(count))
        g.add_edges_from(pairs)
        return nx.is_connected(g)

    reach = JOIN_REACH * median_part_size(shape_set.library)
    return _least_touching(shape_set.library, shape, tol, reach, one_piece) if reach > tol else None


def joining_text(join: float | None) -> str:
    """What to say of a shape in pieces, given its :func:`joining_tolerance`: the
    ``--tolerance`` that joins them, or that none near a part's size does."""
    if join is None:
        return (f"no tolerance up to {JOIN_REACH:.0%} of a part's size joins them (they are apart, not left "
                "short by hand)")
    return f"--tolerance {join:.2g} joins them"


def gaps_to_close(shape_set: ShapeSet, shape: Shape, g, tol: float, kinds: set | None = None) -> tuple:
    """``(joining tolerance or None, near misses)`` of a shape whose graph at ``tol`` is
    ``g``: for a shape in pieces, the tolerance that joins them (:func:`joining_tolerance`)
    and the near misses left at it; for one in one piece, None and its near misses
    (``kinds``: :func:`near_misses`)."""
    if len(g) == 0 or nx.is_connected(g):
        return None, near_misses(shape_set, shape, g, tol, kinds)
    join = joining_tolerance(shape_set, shape, tol)
    if join is None:
        return None, []
    return join, near_misses(shape_set, shape, shape_graph(shape_set, shape, join), join, kinds)


def contact_kinds(graphs) -> set:
    """The pairs of part types (frozensets of part names) that touch somewhere in ``graphs``."""
    return {frozenset((g.nodes[i]["part"], g.nodes[j]["part"])) for g in graphs for i, j in g.edges}


def near_misses(shape_set: ShapeSet, shape: Shape, g, tol: float, kinds: set | None = None) -> list:
    """``(i, j, tolerance at which they touch)`` for the pairs of parts of ``shape`` nearer
    than :data:`NEAR_MISS` of the median part's size (or 4x ``tol``) that do not touch in
    its shape graph ``g``: gaps a hand may have left between parts meant to touch. Only
    pairs of types that touch somewhere in the set (``kinds``, :func:`contact_kinds`; all
    when None) and that share no neighbour: two beams ending 3 cm apart on the column both
    rest on are built so (the shipped colonnade), not a wall left short of its tower."""
    reach = max(4.0 * tol, NEAR_MISS * median_part_size(shape_set.library))
    near = [(i, j) for i, j in contact_pairs(shape_set.library, shape.parts, shape.transforms, reach)
            if not g.has_edge(i, j) and not set(g.neighbors(i)) & set(g.neighbors(j))
            and (kinds is None or frozenset((shape.parts[i], shape.parts[j])) in kinds)]
    out = []
    for i, j in near:
        need = _least_touching(shape_set.library, Shape.of([shape.parts[i], shape.parts[j]],
                                                            [shape.transforms[i], shape.transforms[j]]),
                               tol, reach, bool)
        if need is not None:
            out.append((i, j, need))
    return out


def near_miss_note(shape: Shape, misses: list, tol: float, index: int, inputs) -> str:
    """One line naming the near misses (:func:`near_misses`) of shape ``index``."""
    names = [f"{shape.parts[i]} #{i} and {shape.parts[j]} #{j}" for i, j, _ in misses[:3]]
    more = f" and {len(misses) - 3} more pairs" if len(misses) > 3 else ""
    need = max(t for _, _, t in misses)
    source = f" ({inputs[index]})" if inputs else ""
    return (f"shape {index}{source}: {'; '.join(names)}{more} are nearer than {NEAR_MISS:.0%} of a part's size "
            f"but do not touch within the contact tolerance {tol:.3g}, so no contact joins them; if they were placed "
            f"by eye to touch, give --tolerance {need:.2g} (new shapes otherwise take each such part as free there)")


def _solid_holds(library: dict, name: str, transform: np.ndarray, points: np.ndarray) -> bool:
    """Do all ``points`` lie inside the solid of part ``name`` placed by ``transform`` (a box's
    parallelepiped; a mesh's inside by its generalised winding number, either winding)?"""
    shape: PartShape = library[name]
    t = np.asarray(transform, dtype=np.float64)
    if shape.kind == "box":
        local = np.linalg.solve(t[:3, :3], (points - t[:3, 3]).T).T
        return bool(np.all(np.abs(local) <= 0.5 * np.asarray(shape.size) * (1 + 1e-9)))
    from ..geometry.inside import winding_numbers
    return bool(np.all(np.abs(winding_numbers(part_points(library, name, t), np.asarray(shape.faces), points)) >= 0.5))


def enclosing_parts(shape_set: ShapeSet, shape: Shape, pieces) -> dict:
    """``{part: (other part, True when it lies inside the other / False when it holds the
    other inside it)}`` for the parts outside the largest of ``pieces`` (the connected
    components of the shape's graph, largest first) that lie wholly inside a part of the
    largest piece, or hold one wholly inside them. One of the two is a mesh part: a mesh part touches
    another only where their surfaces meet (a box inside a box touches it), so such a part
    touches nothing there however near (h154: a part inside another was called apart, with
    advice about the contact tolerance, which bridges gaps between parts side by side)."""
    library = shape_set.library
    points = [part_points(library, p, t) for p, t in zip(shape.parts, shape.transforms)]
    lo, hi = [q.min(0) for q in points], [q.max(0) for q in points]

    def inside(a: int, b: int) -> bool:  # part a wholly inside part b (a sample of a's vertices)
        if not (np.all(lo[b] <= lo[a]) and np.all(hi[a] <= hi[b])):
            return False
        sample = points[a][::max(1, len(points[a]) // 64)]
        return _solid_holds(library, shape.parts[b], shape.transforms[b], sample)

    out = {}
    for v in sorted(v for piece in pieces[1:] for v in piece):
        # the other part in the largest piece: a part inside one that is itself apart from the
        # shape is apart too, and moving it out to its holder's surface would not join it (h159)
        for u in sorted(pieces[0]):
            boxes = library[shape.parts[u]].kind == library[shape.parts[v]].kind == "box"
            if boxes:
                continue
            if inside(v, u) or inside(u, v):
                out[v] = (u, inside(v, u))
                break
    return out


ENCLOSED_ADVICE = "move a part that lies inside another out until their surfaces meet, or leave it out"
"""What to do about parts :func:`enclosing_parts` finds (where no contact tolerance within
reach joins them: :func:`enclosed_advice`)."""


def enclosed_advice(join: float | None) -> str | None:
    """The advice for a shape whose loose parts all lie inside another part or hold one,
    given the tolerance that joins its pieces (:func:`gaps_to_close`): None where one within
    reach does (a part near the inside of a wall is joined by it as any gap is, h159), so
    the tolerance advice stands."""
    if join is not None:
        return None
    return f"{ENCLOSED_ADVICE} (no contact tolerance up to {JOIN_REACH:.0%} of a part's size reaches its surface)"


def only_enclosed(pieces, enclosed: dict) -> bool:
    """Is every part outside the largest of ``pieces`` one that lies inside another part or
    holds one (``enclosed``: :func:`enclosing_parts`)? Then no contact tolerance is the fix."""
    return bool(enclosed) and all(v in enclosed for piece in pieces[1:] for v in piece)


def loose_parts(g, pieces, index: int, inputs, letters: dict, tolerance: float | None = None,
                enclosed: dict | None = None) -> str:
    """Which parts of shape ``index`` touch nothing of its largest piece (for messages;
    ``letters``: part name -> type letter), and within what ``tolerance`` (a gap a part
    placed by eye leaves is found only within it); ``enclosed`` (:func:`enclosing_parts`)
    names those that lie inside another part or hold one, rather than apart from it."""
    name_of = {letter: name for name, letter in letters.items()}

    def name(v):
        return name_of.get(g.nodes[v]["type"], g.nodes[v]["type"])

    loose = sorted(name(v) for piece in pieces[1:] for v in piece)
    shown = ", ".join(loose[:8]) + (f" and {len(loose) - 8} more" if len(loose) > 8 else "")
    source = f" ({inputs[index]})" if inputs else ""
    within = f" within {tolerance:.3g}" if tolerance is not None else ""
    if enclosed:
        said = [f"{name(v)} #{v} lies inside {name(u)} #{u}" if is_in else f"{name(v)} #{v} holds {name(u)} #{u} "
                "inside it" for v, (u, is_in) in sorted(enclosed.items())]
        held = ("; ".join(said[:3]) + (f" and {len(said) - 3} more" if len(said) > 3 else "")
                + ", touching none of its surface (a mesh part touches another only where their surfaces meet, "
                "not inside it)")
        if only_enclosed(pieces, enclosed):
            return f"shape {index}{source} is in {len(pieces)} pieces: {held}"
    if all(len(piece) == 1 for piece in pieces[1:]):
        text = (f"shape {index}{source} is in {len(pieces)} pieces: {shown} "
                f"touch{'es' if len(loose) == 1 else ''} no other part{within}")
    else:  # pieces of several parts: those parts touch each other, only not the largest piece
        sizes = ", ".join(str(len(piece)) for piece in pieces[:6]) + (", ..." if len(pieces) > 6 else "")
        text = (f"shape {index}{source} is in {len(pieces)} pieces of {sizes} parts: {shown} touch nothing of the "
                f"largest piece{within}")
    return text + (f" ({held})" if enclosed else "")
