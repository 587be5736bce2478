"""Example preprocessing (seed 000 section 4): symmetry groups, slots, slot groups.

1. **Symmetry groups** among the children of every part node, from the world transforms
   alone. Two sibling units (a node with its subtree, or an already-found group) with the
   same structure are related by the world map ``G = W_b W_a^-1`` of their first parts;
   the relation holds when ``G`` maps every transform of one subtree onto the other's.
   Passes, in order: reflection pairs (``G`` a mirror), then translation and rotation
   chains of at least three units with one constant ``G`` (longest chain first), then
   reflection pairs again (mirrored rows), so groups nest (``trans(refl(panel))``).
   A group is canonicalised in its parent's frame: mirror normals, translation steps and
   rotation axes point along their largest component, rotation angles are positive, and
   full-circle rotation groups start at the member nearest a fixed reference direction.
2. **Slots** per parent part type and child type with the greedy minimax-Hausdorff
   assignment of eq. 1: start from a parent with the most children of that type, then
   repeatedly commit the parent whose best assignment raises the objective least. A
   parent's best assignment is a bottleneck assignment, solved exactly (threshold search
   over the cost values with ``scipy.optimize.linear_sum_assignment``, ties broken by the
   summed cost). Distances are Hausdorff distances between point samples of the units'
   parts (box corners and centre, mesh vertices) in the parent's local frame.
3. **Slot groups**: slots whose contents overlap after removing the parent's volume, by
   a voxel test in the parent's local frame (:data:`OVERLAP_VOXELS` voxels along the
   longest side; two slots overlap when a voxel centre lies inside a part of each and
   outside the parent). Chosen over manifold3d booleans because example meshes need not
   be watertight manifolds, and because touching parts (a wing against a hull) share no
   voxel centre, so only real interpenetration deeper than about one voxel counts.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field

import numpy as np
from scipy.optimize import linear_sum_assignment

from ..geometry.voxel import VoxelGrid, voxelize
from .examples import ExampleNode, ExampleSet, ExamplesError
from .transforms import (WORLD_FRAME, Frame, canonical_direction, frame_of, in_frame,
                         rotation_axis_angle, sym_params, xform_params)

MATCH_TOLERANCE = 1e-5
OVERLAP_VOXELS = 40
MIN_CHAIN = 3


# ---- symmetry detection ---------------------------------------------------------------

def _close(a: np.ndarray, b: np.ndarray) -> bool:
    scale = 1.0 + max(float(np.abs(a).max()), float(np.abs(b).max()))
    return float(np.abs(a - b).max()) <= MATCH_TOLERANCE * scale


def _raw_signature(node: ExampleNode) -> str:
    return f"{node.part}[{','.join(sorted(_raw_signature(c) for c in node.children))}]"


@dataclass
class Unit:
    """A child of a part node: one node (with its subtree) or a symmetry group of units."""

    kind: str  # "node", "refl", "trans" or "rot"
    node: ExampleNode | None = None
    members: list = field(default_factory=list)
    g: np.ndarray | None = None  # world map from member 0 to member 1
    sig: str = ""
    type: str = ""

    def transforms(self) -> list:
        """(part, world) of every node in the unit's subtrees."""
        if self.kind == "node":
            return [(n.part, n.transform) for n in self.node.walk()]
        return [t for m in self.members for t in m.transforms()]

    def top_parts(self) -> list:
        """(part, world) of the unit's own parts (all members, not their descendants)."""
        if self.kind == "node":
            return [(self.node.part, self.node.transform)]
        return [t for m in self.members for t in m.top_parts()]

    def first(self) -> np.ndarray:
        return self.node.transform if self.kind == "node" else self.members[0].first()

    def representative(self) -> "Unit":
        return self if self.kind == "node" else self.members[0].representative()


def _leaf(node: ExampleNode) -> Unit:
    return Unit("node", node=node, sig=_raw_signature(node), type=node.part)


def _group(kind: str, members: list, g: np.ndarray) -> Unit:
    return Unit(kind, members=members, g=g, sig=f"{kind}{len(members)}({members[0].sig})",
                type=f"{kind}({members[0].type})")


def _maps_onto(g: np.ndarray, a: Unit, b: Unit) -> bool:
    """Whether ``g`` maps every (part, transform) of ``a`` onto a distinct one of ``b``."""
    source, target = a.transforms(), b.transforms()
    if len(source) != len(target):
        return False
    free = list(range(len(target)))
    for part, w in source:
        gw = g @ w
        for k in free:
            if target[k][0] == part and _close(gw, target[k][1]):
                free.remove(k)
                break
        else:
            return False
    return True


def _linear_kind(g: np.ndarray) -> str | None:
    lin = g[:3, :3]
    if not np.allclose(lin.T @ lin, np.eye(3), atol=1e-6):
        return None
    if np.allclose(lin, np.eye(3), atol=1e-9):
        return "trans" if np.linalg.norm(g[:3, 3]) > 1e-9 else None
    det = np.linalg.det(lin)
    if det < 0:
        return "refl" if np.allclose(lin, lin.T, atol=1e-6) and abs(np.trace(lin) - 1) < 1e-6 else None
    return "rot"


def _pair_reflections(units: list, frame: Frame) -> list:
    out, used = [], set()
    for i, a in enumerate(units):
        if i in used:
            continue
        for j in range(i + 1, len(units)):
            b = units[j]
            if j in used or b.sig != a.sig:
                continue
            g = b.first() @ np.linalg.inv(a.first())
            if _linear_kind(g) == "refl" and _maps_onto(g, a, b):
                used.update((i, j))
                # canonical order: member 0 on the positive side of the (canonical) plane
                gf = in_frame(g, frame)
                w, v = np.linalg.eigh(0.5 * (gf[:3, :3] + gf[:3, :3].T))
                n, _ = canonical_direction(v[:, int(np.argmin(w))])
                d = 0.5 * float(n @ gf[:3, 3])
                pa = np.linalg.inv(frame.matrix()) @ a.first()
                members = [a, b] if float(n @ pa[:3, 3]) - d >= 0 else [b, a]
                out.append(_group("refl", members, g))
                break
        else:
            out.append(a)
    return out


def _extend(g: np.ndarray, start: int, units: list, free: set) -> list:
    chain, cur = [start], start
    while True:
        for k in sorted(free):
            if k not in chain and _maps_onto(g, units[cur], units[k]):
                chain.append(k)
                cur = k
                break
        else:
            return chain


def _chains(units: list, frame: Frame) -> list:
    free = set(range(len(units)))
    groups = []
    while True:
        best = None
        for i in sorted(free):
            for j in sorted(free):
                if i == j or units[i].sig != units[j].sig:
                    continue
                g = units[j].first() @ np.linalg.inv(units[i].first())
                kind = _linear_kind(g)
                if kind not in ("trans", "rot") or not _maps_onto(g, units[i], units[j]):
                    continue
                forward = _extend(g, i, units, free)
                backward = _extend(np.linalg.inv(g), i, units, free - set(forward[1:]))
                chain = list(reversed(backward[1:])) + forward
                if best is None or len(chain) > len(best[0]):
                    best = (chain, g, kind)
        if best is None or len(best[0]) < MIN_CHAIN:
            break
        chain, g, kind = best
        free -= set(chain)
        groups.append((chain, g, kind))
    out = [units[k] for k in sorted(free)]
    for chain, g, kind in groups:
        members = [units[k] for k in chain]
        gf = in_frame(g, frame)
        if kind == "trans":
            _, sign = canonical_direction(gf[:3, 3])
            if sign < 0:
                members, g = members[::-1], np.linalg.inv(g)
        else:
            _, angle = rotation_axis_angle(gf)
            if angle < 0:
                members, g = members[::-1], np.linalg.inv(g)
                angle = -angle
            if abs(len(members) * angle - 2 * np.pi) < 1e-3:
                members = _start_nearest_reference(members, g, frame)
        out.append(_group(kind, members, g))
    return out


def _start_nearest_reference(members: list, g: np.ndarray, frame: Frame) -> list:
    """Roll a full-circle rotation group to start at the member first reached, turning
    the group's way, from a reference direction perpendicular to the axis."""
    gf = in_frame(g, frame)
    axis, _ = rotation_axis_angle(gf)
    centre, *_ = np.linalg.lstsq(np.eye(3) - gf[:3, :3], gf[:3, 3], rcond=None)
    ref = np.eye(3)[int(np.argmin(np.abs(axis)))]
    ref = ref - (ref @ axis) * axis
    ref /= np.linalg.norm(ref)
    finv = np.linalg.inv(frame.matrix())
    best, best_angle = 0, np.inf
    for k, m in enumerate(members):
        p = (finv @ m.first())[:3, 3] - centre
        p = p - (p @ axis) * axis
        angle = np.arctan2(np.cross(ref, p) @ axis, ref @ p) % (2 * np.pi)
        if angle < best_angle - 1e-9:
            best, best_angle = k, angle
    return members[best:] + members[:best]


def group_children(children: list, frame: Frame) -> list:
    """Symmetry groups among sibling nodes (a list of :class:`Unit`)."""
    units = [_leaf(c) for c in children]
    units = _pair_reflections(units, frame)
    units = _chains(units, frame)
    return _pair_reflections(units, frame)


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
    symmetry type; ``max_count[type]``: the largest member count seen.
    """

    parts: dict
    slots: dict
    groups: dict
    nodes: list
    roots: list
    sym_inner: dict
    max_count: dict
    hausdorff_objective: dict = field(default_factory=dict)

    @property
    def types(self) -> list:
        return sorted({n.type for n in self.nodes})

    def kind_of(self, type_: str) -> str:
        return type_.split("(", 1)[0] if "(" in type_ else "part"


@dataclass
class _PartInfo:
    node: ExampleNode
    frame: Frame
    units: list
    slot_of: dict = field(default_factory=dict)  # id(unit) -> slot index


def _sample_points(shape, world: np.ndarray) -> np.ndarray:
    if shape.kind == "box":
        half = np.asarray(shape.size) / 2
        local = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)] + [[0, 0, 0]]) * half
    else:
        local = np.asarray(shape.vertices, dtype=np.float64)
        if len(local) > 64:
            local = local[np.linspace(0, len(local) - 1, 64).astype(int)]
    return local @ world[:3, :3].T + world[:3, 3]


def _hausdorff(a: np.ndarray, b: np.ndarray) -> float:
    d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
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


def _assign_slots(parents: list, child_type: str, parts: dict) -> tuple[int, float]:
    """Greedy minimax-Hausdorff slot assignment (eq. 1) for one (parent type, child type).

    Sets ``info.slot_of`` entries to a slot offset in [0, m); returns m and f(N).
    """
    entries = []  # per parent: list of (unit, points in the parent's local frame)
    for info in parents:
        inv = np.linalg.inv(info.node.transform)
        units = [u for u in info.units if u.type == child_type]
        if units:
            pts = [np.concatenate([_sample_points(parts[p], inv @ w) for p, w in u.top_parts()]) for u in units]
            entries.append((info, list(zip(units, pts))))
    if not entries:
        return 0, 0.0
    m = max(len(e[1]) for e in entries)
    first = max(range(len(entries)), key=lambda k: (len(entries[k][1]), -k))
    slots = [[] for _ in range(m)]  # point sets assigned to each slot
    info, items = entries[first]
    for s, (unit, pts) in enumerate(items):
        info.slot_of[id(unit)] = s
        slots[s].append(pts)
    remaining = [k for k in range(len(entries)) if k != first]
    f = 0.0
    while remaining:
        best = None
        for k in remaining:
            items = entries[k][1]
            cost = np.array([[max((_hausdorff(pts, q) for q in slots[s]), default=0.0) for s in range(m)]
                             for _, pts in items])
            threshold, total, cols = _bottleneck(cost)
            key = (max(f, threshold), threshold, total, k)
            if best is None or key < best[0]:
                best = (key, k, cols)
        key, k, cols = best
        f = key[0]
        info, items = entries[k]
        for (unit, pts), s in zip(items, cols):
            info.slot_of[id(unit)] = int(s)
            slots[int(s)].append(pts)
        remaining.remove(k)
    return m, f


def _slot_groups(parent_type: str, parents: list, slot_types: list, offsets: dict, parts: dict) -> list:
    """Connected components of the slot-overlap graph (voxel test in the parent's frame)."""
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

    for i, j in itertools.combinations(range(n), 2):
        if occupied[i] is not None and occupied[j] is not None and (occupied[i] & occupied[j]).any():
            parent_of[find(i)] = find(j)
    groups = {}
    for i in range(n):
        groups.setdefault(find(i), []).append(i)
    return sorted(groups.values())


def preprocess(example_set: ExampleSet) -> Dataset:
    """Symmetry groups, slots and slot groups of an example set (seed 000 section 4)."""
    parts = example_set.parts
    infos = []  # every part node that is a unit representative or a root

    def visit(node: ExampleNode) -> _PartInfo:
        lo, hi = parts[node.part].local_bounds()
        frame = frame_of(node.transform, lo, hi)
        info = _PartInfo(node, frame, group_children(node.children, frame))
        infos.append(info)
        for unit in info.units:
            visit(unit.representative().node)
        return info

    root_infos = [visit(e) for e in example_set.examples]
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
            m, f = _assign_slots(parents, child_type, parts)
            offsets[child_type] = len(slot_types)
            slot_types += [child_type] * m
            objective[(parent_type, child_type)] = f
        slots[parent_type] = slot_types
        offsets_of[parent_type] = offsets
        groups[parent_type] = _slot_groups(parent_type, parents, slot_types, offsets, parts) if slot_types else []

    nodes, sym_inner, max_count = [], {}, {}

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
        pnode = add(PNode(0, unit.kind, unit.type, example, sym=sym_params(unit.kind, unit.g, frame),
                          count=len(unit.members)))
        sym_inner[unit.type] = unit.members[0].type
        max_count[unit.type] = max(max_count.get(unit.type, 0), len(unit.members))
        child = convert_unit(unit.members[0], frame, example)
        child.parent, child.parent_slot = pnode.id, 0
        pnode.children = [(0, child)]
        pnode.height = child.height + 1
        return pnode

    roots = [convert_part(info, WORLD_FRAME, k).id for k, info in enumerate(root_infos)]
    return Dataset(parts, slots, groups, nodes, roots, sym_inner, max_count, objective)
