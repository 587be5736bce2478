"""Example preprocessing (seed 000 section 4): symmetry groups, slots, slot groups.

1. **Symmetry groups** among the children of every part node, approximate, with a
   tolerance relative to the units' size (:mod:`procmod.learn.symmetry`): reflection
   pairs, translation and rotation chains, nested.
2. **Slots** per parent part type and child type with the greedy minimax-Hausdorff
   assignment of eq. 1: start from a parent with the most children of that type, then
   repeatedly commit the parent whose best assignment raises the objective least. A
   parent's best assignment is a bottleneck assignment, solved exactly (threshold search
   over the cost values with ``scipy.optimize.linear_sum_assignment``, ties broken by the
   summed cost). Distances are Hausdorff distances between surface samples of the
   units' parts (:data:`SLOT_SAMPLES` area-weighted points per part,
   :func:`procmod.geometry.part_library.surface_samples`) in the parent's local frame.
3. **Slot groups**: slots whose contents overlap after removing the parent's volume, by
   a voxel test in the parent's local frame (:data:`OVERLAP_VOXELS` voxels along the
   longest side; two slots overlap when a voxel centre lies inside a part of each and
   outside the parent). Chosen over manifold3d booleans because example meshes need not
   be watertight manifolds, and because touching parts (a wing against a hull) share no
   voxel centre, so only real interpenetration deeper than about one voxel counts.
"""

from __future__ import annotations

import itertools
import math
from collections import Counter
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.distance import cdist
from scipy.spatial.transform import Rotation

from ..geometry.part_library import flip_deviations, round_axes, surface_samples
from ..geometry.voxel import VoxelGrid, voxelize
from .examples import ExampleNode, ExampleSet, ExamplesError
from .ground import examples_ground
from .perturb import example_diagonal
from .symmetry import (PAIRING_RULES, SYMMETRY_TOLERANCE, Unit, align_mirror_sides, align_ring_starts,
                       arrangement_shape, box_corners, group_children)
from .transforms import (ANCHOR_SIDES, CURRENT, DIAGONAL_POLE, Frame, Units, anchor_terms, angles_direction,
                         decompose, direction_angles, euler_of, frame_of, rot_of, spread_pole, sym_params,
                         symmetry_direction, turned_frame, SYM_KINDS, node_kind, reserved_name, xform_params)

OVERLAP_VOXELS = 40
SLOT_SAMPLES = 64  # surface points per part for the Hausdorff distances of eq. 1


# ---- processed hierarchies --------------------------------------------------------------

@dataclass
class PNode:
    """A node of a processed example: a part node or a symmetry node.

    ``x`` / ``signs``: the node's transform components relative to its part ancestor
    (part nodes); ``sym`` / ``count``: symmetry parameters (symmetry nodes); ``children``:
    ``(slot, PNode)`` pairs (a symmetry node has one child, slot 0); ``used``: slot-use
    bits of a part node, one per slot of its part type.
    """

    id: int
    kind: str
    type: str
    example: int
    part: str | None = None
    x: np.ndarray | None = None
    signs: np.ndarray | None = None
    sym: np.ndarray | None = None
    count: int = 0
    children: list = field(default_factory=list)
    used: np.ndarray | None = None
    parent: int = -1
    parent_slot: int = -1
    height: int = 0
    world: np.ndarray | None = None


@dataclass
class Dataset:
    """Preprocessed examples: what the learner sees.

    ``slots[T]``: the slot types of part type T, in slot order; ``groups[T]``: its slot
    groups (lists of slot indices); ``nodes``: every processed node (``nodes[i].id == i``);
    ``roots``: the root node of each example; ``sym_inner[type]``: the child type of a
    symmetry type; ``max_count[type]``: the largest member count seen; ``units``: the
    lengths the transform components are measured against
    (:class:`procmod.learn.transforms.Units`).
    """

    parts: dict
    slots: dict
    groups: dict
    nodes: list
    roots: list
    sym_inner: dict
    max_count: dict
    hausdorff_objective: dict = field(default_factory=dict)
    units: Units = Units()

    @property
    def types(self) -> list:
        return sorted({n.type for n in self.nodes})

    def kind_of(self, type_: str) -> str:
        return node_kind(type_)


def run_steps(data: Dataset, mine, slot: int) -> dict | None:
    """Node id -> its step (1, 2, ...) along the runs that the nodes marked in ``mine``
    (a boolean per node) make through ``slot``: a run starts at a marked node whose parent
    is unmarked or holds it in another slot, and goes on through each node's child in
    ``slot``. None when a marked node's child in that slot is unmarked (not one run)."""
    steps = {}
    for n in data.nodes:
        if not mine[n.id]:
            continue
        if n.parent >= 0 and mine[n.parent] and n.parent_slot == slot:
            continue  # numbered from its run's start
        k, node = 1, n
        while True:
            steps[node.id] = k
            nxt = [c for s, c in node.children if s == slot]
            if not nxt:
                break
            if not mine[nxt[0].id]:
                return None
            node, k = nxt[0], k + 1
    return steps


def fixed_runs(data: Dataset) -> dict:
    """Part type -> (slot, L) for each type that holds itself in exactly one slot and whose
    runs through it are all L >= 2 long, in two examples or more: a count the examples agree
    on (a snake of five links, each under the one before). A type that holds itself in two slots branches
    (a tree), and a run of varying length (the castles' walls of 2-5 segments) is left to
    the paper's recursion."""
    out = {}
    for t, slot_types in sorted(data.slots.items()):
        own = [s for s, st in enumerate(slot_types) if st == t]
        if len(own) != 1:
            continue
        mine = [n.kind == "part" and n.type == t for n in data.nodes]
        steps = run_steps(data, mine, own[0])
        if not steps:
            continue
        ends = [k for i, k in steps.items() if not any(s == own[0] for s, _ in data.nodes[i].children)]
        # runs in two examples at least: one run alone (one robot's two chassis halves among
        # ten robots) says nothing of a count the examples agree on
        examples = {data.nodes[i].example for i, k in steps.items() if k == 1}
        if len(set(ends)) == 1 and ends[0] >= 2 and len(examples) >= 2:
            out[t] = (own[0], ends[0])
    return out


@dataclass
class _PartInfo:
    node: ExampleNode
    frame: Frame
    units: list
    slot_of: dict = field(default_factory=dict)  # id(unit) -> slot index
    pairing_choices: bool = False  # whether a child unit mirrored several siblings (group_children's choices)
    rule: str = PAIRING_RULES[0]  # the pairing rule its children were grouped by


def _placed(local: np.ndarray, m: np.ndarray) -> np.ndarray:
    return local @ m[:3, :3].T + m[:3, 3]


def _hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    """Symmetric Hausdorff distance of two point sets."""
    d = cdist(a, b)
    return float(max(d.min(1).max(), d.min(0).max()))


def _bottleneck(cost: np.ndarray) -> tuple[float, float, np.ndarray]:
    """Assignment of rows to distinct columns minimising the largest cost, then the sum."""
    values = np.unique(cost)
    lo, hi = 0, len(values) - 1
    while lo < hi:  # smallest threshold admitting a complete assignment
        mid = (lo + hi) // 2
        r, c = linear_sum_assignment((cost > values[mid]).astype(float))
        if (cost[r, c] > values[mid]).any():
            lo = mid + 1
        else:
            hi = mid
    threshold = values[lo]
    masked = np.where(cost > threshold, 1e12, cost)
    r, c = linear_sum_assignment(masked)
    cols = np.empty(cost.shape[0], dtype=int)
    cols[r] = c
    return float(threshold), float(cost[r, c].sum()), cols


def _assign_slots(parents: list, child_type: str, samples: dict) -> tuple[int, float]:
    """Greedy minimax-Hausdorff slot assignment (eq. 1) for one (parent type, child type).

    ``samples[part]``: surface points of each part in its local frame. Sets
    ``info.slot_of`` entries to a slot offset in [0, m); returns m and f(N).
    """
    entries = []  # per parent: list of (unit, points in the parent's local frame)
    for info in parents:
        inv = np.linalg.inv(info.node.transform)
        units = [u for u in info.units if u.type == child_type]
        if units:
            pts = [np.concatenate([_placed(samples[p], inv @ w) for p, w in u.top_parts()]) for u in units]
            entries.append((info, list(zip(units, pts))))
    if not entries:
        return 0, 0.0
    m = max(len(e[1]) for e in entries)
    first = max(range(len(entries)), key=lambda k: (len(entries[k][1]), -k))
    # cost[k][i, s]: the largest distance of parent k's i-th unit to the units already in
    # slot s; updated with each committed parent's units only (each pair computed once)
    cost = {k: np.zeros((len(entries[k][1]), m)) for k in range(len(entries))}
    remaining = [k for k in range(len(entries)) if k != first]

    def commit(k, cols):
        info, items = entries[k]
        for (unit, pts), s in zip(items, cols):
            info.slot_of[id(unit)] = int(s)
            for r in remaining:
                for i, (_, other) in enumerate(entries[r][1]):
                    cost[r][i, s] = max(cost[r][i, s], _hausdorff(other, pts))

    commit(first, range(len(entries[first][1])))
    f = 0.0
    while remaining:
        best = None
        for k in remaining:
            threshold, total, cols = _bottleneck(cost[k])
            key = (max(f, threshold), threshold, total, k)
            if best is None or key < best[0]:
                best = (key, k, cols)
        key, k, cols = best
        f = key[0]
        remaining.remove(k)
        commit(k, cols)
    return m, f


ONE_OF_NODES = 5
"""Nodes of a part type needed before "exactly one of these slots" is taken as a constraint
(:func:`_one_of_sets`): two independent slots each filled half the time look so by chance
in 1 of 8 sets of three nodes, 1 of 32 of five."""


def _one_of_sets(used: np.ndarray) -> list:
    """The sets of two or more slots of which each of a part type's (at least
    :data:`ONE_OF_NODES`) nodes fills exactly one, each slot filled by some node: ``used``
    is (nodes x slots), whether each node fills each slot.

    Design change (seed 000 groups slots by overlap only, and leaves other dependencies
    to the author's annotations): such slots are grouped too, so the group's NADE can
    learn the constraint. Every lamp of a set had one shade, on its pole or on an arm
    (two slots of the pole that do not overlap); drawn independently, 100 of 200
    samples had none or two (an adversarial pass); grouped, 6 of 200. It was tested on
    pairs alone: street lamps with one arm, a mirrored pair or a ring of three (three
    slots, one a lamp) had no arm in 55 of 200 samples and 4-6 in 28 (h88). Such a set
    is a clique of the graph of slots never filled together (the maximal ones suffice:
    a slot outside a set that covers every node shares a node with one of it). The
    authored sets and the quadrupeds get the same groups as before."""
    nodes, n = used.shape
    if nodes < ONE_OF_NODES:
        return []
    counts = used.sum(axis=0)
    filled = [i for i in range(n) if counts[i] > 0]
    # pairs, every one of them (cheap; a layout seen in one lamp of six is one too)
    found = [[i, j] for i, j in itertools.combinations(filled, 2) if (used[:, i] ^ used[:, j]).all()]
    # larger sets: the slots only one node fills say nothing of a choice when that node
    # fills several of them (examples each holding children of their own made every pick
    # of one slot a node such a set, k^nodes of them, h89); one such slot of its node stays
    # (a layout seen once, h92)
    lone = {}
    for i in filled:
        if counts[i] == 1:
            lone.setdefault(int(np.argmax(used[:, i])), []).append(i)
    dropped = {i for slots in lone.values() if len(slots) > 1 for i in slots}
    candidates = [i for i in filled if i not in dropped]
    if len(candidates) < 3:
        return found
    import networkx as nx

    apart = nx.Graph()
    apart.add_nodes_from(candidates)
    apart.add_edges_from((i, j) for i, j in itertools.combinations(candidates, 2)
                         if not (used[:, i] & used[:, j]).any())
    # finding such sets is exact cover (NP-complete): the maximal cliques are listed lazily,
    # at most ONE_OF_CLIQUES of them (a few in any set seen), in networkx's fixed order
    for clique in itertools.islice(nx.find_cliques(apart), ONE_OF_CLIQUES):
        if len(clique) >= 3 and (used[:, clique].sum(axis=1) == 1).all():
            found.append(sorted(clique))
    return found


ONE_OF_CLIQUES = 10_000  # maximal cliques :func:`_one_of_sets` looks at, at most


def _slot_groups(parent_type: str, parents: list, slot_types: list, offsets: dict, parts: dict) -> list:
    """Connected components of the graph of slots that overlap (voxel test in the parent's
    frame) or of which each node fills exactly one (:func:`_one_of_sets`)."""
    n = len(slot_types)
    if n <= 1:
        return [list(range(n))]
    contents = [[] for _ in range(n)]
    for info in parents:
        inv = np.linalg.inv(info.node.transform)
        for u in info.units:
            s = offsets[u.type] + info.slot_of[id(u)]
            contents[s] += [parts[p].part(inv @ w) for p, w in u.top_parts()]
    parent_part = parts[parent_type].part(np.eye(4))
    from ..geometry.solid import scene_bounds
    lo, hi = scene_bounds([p for c in contents for p in c] + [parent_part])
    size = float((hi - lo).max()) / OVERLAP_VOXELS
    grid = VoxelGrid.around(lo, hi, size, margin=size)
    inside_parent = voxelize([parent_part], grid)
    occupied = [voxelize(c, grid) & ~inside_parent if c else None for c in contents]
    parent_of = list(range(n))

    def find(i):
        while parent_of[i] != i:
            parent_of[i] = parent_of[parent_of[i]]
            i = parent_of[i]
        return i

    used = np.zeros((len(parents), n), dtype=bool)  # which slots each parent fills
    for k, info in enumerate(parents):
        for u in info.units:
            used[k, offsets[u.type] + info.slot_of[id(u)]] = True
    for i, j in itertools.combinations(range(n), 2):
        if occupied[i] is not None and occupied[j] is not None and (occupied[i] & occupied[j]).any():
            parent_of[find(i)] = find(j)
    for one_of in _one_of_sets(used):
        for i in one_of[1:]:
            parent_of[find(i)] = find(one_of[0])
    groups = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(i)
    return sorted(groups.values())


SPAN_PREFERENCE = 0.5
"""A translation symmetry type's parameters are its rows' span instead of their step when
the span's spread is under this share of the step's (:func:`span_types`)."""


def span_types(nodes: list) -> tuple:
    """The translation symmetry types whose rows hold their span (first member to last)
    across the examples better than their step: their counts vary, and the spread of the
    spans' lengths along the row (their standard deviation over their mean) is under
    :data:`SPAN_PREFERENCE` of the steps'. (Along the row only: across it the components
    are fractions of the parent's thin side, where a millimetre's placement is a large
    share, h88's rails.)

    Design change (seed 000 draws a symmetry's parameters, here the step, and its count
    independently): posts along rails of one length, 4 to 7 of them, have steps that
    shrink as their count grows; drawn apart, 67 of 136 sampled fences had a post 15 cm
    or more past a rail's end, and 85 of 200 sampled shelving units a shelf above the
    unit (h88). Drawing the span makes the step follow the count. A row whose step is what
    holds (a colonnade that grows with its count) keeps its step."""
    rows = {}
    for n in nodes:
        if n.kind == "trans" and n.sym is not None and n.count >= 2:
            rows.setdefault(n.type, []).append(n)
    found = []
    for sym_type, group in sorted(rows.items()):
        if len(group) < 3 or len({n.count for n in group}) < 2:
            continue
        steps = np.array([n.sym[:3] for n in group], dtype=np.float64)
        # each row's step along the rows' common axis, whichever way it points (a row's
        # direction may flip between examples: their mean step then was near zero, h89)
        axis = np.linalg.svd(steps, full_matrices=False)[2][0]
        steps = np.abs(steps @ axis)
        spans = steps * np.array([n.count - 1 for n in group], dtype=np.float64)

        def spread(v: np.ndarray) -> float:
            return float(v.std()) / max(abs(float(v.mean())), 1e-12)

        if spread(spans) < SPAN_PREFERENCE * spread(steps):
            found.append(sym_type)
    return tuple(found)


ANCHOR_GAIN = 0.25
"""A child type's translation along an axis of its parent type's frame is measured between
points of the two boxes (:func:`choose_anchors`) when that leaves under this share of the
variance its translation between the origins has..."""

ANCHOR_SPREAD = 0.01
"""...and the origins' translation spreads by more than this share of the parent's extent
(a child the examples place alike either way keeps its origin)."""


def choose_anchors(nodes: list, bounds: dict) -> dict:
    """Per parent part type, per child part type, per axis of the parent's frame: the pair
    of box points (:data:`~procmod.learn.transforms.ANCHOR_SIDES`, parent's and child's)
    between which the examples' translations of that child spread least, where that is
    under :data:`ANCHOR_GAIN` of the spread between the origins; None where the origins
    keep (see :func:`procmod.learn.transforms.anchor_terms`).

    Design change (seed 000 measures a child's translation between the frames' origins,
    as fractions of the parent's box, and draws it apart from the child's scale and from
    the parent's): parts attached face to face whose sizes vary (legs under a table top or
    a robot's torso, a stem on a candelabra's base) kept their contact in every example
    and lost it in the samples. h98's hand-placed sets: 87 of 200 candelabra stems floated
    above the base, 43 of 200 robots had a leg off the torso. Measured between the faces
    that touch, the offset is the same in every example, and the samples keep it."""
    by_id = {n.id: n for n in nodes}
    found = {}  # (parent type, child type) -> [(offset from each option, extent) per placement]
    # measured in the parent's extent, then in the child's: (a_p, a_c) and (a_p, a_c, 1).
    # In the parent's, a_p only adds a constant (half its extent): what it picks is the
    # child's side. In the child's, the parent's side counts: a sill a metre above the
    # bottom of facades of any height, a window a metre in from their edges
    options = [(a, c) for a in ANCHOR_SIDES for c in ANCHOR_SIDES]
    options += [(a, c, 1) for a in ANCHOR_SIDES for c in ANCHOR_SIDES]
    options.sort(key=lambda o: (len(o), abs(o[0]) + abs(o[1]), o))  # the plainest first, among equals
    for n in nodes:
        if n.kind != "part" or n.parent < 0:  # (a root: placed in the world frame)
            continue
        parent = by_id[n.parent]
        while parent.kind != "part":  # through the symmetries holding it: its nearest part ancestor
            parent = by_id[parent.parent]
        frame = frame_of(parent.world, *bounds[parent.part], part=parent.part)
        rot, s, t = decompose(n.world)
        turn = frame.rot.T @ rot
        base = frame.rot.T @ (t - frame.t)
        rows, lengths = [base / frame.extent], [np.array(frame.extent, dtype=np.float64)]
        for option in options:
            shift, measure = anchor_terms(turn, s, bounds[n.part], frame, [option] * 3)
            rows.append((base + shift) / measure)
            lengths.append(measure)
        found.setdefault((parent.part, n.part), []).append((np.array(rows), np.array(lengths), n))
    anchors = {}
    for (parent_type, child_type), placements in sorted(found.items()):
        if len(placements) < 2:
            continue
        values = np.array([rows for rows, _, _ in placements])  # placements x (1 + options) x axes
        # each option's spread as a length (its values' variance in the lengths it measures
        # in, at their mean): options measured in the parent's extent and in the child's
        # compare; among the parent's, this orders them as their values' variance does
        spread = values.var(axis=0) * np.array([lengths for _, lengths, _ in placements]).mean(axis=0) ** 2
        chosen = [None, None, None]
        for axis in range(3):
            origins = float(spread[0, axis])
            if not float(values[:, 0, axis].var()) > ANCHOR_SPREAD ** 2:
                continue
            best = min(range(len(options)), key=lambda k: float(spread[1 + k, axis]))
            least = float(spread[1 + best, axis])
            # the plainest option within rounding of the least
            best = next(k for k in range(len(options)) if float(spread[1 + k, axis]) <= least + 1e-12 + 1e-6 * least)
            if float(spread[1 + best, axis]) < ANCHOR_GAIN * origins:
                chosen[axis] = options[best]
        if any(c is not None for c in chosen):
            anchors.setdefault(parent_type, {})[child_type] = tuple(chosen)
            for rows, _, n in placements:  # its translation from here on is the anchors'
                for axis, option in enumerate(chosen):
                    if option is not None:
                        n.x[6 + axis] = rows[1 + options.index(option), axis]
    return anchors


CONSENSUS_LOOSENING = 3.0
"""How much looser a symmetry group may be in one example when other examples hold it
within the tolerance itself (:func:`_regroup_by_consensus`)."""


def _regroup_by_consensus(generation: list, corners: dict, tolerance: float, flips: dict, rounds: dict) -> None:
    """Group the children of a part node again, within :data:`CONSENSUS_LOOSENING` times
    the tolerance, where that gives fewer units arranged exactly as another node of the
    same part type has its children within the tolerance itself.

    Parts placed by eye are off by more in a long row or a wide ring than the tolerance
    (a fraction of each member's size) allows: posts moved 1-6 cm along a 6 m fence made
    three of six examples ``rail[post, trans5(post)]`` beside ``rail[trans6(post)]``, and
    11 of 20 samples had 5 or 7 posts, some inside others; petals off by 3% of a flower,
    four of six ``disc[petal, rot4(petal)]``. Another example holding the group within
    the tolerance is the evidence that it is meant; a looser tolerance everywhere changed
    the authored sets' groups (castles lost their rings of towers)."""
    held = {}
    for info in generation:
        held.setdefault(info.node.part, set()).add(_arrangement(info.units))
    for info in generation:
        parts = [u.representative().node.part for u in info.units]
        if len(parts) == len(set(parts)):
            continue  # no two units of one part: nothing left to group
        fewer = {a for a in held[info.node.part] if len(a) < len(info.units)}
        if not fewer:
            continue  # no node to take as evidence: not worth the grouping (scattered rocks cost 2.5x)
        loose = group_children(info.node.children, info.frame, corners, CONSENSUS_LOOSENING * tolerance, flips,
                               rounds, rule=info.rule)
        if _arrangement(loose) in fewer:
            info.units = loose


def _pair_by_agreement(generation: list, corners: dict, tolerance: float, flips: dict, rounds: dict) -> None:
    """Group the children of the part nodes of a type again by each other pairing rule
    (:data:`~procmod.learn.symmetry.PAIRING_RULES`) where one of them had a unit mirror
    several siblings, and keep the rule whose most common arrangement
    (:func:`~procmod.learn.symmetry.arrangement_shape`) half the nodes share, is the most
    compact, then the one the most nodes share (the file's order where no other does
    better). The first partner in the file's order is what authored sets are consistent
    in, but glTF's sibling order is the exporter's: six Blender tables whose legs were
    listed in varying order had paired them across the width in some and the diagonal in
    others, and half the sampled tables had a leg off the top (h162)."""
    by_type = {}
    for info in generation:
        by_type.setdefault(info.node.part, []).append(info)
    for infos in by_type.values():
        if not any(info.pairing_choices for info in infos):
            continue
        best, score = None, None
        for rule in PAIRING_RULES:
            units = [info.units if rule == info.rule else
                     group_children(info.node.children, info.frame, corners, tolerance, flips, rounds, rule=rule)
                     for info in infos]
            shapes = Counter(arrangement_shape(u, info.frame) for u, info in zip(units, infos))
            shape, agreeing = shapes.most_common(1)[0]
            # among rules whose most common arrangement at least half the nodes share, the one
            # whose arrangement is the most compact (fewest units, then least nesting: a ring
            # of six mirrored pairs, rot(refl), over three mirrored mirror pairs, which two
            # shuffled files' worth of agreement had preferred, h164), then the one more
            # nodes share
            mine = (2 * agreeing < len(infos), len(shape), max(map(_nesting, shape), default=0), -agreeing)
            if score is None or mine < score:
                best, score = (rule, units), mine
        rule, units = best
        for info, grouped in zip(infos, units):
            info.rule, info.units = rule, grouped


def _nesting(shape: tuple) -> int:
    """How deep one unit's :func:`~procmod.learn.symmetry.arrangement_shape` nests groups."""
    return 0 if len(shape) == 1 else 1 + _nesting(shape[3])


def _arrangement(units: list) -> tuple:
    """How a node's children are grouped: their units' signatures, sorted."""
    return tuple(sorted(u.sig for u in units))


def check_part_names(parts) -> None:
    """Refuse a part name that reads as the name procmod gives a learned symmetry
    (``rot(leg)``); ``procmod learn`` checks it before its output folder is made (it had
    left an empty one behind)."""
    reserved = sorted(name for name in parts if reserved_name(name))
    if reserved:
        raise ExamplesError(f"part name {reserved[0]!r} reads as the name procmod gives a learned symmetry "
                            f"({', '.join(SYM_KINDS)} of a part: KIND(PART)); rename the part (in a glTF file or "
                            "a Blender scene, its mesh)")


def preprocess(example_set: ExampleSet, tolerance: float = SYMMETRY_TOLERANCE) -> Dataset:
    """Symmetry groups, slots and slot groups of an example set (seed 000 section 4).

    ``tolerance``: how far (a fraction of their size) sibling units may deviate from an
    exact symmetry and still form a group (:mod:`procmod.learn.symmetry`).
    """
    example_set = squared_examples(example_set)
    parts = example_set.parts
    check_part_names(parts)
    bounds = {name: shape.local_bounds() for name, shape in parts.items()}
    corners = {name: box_corners(lo, hi) for name, (lo, hi) in bounds.items()}
    samples = {name: surface_samples(shape, SLOT_SAMPLES) for name, shape in parts.items()}
    # a part's own symmetries (flips of its axes it looks the same under, within the
    # symmetry tolerance): a placement turned over may then be a mirror image
    flips = {name: tuple(int(m) for m in np.flatnonzero(flip_deviations(shape) <= tolerance))
             for name, shape in parts.items()}
    # the axes a part is round about: a ring of its copies, moved but not turned, is a ring
    rounds = {name: round_axes(shape, tolerance) for name, shape in parts.items()}
    # generation by generation (roots, then the representatives of their units, ...), so
    # that the rings of one type, wherever they are, start at corresponding members
    # before their first members are looked into
    made = {}
    frontier = list(example_set.examples)
    consensus, mirror_sides = {}, {}
    while frontier:
        generation = []
        for node in frontier:
            lo, hi = bounds[node.part]
            frame = frame_of(node.transform, lo, hi)  # CURRENT conventions (Units), as sym_params'
            choices = []
            info = _PartInfo(node, frame, group_children(node.children, frame, corners, tolerance, flips, rounds,
                                                         choices=choices), pairing_choices=bool(choices))
            made[id(node)] = info
            generation.append(info)
        _pair_by_agreement(generation, corners, tolerance, flips, rounds)
        _regroup_by_consensus(generation, corners, tolerance, flips, rounds)
        align_ring_starts([(u, info.frame) for info in generation for u in info.units], consensus)
        align_mirror_sides([(u, info.frame, info.node.part) for info in generation for u in info.units],
                           mirror_sides)
        frontier = [u.representative().node for info in generation for u in info.units]
    infos = []  # every part node that is a unit representative or a root, depth first

    def order(node: ExampleNode) -> _PartInfo:
        info = made[id(node)]
        infos.append(info)
        for unit in info.units:
            order(unit.representative().node)
        return info

    root_infos = [order(e) for e in example_set.examples]
    by_node = {id(i.node): i for i in infos}
    by_type = {}
    for info in infos:
        by_type.setdefault(info.node.part, []).append(info)
    slots, groups, offsets_of, objective = {}, {}, {}, {}
    for parent_type in sorted(by_type):
        parents = by_type[parent_type]
        child_types = sorted({u.type for info in parents for u in info.units})
        slot_types, offsets = [], {}
        for child_type in child_types:
            m, f = _assign_slots(parents, child_type, samples)
            offsets[child_type] = len(slot_types)
            slot_types += [child_type] * m
            objective[(parent_type, child_type)] = f
        slots[parent_type] = slot_types
        offsets_of[parent_type] = offsets
        groups[parent_type] = _slot_groups(parent_type, parents, slot_types, offsets, parts) if slot_types else []

    nodes, sym_inner, max_count = [], {}, {}
    turns = {}  # symmetry type -> the reference direction its nodes turn the held symmetry's frame from

    def add(pnode: PNode) -> PNode:
        pnode.id = len(nodes)
        nodes.append(pnode)
        return pnode

    def convert_part(info: _PartInfo, frame: Frame, example: int) -> PNode:
        x, signs = xform_params(info.node.transform, frame)
        pnode = add(PNode(0, "part", info.node.part, example, part=info.node.part, x=x, signs=signs,
                          world=info.node.transform))
        slot_types = slots[info.node.part]
        pnode.used = np.zeros(len(slot_types), dtype=bool)
        for unit in info.units:
            s = offsets_of[info.node.part][unit.type] + info.slot_of[id(unit)]
            if pnode.used[s]:
                raise ExamplesError(f"internal: slot {s} of {info.node.part} assigned twice")
            pnode.used[s] = True
            child = convert_unit(unit, info.frame, example)
            child.parent, child.parent_slot = pnode.id, s
            pnode.children.append((s, child))
        pnode.children.sort(key=lambda sc: sc[0])
        pnode.height = 1 + max((c.height for _, c in pnode.children), default=-1)
        return pnode

    def convert_unit(unit: Unit, frame: Frame, example: int) -> PNode:
        if unit.kind == "node":
            return convert_part(by_node[id(unit.node)], frame, example)
        measured = frame.for_symmetry()  # (turned by a symmetry holding it)
        pnode = add(PNode(0, unit.kind, unit.type, example,
                          sym=sym_params(unit.kind, unit.g, measured, towards=unit.normal), count=len(unit.members)))
        sym_inner[unit.type] = unit.members[0].type
        max_count[unit.type] = max(max_count.get(unit.type, 0), len(unit.members))
        inner = frame._replace(measure=None)
        if unit.type in turns:
            inner = frame._replace(measure=turned_frame(measured, turns[unit.type],
                                                        symmetry_direction(pnode.sym, DIAGONAL_POLE)))
        child = convert_unit(unit.members[0], inner, example)
        child.parent, child.parent_slot = pnode.id, 0
        pnode.children = [(0, child)]
        pnode.height = child.height + 1
        return pnode

    world_extent = set_size(example_set)
    # (the roots measured facing the world's axes, as centred_examples turned them; the
    # program's roots face example_set.facing when sampled: Units.world_frame)
    roots_frame = Units(world_extent).world_frame()

    def convert_all(with_turns: dict) -> list:
        nodes.clear()
        turns.clear()
        turns.update(with_turns)
        return [convert_part(info, roots_frame, k).id for k, info in enumerate(root_infos)]

    # a symmetry holding another has it measure its parameters in a frame turned from the
    # outer's reference direction to its own (transforms.turned_frame), where its
    # directions vary and the inner's follow them: the inner's directions then spread
    # less. Where they vary apart (placement noise in both) they spread more that way, and
    # independent draws of the two then added up (h77: posts at a box's corners, three
    # mirrors deep, leaned twice as far), so a turn is kept only where it narrows the
    # held symmetry's spread. Outer types' turns decide inner types' frames: outside in
    accepted, refused = {}, set()
    roots = convert_all(accepted)
    for _ in range(MAX_TURN_PASSES):
        found = _turn_references(nodes)
        trial = {t: r for t, r in found.items() if t not in refused}
        if trial == accepted:
            break
        for sym_type in sorted(set(trial) - set(accepted)):
            before = _held_spread(nodes, sym_type)
            convert_all({**{t: trial[t] for t in accepted if t in trial}, sym_type: trial[sym_type]})
            if not _held_spread(nodes, sym_type) < before:
                refused.add(sym_type)
        accepted = {t: r for t, r in trial.items() if t not in refused}
        roots = convert_all(accepted)
    anchors = choose_anchors(nodes, bounds)
    units = Units(world_extent, reference_log_scales(nodes), CURRENT, _spread_poles(nodes), turns, span_types(nodes),
                  anchors, examples_ground(example_set), example_set.facing)
    for n in nodes:
        if n.kind == "part":
            n.x[0:3] -= units.log_scale(n.part)
        elif n.type in units.sym_poles:
            n.sym = n.sym.copy()
            n.sym[0:2] = direction_angles(angles_direction(n.sym[0], n.sym[1]), units.pole(n.type))
        elif n.type in units.trans_spans:
            n.sym = n.sym.copy()
            n.sym[0:3] *= max(n.count - 1, 1)
    unwrap_angles(nodes)
    return Dataset(parts, slots, groups, nodes, roots, sym_inner, max_count, objective, units)


# Passes of preprocess's conversion at most: one per level of symmetries nested in
# symmetries whose directions vary (a grid of mirrored pairs is two)
MAX_TURN_PASSES = 6


def _held_spread(nodes: list, sym_type: str) -> float:
    """How far the directions of the symmetries that ``sym_type``'s nodes hold spread (one
    less the largest eigenvalue of their mean outer product: 0 when they all agree, up to
    sign): mirror normals and rotation axes, and translations' steps."""
    found = []
    for n in nodes:
        if n.type == sym_type and n.children:
            held = n.children[0][1]
            if held.kind in ("refl", "rot"):
                found.append(symmetry_direction(held.sym, DIAGONAL_POLE))
            elif held.kind == "trans" and np.linalg.norm(held.sym[:3]) > 0:
                found.append(np.asarray(held.sym[:3], dtype=np.float64) / np.linalg.norm(held.sym[:3]))
    if len(found) < 2:
        return 0.0
    found = np.array(found)
    return float(1.0 - np.linalg.eigvalsh(found.T @ found / len(found))[-1])


def _turn_references(nodes: list) -> dict:
    """Per mirror or rotation type that holds another symmetry and whose directions (in
    the frames its nodes were converted in) vary (:func:`spread_pole`'s test), their mean
    direction, as three floats: the reference a node turns the held symmetry's frame from."""
    directions = {}
    for n in nodes:
        if n.kind in ("refl", "rot") and n.children and n.children[0][1].kind != "part":
            direction = symmetry_direction(n.sym, DIAGONAL_POLE)
            directions.setdefault(n.type, []).append(direction)
    turns = {}
    for sym_type, found in sorted(directions.items()):
        found = np.array(found)
        if spread_pole(found) is None:
            continue  # one direction (rounding aside): nothing to follow
        found = found * np.where(found @ found[0] < 0, -1.0, 1.0)[:, None]  # one hemisphere
        mean = found.mean(axis=0)
        if np.linalg.norm(mean) < 1e-6:
            continue  # spread all round: no direction to turn from
        turns[sym_type] = tuple(float(v) for v in mean / np.linalg.norm(mean))
    return turns


def _spread_poles(nodes: list) -> dict:
    """Per mirror or rotation type whose directions (mirror normals, rotation axes) are
    spread over a circle, the pole to take their angles about (:func:`spread_pole`), as
    :class:`Units` holds it. The nodes' angles were taken about the default pole."""
    directions = {}
    for n in nodes:
        if n.kind in ("refl", "rot"):
            directions.setdefault(n.type, []).append(angles_direction(n.sym[0], n.sym[1]))
    poles = {}
    for sym_type, found in sorted(directions.items()):
        pole = spread_pole(np.array(found))
        if pole is not None:
            poles[sym_type] = tuple(tuple(float(v) for v in row) for row in pole)
    return poles


def set_size(example_set: ExampleSet) -> float:
    """The world frame's extent (:class:`~procmod.learn.transforms.Units`): the geometric
    mean of the examples' bounding-box diagonals (1 if they have no size)."""
    logs = [np.log(d) for d in (example_diagonal(root, example_set.parts) for root in example_set.examples)
            if d > 0]
    size = float(np.exp(np.mean(logs))) if logs else 1.0
    return size if np.isfinite(size) and size > 0 else 1.0


def reference_log_scales(nodes: list) -> dict:
    """Per part name, the mean log-scale (per axis) of its part nodes: the reference
    their components' log-scales are taken against."""
    logs = {}
    for n in nodes:
        if n.kind == "part":
            logs.setdefault(n.part, []).append(n.x[0:3])
    return {part: tuple(float(v) for v in np.mean(values, axis=0)) for part, values in logs.items()}


def _wrap(a):
    return (np.asarray(a) + np.pi) % (2 * np.pi) - np.pi


def _circular_mean(a: np.ndarray) -> np.ndarray:
    return np.arctan2(np.sin(a).mean(0), np.cos(a).mean(0))


SQUARE_TURN = np.radians(3.0)
"""A part's turn in its parent's frame is squared (:func:`squared_examples`) about each
axis where every placement of that part under that parent holds it within this angle of
a quarter turn."""


def squared_examples(example_set: ExampleSet) -> ExampleSet:
    """The example set with every part's turn in its parent's frame (a root's: in the
    world) set to the nearest quarter turns, Euler angle by Euler angle, where every
    placement of that part under that parent type holds the angle within
    :data:`SQUARE_TURN` of one; world translations and scales kept, the children's world
    transforms too (each is squared in its squared parent's frame in turn).

    Design change (seed 000 learns the placements as given): parts placed by eye are a
    degree or so off level, each independently in the world, but the learner measures a
    part in its parent's frame, so the noise of every level adds up down a chain: a
    helper's buildings of floors stacked on floors, each placed level within 0.7 degrees,
    sampled roofs tilted by a median 1.1 degrees and up to 8 (pyramid roofs 8-10 m wide
    sank 15 cm or more into the top floor in 110 of 194 samples, up to 1.35 m; no example's
    roof is tilted). Squaring the examples themselves (not only the learned angles) keeps
    the children's placements measured in the frames the samples build: squared angles
    over unsquared frames had put rows of windows 5-10 cm off their floors' faces. A turn
    of its own (a roof turned 45 degrees, a lean of 10) is kept as placed."""
    quarter = np.pi / 2
    angles = {}  # (parent part or None, part) -> Euler angles of each placement in its parent's frame

    def collect(node: ExampleNode, parent_rot: np.ndarray, parent_part) -> None:
        rot = decompose(node.transform)[0]
        angles.setdefault((parent_part, node.part), []).append(euler_of(parent_rot.T @ rot))
        for child in node.children:
            collect(child, rot, node.part)

    for example in example_set.examples:
        collect(example, np.eye(3), None)

    def off_square(e: np.ndarray) -> np.ndarray:  # each angle's distance to its nearest quarter turn
        return np.abs(_wrap(e - np.round(e / quarter) * quarter))

    square = {key: (off_square(np.array(values)) <= SQUARE_TURN).all(axis=0) for key, values in angles.items()}
    if not any(flags.any() for flags in square.values()):
        return example_set

    def squared(node: ExampleNode, parent_rot: np.ndarray, parent_part) -> ExampleNode:
        rot, scale, _ = decompose(node.transform)
        flags = square[(parent_part, node.part)]
        m = np.array(node.transform, dtype=np.float64)
        if flags.any():
            e = euler_of(parent_rot.T @ rot)
            off = off_square(e)
            # measured again in the squared parent's frame: an angle now over the limit is
            # left (a part on its side under a parent tilted by a degree reads, once the
            # parent is squared, angles of 135 degrees about two axes, each "nearest" a
            # quarter turn of its own: rounded, the part had spun by 90 degrees, h101)
            snap = flags & (off <= SQUARE_TURN)
            if (off[snap] > 1e-9).any():  # (a placement already square is kept bit for bit)
                squared_rot = parent_rot @ rot_of(np.where(snap, np.round(e / quarter) * quarter, e))
                # (each angle within the limit: at most sqrt(3) times it in all)
                if Rotation.from_matrix(squared_rot.T @ rot).magnitude() <= math.sqrt(3.0) * SQUARE_TURN:
                    rot = squared_rot
                    m[:3, :3] = rot * scale
        return ExampleNode(node.part, m, [squared(c, rot, node.part) for c in node.children])

    return replace(example_set, examples=[squared(e, np.eye(3), None) for e in example_set.examples])


def unwrap_angles(nodes: list) -> None:
    """Angles that mean one rotation written near one another, per place (parent type and
    slot): the learner models Euler angles and symmetry angles with Gaussians, and a
    constant half turn written +pi in one example and -pi in the next (as rounding or
    placement noise decides) would look like the widest possible spread.

    Euler angles: of the two xyz triples of a rotation, (a, b, c) and (a + pi, pi - b,
    c + pi), each node takes the one nearer the place's circular means (two rounds), then
    every angle is moved by a multiple of 2 pi to within pi of its mean. Symmetry
    azimuths and rotation angles are moved likewise. The rotations are unchanged."""
    places = {}
    for n in nodes:
        if n.x is not None:
            key = ("x", nodes[n.parent].type if n.parent >= 0 else None, n.parent_slot)
            places.setdefault(key, []).append(n)
        if n.sym is not None and n.kind in ("refl", "rot"):
            places.setdefault(("sym", n.type), []).append(n)
    for key, group in places.items():
        if key[0] == "x":
            e = np.array([n.x[3:6] for n in group])
            dual = _wrap(e + np.array([np.pi, 0.0, np.pi]))
            dual[:, 1] = _wrap(np.pi - e[:, 1])
            for _ in range(2):
                mu = _circular_mean(e)
                pick = (np.abs(_wrap(dual - mu)) ** 2).sum(1) < (np.abs(_wrap(e - mu)) ** 2).sum(1) - 1e-12
                e = np.where(pick[:, None], dual, e)
            mu = _circular_mean(e)
            e = mu + _wrap(e - mu)
            for n, angles in zip(group, e):
                n.x = n.x.copy()
                n.x[3:6] = angles
        else:
            which = [1] if group[0].kind == "refl" else [1, 5]  # azimuth; rotation angle
            a = np.array([n.sym[which] for n in group])
            mu = _circular_mean(a)
            a = mu + _wrap(a - mu)
            for n, values in zip(group, a):
                n.sym = n.sym.copy()
                n.sym[which] = values
