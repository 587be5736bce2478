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

- other examples hang parts of type ``C`` under parts of ``A``'s type (the file's own
  evidence; a set hung one way throughout is left as it is);
- every example is rooted at a part of one type (a set rooted at a chair's pole in some
  files and at its seat in others is left as it is);
- it touches ``A`` and does not touch ``P`` (a crown on top of the trunk, touching a
  branch too, stays under the trunk). Touching is a gap of at most 2% of the example's
  size (hand placement leaves millimetres to centimetres), or of as much as the examples'
  own ``C`` parts sit from their ``A`` parents (times 1.5), up to 10%.

Transforms are world transforms (:class:`procmod.learn.examples.ExampleNode`), so a
move changes no part's placement, only which part holds it.
"""

from __future__ import annotations

from collections import Counter, defaultdict
from dataclasses import replace

import numpy as np
from scipy.spatial import cKDTree

from .examples import ExampleNode, ExampleSet

SAMPLES_PER_EDGE = 12
"""The most points a triangle's longest edge gets when a part's surface is sampled for gaps."""

ATTACH_SLACK = 0.02
"""Gaps up to this fraction of the example's size count as touching, whatever the examples'
own gaps (hand placement leaves millimetres)."""

MAX_TOUCH = 0.1
"""Gaps over this fraction of the example's size never count as touching (however far the
examples' own attached parts sit from their parents)."""


def consistent_hanging(example_set: ExampleSet) -> tuple[ExampleSet, list]:
    """``example_set`` with parts moved down to the part they are attached to, where other
    examples hang parts of their type there (module docstring), and the moves as
    ``(example index, part type, from part type, to part type)``. The set is returned as
    it is when nothing moves."""
    parent_types = defaultdict(Counter)  # child type -> parent type -> count
    for root in example_set.examples:
        for node in root.walk():
            for child in node.children:
                parent_types[child.part][node.part] += 1
    mixed = {child: set(kinds) for child, kinds in parent_types.items() if len(kinds) > 1}
    # files rooted at different parts (a chair at its pole here, at its seat there) hang
    # everything differently: moving parts within each made h114's chairs' leg rings worse
    # (5 legs in 37 of 100 samples, against 75), so such sets are left as they are
    if not mixed or len({root.part for root in example_set.examples}) > 1:
        return example_set, []
    surfaces = _Surfaces(example_set)
    attach = _attach_gaps(example_set, mixed, surfaces)
    examples, moves = [], []
    for index, root in enumerate(example_set.examples):
        copy = _copied(root)
        size = surfaces.example_size(copy)
        moved = _rehang(copy, mixed, attach, surfaces, size)
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
    return (f"parts hung higher up in {len(files)} example(s) ({shown}) than in others were moved down to the "
            f"part they touch, as the other examples hang them ({said}); parent them so in the files to keep "
            "this from being needed")


def _copied(node: ExampleNode) -> ExampleNode:
    """A copy of a hierarchy's nodes (transforms shared: they are never changed)."""
    return ExampleNode(node.part, node.transform, [_copied(child) for child in node.children])


def _rehang(root: ExampleNode, mixed: dict, attach: dict, surfaces: "_Surfaces", size: float) -> list:
    """Move the parts of one example (``size``: its diagonal) down, in place; the moves as
    (type, from, to)."""
    slack = ATTACH_SLACK * size
    moves = []
    changed = True
    while changed:  # a move goes strictly deeper, so this ends
        changed = False
        for parent in list(root.walk()):
            for child in list(parent.children):
                if child.part not in mixed:
                    continue
                others = mixed[child.part] - {parent.part}
                inside = set(map(id, child.walk()))
                below = [n for n in parent.walk() if n is not parent and n.part in others and id(n) not in inside]
                if not below:
                    continue
                touch = {n.part: min(max(attach.get((child.part, n.part), 0.0), slack), MAX_TOUCH * size)
                         for n in below}
                # the boxes' gap is at most the parts': only the parts whose boxes are near are measured
                near = [n for n in below if surfaces.box_gap(child, n) <= touch[n.part]]
                if not near:
                    continue
                gaps = [surfaces.gap(child, n) for n in near]
                best = int(np.argmin(gaps))
                target = near[best]
                # touching the part below, and not the one holding it
                if gaps[best] <= touch[target.part] < surfaces.gap(child, parent):
                    parent.children = [c for c in parent.children if c is not child]
                    target.children.append(child)
                    moves.append((child.part, parent.part, target.part))
                    changed = True
    return moves


def _attach_gaps(example_set: ExampleSet, mixed: dict, surfaces: "_Surfaces") -> dict:
    """(child type, parent type) -> the largest gap between such a child and its parent
    in the examples as given, times 1.5: how far apart the examples' own attached parts sit."""
    gaps = defaultdict(float)
    for root in example_set.examples:
        for node in root.walk():
            for child in node.children:
                if child.part in mixed:
                    key = (child.part, node.part)
                    gaps[key] = max(gaps[key], 1.5 * surfaces.gap(child, node))
    return gaps


class _Surfaces:
    """Points on each placed part's surface (cached per node) and the gaps between parts."""

    def __init__(self, example_set: ExampleSet):
        self.parts = example_set.parts
        self.local = {}  # part type -> points on its surface, in its own frame
        self.placed = {}  # id(node) -> (points, KD-tree); ("box", id(node)) -> its box
        self.held = []  # every node measured, kept alive so that its id is never reused by another

    def _local_points(self, part: str) -> np.ndarray:
        if part not in self.local:
            triangles = self.parts[part].local_triangles()
            self.local[part] = surface_points(triangles)
        return self.local[part]

    def _tree(self, node: ExampleNode):
        key = id(node)
        if key not in self.placed:
            m = np.asarray(node.transform, dtype=np.float64)
            points = self._local_points(node.part) @ m[:3, :3].T + m[:3, 3]
            self.placed[key] = (points, cKDTree(points))
            self.held.append(node)
        return self.placed[key]

    def box(self, node: ExampleNode) -> tuple:
        """A box around a placed part (its local box's corners placed)."""
        key = ("box", id(node))
        if key not in self.placed:
            lo, hi = self.parts[node.part].local_bounds()
            corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
            m = np.asarray(node.transform, dtype=np.float64)
            placed = corners @ m[:3, :3].T + m[:3, 3]
            self.placed[key] = (placed.min(axis=0), placed.max(axis=0))
            self.held.append(node)
        return self.placed[key]

    def box_gap(self, a: ExampleNode, b: ExampleNode) -> float:
        """The gap between two parts' boxes: at most the gap between the parts."""
        (alo, ahi), (blo, bhi) = self.box(a), self.box(b)
        return float(np.linalg.norm(np.maximum(0.0, np.maximum(alo - bhi, blo - ahi))))

    def gap(self, a: ExampleNode, b: ExampleNode) -> float:
        """The least distance between points on two parts' surfaces (0 where they overlap
        closely; accurate to the sampling, a few per cent of a part)."""
        points, _ = self._tree(a)
        _, tree = self._tree(b)
        return float(tree.query(points, k=1)[0].min())

    def example_size(self, root: ExampleNode) -> float:
        """The diagonal of an example's points' bounding box."""
        points = np.concatenate([self._tree(node)[0] for node in root.walk()])
        return float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))


MAX_SURFACE_POINTS = 20_000
"""About the most grid points a part's surface gets (a finely meshed part has its corners)."""


def surface_points(triangles: np.ndarray) -> np.ndarray:
    """Points covering triangles (n, 3, 3): each triangle's corners and a barycentric grid
    whose spacing is a twelfth of the shape's longest triangle edge (coarser where that
    would make over :data:`MAX_SURFACE_POINTS`), at most :data:`SAMPLES_PER_EDGE` a side,
    so that a large flat face (a box's) is covered, not only its corners."""
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
    return np.concatenate(points)


__all__ = ["consistent_hanging", "hanging_note", "surface_points"]
