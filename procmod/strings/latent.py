"""Latent-space sampling and search graphs (seed 001, sections 5.2-5.3).

- :func:`perturb`: decode ``z + r`` around an encoded training string, growing ``|r|``
  until a valid string different from the original comes out (or the largest step).
- :func:`interpolate`: equidistant points on the segment between two encodings, each
  perturbed as above with smaller steps.
- :func:`latent_path`: a path of exactly ``length`` points from one encoding to another,
  made by repeatedly splitting every segment at the training encoding closest to both its
  endpoints; :func:`sample_path` samples along every segment like :func:`interpolate`.
- :func:`search_graph`: valid decoded points as nodes, each joined to its ``k`` nearest
  neighbours in latent space and to every node whose string is the same graph; edge
  weights are the type-histogram metric E; interpolation is a shortest path.
- :func:`naive_graph`: the ablation of Table 2: the same over strings, neighbours by string
  similarity instead of latent distance.
"""

from __future__ import annotations

import difflib

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError
from .codec import parse
from .shapes import histogram_distance

PERTURB_STEPS = (0.05, 0.1, 0.15, 0.2, 0.25)  # the paper's maximum offset is 0.25
_SAME_POINT = 1e-9  # latent points closer than this are one point (encodings are O(1) in size)


def _types(text: str) -> list[str]:
    return [c for c in text if c.isalpha()]


def perturb(model, z0: np.ndarray, original: str | None, rng: np.random.Generator,
            steps=PERTURB_STEPS, per_step: int = 4) -> str | None:
    """A valid string decoded near ``z0`` that differs from ``original``, or None."""
    for scale in steps:
        z = z0[None, :] + scale * rng.standard_normal((per_step, z0.shape[0]))
        for s in model.decode(z, rng=rng):
            if s is not None and s != original and model.is_valid(s):
                return s
    return None


def interpolate(model, za: np.ndarray, zb: np.ndarray, points: int, rng: np.random.Generator,
                steps=(0.02, 0.05, 0.1)) -> list[str]:
    """Valid strings found on (and near) the segment from ``za`` to ``zb``."""
    out = []
    for t in np.linspace(0, 1, points):
        s = perturb(model, (1 - t) * za + t * zb, None, rng, steps, per_step=2)
        if s is not None:
            out.append(s)
    return out


def latent_path(za: np.ndarray, zb: np.ndarray, anchors: np.ndarray, length: int = 32) -> np.ndarray:
    """Seed 001's latent path: ``length`` points from ``za`` to ``zb`` (both included, first
    and last) through training encodings.

    The path starts as the segment ``[za, zb]``; each round splits every segment
    ``(a, b)`` at the training encoding (a row of ``anchors``) closest to both its
    endpoints, i.e. whose larger distance to ``a`` and ``b`` is smallest, so 2 points
    become 3, 5, 9, 17, 33. Only encodings not on the path yet are used (the endpoints are
    usually training encodings themselves), each at most once. The last round splits only
    as many segments as ``length`` still needs, the longest first, so the path has exactly
    ``length`` points (seed 001 uses 32; a path of ``2^k + 1`` points needs no partial round).

    Raises
    ------
    InvalidArgumentError
        If ``length`` is below 2, or ``anchors`` holds fewer than ``length - 2`` points
        off the path's ends.
    """
    if length < 2:
        raise InvalidArgumentError(f"a latent path has at least its 2 endpoints; got length {length}")
    anchors = np.asarray(anchors, dtype=float)
    path = [np.asarray(za, dtype=float), np.asarray(zb, dtype=float)]
    # encodings at the endpoints (or repeated) would give zero-length segments: not candidates
    free = np.ones(len(anchors), dtype=bool)
    for p in path:
        free &= np.linalg.norm(anchors - p, axis=1) > _SAME_POINT
    if free.sum() < length - 2:
        raise InvalidArgumentError(f"a latent path of {length} points needs {length - 2} training encodings "
                                   f"besides its endpoints; got {int(free.sum())} (ask for a shorter path or "
                                   "give more anchors)")
    while len(path) < length:
        segments = list(zip(path[:-1], path[1:]))
        split = set(range(len(segments)))
        if len(path) + len(segments) > length:  # the last round: the longest segments only
            by_length = sorted(range(len(segments)), key=lambda k: -np.linalg.norm(segments[k][1] - segments[k][0]))
            split = set(by_length[:length - len(path)])
        new = [path[0]]
        for k, (a, b) in enumerate(segments):
            if k in split:
                far = np.maximum(np.linalg.norm(anchors - a, axis=1), np.linalg.norm(anchors - b, axis=1))
                far[~free] = np.inf
                pick = int(np.argmin(far))
                new.append(anchors[pick])
                # used once; its duplicates would repeat the point
                free &= np.linalg.norm(anchors - anchors[pick], axis=1) > _SAME_POINT
            new.append(b)
        path = new
    return np.array(path)


def sample_path(model, path: np.ndarray, per_segment: int, rng: np.random.Generator) -> list[str]:
    out = []
    for a, b in zip(path[:-1], path[1:]):
        out += interpolate(model, a, b, per_segment, rng)
    return out


def same_graph(a: str, b: str) -> bool:
    ga, gb = parse(a).graph, parse(b).graph
    if ga.number_of_nodes() != gb.number_of_nodes() or ga.number_of_edges() != gb.number_of_edges():
        return False
    return nx.is_isomorphic(ga, gb, node_match=lambda x, y: x["type"] == y["type"])


def _graph_key(text: str) -> str:
    g = parse(text).graph
    return nx.weisfeiler_lehman_graph_hash(g, node_attr="type", iterations=4)


def _add_equivalents(g: nx.Graph, strings: list[str]) -> None:
    groups: dict[str, list[int]] = {}
    for i, s in enumerate(strings):
        groups.setdefault(_graph_key(s), []).append(i)
    for members in groups.values():
        for x in range(len(members)):
            for y in range(x + 1, len(members)):
                i, j = members[x], members[y]
                if strings[i] == strings[j] or same_graph(strings[i], strings[j]):
                    g.add_edge(i, j, weight=0.0)


def search_graph(z: np.ndarray, strings: list[str], k: int = 3) -> nx.Graph:
    """Seed 001's latent search graph: kNN in latent space + equivalent strings, weights E."""
    g = nx.Graph()
    g.add_nodes_from(range(len(strings)))
    d = np.linalg.norm(z[:, None] - z[None], axis=2)
    np.fill_diagonal(d, np.inf)
    for i in range(len(strings)):
        for j in np.argsort(d[i])[:k]:
            g.add_edge(i, int(j))
    _add_equivalents(g, strings)
    for i, j in g.edges:
        g.edges[i, j]["weight"] = histogram_distance(_types(strings[i]), _types(strings[j]))
    return g


def naive_graph(strings: list[str], k: int = 3) -> nx.Graph:
    """The ablation: kNN by string similarity (difflib ratio) + equivalent strings, weights E."""
    g = nx.Graph()
    g.add_nodes_from(range(len(strings)))
    for i, s in enumerate(strings):
        m = difflib.SequenceMatcher(autojunk=False)
        m.set_seq2(s)
        sims = []
        for j, t in enumerate(strings):
            if j != i:
                m.set_seq1(t)
                sims.append((-m.ratio(), j))
        for _, j in sorted(sims)[:k]:
            g.add_edge(i, j)
    _add_equivalents(g, strings)
    for i, j in g.edges:
        g.edges[i, j]["weight"] = histogram_distance(_types(strings[i]), _types(strings[j]))
    return g


def path_statistics(g: nx.Graph, pairs: int, rng: np.random.Generator) -> dict:
    """Connected components, and the average / max accumulated weight of shortest paths
    between random node pairs in the same component (Table 2)."""
    comps = list(nx.connected_components(g))
    index = {v: c for c, comp in enumerate(comps) for v in comp}
    nodes = sorted(g.nodes)
    weights = []
    tries = 0
    while len(weights) < pairs and tries < 20 * pairs:
        tries += 1
        a, b = (nodes[int(i)] for i in rng.integers(len(nodes), size=2))
        if a == b or index[a] != index[b]:
            continue
        weights.append(nx.shortest_path_length(g, a, b, weight="weight"))
    return {"nodes": g.number_of_nodes(), "edges": g.number_of_edges(), "components": len(comps),
            "avg_weight": float(np.mean(weights)) if weights else 0.0,
            "max_weight": float(np.max(weights)) if weights else 0.0, "paths": len(weights)}


def one_per_graph(strings, graph_of) -> list:
    """The first of ``strings`` for each distinct typed graph (``graph_of(string)``): one
    shape however its string is written (``T(t(T))`` and ``t(T)T``)."""
    kept, seen = [], GraphIndex()
    for s in dict.fromkeys(strings):
        graph = graph_of(s)
        if graph not in seen:
            seen.add(graph)
            kept.append(s)
    return kept


class GraphIndex:
    """Typed graphs indexed by Weisfeiler-Lehman hash, for "is this graph new?" checks
    (exact isomorphism with node types within a hash bucket)."""

    def __init__(self, graphs=()):
        self.buckets: dict[str, list] = {}
        for g in graphs:
            self.add(g)

    @staticmethod
    def _key(g) -> str:
        return nx.weisfeiler_lehman_graph_hash(g, node_attr="type", iterations=4)

    def add(self, g) -> None:
        self.buckets.setdefault(self._key(g), []).append(g)

    def __contains__(self, g) -> bool:
        return any(nx.is_isomorphic(g, h, node_match=lambda a, b: a["type"] == b["type"])
                   for h in self.buckets.get(self._key(g), []))
