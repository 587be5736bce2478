"""Graph-based shape sampling (seed 001, section 4): grow a collection of valid variants.

One attempt: sample a random connected subgraph ``s`` of shape 1; its boundary ``B1`` is
the set of nodes outside ``s`` adjacent to it. Find nodes ``B2`` in shape 2 of the same
types with the same pairwise centroid distances (randomised backtracking, first match).
Dock ``s`` by the least-squares rigid transform taking the centroids of ``B1`` onto those
of ``B2`` (SVD of the 3x3 covariance), keeping the rotation it computes, at whatever
angle (``AugmentParams(rotate=False)``: translations only); where the centroids leave a
rotation free (one boundary node, or a line of them) the boundary part's own pose fixes it
(:func:`part_docks`), not the least-squares fit, whose spin about the line is rounding
error. procmod strings is z-up, so a dock turns about the vertical only
(:func:`upright_docks`; ``AugmentParams(upright=False)``: about any axis). The parts of
shape 2 that collide with the docked ``s`` go, together with their whole component of
``G2 - B2``; other components of ``G2 - B2`` are kept or dropped as the grammar needs. The
merged shape is kept only if its geometry validates (its recomputed shape graph is
connected and obeys the tiling grammar) and it is not a duplicate: by default its
node-type histogram is new (seed 001's conservative rule); ``AugmentParams(distinct=
"graph")`` only asks for a new graph.

A round runs ``p`` attempts through a :class:`concurrent.futures.Executor`; each attempt
is a module-level function with its own seed, so a round's result does not depend on
where its attempts ran. Rounds repeat on the growing collection.
"""

from __future__ import annotations

import itertools
import time
from dataclasses import dataclass, field, replace

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError, checked_count
from ..core.random import check_seed
from .contacts import centroids, contact_pairs, contact_tolerance, part_points, shape_graph, tolerance_for
from .grammar import Grammar
from .shapes import Shape, ShapeSet, type_histogram


def random_connected_subgraph(g: nx.Graph, size: int, rng: np.random.Generator) -> set:
    """A random connected node set of about ``size`` nodes (random frontier growth)."""
    nodes = sorted(g.nodes)
    start = nodes[int(rng.integers(len(nodes)))]
    chosen = {start}
    frontier = set(g.neighbors(start))
    while len(chosen) < size and frontier:
        options = sorted(frontier)
        v = options[int(rng.integers(len(options)))]
        chosen.add(v)
        frontier.discard(v)
        frontier.update(u for u in g.neighbors(v) if u not in chosen)
    return chosen


def match_boundary(b1: list, types1: list, c1: np.ndarray, types2: list, c2: np.ndarray, tol: float,
                   rng: np.random.Generator, max_steps: int = 20000) -> list | None:
    """Nodes of shape 2 matching ``b1`` (same types, pairwise centroid distances within ``tol``).

    Randomised depth-first search; the first match found is returned, or None.
    """
    by_type: dict[str, list[int]] = {}
    for k, t in enumerate(types2):
        by_type.setdefault(t, []).append(k)
    candidates = []
    for v in b1:
        pool = by_type.get(types1[v], [])
        if not pool:
            return None
        candidates.append([pool[k] for k in rng.permutation(len(pool))])
    d1 = np.linalg.norm(c1[b1][:, None] - c1[b1][None], axis=2)
    assignment: list[int] = []
    steps = 0

    def extend(i: int) -> bool:
        nonlocal steps
        if i == len(b1):
            return True
        for w in candidates[i]:
            steps += 1
            if steps > max_steps:
                return False
            if w in assignment:
                continue
            if all(abs(np.linalg.norm(c2[w] - c2[assignment[k]]) - d1[i, k]) <= tol for k in range(i)):
                assignment.append(w)
                if extend(i + 1):
                    return True
                assignment.pop()
        return False

    return list(assignment) if extend(0) else None


def _lands(m: np.ndarray, p: np.ndarray, q: np.ndarray, tol: float) -> bool:
    """Whether the rigid motion ``m`` takes every point of ``p`` to within ``tol`` of its ``q``."""
    return bool(np.linalg.norm(p @ m[:3, :3].T + m[:3, 3] - q, axis=1).max() <= tol)


def _add_new(out: list, m: np.ndarray) -> None:
    if not any(np.abs(m - o).max() <= 1e-9 for o in out):
        out.append(m)


def docking_transforms(p: np.ndarray, q: np.ndarray, tol: float, part_docks=(),
                       fitted: bool = True) -> list[np.ndarray]:
    """Rigid 4x4 transforms taking points ``p`` onto ``q``: the least-squares one (Kabsch:
    SVD of the covariance, with the reflection fix), then those of ``part_docks`` that also
    take every point of ``p`` to within ``tol`` of its ``q``.

    ``part_docks`` are the motions that lay a boundary part exactly onto its match, up to
    the part's own symmetries (:func:`part_docks`). They matter where the points leave a
    rotation free (one point, or all on a line): the rotation is then read off the parts'
    own poses, whatever angle that is, instead of assumed (quarter turns, as before: a
    property of grids). There ``fitted=False`` replaces the least-squares transform by the
    translation of ``p``'s centroid onto ``q``'s (kept only where it lands every point): a
    least-squares spin about a line of points is rounding error, and a fence docked by one
    was kept tilted by 0.02-0.5 degrees (within the landing check's tolerance).
    """
    cp, cq = p.mean(0), q.mean(0)
    r = np.eye(3)
    if fitted:
        x, y = p - cp, q - cq
        u, _, vt = np.linalg.svd(x.T @ y)
        d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
        r = vt.T @ np.diag([1.0, 1.0, d]) @ u.T
    t = np.eye(4)
    t[:3, :3] = r
    t[:3, 3] = cq - r @ cp
    out = [t] if fitted or _lands(t, p, q, tol) else []
    for m in part_docks:
        if _lands(m, p, q, tol):
            _add_new(out, m)
    return out


# A dock whose vertical moves by more than this (10 degrees) is dropped, not set upright.
UPRIGHT_COS = float(np.cos(np.radians(10.0)))


def upright_docks(docks: list, p: np.ndarray, q: np.ndarray, tol: float) -> list[np.ndarray]:
    """``docks`` turned about the vertical (z) only: each rotation replaced by the nearest
    turn about z (in the Frobenius norm: the turn by the angle of its upper 2x2 block's
    rotation part), its translation refitted to the centroids of ``p`` and ``q``, and kept
    where it still lands every point of ``p`` within ``tol`` of its ``q``.

    procmod strings is z-up (its edge categories tell configurations apart in the world's
    frame, up to turns about z). A dock that tilts the vertical lands the boundary parts
    where a part's own symmetry allows it (a post or a rail half-turned about a horizontal
    axis is the same post or rail) but turns the whole docked piece over: fences whose
    rails hung at the foot of their posts, posts floating off the ground, twice the edge
    categories. Docks that must tilt to land, or that tilt by more than
    :data:`UPRIGHT_COS` allows, are dropped; a least-squares dock tilted by noise in the
    centroids is set upright."""
    cp, cq = p.mean(0), q.mean(0)
    out = []
    for m in docks:
        r = m[:3, :3]
        if r[2, 2] < UPRIGHT_COS:
            # tilted by more than noise tilts a fitted dock, or turned over: dropped. Turned
            # over, its upper 2x2 block is a mirror, and the nearest turn about z an angle of
            # rounding errors, which a round boundary post lands at any angle (a review's fence
            # of 48-sided posts took rails at 155.8 and 114.1 degrees for the inputs' 17 and 38)
            continue
        angle = np.arctan2(r[1, 0] - r[0, 1], r[0, 0] + r[1, 1])
        turn = np.eye(4)
        c, s = np.cos(angle), np.sin(angle)
        turn[:2, :2] = [[c, -s], [s, c]]
        turn[:3, 3] = cq - turn[:3, :3] @ cp
        if _lands(turn, p, q, tol):
            _add_new(out, turn)
    return out


# part geometry (library-frame vertices) -> its symmetries as 4x4 maps in library coordinates
_SYMMETRIES: dict[bytes, list] = {}


def _part_symmetries(library: dict, name: str) -> list[np.ndarray]:
    from .frames import symmetry_group

    p = part_points(library, name, np.eye(4))
    key = p.tobytes()
    if key not in _SYMMETRIES:
        c = p.mean(0)
        out = []
        for r in symmetry_group(p) or [np.eye(3)]:
            m = np.eye(4)
            m[:3, :3] = r
            m[:3, 3] = c - r @ c
            out.append(m)
        _SYMMETRIES[key] = out
    return _SYMMETRIES[key]


def part_docks(library: dict, part: str, t_a: np.ndarray, t_b: np.ndarray) -> list[np.ndarray]:
    """The rigid motions ``D`` that put a part placed by ``t_a`` exactly where the same part
    placed by ``t_b`` is: ``D t_a S = t_b`` for each symmetry ``S`` of the part (its vertex
    set mapped onto itself); none when the placements differ by more than a rigid motion."""
    out = []
    inv_a = np.linalg.inv(t_a)
    for sym in _part_symmetries(library, part):
        m = t_b @ np.linalg.inv(sym) @ inv_a
        r = m[:3, :3]
        if np.abs(r @ r.T - np.eye(3)).max() <= 1e-6 and np.linalg.det(r) > 0:
            out.append(m)
    return out


DISTINCT_MODES = ("histogram", "graph")  # AugmentParams.distinct, see SeenShapes
MIN_MAX_PARTS = 120  # AugmentParams.max_parts's least default


@dataclass
class AugmentParams:
    """Constants of graph-based sampling (see docs/strings.md for why these values)."""

    tries: int = 30  # subgraph samples per attempt
    max_boundary: int = 8  # larger boundaries are skipped (matching cost grows fast)
    distance_tol: float = 1e-3  # relative to the median part diagonal
    max_subsets: int = 16  # keep/drop choices tried per docking
    # variants larger than this are not kept (docking grows shapes); None: twice the largest
    # input's parts, at least MIN_MAX_PARTS (a fixed 120 had cut a 301-part fence's variants
    # to fragments of 28-112 parts, without a word)
    max_parts: int | None = None
    # keep the rotations docking computes (False: translations only, every variant in the
    # inputs' orientation: what sampling did before off-grid sets, docs/strings.md)
    rotate: bool = True
    # docks turn about the vertical (z) only (upright_docks); False: about any axis, for a
    # set with no up (a molecule, a structure in orbit)
    upright: bool = True
    # Which variants count as duplicates: "histogram" (seed 001: any shape whose node-type
    # histogram was seen, conservative) or "graph" (only a shape whose typed shape graph is
    # isomorphic to one seen). See SeenShapes and docs/strings.md ("Sampling").
    distinct: str = "histogram"

    def __post_init__(self):
        if self.distinct not in DISTINCT_MODES:
            raise InvalidArgumentError(f"distinct must be one of {', '.join(DISTINCT_MODES)}, "
                                       f"got {self.distinct!r}")


def with_part_limit(params: AugmentParams, shapes) -> AugmentParams:
    """``params`` with ``max_parts`` set: as given, else twice the largest of ``shapes``'
    part counts, at least :data:`MIN_MAX_PARTS`."""
    if params.max_parts is not None:
        return params
    return replace(params, max_parts=max(MIN_MAX_PARTS, 2 * max((len(s) for s in shapes), default=0)))


def attempt(shape_set: ShapeSet, shape_a: Shape, shape_b: Shape, grammar: Grammar, seed,
            params: AugmentParams = AugmentParams()) -> tuple[Shape, nx.Graph] | None:
    """One sampling attempt: up to ``params.tries`` random subgraphs of ``shape_a`` docked
    into ``shape_b``; the first merged shape that validates and its (recomputed) shape
    graph, or None. Module-level and picklable, for executors."""
    params = with_part_limit(params, shape_set.shapes)
    rng = np.random.default_rng(seed)
    tol = contact_tolerance(shape_set)
    # the docking distances scale with the parts' size (the default tolerance), widened by
    # a user's larger contact tolerance: parts placed by eye that far off are off as much
    # in the distances between them, twice over (two parts), and walls of bricks jittered
    # by 0.2 mm, 0.1% of a brick, grew no variant (h119)
    default = tolerance_for(shape_set.library)
    scale = default / 1e-3 if default > 0 else 1.0
    dtol = params.distance_tol * scale + 2 * max(0.0, tol - default)
    ga, gb = shape_graph(shape_set, shape_a, tol), shape_graph(shape_set, shape_b, tol)
    ta, tb = shape_set.types(shape_a), shape_set.types(shape_b)
    ca, cb = centroids(shape_set, shape_a), centroids(shape_set, shape_b)
    for _ in range(params.tries):
        size = int(rng.integers(1, max(2, len(shape_a))))
        s = random_connected_subgraph(ga, size, rng)
        b1 = sorted({u for v in s for u in ga.neighbors(v)} - s)
        if not b1 or len(b1) > params.max_boundary:
            continue
        b2 = match_boundary(b1, ta, ca, tb, cb, dtol, rng)
        if b2 is None:
            continue
        if params.rotate:
            # where the boundary's centroids leave a rotation free, the parts' own poses fix it
            spread = np.linalg.svd(ca[b1] - ca[b1].mean(0), compute_uv=False)
            free = len(b1) == 1 or spread[1] <= dtol
            extra = part_docks(shape_set.library, shape_a.parts[b1[0]], shape_a.transforms[b1[0]],
                               shape_b.transforms[b2[0]]) \
                if free and shape_a.parts[b1[0]] == shape_b.parts[b2[0]] else []
            docks = docking_transforms(ca[b1], cb[b2], dtol, extra, fitted=not free)
            if params.upright:
                docks = upright_docks(docks, ca[b1], cb[b2], dtol)
        else:
            docks = [d for d in docking_transforms(ca[b1], cb[b2], dtol)
                     if np.allclose(d[:3, :3], np.eye(3), atol=1e-6)]
        for dock in docks:
            merged = _merge(shape_set, grammar, ga, gb, shape_a, shape_b, s, b1, b2, dock, tol, rng, params)
            if merged is not None:
                return merged
    return None


def _merge(shape_set, grammar, ga, gb, shape_a, shape_b, s, b1, b2, dock, tol, rng, params):
    s = sorted(s)
    lib = shape_set.library
    # The docked boundary must land on shape 2's boundary parts: same pose up to the part's
    # own symmetry (its vertex set), not just the same centroid.
    dtol = 10 * tol
    for u, w in zip(b1, b2):
        p = part_points(lib, shape_a.parts[u], dock @ shape_a.transforms[u])
        q = part_points(lib, shape_b.parts[w], shape_b.transforms[w])
        if np.linalg.norm(p[:, None] - q[None], axis=2).min(1).max() > dtol:
            return None
    moved = [dock @ shape_a.transforms[v] for v in s]
    rest = gb.subgraph(set(gb.nodes) - set(b2))
    components = [sorted(c) for c in nx.connected_components(rest)]
    parts = [shape_b.parts[v] for v in range(len(shape_b))] + [shape_a.parts[v] for v in s]
    transforms = list(shape_b.transforms) + moved
    nb = len(shape_b)
    # Collisions between docked s and shape 2 outside B2 force their components out.
    pairs = [(i, nb + k) for i in range(nb) if i not in set(b2) for k in range(len(s))]
    hits = contact_pairs(lib, parts, transforms, tol, pairs_of=pairs)
    hit_nodes = {i for i, _ in hits}
    forced = [c for c in components if hit_nodes & set(c)]
    free = [c for c in components if not (hit_nodes & set(c))]
    # Predicted graph edges between s and B2 mirror those between s and B1.
    s_index = {v: nb + k for k, v in enumerate(s)}
    b_map = dict(zip(b1, b2))
    cross = [(b_map[u], s_index[v]) for v in s for u in ga.neighbors(v) if u in b_map]
    inner = [(s_index[u], s_index[v]) for u, v in ga.subgraph(s).edges]
    subsets = [()]
    for r in range(1, len(free) + 1):
        subsets += list(itertools.combinations(range(len(free)), r))
        if len(subsets) >= 4 * params.max_subsets:
            break
    order = sorted(range(len(subsets)), key=lambda k: (len(subsets[k]), rng.random()))[:params.max_subsets]
    types = [shape_set.letters[p] for p in parts]
    for k in order:
        drop = set().union(*(set(c) for c in forced), *(set(free[i]) for i in subsets[k]))
        keep = [i for i in range(nb) if i not in drop] + [nb + k2 for k2 in range(len(s))]
        if len(keep) > params.max_parts:
            continue
        keep_set = set(keep)
        predicted = nx.Graph()
        predicted.add_nodes_from((i, {"type": types[i]}) for i in keep)
        predicted.add_edges_from((u, v) for u, v in gb.edges if u in keep_set and v in keep_set)
        predicted.add_edges_from(cross + inner)
        if not grammar.is_valid(predicted):
            continue
        candidate = Shape.of([parts[i] for i in keep], [transforms[i] for i in keep])
        actual = shape_graph(shape_set, candidate, tol)
        if grammar.is_valid(actual):
            return candidate, actual
    return None


class SeenShapes:
    """The duplicate test of a growing collection (``AugmentParams.distinct``).

    ``"histogram"`` is seed 001's rule: a shape is a duplicate when its node-type histogram
    was seen. It is conservative: on a set whose type counts are tied (a colonnade has one
    column per floor tile) it admits only one shape per (floor, beam) count pair, so the
    collection stops growing early. ``"graph"`` discards only shapes whose typed shape graph
    is isomorphic to one seen (Weisfeiler-Lehman hash to bucket, exact isomorphism within
    a bucket), which is what "the same shape" means to the string model: isomorphic graphs
    have the same strings.
    """

    def __init__(self, shape_set: ShapeSet, distinct: str = "histogram"):
        if distinct not in DISTINCT_MODES:
            raise InvalidArgumentError(f"distinct must be one of {', '.join(DISTINCT_MODES)}, got {distinct!r}")
        self.shape_set = shape_set
        self.distinct = distinct
        self._histograms: set = set()
        self._graphs: dict[str, list[nx.Graph]] = {}

    def add(self, shape: Shape, graph: nx.Graph | None = None) -> bool:
        """Record ``shape``; False (and nothing recorded) if it duplicates a seen one.
        ``graph``: its shape graph, if already computed (the graph rule needs it)."""
        if self.distinct == "histogram":
            key = type_histogram(self.shape_set.types(shape))
            if key in self._histograms:
                return False
            self._histograms.add(key)
            return True
        g = shape_graph(self.shape_set, shape) if graph is None else graph
        key = nx.weisfeiler_lehman_graph_hash(g, node_attr="type", iterations=3)
        bucket = self._graphs.setdefault(key, [])
        same_type = nx.algorithms.isomorphism.categorical_node_match("type", None)
        if any(nx.is_isomorphic(g, other, node_match=same_type) for other in bucket):
            return False
        bucket.append(g)
        return True


@dataclass
class AugmentResult:
    """A grown collection: the shapes (inputs first) and one row per round."""

    shapes: list
    rounds: list = field(default_factory=list)  # dicts: round, attempts, new, shapes, seconds


def augment(shape_set: ShapeSet, count: int, seed: int = 0, parallel: int = 8, max_rounds: int = 50,
            executor=None, params: AugmentParams = AugmentParams(), progress=None,
            seconds: float | None = None) -> AugmentResult:
    """Grow the set's shapes into a collection of ``count`` valid variants (inputs included).

    Parameters
    ----------
    shape_set : ShapeSet
        The input shapes (one or two) and their part library.
    count : int
        Stop when the collection holds this many shapes.
    parallel : int
        Attempts ``p`` per round (the paper keeps p linear in the processors).
    executor : concurrent.futures.Executor, optional
        Runs the attempts of a round (default: inline).
    seconds : float, optional
        Stop after this much wall time, whatever the count.
    """
    from ..parallel import InlineExecutor

    count, parallel, max_rounds = (checked_count(name, value) for name, value in
                                   (("count", count), ("parallel", parallel), ("max_rounds", max_rounds)))
    check_seed(seed)  # what numpy takes, as the engines do: a list seeds too
    if isinstance(seed, np.random.SeedSequence):  # each round's draws are seeded from [seed, round, k]
        raise InvalidArgumentError("seed must be a whole number or a sequence of them for augment, not a "
                                   "SeedSequence (give its entropy)")
    executor = executor or InlineExecutor()
    params = with_part_limit(params, shape_set.shapes)
    graphs = [shape_graph(shape_set, s) for s in shape_set.shapes]
    grammar = Grammar.from_graphs(graphs)
    shapes = list(shape_set.shapes)
    seen = SeenShapes(shape_set, params.distinct)
    for s in shapes:
        seen.add(s)
    result = AugmentResult(shapes)
    start = time.perf_counter()
    rng = np.random.default_rng(seed)
    for round_ in range(max_rounds):
        if len(shapes) >= count or (seconds is not None and time.perf_counter() - start > seconds):
            break
        pairs = [(int(rng.integers(len(shapes))), int(rng.integers(len(shapes)))) for _ in range(parallel)]
        futures = [executor.submit(attempt, shape_set, shapes[a], shapes[b], grammar, [seed, round_, k], params)
                   for k, (a, b) in enumerate(pairs)]
        new = valid = 0
        for f in futures:
            found = f.result()
            if found is None or len(shapes) >= count:
                continue
            valid += 1
            shape, graph = found
            if not seen.add(shape, graph):
                continue
            shapes.append(shape)
            new += 1
        # valid: attempts that made a shape (new or a duplicate); the rest found no valid dock
        result.rounds.append({"round": round_ + 1, "attempts": parallel, "valid": valid, "new": new,
                              "shapes": len(shapes), "seconds": round(time.perf_counter() - start, 3)})
        if progress is not None:
            progress(result.rounds[-1])
    return result
