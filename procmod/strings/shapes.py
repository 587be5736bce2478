"""Shapes made of rigid parts, their shape graphs and tiling-grammar rules (seed 001, section 3).

A shapes file (``procmod-shapes/1``) is ``{"format": "procmod-shapes/1", "parts": {...},
"shapes": [{"nodes": [{"part": NAME, "transform": [[4x4]]}, ...]}, ...]}``: a part library
(as in ``procmod-examples/1``) and flat lists of part instances in world space.

Each part name gets a one-letter node type (:func:`type_letters`). Two parts are
neighbours iff their surfaces intersect, within a tolerance (:func:`shape_graph`): an
exact separating-axis test for two boxes, python-fcl on triangle meshes otherwise.

The tiling grammar (:class:`Grammar`) is what the input shapes show: for each node type,
the multisets of neighbour types a node of that type may have. A graph is valid when it is
connected and every node's neighbour multiset was seen for its type; a shape is valid when
the graph recomputed from its geometry is.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass
from pathlib import Path

import networkx as nx
import numpy as np

from ..core.errors import ProcmodError
from ..core.paths import contained_path, named_file
from ..core.serialize import write_text_atomic
from ..geometry.part_library import (PartLibraryError, PartShape, part_library_to_json, read_part_library,
                                     read_transform, transform_to_json)
from .codec import LETTERS, GraphError, check_graph

SHAPES_FORMAT = "procmod-shapes/1"
GRAPH_FORMAT = "procmod-graph/1"
DEFAULT_TOLERANCE = 1e-3  # times the median part diagonal


class ShapesFormatError(ProcmodError):
    """A shapes or graph file that cannot be read; the message names the JSON path."""


@dataclass(frozen=True)
class Shape:
    """One shape: part names and their 4x4 world transforms (numpy arrays)."""

    parts: tuple  # part names
    transforms: tuple  # 4x4 float arrays

    def __len__(self) -> int:
        return len(self.parts)

    @staticmethod
    def of(parts, transforms) -> "Shape":
        return Shape(tuple(parts), tuple(np.asarray(t, dtype=np.float64).reshape(4, 4) for t in transforms))


@dataclass
class ShapeSet:
    """A part library, its type letters and shapes (what a shapes file holds)."""

    library: dict  # name -> PartShape
    shapes: list  # of Shape
    letters: dict  # part name -> one-letter type
    base_dir: Path | None = None  # where mesh paths are relative to

    @property
    def part_of_letter(self) -> dict:
        return {v: k for k, v in self.letters.items()}

    def types(self, shape: Shape) -> list[str]:
        return [self.letters[p] for p in shape.parts]


def type_letters(names) -> dict[str, str]:
    """One distinct letter per part name, in sorted name order.

    A name that is itself one letter keeps it; otherwise the first letter of the name
    upper-cased, else lower-cased, else the name's other letters, else the first unused
    letter A-Z, a-z.
    """
    names = sorted(names)
    used: set[str] = set()
    out: dict[str, str] = {}
    for name in names:
        if len(name) == 1 and name in LETTERS:
            out[name] = name
            used.add(name)
    for name in names:
        if name in out:
            continue
        candidates = [c for ch in name if ch in LETTERS for c in (ch.upper(), ch.lower())]
        candidates += sorted(LETTERS)
        letter = next((c for c in candidates if c not in used), None)
        if letter is None:
            raise ShapesFormatError(f"more than {len(LETTERS)} part names; node types are single letters")
        out[name] = letter
        used.add(letter)
    return out


def read_shapes(path: str | os.PathLike) -> ShapeSet:
    """Read a ``procmod-shapes/1`` file (mesh paths relative to it), checked.

    Raises
    ------
    ShapesFormatError
        Naming the JSON path of the problem (``shapes[2].nodes[5].part``).
    """
    path = Path(path)
    if not path.is_file():
        raise ShapesFormatError(f"shapes file {path} does not exist")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ShapesFormatError(f"{path} is not JSON ({exc})") from None
    return shapes_from_dict(data, path.parent, str(path))


def shapes_from_dict(data, base_dir, source: str = "shapes") -> ShapeSet:
    """A :class:`ShapeSet` from the parsed JSON of a shapes file."""
    if not isinstance(data, dict):
        raise ShapesFormatError(f"{source}: expected a JSON object with format, parts and shapes")
    if data.get("format") != SHAPES_FORMAT:
        raise ShapesFormatError(f"{source}: format is {data.get('format')!r}, expected {SHAPES_FORMAT!r}")
    try:
        library = read_part_library(data.get("parts"), base_dir)
    except PartLibraryError as exc:
        raise ShapesFormatError(f"{source}: {exc}") from None
    shapes_json = data.get("shapes")
    if not isinstance(shapes_json, list) or not shapes_json:
        raise ShapesFormatError(f"{source}: 'shapes' must be a non-empty list of {{\"nodes\": [...]}}")
    shapes = []
    for i, s in enumerate(shapes_json):
        where = f"shapes[{i}]"
        if not isinstance(s, dict) or not isinstance(s.get("nodes"), list) or not s["nodes"]:
            raise ShapesFormatError(f"{source}: {where}: expected {{\"nodes\": [...]}} with at least one node")
        names, transforms = [], []
        for j, node in enumerate(s["nodes"]):
            w = f"{where}.nodes[{j}]"
            if not isinstance(node, dict):
                raise ShapesFormatError(f"{source}: {w}: expected {{\"part\": NAME, \"transform\": [[4x4]]}}")
            name = node.get("part")
            if name not in library:
                raise ShapesFormatError(f"{source}: {w}.part: unknown part {name!r}; the library has "
                                        f"{', '.join(sorted(library))}")
            try:
                transforms.append(read_transform(node.get("transform"), f"{w}.transform"))
            except PartLibraryError as exc:
                raise ShapesFormatError(f"{source}: {exc}") from None
            names.append(name)
        shapes.append(Shape.of(names, transforms))
    return ShapeSet(library, shapes, type_letters(library), Path(base_dir))


def shapes_to_dict(shape_set: ShapeSet, shapes=None) -> dict:
    """The JSON object of a shapes file for ``shapes`` (default: the set's own)."""
    shapes = shape_set.shapes if shapes is None else shapes
    return {"format": SHAPES_FORMAT, "parts": part_library_to_json(shape_set.library),
            "shapes": [{"nodes": [{"part": p, "transform": transform_to_json(t)}
                                  for p, t in zip(s.parts, s.transforms)]} for s in shapes]}


def write_shapes(shape_set: ShapeSet, path: str | os.PathLike, shapes=None) -> None:
    """Write a shapes file atomically. Mesh paths are written as they were read; mesh files
    are copied beside the new file when it goes to another folder."""
    import shutil

    path = Path(path)
    if shape_set.base_dir is not None and path.parent.resolve() != Path(shape_set.base_dir).resolve():
        for shape in shape_set.library.values():
            if shape.kind == "mesh":
                # inside the new file's folder only (a mesh the shapes file reached with ".." is refused)
                target = contained_path(path.parent, shape.source, f"parts.{shape.name}.mesh")
                target.parent.mkdir(parents=True, exist_ok=True)
                shutil.copyfile(named_file(shape_set.base_dir, shape.source, f"parts.{shape.name}.mesh"), target)
    write_text_atomic(path, json.dumps(shapes_to_dict(shape_set, shapes)) + "\n")


# ---------------------------------------------------------------------------------------------
# Graph files


def graph_to_dict(g: nx.Graph) -> dict:
    """The ``procmod-graph/1`` JSON object of a typed graph."""
    n = g.number_of_nodes()
    return {"format": GRAPH_FORMAT, "types": [g.nodes[v]["type"] for v in range(n)],
            "edges": sorted([min(u, v), max(u, v)] for u, v in g.edges)}


def graph_from_dict(data, source: str = "graph") -> nx.Graph:
    """A typed graph from ``procmod-graph/1`` JSON, checked (connected, letters, no self-loops)."""
    if not isinstance(data, dict) or data.get("format") != GRAPH_FORMAT:
        raise ShapesFormatError(f"{source}: expected a JSON object with \"format\": {GRAPH_FORMAT!r}")
    types, edges = data.get("types"), data.get("edges")
    if not isinstance(types, list) or not types:
        raise ShapesFormatError(f"{source}: 'types' must be a non-empty list of one-letter strings")
    g = nx.Graph()
    for i, t in enumerate(types):
        if not isinstance(t, str) or len(t) != 1 or t not in LETTERS:
            raise ShapesFormatError(f"{source}: types[{i}] is {t!r}; node types are single letters A-Z or a-z")
        g.add_node(i, type=t)
    if not isinstance(edges, list):
        raise ShapesFormatError(f"{source}: 'edges' must be a list of [i, j] pairs")
    for k, e in enumerate(edges):
        if (not isinstance(e, list) or len(e) != 2 or not all(isinstance(x, int) and not isinstance(x, bool)
                                                                 for x in e)):
            raise ShapesFormatError(f"{source}: edges[{k}] is {e!r}; expected [i, j] with node indices")
        if not all(0 <= x < len(types) for x in e):
            raise ShapesFormatError(f"{source}: edges[{k}] = {e} names a node outside 0..{len(types) - 1}")
        g.add_edge(*e)
    try:
        check_graph(g)
    except GraphError as exc:
        raise ShapesFormatError(f"{source}: {exc}") from None
    return g


def read_graph(path: str | os.PathLike) -> nx.Graph:
    """Read a ``procmod-graph/1`` file."""
    path = Path(path)
    if not path.is_file():
        raise ShapesFormatError(f"graph file {path} does not exist")
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise ShapesFormatError(f"{path} is not JSON ({exc})") from None
    return graph_from_dict(data, str(path))


def write_graph(g: nx.Graph, path: str | os.PathLike) -> None:
    write_text_atomic(path, json.dumps(graph_to_dict(g)) + "\n")


# ---------------------------------------------------------------------------------------------
# Contacts


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


def meshes_touch(obj_a, obj_b, tol: float) -> bool:
    """Do two fcl triangle meshes' surfaces intersect or come within ``tol``?"""
    import fcl
    if fcl.collide(obj_a, obj_b, fcl.CollisionRequest(), fcl.CollisionResult()):
        return True
    return fcl.distance(obj_a, obj_b, fcl.DistanceRequest(), fcl.DistanceResult()) <= tol


def tolerance_for(library: dict) -> float:
    """The default contact tolerance: :data:`DEFAULT_TOLERANCE` times the median part diagonal."""
    diagonals = [float(np.linalg.norm(np.subtract(*s.local_bounds()[::-1]))) for s in library.values()]
    return DEFAULT_TOLERANCE * float(np.median(diagonals))


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
    tol = tolerance_for(shape_set.library) if tol is None else tol
    g = nx.Graph()
    for k, name in enumerate(shape.parts):
        g.add_node(k, type=shape_set.letters[name], part=name)
    g.add_edges_from(contact_pairs(shape_set.library, shape.parts, shape.transforms, tol))
    return g


def centroids(shape_set: ShapeSet, shape: Shape) -> np.ndarray:
    """Centroid (vertex mean) of each part, ``(n, 3)``."""
    return np.array([part_points(shape_set.library, p, t).mean(0) for p, t in zip(shape.parts, shape.transforms)])


# ---------------------------------------------------------------------------------------------
# Tiling grammar


def first_poses(shape_set: ShapeSet) -> dict[str, np.ndarray]:
    """Per type letter, the pose of its first instance in the set's shapes (where an
    instantiation places its first part)."""
    out: dict[str, np.ndarray] = {}
    for shape in shape_set.shapes:
        for p, t in zip(shape.parts, shape.transforms):
            out.setdefault(shape_set.letters[p], np.asarray(t, dtype=np.float64))
    return out


def neighbour_key(g: nx.Graph, v) -> str:
    """The sorted letters of ``v``'s neighbours' types (its neighbour multiset)."""
    return "".join(sorted(g.nodes[u]["type"] for u in g.neighbors(v)))


def type_automorphisms(g: nx.Graph, limit: int = 64) -> list[dict]:
    """The automorphisms of ``g`` that keep node types (``{node: node}``), the identity
    first, at most ``limit`` of them.

    A string names its graph only up to these: a ring's parts look alike to it, so which of
    them the shape's corners are is arbitrary. Two edge labellings related by one describe
    the same shape (each part where its image was), and the tagger's targets and accuracy
    count them as equal. ``limit`` bounds the cost where many parts are interchangeable
    (a part with k alike leaves alone has k! of them); the first ones found are kept."""
    identity = {v: v for v in g.nodes}
    out = [identity]
    matcher = nx.algorithms.isomorphism.GraphMatcher(g, g, node_match=lambda a, b: a["type"] == b["type"])
    for mapping in matcher.isomorphisms_iter():
        if len(out) >= limit:
            break
        if mapping != identity:
            out.append(mapping)
    return out


RING_MULTIPLE_KEY = "ring_length_multiple"  # in the rules' JSON: never a type letter


def ring_multiple_of(lengths) -> int:
    """The ring-length rule learned from cycle lengths: their greatest common divisor,
    capped to a divisor of 4 (1: no rule).

    Why capped: 2 (even rings, as in any bipartite pattern) and 4 (cells and links
    alternating on a square grid: an even number of grid steps, two edges each) are facts
    about a set's lattice; a larger common divisor is what a handful of rings happen to
    share (one input ring 28 long must not make every ring 28 long). Only 2 and 4 are
    used because for them "every cycle" can be checked on a cycle basis (see
    :func:`ring_rule_breaks`)."""
    g = 0
    for n in lengths:
        g = math.gcd(g, int(n))
    return math.gcd(g, 4) if g else 1


def ring_rule_breaks(cycles: list[set], multiple: int) -> list[str]:
    """Why the cycles spanned by a cycle basis (each basis cycle as its set of edges) are not
    all a multiple of ``multiple`` (2 or 4) long; empty when they are.

    Every cycle is a sum (symmetric difference) of basis cycles, and
    ``|A + B| = |A| + |B| - 2 |A & B|`` (further terms are multiples of 4), so every cycle is
    a multiple of 2 long iff every basis cycle is, and a multiple of 4 iff every basis cycle
    is and every two share an even number of edges."""
    out = [f"a ring of {len(c)} parts; every ring of the input shapes is a multiple of {multiple} parts long"
           for c in cycles if len(c) % multiple]
    if multiple == 4 and not out:
        for i, a in enumerate(cycles):
            for b in cycles[i + 1:]:
                k = len(a & b)
                if k % 2:
                    out.append(f"rings of {len(a)} and {len(b)} parts share {k} contacts, so the ring around "
                               f"both is {len(a) + len(b) - 2 * k} long; every ring of the input shapes is a "
                               f"multiple of 4 parts long")
    return out


@dataclass
class Grammar:
    """Tiling-grammar rules: node type -> the neighbour multisets seen for it (sorted letters);
    and the ring-length rule: every cycle's length (parts) is a multiple of
    ``ring_multiple`` (learned by :func:`ring_multiple_of` from the graphs' cycle bases; 1:
    no rule).

    The neighbour multisets say nothing about how long a ring is, yet a ring of the wrong
    length has no embedding: in the example sets every ring alternates cells (towers,
    modules, columns) and links (walls, corridors, beams) on a square grid, so every ring
    is a multiple of 4 long, and before this rule most novel VAE samples had a ring that no
    placement of the parts realises (docs/strings.md, "Ring-length rule")."""

    rules: dict
    ring_multiple: int = 1

    @staticmethod
    def from_graphs(graphs) -> "Grammar":
        rules: dict[str, set] = {}
        lengths = set()
        for g in graphs:
            for v in g.nodes:
                rules.setdefault(g.nodes[v]["type"], set()).add(neighbour_key(g, v))
            lengths.update(len(c) for c in nx.cycle_basis(g))
        return Grammar({t: frozenset(keys) for t, keys in rules.items()}, ring_multiple_of(lengths))

    def bad_rings(self, g: nx.Graph) -> list[str]:
        """Why ``g``'s rings break the ring-length rule (empty: they keep it)."""
        if self.ring_multiple == 1:
            return []
        cycles = [{frozenset(e) for e in zip(c, c[1:] + c[:1])} for c in nx.cycle_basis(g)]
        return ring_rule_breaks(cycles, self.ring_multiple)

    @property
    def types(self) -> list[str]:
        return sorted(self.rules)

    def violations(self, g: nx.Graph, limit: int = 5) -> list[str]:
        """Why ``g`` breaks the grammar (empty when it is valid); at most ``limit`` reasons."""
        out = []
        if g.number_of_nodes() == 0:
            return ["the graph has no nodes"]
        if not nx.is_connected(g):
            out.append(f"the graph has {nx.number_connected_components(g)} connected parts, not one")
        for v in g.nodes:
            t = g.nodes[v]["type"]
            if t not in self.rules:
                out.append(f"node {v}: type {t!r} does not occur in the input shapes")
            else:
                key = neighbour_key(g, v)
                if key not in self.rules[t]:
                    allowed = ", ".join(sorted(k or "-" for k in self.rules[t]))
                    out.append(f"node {v} ({t}) has neighbours {key or '-'}; the rules allow {allowed}")
            if len(out) >= limit:
                return out
        return out + self.bad_rings(g)[:limit - len(out)]

    def is_valid(self, g: nx.Graph) -> bool:
        if g.number_of_nodes() == 0 or not nx.is_connected(g):
            return False
        return all(g.nodes[v]["type"] in self.rules and neighbour_key(g, v) in self.rules[g.nodes[v]["type"]]
                   for v in g.nodes) and not self.bad_rings(g)

    def node_ok(self, g: nx.Graph, v) -> bool:
        t = g.nodes[v]["type"]
        return t in self.rules and neighbour_key(g, v) in self.rules[t]

    def to_json(self) -> dict:
        """``{type: [neighbour keys]}``, plus ``"ring_length_multiple"`` when there is a ring rule."""
        out = {t: sorted(keys) for t, keys in sorted(self.rules.items())}
        if self.ring_multiple > 1:
            out[RING_MULTIPLE_KEY] = self.ring_multiple
        return out

    @staticmethod
    def from_json(data) -> "Grammar":
        """The inverse of :meth:`to_json` (grammars saved before the ring rule have none)."""
        rules = {t: frozenset(keys) for t, keys in data.items() if t != RING_MULTIPLE_KEY}
        return Grammar(rules, int(data.get(RING_MULTIPLE_KEY, 1)))


def validate_shape(shape_set: ShapeSet, shape: Shape, grammar: Grammar, tol: float | None = None) -> list[str]:
    """Geometric validation: recompute the shape graph and check it against ``grammar``."""
    return grammar.violations(shape_graph(shape_set, shape, tol))


def type_histogram(types) -> tuple:
    """A hashable node-type histogram: sorted ``(letter, count)`` pairs."""
    counts: dict[str, int] = {}
    for t in types:
        counts[t] = counts.get(t, 0) + 1
    return tuple(sorted(counts.items()))


def histogram_distance(types_x, types_y) -> float:
    """Seed 001's E(x, y) = sum over types |T_x - T_y| / (N_x + N_y)."""
    hx, hy = dict(type_histogram(types_x)), dict(type_histogram(types_y))
    total = sum(hx.values()) + sum(hy.values())
    return sum(abs(hx.get(t, 0) - hy.get(t, 0)) for t in set(hx) | set(hy)) / max(total, 1)
