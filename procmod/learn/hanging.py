"""Parts hung alike in every example: a part that one file hangs under the part it is
attached to, and another under a part higher up, is moved down to the part it touches.

Hand-made example sets mix parenting styles: one file hangs a turbine's blades under its
hub and the hub under the nacelle, another (made by someone else, or exported "flat")
hangs hub and blades straight under the tower. The learner reads a hierarchy as it is
given, so the two styles became different slots drawn apart from each other: sampled
turbines had no rotor in 16 of 100, two in 23, and six blades in 26 (h114's sweep; a
tree whose leaves hang under a branch in some files and under the trunk in others drew
0-10 of them, floating, in 69 of 100).

The rule moves a part only down its own file's hierarchy, and only where the set itself
says so: a part of type ``C`` hanging under a part ``P`` is moved under a part ``A``
below ``P`` when

- examples hang parts of type ``C`` under parts of ``A``'s type (the set's own evidence:
  parts of a type that every example hangs under parts of one type never move);
- every example is rooted at a part of one type (a set rooted at a chair's pole in some
  files and at its seat in others is left as it is);
- it touches ``A`` and does not touch ``P`` (a crown on top of the trunk, touching a
  branch too, stays under the trunk; a floor lamp standing on the floor stays there).
  Two parts touch when the gap between their surfaces is at most :data:`TOUCH` of the
  smaller one's size (hand placement leaves millimetres to centimetres; a measure of the
  whole example let a city's windows a metre above the ground "touch" it).

Of several ``A`` parts touching it, it goes under the one it sits on as the examples'
``C`` parts sit on their ``A`` holders (how far out and how far up from the holder,
for its size, nearest one of theirs: a crate under the crate it rests on, not the one
beside or above it); of those about as good, the one it sits on in the same direction
as theirs (a beam across two posts under the post the examples hang it from); then the
largest (a twig touching the other twigs at its base goes under the branch they grow
from).

Transforms are world transforms (:class:`procmod.learn.examples.ExampleNode`), so a
move changes no part's placement, only which part holds it.
"""

from __future__ import annotations

from collections import Counter, defaultdict, deque
from dataclasses import replace

import numpy as np
import trimesh

from .examples import ExampleNode, ExampleSet
from .symmetry import box_corners

TOUCH = 0.1
"""Two parts touch when the gap between their surfaces is at most this fraction of the
smaller one's diagonal."""

SAMPLES_PER_EDGE = 12
"""The most points a triangle's longest edge gets when a part's surface is sampled."""

MAX_SURFACE_POINTS = 4_000
"""About the most grid points a part's surface gets (a finely meshed part has its corners)."""

TIE = 0.05
"""Holders where a part would sit within this fraction of their size of the best fit to
the examples fit about as well: the largest of them holds it."""

DENSE = 2_000
"""Triangles near the points above which each point is measured only against the
triangles near it (an R-tree of their boxes)."""

_POINTS_A_CHUNK = 512  # points whose nearby triangles are measured at once

_PAIRS = 1 << 18  # point-triangle pairs measured at once (memory: tens of MB of gathered arrays)


def consistent_hanging(example_set: ExampleSet) -> tuple[ExampleSet, list]:
    """``example_set`` with parts moved down to the part they touch, where other examples
    hang parts of their type there (module docstring), and the moves as ``(example index,
    part type, from part type, to part type)``. The set is returned as it is when nothing
    moves."""
    parent_types = defaultdict(set)  # child type -> the types of the parts it hangs under
    for root in example_set.examples:
        for node in root.walk():
            for child in node.children:
                parent_types[child.part].add(node.part)
    mixed = {child: kinds for child, kinds in parent_types.items() if len(kinds) > 1}
    # files rooted at different parts (a chair at its pole here, at its seat there) hang
    # everything differently: moving parts within each made h114's chairs' leg rings worse
    # (5 legs in 37 of 100 samples, against 75), so such sets are left as they are
    if not mixed or len({root.part for root in example_set.examples}) > 1:
        return example_set, []
    surfaces = _Surfaces(example_set.parts)
    offsets = _offsets(example_set, mixed, surfaces)
    examples, moves = [], []
    for index, root in enumerate(example_set.examples):
        copy = _copied(root)
        moved = _rehang(copy, mixed, offsets, surfaces)
        moves += [(index, *move) for move in moved]
        examples.append(copy if moved else root)
    if not moves:
        return example_set, []
    return replace(example_set, examples=examples), moves


def hanging_note(moves: list, labels: list | None = None) -> str | None:
    """One line saying which parts were moved to the part they touch (None for none);
    ``labels`` name the examples (by default ``examples[i]``)."""
    if not moves:
        return None
    labels = labels or [f"examples[{i}]" for i in range(max(index for index, *_ in moves) + 1)]
    kinds = Counter((part, before, after) for _, part, before, after in moves)
    files = sorted({index for index, *_ in moves})
    said = "; ".join(f"{count} {part} from under {before} to under {after}"
                     for (part, before, after), count in kinds.most_common(4))
    shown = ", ".join(labels[i] for i in files[:3]) + (", ..." if len(files) > 3 else "")
    return (f"parts hung higher up in {len(files)} example(s) ({shown}) than other examples hang their kind were "
            f"moved down to the part they touch ({said}); parent them so in the files to keep this from being "
            "needed")


def _copied(node: ExampleNode) -> ExampleNode:
    """A copy of a hierarchy's nodes (transforms shared: they are never changed)."""
    return ExampleNode(node.part, node.transform, [_copied(child) for child in node.children])


def _rehang(root: ExampleNode, mixed: dict, offsets: dict, surfaces: "_Surfaces") -> list:
    """Move the parts of one example down, in place; the moves as (type, from, to). Each
    part is looked at under each part that holds it (once, and again after a move: it may
    go further down)."""
    moves = []
    below = {}  # (id of a part, types) -> the parts of those types in its subtree; moves down keep it
    gone = defaultdict(set)  # id of a part -> ids of the children moved away (dropped at the end: one pass)
    queue = deque((parent, child) for parent in root.walk() for child in parent.children if child.part in mixed)
    while queue:
        parent, child = queue.popleft()
        others = frozenset(mixed[child.part] - {parent.part})
        key = (id(parent), others)
        if key not in below:
            below[key] = [n for n in _walk(parent, gone) if n is not parent and n.part in others]
        if not below[key]:
            continue
        inside = set(map(id, _walk(child, gone)))
        near = [n for n in surfaces.touching(child, below[key], key) if id(n) not in inside]
        if not near or surfaces.touches(child, parent):
            continue
        target = _holder(child, near, offsets, surfaces)
        gone[id(parent)].add(id(child))
        target.children.append(child)
        moves.append((child.part, parent.part, target.part))
        queue.append((target, child))
    for node in root.walk():
        if gone.get(id(node)):
            node.children = [c for c in node.children if id(c) not in gone[id(node)]]
    surfaces.forget()
    return moves


def _holder(child: ExampleNode, near: list, offsets: dict, surfaces: "_Surfaces") -> ExampleNode:
    """Of the parts ``near`` that ``child`` touches, the one to hang it under: the one it
    sits on as the examples' parts of its type sit on their holders (:func:`_placement`
    nearest one of theirs: a crate under the crate below it, not the one beside or above
    it); of those about as good, the one where it sits in the same direction as theirs
    (a beam across two posts under the post the examples hang it from, whichever the file
    lists first); then the largest (a twig touching the other twigs at its base goes
    under the branch they grow from)."""
    if len(near) == 1:
        return near[0]
    for turned in (True, False):
        misfit = []
        for n in near:
            seen = offsets[(child.part, n.part)][turned]
            misfit.append(float(np.linalg.norm(seen - _placement(child, n, surfaces, turned), axis=1).min()))
        best = min(misfit)
        near = [n for n, m in zip(near, misfit) if m <= best + TIE]
    return max(near, key=surfaces.diagonal)


def _placement(child: ExampleNode, holder: ExampleNode, surfaces: "_Surfaces", turned: bool) -> np.ndarray:
    """Where a part's centre sits from a holder's, for the holder's size, in the world's
    axes: ``turned``, how far out sideways and how far up (y), the same wherever about the
    vertical it lies (a branch's twig sits as far out and up wherever the branch points);
    else the offset itself (x, y, z). Not in the holder's own axes: users turn symmetric
    parts by quarter and half turns that leave them looking the same, and "on top" then
    lies along any of a crate's own axes."""
    (lo, hi), (hlo, hhi) = surfaces.box(child), surfaces.box(holder)
    shift = (lo + hi - hlo - hhi) / 2 / max(float(np.linalg.norm(hhi - hlo)), 1e-300)
    return np.array([np.hypot(shift[0], shift[2]), shift[1]]) if turned else shift


def _offsets(example_set: ExampleSet, mixed: dict, surfaces: "_Surfaces") -> dict:
    """(child type, holder type) -> {turned: the examples' :func:`_placement` of children
    of the mixed types in their holders}, for turned True (n, 2) and False (n, 3)."""
    found = defaultdict(lambda: {True: [], False: []})
    for root in example_set.examples:
        for node in root.walk():
            for child in node.children:
                if child.part in mixed:
                    for turned in (True, False):
                        found[(child.part, node.part)][turned].append(_placement(child, node, surfaces, turned))
        surfaces.forget()
    return {key: {turned: np.array(points) for turned, points in both.items()} for key, both in found.items()}


def _walk(node: ExampleNode, gone: dict):
    """A part and its descendants, depth first, leaving out the children moved away."""
    yield node
    for child in node.children:
        if id(child) not in gone.get(id(node), ()):
            yield from _walk(child, gone)


class _Surfaces:
    """The placed parts' boxes, surface points and triangles, and whether two parts touch."""

    def __init__(self, parts: dict):
        self.parts = parts
        self.local = {}  # part type -> (surface points, triangles, box corners, vertices), in its own frame
        # one example's, until forget(); each entry keeps its node, so that no id is reused meanwhile
        self.boxes = {}  # id(node) -> (node, its box)
        self.surfaces = {}  # id(node) -> (node, ((corners, surface points), _Triangles))
        self.stacked = {}  # a key -> the boxes of a list of nodes as arrays (lows, highs, diagonals)

    def forget(self) -> None:
        """Drop what was measured of one example (its ids may be reused by another's)."""
        self.boxes.clear()
        self.surfaces.clear()
        self.stacked.clear()

    def _local(self, part: str):
        if part not in self.local:
            triangles = np.asarray(self.parts[part].local_triangles(), dtype=np.float64)
            corners = box_corners(*self.parts[part].local_bounds())
            vertices = np.unique(triangles.reshape(-1, 3), axis=0)
            self.local[part] = (surface_points(triangles), triangles, corners, vertices)
        return self.local[part]

    @staticmethod
    def _placed(points: np.ndarray, node: ExampleNode) -> np.ndarray:
        m = np.asarray(node.transform, dtype=np.float64)
        return points @ m[:3, :3].T + m[:3, 3]

    def box(self, node: ExampleNode) -> tuple:
        """A box around a placed part (its local box's corners placed)."""
        if id(node) not in self.boxes:
            corners = self._placed(self._local(node.part)[2], node)
            self.boxes[id(node)] = (node, (corners.min(axis=0), corners.max(axis=0)))
        return self.boxes[id(node)][1]

    def diagonal(self, node: ExampleNode) -> float:
        lo, hi = self.box(node)
        return float(np.linalg.norm(hi - lo))

    def touching(self, child: ExampleNode, nodes: list, key) -> list:
        """The nodes whose parts touch ``child``'s (their boxes tested first, all at once;
        ``key`` names the list, whose boxes are kept)."""
        if key not in self.stacked:
            boxes = [self.box(n) for n in nodes]
            los, his = np.array([b[0] for b in boxes]), np.array([b[1] for b in boxes])
            self.stacked[key] = (los, his, np.linalg.norm(his - los, axis=1))
        los, his, diagonals = self.stacked[key]
        lo, hi = self.box(child)
        box_gaps = np.linalg.norm(np.maximum(0.0, np.maximum(los - hi, lo - his)), axis=1)
        limits = TOUCH * np.minimum(diagonals, np.linalg.norm(hi - lo))
        return [nodes[i] for i in np.flatnonzero(box_gaps <= limits)
                if self.gap(child, nodes[i], limits[i]) <= limits[i]]

    def touches(self, a: ExampleNode, b: ExampleNode) -> bool:
        limit = TOUCH * min(self.diagonal(a), self.diagonal(b))
        return self.gap(a, b, limit) <= limit

    def _surface(self, node: ExampleNode) -> tuple:
        """A placed part's corners and surface points, and its triangles (:class:`_Triangles`),
        kept for the example."""
        if id(node) not in self.surfaces:
            points, triangles, _, vertices = self._local(node.part)
            placed = (self._placed(vertices, node), self._placed(points, node))
            self.surfaces[id(node)] = (node, (placed, _Triangles(self._placed(triangles, node))))
        return self.surfaces[id(node)][1]

    def gap(self, a: ExampleNode, b: ExampleNode, limit: float) -> float:
        """A gap between two placed parts' surfaces (each one's surface points against the
        other's triangles) of at most ``limit`` if there is one (the first found: enough to
        say that they touch); else a number above ``limit``."""
        (corners_a, points_a), triangles_a = self._surface(a)
        (corners_b, points_b), triangles_b = self._surface(b)
        best = np.inf
        # the corners first: parts that touch mostly touch at one (a window's on its wall)
        for points, triangles in ((corners_a, triangles_b), (corners_b, triangles_a),
                                  (points_a, triangles_b), (points_b, triangles_a)):
            best = min(best, triangles.distance(points, limit))
            if best <= limit:
                break
        return best


class _Triangles:
    """Placed triangles with what a point's distance to them needs, worked out once."""

    def __init__(self, triangles: np.ndarray):
        self.corners = triangles
        self.tree = None  # an R-tree of the triangles' boxes, made when first needed
        self.lo, self.hi = triangles.min(axis=1), triangles.max(axis=1)
        self.all_lo, self.all_hi = triangles.min(axis=(0, 1)), triangles.max(axis=(0, 1))
        a, b, c = triangles[:, 0], triangles[:, 1], triangles[:, 2]
        normal = np.cross(b - a, c - a)
        length = np.linalg.norm(normal, axis=1)
        self.flat = length > 0
        self.unit = np.divide(normal, length[:, None], out=np.zeros_like(normal), where=self.flat[:, None])
        # each edge: its start, direction, squared length, and the in-plane normal pointing inwards
        self.edges = []
        for u, v in ((a, b), (b, c), (c, a)):
            d = v - u
            self.edges.append((u, d, np.maximum(np.einsum("td,td->t", d, d), 1e-300), np.cross(self.unit, d)))

    def distance(self, points: np.ndarray, limit: float, stop: float | None = None) -> float:
        """The least distance from ``points`` to the triangles where it may be at most
        ``limit``; else a number above ``limit``. Exact: each point is measured against
        the triangles within ``limit`` of the points' box (up to :data:`DENSE` of them;
        for more, those whose own box is within ``limit`` of the point, found in an R-tree).
        Stops at the first chunk of points that finds one within ``stop`` (by default
        ``limit``)."""
        stop = limit if stop is None else stop
        if len(points) == 0 or len(self.corners) == 0:
            return np.inf
        points = points[((points >= self.all_lo - limit) & (points <= self.all_hi + limit)).all(axis=1)]
        if len(points) == 0:
            return np.inf
        chosen = np.flatnonzero(((self.hi >= points.min(axis=0) - limit)
                                 & (self.lo <= points.max(axis=0) + limit)).all(axis=1))
        if len(chosen) == 0:
            return np.inf
        best = np.inf
        if len(chosen) <= DENSE:  # every point against every triangle near them
            step = max(1, _PAIRS // len(chosen))
            for i in range(0, len(points), step):
                best = min(best, float(self._distances(points[i:i + step], chosen).min()))
                if best <= stop:
                    break
            return best
        if self.tree is None:
            self.tree = trimesh.util.bounds_tree(np.column_stack([self.lo, self.hi]))
        for i in range(0, len(points), _POINTS_A_CHUNK):  # each point against the triangles near it
            chunk = points[i:i + _POINTS_A_CHUNK]
            hits = [np.fromiter(self.tree.intersection(np.concatenate([q - limit, q + limit])), dtype=np.int64)
                    for q in chunk]
            counts = np.array([len(h) for h in hits])
            if counts.sum() == 0:
                continue
            which = np.repeat(np.arange(len(chunk)), counts)
            best = min(best, float(self._distances(chunk[which], np.concatenate(hits)[:, None]).min()))
            if best <= stop:
                break
        return best

    def _distances(self, points: np.ndarray, index: np.ndarray) -> np.ndarray:
        """Distances from each point to the triangles ``index`` (t,) (all the points to the
        same ones: an array (p, t)) or ``index[p]`` (p, k) (each point to its own: (p, k)):
        to its plane where the point lies over the triangle, else to its nearest edge."""
        p = points[:, None, :]
        unit = self.unit[index]
        height = np.einsum("...d,...d->...", p - self.corners[index, 0], unit)
        over = np.broadcast_to(self.flat[index], height.shape)
        edges = np.full(height.shape, np.inf)
        for u, d, squared, inward in self.edges:
            u, d, squared, inward = u[index], d[index], squared[index], inward[index]
            offset = p - u
            over = over & (np.einsum("...d,...d->...", offset, inward) >= 0)  # on the triangle's side of the edge
            t = np.clip(np.einsum("...d,...d->...", offset, d) / squared, 0.0, 1.0)
            edges = np.minimum(edges, np.linalg.norm(offset - t[..., None] * d, axis=-1))
        return np.where(over, np.abs(height), edges)


def surface_points(triangles: np.ndarray) -> np.ndarray:
    """Points covering triangles (n, 3, 3): each triangle's corners and a barycentric grid
    whose spacing is a twelfth of the shape's longest triangle edge (coarser where that
    would make over :data:`MAX_SURFACE_POINTS`), at most :data:`SAMPLES_PER_EDGE` a side.
    Measured against the other part's triangles exactly, they find a gap between two
    faces, edges or corners (the least distance between two shapes lies at a corner of
    one of them or between two edges, which the grid's edge points follow)."""
    triangles = np.asarray(triangles, dtype=np.float64)
    if len(triangles) == 0:
        return np.zeros((0, 3))
    edges = np.linalg.norm(triangles - np.roll(triangles, 1, axis=1), axis=2).max(axis=1)
    area = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]),
                                axis=1).sum()
    # a triangle of area a holds about 2a / spacing^2 grid points
    spacing = max(float(edges.max()) / SAMPLES_PER_EDGE, float(np.sqrt(2 * area / MAX_SURFACE_POINTS)), 1e-300)
    points = [triangles.reshape(-1, 3)]
    steps = np.clip(np.ceil(edges / spacing).astype(int), 1, SAMPLES_PER_EDGE)
    for k in np.unique(steps[steps > 1]):
        i, j = np.meshgrid(np.arange(k + 1), np.arange(k + 1), indexing="ij")
        keep = i + j <= k
        weights = np.stack([i[keep], j[keep], k - i[keep] - j[keep]], axis=1) / k  # (m, 3)
        chosen = triangles[steps == k]  # (t, 3, 3)
        points.append(np.einsum("mc,tcd->tmd", weights, chosen).reshape(-1, 3))
    return np.unique(np.concatenate(points), axis=0)


__all__ = ["consistent_hanging", "hanging_note", "surface_points"]
