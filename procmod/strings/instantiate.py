"""Instantiation of shape graphs (seed 001, section 6).

From a random edge, parts are added by transplanting a relative transform seen in the
training shapes for the edge's category (:mod:`.categories`; the categories come from the
tagger's vote, :mod:`.tagger`); a part that collides with placed non-neighbours, misses a
placed neighbour, sits at a pose no example shows, or leaves a placed part it must still
join out of reach, is retried with other examples of the category, then of the other
voted categories, then (Monte Carlo fallback) of any category of that type pair; when none
fits, the search backjumps to the placed part the failures were owed to (see
:func:`instantiate_graph`).
"""

from __future__ import annotations

import heapq
from dataclasses import dataclass

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError
from .categories import EdgeCategories
from .frames import canonical_frame
from .contacts import contact_pairs, contact_tolerance, part_points, shape_graph
from .shapes import Shape, ShapeSet


@dataclass
class InstantiateResult:
    shape: Shape | None
    success: bool
    fallbacks: int = 0
    reason: str = ""
    tries: int = 0  # placements tried (each a contact test), over all backtracking


def _centre_reach(categories: EdgeCategories, shape_set: ShapeSet) -> dict:
    """Per type pair (both orders), the largest centroid distance of two neighbours in any
    example edge: how far apart two parts joined by a path can be, edge by edge."""
    lib = shape_set.library
    part_of = shape_set.part_of_letter
    reach: dict[tuple, float] = {}
    for k, ex in categories.examples.items():
        name = categories.names[k]
        if name is None or name[0] not in part_of or name[1] not in part_of:
            continue
        local_b = part_points(lib, part_of[name[1]], np.eye(4)).mean(0)
        local_a = part_points(lib, part_of[name[0]], np.eye(4)).mean(0)
        for rel in ex:
            # rel[0]: B's transform in A's canonical frame (origin = A's vertex mean), and back
            d = max(float(np.linalg.norm(rel[0][:3, :3] @ local_b + rel[0][:3, 3])),
                    float(np.linalg.norm(rel[1][:3, :3] @ local_a + rel[1][:3, 3])))
            for key in ((name[0], name[1]), (name[1], name[0])):
                reach[key] = max(reach.get(key, 0.0), d)
    return reach


def _first_pose(categories: EdgeCategories, shape_set: ShapeSet, voted, t: str, given: np.ndarray) -> np.ndarray:
    """The pose of the first part placed, of type ``t``, whose start edge was voted ``voted``
    (a category, a ranked list of them, or None): ``given`` (its type's start pose: its
    first instance in the inputs), unless no example of the voted category shows the part
    turned so, up to its own symmetry and the whole-shape turns. Then it is turned as an
    example shows it (the turn closest to ``given``'s), its vertex mean over ``given``'s and
    its lowest point at ``given``'s height. A part type seen both square to the axes and
    turned 45 degrees about x had every shape started from that type's first instance's
    turn, and a flat shape started from the turned one came out tilted by 45 degrees."""
    k = voted if voted is None or isinstance(voted, (int, np.integer)) else next(iter(voted), None)
    name = categories.names[k] if k is not None and 0 < k < len(categories.names) else None
    if name is None or t not in name[:2]:
        return given
    lib, part_of = shape_set.library, shape_set.part_of_letter
    turns = []
    for rel in categories.examples.get(k, []):
        if len(rel) < 3:  # categories saved before the A part's turn was kept
            continue
        if t == name[0]:
            turns.append(rel[2][:3, :3])
        if t == name[1]:  # B's turn: its pose in A's canonical frame, that frame at A's turn
            turns.append((canonical_frame(lib, part_of[name[0]], rel[2], categories.groups) @ rel[0])[:3, :3])
    turns = [g[:3, :3] @ r for g in categories.symmetries if np.linalg.det(g[:3, :3]) > 0 for r in turns]
    if not turns:
        return given
    part = part_of[t]

    def frame_turn(r: np.ndarray) -> np.ndarray:  # the canonical frame's turn: one per placement
        m = np.eye(4)
        m[:3, :3] = r
        return canonical_frame(lib, part, m, categories.groups)[:3, :3]

    have = frame_turn(given[:3, :3])
    if any(np.abs(frame_turn(r) - have).max() <= 1e-4 for r in turns):
        return given
    best = max(turns, key=lambda r: float(np.trace(given[:3, :3].T @ r)))
    pose = np.eye(4)
    pose[:3, :3] = best
    q, was = part_points(lib, part, pose), part_points(lib, part, given)
    pose[:3, 3] = [*(was.mean(0)[:2] - q.mean(0)[:2]), was[:, 2].min() - q[:, 2].min()]
    return pose


def instantiate_graph(g: nx.Graph, edge_cats: dict, categories: EdgeCategories, shape_set: ShapeSet,
                      rng: np.random.Generator, start_pose: dict | None = None,
                      tries_per_edge: int = 24, debug: list | None = None, budget: int = 4000) -> InstantiateResult:
    """Embed a typed graph in 3D by transplanting edges with the given categories.

    ``edge_cats`` maps ``(min, max)`` node pairs to a category, or to a list of categories
    best first (from the tagger's vote, ``ranked=True``);
    ``shape_set`` supplies the part library; ``start_pose`` maps a type to the 4x4 pose of
    the first part (default: identity; a given pose is turned as its start edge's category
    shows the part where that category never shows it turned so: :func:`_first_pose`).
    Success means the recomputed shape graph is ``g``.

    Parts are placed in breadth-first order from a random edge, rings first. Each part's
    candidate poses are the example edges of its voted category, then those of the other
    ranked categories, then (the Monte Carlo fallback) those of every other category
    of its type pair; a pose is accepted when the part touches exactly its placed graph
    neighbours, each at a pose some category shows, and when every placed part it is still
    to be joined to (through parts not yet placed) is within reach (the sum of the largest
    example distances along the shortest such path). When no candidate of a part is
    accepted, the search jumps back to the latest placed part one of the failures was owed
    to (conflict-directed backjumping) and tries that part's next candidate; the paper's
    construction never revises a placed part, so a ring that does not close with the first
    choices fails. The search is complete (from the first part's pose, with
    ``tries_per_edge`` at least the examples kept per category, as by default): a failure with
    reason "every candidate pose tried" means no choice of example poses realises the graph.
    ``budget`` bounds the candidates tried (a failure then says so); ``tries_per_edge``
    bounds the candidates per category.
    """
    part_of = shape_set.part_of_letter
    for v in g.nodes:
        if g.nodes[v]["type"] not in part_of:
            return InstantiateResult(None, False, reason=f"type {g.nodes[v]['type']!r} is not a part of the library")
    if budget < 1:
        raise InvalidArgumentError(f"budget must be at least 1 (got {budget})")
    lib = shape_set.library
    tol = contact_tolerance(shape_set)
    n = g.number_of_nodes()
    types = [g.nodes[v]["type"] for v in range(n)]
    parts = [part_of[t] for t in types]
    edges = sorted(g.edges)
    if not edges:  # a lone part: posed as a first part is (it had stood on its side, off the ground: h69)
        pose = np.asarray((start_pose or {}).get(types[0], np.eye(4)), dtype=np.float64)
        return InstantiateResult(Shape.of(parts, [pose]), True)
    reach = _centre_reach(categories, shape_set)
    # Placement order: breadth first, over the 2-core (the rings and what joins them) first,
    # then the trees hanging off it: a ring that cannot close is found before any branch is
    # placed, so backtracking does not re-place branches that have nothing to do with it.
    core = set(nx.k_core(g, 2).nodes) if g.number_of_edges() >= g.number_of_nodes() else set()
    starts = [e for e in edges if e[0] in core] or edges
    u0, v0 = starts[int(rng.integers(len(starts)))]
    order, parent = [u0], {u0: None}
    for inner in (True, False):
        k = 0
        while k < len(order):
            x = order[k]
            k += 1
            nbrs = sorted(g.neighbors(x))
            for y in [nbrs[i] for i in rng.permutation(len(nbrs))]:
                if y not in parent and (not inner or y in core):
                    parent[y] = x
                    order.append(y)
    if len(order) < n:
        return InstantiateResult(None, False, reason="the graph is not connected")
    adj = [sorted(g.neighbors(v)) for v in range(n)]
    poses: dict[int, np.ndarray] = {}
    frames: dict[int, np.ndarray] = {}
    centre: dict[int, np.ndarray] = {}
    box: dict[int, tuple] = {}  # placed node -> (lo, hi) of its points, widened by tol
    pts0 = {name: part_points(lib, name, np.eye(4)) for name in set(parts)}

    def place(v: int, pose: np.ndarray) -> None:
        poses[v] = pose
        frames[v] = canonical_frame(lib, parts[v], pose, categories.groups)
        q = pts0[parts[v]] @ pose[:3, :3].T + pose[:3, 3]
        centre[v] = q.mean(0)
        box[v] = (q.min(0) - tol, q.max(0) + tol)

    def unplace(v: int) -> None:
        for d in (poses, frames, centre, box):
            d.pop(v, None)

    def candidates(y: int) -> list[tuple[np.ndarray, bool]]:
        """World poses for y next to its placed BFS parent, voted category first (True)."""
        x = parent[y]
        a_type, b_type = min(types[x], types[y]), max(types[x], types[y])
        k = edge_cats.get((min(x, y), max(x, y)))
        allowed = categories.allowed(types[x], types[y])
        ranked = [c for c in ([k] if isinstance(k, (int, np.integer)) else list(k or [])) if c in allowed]
        out, keys = [], set()
        # the voted category, then the other ranked ones (best first), then the rest of the pair
        for voted, cats in ([(True, ranked[:1])] + [(False, [c]) for c in ranked[1:]]
                            + [(False, [c for c in allowed if c not in ranked])]):
            group = []
            for c in cats:
                rels = categories.examples.get(c, [])
                for rel in [rels[i] for i in rng.permutation(len(rels))][:tries_per_edge]:
                    if types[x] == a_type:
                        group.append(frames[x] @ rel[0])  # x plays the A part
                    if types[x] == b_type:
                        group.append(frames[x] @ rel[1])  # x plays the B part
            for i in rng.permutation(len(group)):
                key = tuple(np.round(group[i][:3], 4).reshape(-1).tolist())
                if key not in keys:  # examples of one category mostly coincide
                    keys.add(key)
                    out.append((group[i], voted))
        return out

    def fits(y: int, pose: np.ndarray) -> set | None:
        """None if y fits at ``pose``; else the placed nodes the failure is owed to (besides
        y's parent, whose pose the candidate came from)."""
        q = pts0[parts[y]] @ pose[:3, :3].T + pose[:3, 3]
        lo, hi = q.min(0) - tol, q.max(0) + tol
        near = [v for v, (blo, bhi) in box.items() if np.all(blo <= hi) and np.all(lo <= bhi)]
        m = len(near)
        names = [parts[v] for v in near] + [parts[y]]
        trans = [poses[v] for v in near] + [pose]
        touching = {near[i] for i, _ in contact_pairs(lib, names, trans, tol, pairs_of=[(i, m) for i in range(m)])}
        nbrs = {v for v in adj[y] if v in poses}
        if touching != nbrs:
            if debug is not None:
                debug.append((y, "touching", sorted(touching), sorted(nbrs)))
            return touching ^ nbrs
        fy = canonical_frame(lib, parts[y], pose, categories.groups)
        unseen = {v for v in nbrs if not categories.pose_seen(frames[v], fy, types[v], types[y])}
        if unseen:
            if debug is not None:
                debug.append((y, "pose not seen", sorted(unseen)))
            return unseen
        far = out_of_reach(y, q.mean(0))
        if far is not None and debug is not None:
            debug.append((y, "out of reach", far))
        return None if far is None else {far}

    def out_of_reach(y: int, cy: np.ndarray) -> int | None:
        """A placed node joined to y through unplaced nodes that is farther from y than that
        path can stretch (Dijkstra over unplaced nodes, edge length = the pair's largest
        example distance), or None. Checking the new node's pairs suffices: older pairs were
        checked when they were placed, and placing nodes only removes paths."""
        dist = {y: 0.0}
        heap = [(0.0, y)]
        while heap:
            d, u = heapq.heappop(heap)
            if d > dist.get(u, np.inf):
                continue
            for w in adj[u]:
                step = reach.get((types[u], types[w]), np.inf)
                if w in poses or w == y:
                    if u != y and w != y and float(np.linalg.norm(centre[w] - cy)) > d + step + 1e-6 + tol:
                        return w
                    continue
                if d + step < dist.get(w, np.inf):
                    dist[w] = d + step
                    heapq.heappush(heap, (d + step, w))
        return None

    # Depth-first search with conflict-directed backjumping: each part's candidates are its
    # voted category's poses, then the other categories' (the Monte Carlo fallback); when none
    # fits, the search jumps back to the latest placed part that one of the failures was owed
    # to (a part it collided with, a neighbour it could not reach, its parent), not merely to
    # the previous part in the order (which on a tree is usually unrelated), and that part
    # takes its next candidate. Complete: if it ends without a shape, no choice of the
    # example poses realises the graph.
    first = np.asarray((start_pose or {}).get(types[u0], np.eye(4)), dtype=np.float64)
    place(u0, first if start_pose is None or types[u0] not in start_pose
          else _first_pose(categories, shape_set, edge_cats.get((min(u0, v0), max(u0, v0))), types[u0], first))
    pos_of = {v: i for i, v in enumerate(order)}
    cands: list = [None] * n
    ptr = [0] * n
    conf: list[set] = [set() for _ in range(n)]
    voted_at = [True] * n
    tries = 0
    i = 1
    if n > 1:
        cands[1], conf[1] = candidates(order[1]), {0}
    while 0 < i < n:
        y = order[i]
        if ptr[i] >= len(cands[i]):
            culprits = conf[i] - {0}  # the first part's pose is arbitrary: never the cause
            if not culprits:
                break
            h = max(culprits)
            conf[h] |= culprits - {h}
            for j in range(h, i):
                unplace(order[j])
            for j in range(h + 1, i + 1):
                conf[j] = set()
            ptr[h] += 1
            i = h
            continue
        if tries >= budget:
            return InstantiateResult(None, False, sum(not v for v in voted_at[1:i]),
                                     f"search budget of {budget} placements spent at node {y} ({types[y]})", tries)
        pose, voted = cands[i][ptr[i]]
        tries += 1
        bad = fits(y, pose)
        if bad is None:
            place(y, pose)
            voted_at[i] = voted
            if debug is not None:
                debug.append(("placed", parent[y], y, voted, pose))
            i += 1
            if i < n:
                cands[i], ptr[i], conf[i] = candidates(order[i]), 0, {pos_of[parent[order[i]]]}
        else:
            conf[i] |= {pos_of[v] for v in bad}
            ptr[i] += 1
    if len(poses) < n:
        return InstantiateResult(None, False, 0, "no placement of the parts realises the graph "
                                 "(every candidate pose tried)", tries)
    fallbacks = sum(not v for v in voted_at[1:])
    shape = Shape.of(parts, [poses[v] for v in range(n)])
    actual = shape_graph(shape_set, shape, tol)
    same = set(map(tuple, map(sorted, actual.edges))) == set(map(tuple, map(sorted, g.edges)))
    return InstantiateResult(shape, same, fallbacks, "" if same else "the built shape's contacts differ from the graph",
                             tries)
