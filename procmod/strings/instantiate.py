"""Instantiation of shape graphs (seed 001, section 6).

1. **Local frames** by the extremal-point ("diagonal") method: the vertex ``v`` farthest
   from the centre of gravity, the vertex ``w`` farthest from ``v``, the vertex ``u``
   farthest from the line ``vw``; tied vertices are averaged, and when the average
   collapses (a box's corners all tie) the tied vertex listed first in the part library
   is taken, which keeps the frame attached to the part however it is placed.
2. **Edge categories**: per pair of node types, the relative poses of neighbours (one
   part's frame seen from the other's) are clustered by mean shift (scikit-learn);
   same-type pairs take the unordered pair of both directions' clusters.
3. A **tagger** (bidirectional recurrent net + linear layer) maps a string to one category
   per character (a dummy one for brackets, bonds and the root); logits of categories the
   edge's type pair does not have are set to -inf. A string's labels are decoded jointly
   (:mod:`procmod.strings.decoding`: every part's star of categories seen in training,
   every ring closed), then several strings of one graph vote.
4. **Instantiation**: from a random edge, parts are added by transplanting a relative
   transform seen in the training shapes for the edge's category; a part that collides
   with placed non-neighbours, misses a placed neighbour, sits at a pose no example shows,
   or leaves a placed part it must still join out of reach, is retried with other examples
   of the category, then of the other voted categories, then (Monte Carlo fallback) of any
   category of that type pair; when none fits, the search backjumps to the placed part the
   failures were owed to (see :func:`instantiate_graph`).
"""

from __future__ import annotations

import heapq
import json
import os
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import networkx as nx
import numpy as np
import torch
from torch import nn

from ..core.errors import InvalidArgumentError
from ..core.serialize import write_text_atomic
from .codec import encode_with_order, parse
from .decoding import CategoryDecoder, star_set
from .shapes import (Shape, ShapeSet, contact_pairs, first_poses, part_points, shape_graph, tolerance_for,
                     type_automorphisms)
from .vae import ModelFileError, Vocab, cpu_state, torch_threads, training_device

# ---------------------------------------------------------------------------------------------
# Local frames


def _extreme(points: np.ndarray, dist: np.ndarray, eps: float) -> np.ndarray:
    """The average of the points at maximal ``dist``; the first of them if they average out."""
    top = np.nonzero(dist >= dist.max() - eps)[0]
    return points[top].mean(0), points[top[0]]


def local_frame(points: np.ndarray, eps_rel: float = 1e-5) -> np.ndarray:
    """A rigid 4x4 frame (origin = vertex mean) from a part's world vertices, by the
    extremal-point method (see the module docstring)."""
    p = np.asarray(points, dtype=np.float64)
    c = p.mean(0)
    scale = max(float(np.linalg.norm(p - c, axis=1).max()), 1e-12)
    eps = eps_rel * scale
    avg, first = _extreme(p, np.linalg.norm(p - c, axis=1), eps)
    v = avg if np.linalg.norm(avg - c) > 1e-3 * scale else first
    avg, first = _extreme(p, np.linalg.norm(p - v, axis=1), eps)
    w = avg if np.linalg.norm(avg - v) > 1e-3 * scale else first
    a1 = (w - v) / max(np.linalg.norm(w - v), 1e-12)
    rel = p - v
    foot = v + np.outer(rel @ a1, a1)
    off = np.linalg.norm(p - foot, axis=1)
    avg, first = _extreme(p, off, eps)
    u = avg if np.linalg.norm(avg - (v + ((avg - v) @ a1) * a1)) > 1e-3 * scale else first
    a2 = u - (v + ((u - v) @ a1) * a1)
    if np.linalg.norm(a2) < 1e-9 * scale:  # all points on one line: any perpendicular
        a2 = np.cross(a1, [1.0, 0.0, 0.0] if abs(a1[0]) < 0.9 else [0.0, 1.0, 0.0])
    a2 /= np.linalg.norm(a2)
    a3 = np.cross(a1, a2)
    f = np.eye(4)
    f[:3, 0], f[:3, 1], f[:3, 2], f[:3, 3] = a1, a2, a3, c
    return f


def _candidate_rotations() -> list[np.ndarray]:
    """The 24 rotations of the cube, each also composed with quarter-of-a-quarter turns
    (45 degrees) about z: the symmetries :func:`symmetry_group` looks for."""
    mats = []
    for perm in ((0, 1, 2), (1, 2, 0), (2, 0, 1), (1, 0, 2), (0, 2, 1), (2, 1, 0)):
        for signs in np.ndindex(2, 2, 2):
            m = np.zeros((3, 3))
            for r, c in enumerate(perm):
                m[r, c] = 1 - 2 * signs[r]
            if np.linalg.det(m) > 0:
                mats.append(m)
    out = []
    for k in range(8):
        c, s_ = np.cos(k * np.pi / 4), np.sin(k * np.pi / 4)
        rz = np.array([[c, -s_, 0], [s_, c, 0], [0, 0, 1]])
        out += [rz @ m for m in mats]
    uniq = []
    for m in out:
        if not any(np.allclose(m, u, atol=1e-9) for u in uniq):
            uniq.append(m)
    return uniq


_CANDIDATES = None


def symmetry_group(local_points: np.ndarray, rel_tol: float = 1e-4) -> list[np.ndarray]:
    """Rotations (about the vertex mean, in the part's library frame) that map its vertex
    set onto itself, among the cube's and 45-degree turns about z (boxes, prisms, cylinders)."""
    global _CANDIDATES
    if _CANDIDATES is None:
        _CANDIDATES = _candidate_rotations()
    p = np.asarray(local_points, dtype=np.float64)
    p = p - p.mean(0)
    tol = rel_tol * max(float(np.linalg.norm(p, axis=1).max()), 1e-12)
    group = []
    for r in _CANDIDATES:
        q = p @ r.T
        if np.linalg.norm(q[:, None] - p[None], axis=2).min(1).max() <= tol:
            group.append(r)
    return group


def canonical_frame(library: dict, name: str, transform: np.ndarray, groups: dict) -> np.ndarray:
    """The extremal-point frame of a placed part, turned by the part's own symmetry to the
    equivalent frame closest to the world axes (so a symmetric part gets the same frame
    however it was turned into place). ``groups`` caches each part's symmetries."""
    f = local_frame(part_points(library, name, transform))
    group = groups.get(name)
    if group is None:
        local = part_points(library, name, np.eye(4))
        r_local = local_frame(local)[:3, :3]
        # A symmetry S of the part turns its frame R_L into S R_L: in frame terms R_L^T S R_L.
        group = groups[name] = [r_local.T @ sym @ r_local for sym in symmetry_group(local)] or [np.eye(3)]
    # The closest to the world axes (largest trace); ties broken by the rounded entries, so
    # the choice depends only on the set of equivalent frames, not on how the part was turned.
    best, best_score = f, None
    for g in group:
        rot = _orthonormal(f[:3, :3] @ g)
        score = (round(float(np.trace(rot)), 6), tuple(np.round(rot, 6).reshape(9).tolist()))
        if best_score is None or score > best_score:
            best_score = score
            best = f.copy()
            best[:3, :3] = rot
    return best


def _rigid_inverse(f: np.ndarray) -> np.ndarray:
    out = np.eye(4)
    out[:3, :3] = f[:3, :3].T
    out[:3, 3] = -f[:3, :3].T @ f[:3, 3]
    return out


def _orthonormal(m: np.ndarray) -> np.ndarray:
    u, _, vt = np.linalg.svd(m)
    return u @ vt


def _pose_feature(fa: np.ndarray, fb: np.ndarray, length: float, rot_weight: float) -> np.ndarray:
    rel = np.linalg.inv(fa) @ fb
    return np.concatenate([rel[:3, 3] / length, rot_weight * rel[:3, :3].reshape(9)])


# ---------------------------------------------------------------------------------------------
# Edge categories


@dataclass
class CategoryParams:
    bandwidth: float = 0.15  # mean-shift bandwidth in units of the median part diagonal
    rot_weight: float = 0.5  # weight of the rotation entries against normalised offsets
    examples_per_category: int = 24


class EdgeCategories:
    """Edge categories per type pair, fitted on shapes; the relative transforms that
    realise each category, for transplanting.

    ``names[k]`` = ``(A, B, key)`` for category ``k >= 1`` (``A <= B``); category 0 is the
    dummy of characters that stand for no edge. ``clearance[(A, B)]`` (``A <= B``): the
    smallest distance between the frame origins of two parts of those types that are *not*
    neighbours, over the fitted shapes (:func:`part_clearances`; None for categories saved
    before it was kept).
    """

    def __init__(self, names, centres, examples, length, params: CategoryParams,
                 clearance: dict | None = None):
        self.names = [tuple(n) if n is not None else None for n in names]
        self.centres = centres  # (A, B) -> cluster centres (k, 12)
        self.examples = examples  # category -> list of 4x4 (A-part -> B-part relative transforms)
        self.length = length
        self.params = params
        self.clearance = clearance
        self.groups: dict = {}  # part name -> symmetry rotations in frame terms (cache)
        self.index = {n: k for k, n in enumerate(self.names) if n is not None}
        self.by_pair: dict[tuple, list[int]] = {}
        for k, n in enumerate(self.names):
            if n is not None:
                self.by_pair.setdefault((n[0], n[1]), []).append(k)

    def __len__(self) -> int:
        return len(self.names)

    # -- fitting ------------------------------------------------------------------------------

    @staticmethod
    def fit(shape_set: ShapeSet, shapes, graphs, params: CategoryParams = CategoryParams(),
            symmetric: bool = True) -> "EdgeCategories":
        """Cluster the relative poses of neighbours in ``shapes`` (and, when ``symmetric``,
        in their copies turned by :func:`world_symmetries`)."""
        from sklearn.cluster import MeanShift

        clearance = part_clearances(shape_set, shapes, graphs)  # turns and mirrors keep distances
        if symmetric:
            pairs = [(c, g) for s, g in zip(shapes, graphs) for c in symmetric_copies(s, shape_set.library)
                     if c is not None]
            shapes, graphs = [c for c, _ in pairs], [g for _, g in pairs]

        lib = shape_set.library
        diag = [float(np.linalg.norm(np.subtract(*s.local_bounds()[::-1]))) for s in lib.values()]
        length = float(np.median(diag))
        groups: dict = {}
        per_pair: dict[tuple, list] = {}  # (A, B) -> rows (feature, shape, a, b) with a of type A
        for si, (shape, g) in enumerate(zip(shapes, graphs)):
            frames = [canonical_frame(lib, p, t, groups) for p, t in zip(shape.parts, shape.transforms)]
            for a, b in g.edges:
                ta, tb = g.nodes[a]["type"], g.nodes[b]["type"]
                for x, y in ((a, b), (b, a)) if ta == tb else (((a, b),) if ta < tb else ((b, a),)):
                    f = _pose_feature(frames[x], frames[y], length, params.rot_weight)
                    per_pair.setdefault((g.nodes[x]["type"], g.nodes[y]["type"]), []).append((f, si, x, y))
        centres = {}
        labels_of: dict[tuple, np.ndarray] = {}
        for pair, rows in sorted(per_pair.items()):
            feats = np.array([r[0] for r in rows])
            uniq, inverse = np.unique(np.round(feats, 4), axis=0, return_inverse=True)
            ms = MeanShift(bandwidth=params.bandwidth, bin_seeding=False).fit(uniq)
            centres[pair] = ms.cluster_centers_
            labels_of[pair] = ms.labels_[inverse.reshape(-1)]
        names: list = [None]
        examples: dict[int, list] = {}
        index: dict[tuple, int] = {}
        assignments = {}  # (shape, a, b) sorted pair -> category
        for pair, rows in sorted(per_pair.items()):
            labels = labels_of[pair]
            if pair[0] != pair[1]:
                keyed = [((int(l),), r) for l, r in zip(labels, rows)]
            else:
                both: dict[tuple, dict] = {}
                for l, r in zip(labels, rows):
                    both.setdefault((r[1], min(r[2], r[3]), max(r[2], r[3])), {})[(r[2], r[3])] = (int(l), r)
                keyed = []
                for (si, lo, hi), d in both.items():
                    (l1, r1), (l2, _) = d[(lo, hi)], d[(hi, lo)]
                    keyed.append(((min(l1, l2), max(l1, l2)), r1))
            for key, r in keyed:
                name = (pair[0], pair[1], "-".join(map(str, key)))
                if name not in index:
                    index[name] = len(names)
                    names.append(name)
                k = index[name]
                _, si, x, y = r
                assignments[(si, min(x, y), max(x, y))] = k
                ex = examples.setdefault(k, [])
                if len(ex) < 4 * params.examples_per_category:
                    shape = shapes[si]
                    fx = canonical_frame(lib, shape.parts[x], shape.transforms[x], groups)
                    fy = canonical_frame(lib, shape.parts[y], shape.transforms[y], groups)
                    # each part's transform in the other's canonical frame (A -> B, B -> A)
                    ax = shape.transforms[x].copy()
                    ax[:3, 3] = 0.0  # how the A part was turned (for symmetry_permutations)
                    ex.append(np.stack([_rigid_inverse(fx) @ shape.transforms[y],
                                        _rigid_inverse(fy) @ shape.transforms[x], ax]))
        for k, ex in examples.items():
            kept, keys = [], set()
            for m in ex:  # distinct examples, kept at full precision (frames of them must tie exactly)
                key = tuple(np.round(m, 5).reshape(-1).tolist())
                if key not in keys and len(kept) < params.examples_per_category:
                    keys.add(key)
                    kept.append(m)
            examples[k] = kept
        cats = EdgeCategories(names, centres, examples, length, params, clearance)
        cats._fit_assignments = assignments
        return cats

    def edge_categories(self, shape_set: ShapeSet, shape: Shape, g: nx.Graph) -> dict:
        """Category of every edge of a shape: ``{(min, max): k}`` (nearest cluster centre)."""
        lib = shape_set.library
        frames = [canonical_frame(lib, p, t, self.groups) for p, t in zip(shape.parts, shape.transforms)]
        out = {}
        for a, b in g.edges:
            k = self.category_of_frames(frames[a], frames[b], g.nodes[a]["type"], g.nodes[b]["type"])
            if k is not None:
                out[(min(a, b), max(a, b))] = k
        return out

    def category_of_frames(self, fa: np.ndarray, fb: np.ndarray, ta: str, tb: str,
                           seen_only: bool = False) -> int | None:
        """Category of two neighbours of types ``ta``, ``tb`` with canonical frames ``fa``,
        ``fb`` (the nearest cluster centre of their relative pose), or None when their type
        pair has no categories; with ``seen_only`` also None when that centre is farther than
        one bandwidth (the pose is not one of the category's: :meth:`pose_seen`)."""
        if ta > tb:
            fa, fb, ta, tb = fb, fa, tb, ta
        forward = self._pose_distances(fa, fb, ta, tb)
        if forward is None:
            return None
        near = int(np.argmin(forward))
        if seen_only and forward[near] > self.params.bandwidth:
            return None
        key = (near,) if ta != tb else tuple(sorted((near, int(np.argmin(self._pose_distances(fb, fa, tb, ta))))))
        return self.index.get((ta, tb, "-".join(map(str, key))))

    def _pose_distances(self, fa: np.ndarray, fb: np.ndarray, ta: str, tb: str) -> np.ndarray | None:
        """Distances of ``b``'s pose in ``a``'s frame to the cluster centres of the type pair
        ``(ta, tb)``, ``ta <= tb`` (None: the pair has no categories)."""
        centres = self.centres.get((ta, tb))
        if centres is None:
            return None
        return np.linalg.norm(centres - _pose_feature(fa, fb, self.length, self.params.rot_weight), axis=1)

    def _category_of_pair(self, shape_set: ShapeSet, pa: str, ma: np.ndarray, pb: str, mb: np.ndarray):
        lib = shape_set.library
        fa, fb = canonical_frame(lib, pa, ma, self.groups), canonical_frame(lib, pb, mb, self.groups)
        return self.category_of_frames(fa, fb, shape_set.letters[pa], shape_set.letters[pb])

    def symmetry_permutations(self, shape_set: ShapeSet) -> list[dict]:
        """For each of :func:`world_symmetries`, where it sends each category (turning an
        example edge of the category and classifying it again)."""
        if getattr(self, "_perms", None) is not None:
            return self._perms
        part_of = shape_set.part_of_letter
        perms = []
        for g in world_symmetries():
            perm = {0: 0}
            for k, name in enumerate(self.names):
                if name is None or not self.examples.get(k):
                    continue
                pa, pb = part_of[name[0]], part_of[name[1]]
                rel_ab, _, ma = self.examples[k][0]
                mb = canonical_frame(shape_set.library, pa, ma, self.groups) @ rel_ab
                ga = proper_placement(shape_set.library, pa, g @ ma, _MIRROR_CACHE)
                gb = proper_placement(shape_set.library, pb, g @ mb, _MIRROR_CACHE)
                perm[k] = None if ga is None or gb is None else self._category_of_pair(shape_set, pa, ga, pb, gb)
            perms.append(perm)
        self._perms = perms
        return perms

    def pose_seen(self, fa: np.ndarray, fb: np.ndarray, ta: str, tb: str) -> bool:
        """Is ``b``'s pose in ``a``'s frame within one bandwidth of a cluster for its type pair?"""
        if ta > tb:
            fa, fb, ta, tb = fb, fa, tb, ta
        dist = self._pose_distances(fa, fb, ta, tb)
        return dist is not None and float(dist.min()) <= self.params.bandwidth

    def allowed(self, ta: str, tb: str) -> list[int]:
        return self.by_pair.get((min(ta, tb), max(ta, tb)), [])

    def to_json(self) -> dict:
        out = {"names": [list(n) if n else None for n in self.names],
               "centres": {f"{a}|{b}": c.tolist() for (a, b), c in self.centres.items()},
               "examples": {str(k): [m.tolist() for m in v] for k, v in self.examples.items()},
               "length": self.length, "params": asdict(self.params)}
        if self.clearance is not None:
            out["clearance"] = {f"{a}|{b}": d for (a, b), d in sorted(self.clearance.items())}
        return out

    @staticmethod
    def from_json(data) -> "EdgeCategories":
        centres = {tuple(k.split("|")): np.asarray(v) for k, v in data["centres"].items()}
        examples = {int(k): [np.asarray(m) for m in v] for k, v in data["examples"].items()}
        clearance = data.get("clearance")  # absent in categories fitted before it was kept
        if clearance is not None:
            clearance = {tuple(k.split("|")): float(d) for k, d in clearance.items()}
        return EdgeCategories(data["names"], centres, examples, data["length"], CategoryParams(**data["params"]),
                              clearance)


def part_clearances(shape_set: ShapeSet, shapes, graphs) -> dict[tuple[str, str], float]:
    """Per type pair ``(A, B)`` (letters, ``A <= B``), the smallest distance between the
    frame origins (vertex means) of two parts of those types that are not neighbours in
    their shape's graph, over ``shapes``. Structured decoding counts a labelling that puts
    two such parts closer as a fault: it places a part where the generator never put one
    (e.g. two columns on one spot after a wrong turn). Pairs never seen apart are absent."""
    lib = shape_set.library
    out: dict[tuple[str, str], float] = {}
    centre_of: dict = {}  # part name -> vertex mean in the part's own coordinates
    for shape, g in zip(shapes, graphs):
        n = len(shape.parts)
        if n < 2:
            continue
        for p in set(shape.parts):
            if p not in centre_of:
                centre_of[p] = part_points(lib, p, np.eye(4)).mean(0)
        centres = np.array([t[:3, :3] @ centre_of[p] + t[:3, 3] for p, t in zip(shape.parts, shape.transforms)])
        dist = np.linalg.norm(centres[:, None] - centres[None], axis=2)
        apart = ~np.eye(n, dtype=bool)
        for a, b in g.edges:
            apart[a, b] = apart[b, a] = False
        letters = np.array([shape_set.letters[p] for p in shape.parts])
        kinds = sorted(set(letters.tolist()))
        for i, a in enumerate(kinds):
            for b in kinds[i:]:
                pick = apart & np.outer(letters == a, letters == b)
                if pick.any():
                    d = float(dist[pick].min())
                    if d < out.get((a, b), np.inf):
                        out[(a, b)] = d
    return out


# ---------------------------------------------------------------------------------------------
# Tagger


@dataclass
class TaggerConfig:
    cell: str = "lstm"
    embed: int = 32
    hidden: int = 128
    layers: int = 1
    epochs: int = 24
    batch: int = 32
    lr: float = 5e-3
    # learning rate at the last epoch, as a fraction of ``lr`` (cosine in between; 1: constant).
    # The loss plateaus at a constant rate (castle, 288 shapes: 86% training accuracy with 96
    # hidden units; 97% with 128 and a decay to 0.05, held-out 83% -> 89%).
    lr_final: float = 0.05
    dropout: float = 0.1  # between recurrent layers and before the output layer
    symmetric_loss: bool = True  # loss against the closest of a string's symmetric target sequences
    tree: bool = True  # a top-down pass along the spanning tree before the string pass
    # rounds of message passing over the string's graph (tree and ring edges) after the
    # string pass (0: none, as in taggers saved before this option existed). Held-out
    # accuracy per character at 360 shapes, 0 -> 3 rounds: castle 89% -> 94%, moon base
    # 81% -> 89% (docs/strings.md).
    graph_rounds: int = 3


class Tagger(nn.Module):
    """Recurrent tagger: characters -> category logits per character.

    With ``config.tree`` (the default) a GRU cell first runs *down the spanning tree the
    string writes*: a letter's state is computed from its tree parent's state (not from the
    previous character), so what an edge's category depends on along the path from the
    root (which way the walls run after three corners) is a short recurrence, however many
    branches the string wrote in between. A bidirectional LSTM then runs over the string
    (embedding + tree state) for context from anywhere in the string; the output layer sees
    the string state of the character and of both ends of its edge (a ring label's edge
    ends are far apart in the string). Without ``tree`` it is a plain bidirectional LSTM.
    """

    def __init__(self, vocab_size: int, categories: int, config: TaggerConfig):
        super().__init__()
        self.config = config
        self.embedding = nn.Embedding(vocab_size, config.embed, padding_idx=0)
        kind = nn.LSTM if config.cell == "lstm" else nn.GRU
        rnn_in = config.embed
        if config.tree:
            self.tree_cell = nn.GRUCell(config.embed, config.hidden)
            rnn_in += config.hidden
        self.rnn = kind(rnn_in, config.hidden, num_layers=config.layers, batch_first=True, bidirectional=True,
                        dropout=config.dropout if config.layers > 1 else 0.0)
        self.drop = nn.Dropout(config.dropout)
        if config.graph_rounds:
            if not config.tree:
                raise InvalidArgumentError("graph_rounds needs the tree tagger: use tree=True, or "
                                           "graph_rounds=0 for the plain bidirectional LSTM")
            self.message = nn.Linear(2 * config.hidden, 2 * config.hidden)
            self.graph_cell = nn.GRUCell(2 * config.hidden, 2 * config.hidden)
        self.out = nn.Linear((6 if config.tree else 2) * config.hidden, categories)

    def forward(self, tokens: torch.Tensor, mask: torch.Tensor, structure: torch.Tensor | None = None) -> torch.Tensor:
        """Masked logits ``(B, T, K)``: -inf where ``mask`` is False. ``structure`` ``(B, T, 3)``
        (from :func:`string_structure`, needed with ``config.tree``): per character, 1 + the
        position of its tree parent's letter and of the letters at both ends of its edge (0: none)."""
        emb = self.embedding(tokens)
        if not self.config.tree:
            h, _ = self.rnn(emb)
            return self.out(self.drop(h)).masked_fill(~mask, float("-inf"))
        if structure is None:
            raise InvalidArgumentError("the tree tagger needs the strings' structure (string_structure)")
        b, t = tokens.shape
        rows = torch.arange(b, device=tokens.device)
        tree = self._tree_states(emb, structure)
        h, _ = self.rnn(torch.cat([emb, tree], dim=2))
        g = self._graph_states(h, structure) if self.config.graph_rounds else h
        g = torch.cat([g.new_zeros((b, 1, g.shape[2])), g], dim=1)  # slot 0: no letter
        ends = [g[rows[:, None], structure[:, :, k]] for k in (1, 2)]
        feats = torch.cat([h] + ends, dim=2)
        return self.out(self.drop(feats)).masked_fill(~mask, float("-inf"))

    def _graph_states(self, h: torch.Tensor, structure: torch.Tensor) -> torch.Tensor:
        """``config.graph_rounds`` rounds of gated message passing over the graph the string
        writes (every letter a node; tree and ring edges both ways): each letter's state
        becomes a GRU update of its string state by the mean of its neighbours' messages.
        The string pass sees a ring neighbour or a sibling only through the characters
        between them; here a part sees its graph neighbourhood (radius = rounds) directly,
        the same for every string of the graph."""
        b, t, d = h.shape
        ends = structure[:, :, 1:].cpu().numpy()  # 1 + positions of both ends of each character's edge
        rows, cols = np.nonzero(ends[:, :, 0] > 0)
        # (row, end, end) per edge; a set, since a ring edge has two characters
        pairs = {(int(r), int(ends[r, c, 0]) - 1, int(ends[r, c, 1]) - 1) for r, c in zip(rows, cols)}
        if not pairs:
            return h
        arr = np.array(sorted(pairs), dtype=np.int64)
        src = np.concatenate([arr[:, 0] * t + arr[:, 1], arr[:, 0] * t + arr[:, 2]])
        dst = np.concatenate([arr[:, 0] * t + arr[:, 2], arr[:, 0] * t + arr[:, 1]])
        dev = h.device
        src_t, dst_t = torch.from_numpy(src).to(dev), torch.from_numpy(dst).to(dev)
        degree = np.bincount(dst, minlength=b * t).astype(np.float32)
        node_ids = np.nonzero(degree)[0]
        nodes = torch.from_numpy(node_ids).to(dev)
        inv_degree = torch.from_numpy(1.0 / degree[node_ids])[:, None].to(dev)
        flat = h.reshape(b * t, d)
        for _ in range(self.config.graph_rounds):
            msg = flat.new_zeros((b * t, d)).index_add_(0, dst_t, self.message(flat)[src_t])
            updated = self.graph_cell(msg[nodes] * inv_degree, flat[nodes])
            flat = flat.index_copy(0, nodes, updated)
        return flat.reshape(b, t, d)

    def _tree_states(self, emb: torch.Tensor, structure: torch.Tensor) -> torch.Tensor:
        """GRU states down the spanning tree ``(B, T, hidden)``, one tree level at a time
        (a character's parent is always one level up), so the cost is linear in the length."""
        b, t, _ = emb.shape
        dev = emb.device
        parent = structure[:, :, 0].cpu().numpy()  # 1 + parent position, 0: none
        depth = np.zeros((b, t), dtype=np.int64)
        for i in range(t):  # parents come before children in the string
            has = parent[:, i] > 0
            depth[has, i] = depth[np.nonzero(has)[0], parent[has, i] - 1] + 1
        flat_emb = emb.reshape(b * t, -1)
        row_of = np.zeros(b * t, dtype=np.int64)  # flat position -> row in its level's output
        outs, flats = [], []
        prev = None
        for d in range(int(depth.max()) + 1 if t else 0):
            bs, js = np.nonzero(depth == d)
            flat = bs * t + js
            row_of[flat] = np.arange(len(flat))
            x = flat_emb[torch.from_numpy(flat).to(dev)]
            if d == 0:
                h = x.new_zeros((len(flat), self.config.hidden))
            else:
                h = prev[torch.from_numpy(row_of[bs * t + parent[bs, js] - 1]).to(dev)]
            prev = self.tree_cell(x, h)
            outs.append(prev)
            flats.append(flat)
        states = torch.cat(outs)
        order = torch.from_numpy(np.concatenate(flats)).to(dev)
        return emb.new_zeros((b * t, self.config.hidden)).index_copy(0, order, states).reshape(b, t, -1)


def string_structure(text: str) -> np.ndarray:
    """Per character ``(T, 3)``: 1 + the string position of the letter of its tree parent
    (letters) or of the atom it follows (other characters), and of the letters at the two
    ends of the edge it stands for; 0 where there is none."""
    parsed = parse(text)
    pos = {v: i for i, v in enumerate(parsed.char_nodes) if v is not None}
    out = np.zeros((len(text), 3), dtype=np.int64)
    atom = None
    depth_atoms: list = []
    for i, c in enumerate(text):
        node = parsed.char_nodes[i]
        e = parsed.char_edges[i]
        if node is not None:
            if e is not None:
                out[i, 0] = pos[e[0]] + 1
            atom = node
        elif c == "(":
            depth_atoms.append(atom)
        elif c == ")":
            atom = depth_atoms.pop() if depth_atoms else atom
        if node is None and atom is not None:
            out[i, 0] = pos[atom] + 1
        if e is not None:
            out[i, 1], out[i, 2] = pos[e[0]] + 1, pos[e[1]] + 1
    return out


def string_mask(text: str, categories: EdgeCategories) -> tuple[np.ndarray, list]:
    """Allowed categories per character ``(T, K)`` and each character's edge (or None)."""
    parsed = parse(text)
    types = [parsed.graph.nodes[v]["type"] for v in parsed.graph.nodes]
    mask = np.zeros((len(text), len(categories)), dtype=bool)
    for i, e in enumerate(parsed.char_edges):
        allowed = categories.allowed(types[e[0]], types[e[1]]) if e is not None else []
        if e is None or not allowed:
            mask[i, 0] = True
        else:
            mask[i, allowed] = True
    return mask, list(parsed.char_edges)


def world_symmetries() -> list[np.ndarray]:
    """The 8 quarter turns of a whole shape about the vertical (z) axis, with and without a
    mirror in x: moves a string cannot tell apart (mirrors apply to shapes whose parts are
    mirror-symmetric, see :func:`proper_placement`)."""
    out = []
    for mirror in (1.0, -1.0):
        for k in range(4):
            c, s_ = [(1, 0), (0, 1), (-1, 0), (0, -1)][k]
            m = np.eye(4)
            m[:2, :2] = [[c, -s_], [s_, c]]
            out.append(m @ np.diag([mirror, 1.0, 1.0, 1.0]))
    return out


_MIRROR = np.diag([-1.0, 1.0, 1.0, 1.0])


def proper_placement(library: dict, name: str, m: np.ndarray, cache: dict) -> np.ndarray | None:
    """``m`` if it turns without mirroring; else the proper transform that puts the part's
    points in the same place (``m`` times a mirror of the part in its own x), when the part
    is mirror-symmetric; None when it is not (a mirrored copy would need a mirrored part)."""
    if np.linalg.det(m[:3, :3]) > 0:
        return m
    key = ("mirror", name)
    if key not in cache:
        p = part_points(library, name, np.eye(4))
        c = p.mean(0)
        q = (p - c) * [-1.0, 1.0, 1.0] + c
        scale = max(float(np.linalg.norm(p - c, axis=1).max()), 1e-12)
        cache[key] = np.linalg.norm(q[:, None] - p[None], axis=2).min(1).max() <= 1e-6 * scale
        if cache[key]:
            about = np.eye(4)
            about[:3, 3] = c
            back = np.eye(4)
            back[:3, 3] = -c
            cache[("mirror-t", name)] = about @ _MIRROR @ back
    return m @ cache[("mirror-t", name)] if cache[key] else None


_MIRROR_CACHE: dict = {}


def symmetric_copies(shape: Shape, library: dict | None = None) -> list[Shape | None]:
    """A shape turned by each of :func:`world_symmetries` (about its centroid); None for a
    mirror when a part is not mirror-symmetric (needs ``library``; without it mirrors are None)."""
    centre = np.mean([t[:3, 3] for t in shape.transforms], axis=0)
    to, back = np.eye(4), np.eye(4)
    to[:3, 3], back[:3, 3] = -centre, centre
    out = []
    for g in world_symmetries():
        moved = [back @ g @ to @ t for t in shape.transforms]
        if np.linalg.det(g[:3, :3]) < 0:
            if library is None:
                out.append(None)
                continue
            moved = [proper_placement(library, p, m, _MIRROR_CACHE) for p, m in zip(shape.parts, moved)]
            if any(m is None for m in moved):
                out.append(None)
                continue
        out.append(Shape.of(shape.parts, moved))
    return out


def canonical_targets(text: str, order: list[int], labelings: list[dict]) -> list[int]:
    """Target category per character: among the labelings of the symmetric copies of a
    shape that cover every edge, the one whose sequence (in string order) is smallest.

    A string fixes its shape only up to these symmetries, so this makes the target a
    function of the string (and of the shape up to symmetry)."""
    parsed = parse(text)
    best = None
    for cats in labelings:
        seq = []
        for e in parsed.char_edges:
            if e is None:
                seq.append(0)
                continue
            k = cats.get((min(order[e[0]], order[e[1]]), max(order[e[0]], order[e[1]])))
            if k is None:
                break
            seq.append(k)
        else:
            if best is None or seq < best:
                best = seq
    return best


def shape_labelings(shape_set: ShapeSet, shape: Shape, g: nx.Graph, categories: "EdgeCategories",
                    automorphisms: int = 64) -> list[dict]:
    """Edge categories of each symmetric copy of a shape that all its edges fall in, and
    of each of those relabelled by an automorphism of ``g`` (at most ``automorphisms`` of
    them, :func:`~procmod.strings.shapes.type_automorphisms`; 1: none): every labelling a
    string of ``g`` could be right to give, without duplicates."""
    out, seen = [], set()
    auts = type_automorphisms(g, automorphisms) if automorphisms > 1 else [{v: v for v in g.nodes}]
    for copy in symmetric_copies(shape, shape_set.library):
        if copy is None:
            continue
        cats = categories.edge_categories(shape_set, copy, g)
        if len(cats) != g.number_of_edges():
            continue
        for sigma in auts:
            # the part at a takes the place of sigma[a]: edge (a, b) gets sigma's image's category
            moved = {(a, b): cats[(min(sigma[a], sigma[b]), max(sigma[a], sigma[b]))] for a, b in cats}
            key = tuple(sorted(moved.items()))
            if key not in seen:
                seen.add(key)
                out.append(moved)
    return out


def symmetric_targets(text: str, order: list[int], labelings: list[dict]) -> list[list[int]]:
    """Every distinct target sequence of ``text`` (one per symmetric copy of the shape that
    covers every edge), smallest first: the first is :func:`canonical_targets`."""
    parsed = parse(text)
    out = set()
    for cats in labelings:
        seq = []
        for e in parsed.char_edges:
            k = 0 if e is None else cats.get((min(order[e[0]], order[e[1]]), max(order[e[0]], order[e[1]])))
            if k is None:
                break
            seq.append(k)
        else:
            out.add(tuple(seq))
    return [list(t) for t in sorted(out)]


def tagging_examples(shape_set: ShapeSet, shapes, graphs, categories: "EdgeCategories", per_shape: int,
                     rng: np.random.Generator, every_symmetry: bool = False,
                     automorphisms: int = 64) -> list[tuple[str, list]]:
    """(string, target category per character) pairs from shapes, ``per_shape`` strings each
    (targets by :func:`canonical_targets`); with ``every_symmetry`` the targets are the list
    of :func:`symmetric_targets` instead (the canonical one first). The labellings are the
    shape's up to its turns, mirrors and graph automorphisms (``automorphisms``, as
    :func:`shape_labelings`); the strings drawn do not depend on them."""
    out = []
    for shape, g in zip(shapes, graphs):
        labelings = shape_labelings(shape_set, shape, g, categories, automorphisms)
        if not labelings:
            continue
        seen = set()
        for k in range(4 * per_shape):
            if len(seen) >= per_shape:
                break
            text, order = encode_with_order(g, None if k else 0, rng if k else None)
            if text in seen:
                continue
            seen.add(text)
            if every_symmetry:
                out.append((text, symmetric_targets(text, order, labelings)))
            else:
                out.append((text, canonical_targets(text, order, labelings)))
    return out


def _target_sets(targets) -> list[list[int]]:
    """A string's targets as a list of sequences (one, or one per symmetric copy)."""
    return targets if targets and isinstance(targets[0], (list, tuple)) else [targets]


def category_decoder(categories: EdgeCategories, stars: list | None = None,
                     shape_set: ShapeSet | None = None) -> CategoryDecoder:
    """A structured decoder of edge categories (:mod:`procmod.strings.decoding`): stars
    (when given) and, with ``shape_set`` (the shapes the categories were fitted on, for the
    part library and the parts' poses), ring closure, the first part of a string placed in
    its input pose under every turn and mirror of :func:`world_symmetries`."""
    frame_of, roots = None, None
    if shape_set is not None:
        lib, part_of = shape_set.library, shape_set.part_of_letter
        frame_of = lambda t, pose: canonical_frame(lib, part_of[t], pose, categories.groups)  # noqa: E731
        roots = {t: [m for g in world_symmetries()
                     if (m := proper_placement(lib, part_of[t], g @ pose, _MIRROR_CACHE)) is not None]
                 for t, pose in first_poses(shape_set).items()}
    return CategoryDecoder(categories, stars, frame_of, roots)


class TaggerModel:
    """A trained tagger with its vocabulary, edge categories and the stars (the multisets
    of edge categories at one part) its training shapes show, which structured decoding
    (:mod:`procmod.strings.decoding`) keeps labellings to."""

    def __init__(self, net: Tagger, vocab: Vocab, categories: EdgeCategories, stars: list | None = None):
        self.net, self.vocab, self.categories, self.stars = net, vocab, categories, stars
        self._decoders: dict = {}

    def _tensors(self, texts, targets=None):
        """Token ids, masks ``(B, T, K)``, targets ``(B, S, T)`` (S target sequences per string;
        -100: padding) and structure ``(B, T, 3)``."""
        t = max(len(x) for x in texts)
        tok = torch.zeros((len(texts), t), dtype=torch.long)
        mask = torch.zeros((len(texts), t, len(self.categories)), dtype=torch.bool)
        mask[:, :, 0] = True
        sets = [_target_sets(x) for x in targets] if targets is not None else None
        n_sets = max(len(x) for x in sets) if sets else 1
        tgt = torch.full((len(texts), n_sets, t), -100, dtype=torch.long)
        struct = torch.zeros((len(texts), t, 3), dtype=torch.long)
        for k, text in enumerate(texts):
            # ring labels are paired by the structure input: a label past 9 reads like one below
            tok[k, :len(text)] = torch.tensor(self.vocab.encode(text, any_ring_label=True))
            m, _ = string_mask(text, self.categories)
            mask[k, :len(text)] = torch.from_numpy(m)
            struct[k, :len(text)] = torch.from_numpy(string_structure(text))
            if sets is not None:
                for j in range(n_sets):  # fewer symmetric sequences: repeat the first
                    tgt[k, j, :len(text)] = torch.tensor(sets[k][j if j < len(sets[k]) else 0])
        return tok, mask, tgt, struct

    @torch.no_grad()
    def predict(self, texts: list[str]) -> list[np.ndarray]:
        """Per-character category probabilities ``(len, K)`` of each string."""
        with torch_threads():
            return self._predict(texts)

    def _predict(self, texts):
        self.net.eval()
        tok, mask, _, struct = self._tensors(texts)
        prob = torch.softmax(self.net(tok, mask, struct), dim=2).numpy()
        return [prob[k, :len(t)] for k, t in enumerate(texts)]

    def decoder(self, shape_set: ShapeSet | None = None) -> CategoryDecoder:
        """The structured decoder (:func:`category_decoder`) of this tagger's categories and
        stars; ``shape_set``: the training shapes (ring closure needs their part library)."""
        key = id(shape_set)
        if key not in self._decoders:
            self._decoders = {key: (shape_set, category_decoder(self.categories, self.stars, shape_set))}
        return self._decoders[key][1]

    def labels(self, texts: list[str], shape_set: ShapeSet | None = None, structured: bool = True) -> list[np.ndarray]:
        """Category per character of each string: by structured decoding (:meth:`decoder`),
        or with ``structured=False`` each character's most probable category."""
        probs = self.predict(texts)
        if not structured:
            return [p.argmax(1) for p in probs]
        decoder = self.decoder(shape_set)
        return [decoder.decode(t, p) for t, p in zip(texts, probs)]

    def vote(self, g: nx.Graph, strings: int, rng: np.random.Generator, shape_set: ShapeSet | None = None,
             ranked: bool = False, structured: bool = True, soft: bool = True, automorphisms: int = 64) -> dict:
        """Vote over ``strings`` strings of ``g`` (the canonical one, then random ones):
        ``{(min, max): category}``; with ``ranked``, ``{(min, max): [categories]}``, best
        first, for the instantiation to try in that order.

        Each string's prediction fixes the shape only up to a turn / mirror about the
        vertical axis, so (given ``shape_set``, the training shapes) every string's
        prediction is first turned by the symmetry that agrees best with the first string's,
        and moved by the automorphism of ``g`` (at most ``automorphisms`` tried) that does:
        a ring's strings cannot say which of its alike parts is a corner.

        ``soft`` (the default): the tagger's probabilities of each edge are summed over
        every character that writes it in every string (soft voting; a ring edge's two
        labels count as two), and the whole graph is labelled once by structured decoding
        of the logs of those sums (``structured``; else each edge's most probable category);
        ranked: that label, then the rest by summed probability. With ``soft=False``, the
        paper's majority vote: each string is labelled on its own (:meth:`labels`) and each
        edge gets the category most strings gave it; ranked: every category that got a vote,
        most votes first (ties: the lower category).
        """
        texts, orders = [], []
        for k in range(strings):
            text, order = encode_with_order(g, None if k else 0, rng if k else None)
            texts.append(text)
            orders.append(order)
        probs = self.predict(texts)
        if soft:
            labels = [p.argmax(1) for p in probs]  # for the alignment only
        else:
            decoder = self.decoder(shape_set) if structured else None
            labels = [decoder.decode(t, p) if decoder else p.argmax(1) for t, p in zip(texts, probs)]
        # per string: graph edge -> [(label, probabilities)] of each character that writes it
        per_string = []
        for text, order, lab, prob in zip(texts, orders, labels, probs):
            seen: dict[tuple, list] = {}
            for i, e in enumerate(parse(text).char_edges):
                if e is not None:
                    key = (min(order[e[0]], order[e[1]]), max(order[e[0]], order[e[1]]))
                    seen.setdefault(key, []).append((int(lab[i]), prob[i]))
            per_string.append(seen)
        perms = self.categories.symmetry_permutations(shape_set) if shape_set is not None else [None]
        # a string names g only up to its automorphisms: two strings may be right with
        # labellings that differ by one, so each is moved onto the first string's as well
        auts = [None] + [{(a, b): (min(m[a], m[b]), max(m[a], m[b])) for a, b in (
            (min(e), max(e)) for e in g.edges)} for m in type_automorphisms(g, automorphisms)[1:]]
        size = len(self.categories)
        votes: dict[tuple, np.ndarray] = {}
        reference = None
        for seen in per_string:
            perm, moved = None, None
            if reference is not None:
                best_agree = -1
                for edge_map in auts:
                    for candidate in perms:
                        agree = sum((c if candidate is None else candidate.get(c))
                                    == reference.get(e if edge_map is None else edge_map[e])
                                    for e, obs in seen.items() for c, _ in obs)
                        if agree > best_agree:
                            perm, moved, best_agree = candidate, edge_map, agree
            else:
                reference = {e: obs[0][0] for e, obs in seen.items()}
            for e, obs in seen.items():
                v = votes.setdefault(e if moved is None else moved[e], np.zeros(size))
                for c, p in obs:
                    if soft:
                        if perm is None:
                            v += p
                        else:  # probability of category c goes to its image under the turn
                            for c0, c1 in perm.items():
                                if c1 is not None:
                                    v[c1] += p[c0]
                    else:
                        c = c if perm is None else perm.get(c)
                        if c is not None:
                            v[c] += 1
        if soft:
            if structured:
                order = orders[0]
                with np.errstate(divide="ignore"):
                    logp = {(min(a, b), max(a, b)): np.log(votes[(min(order[a], order[b]), max(order[a], order[b]))])
                            for a, b in parse(texts[0]).graph.edges}
                decoded = self.decoder(shape_set).decode_edges(texts[0], logp)
                best = {(min(order[a], order[b]), max(order[a], order[b])): k for (a, b), k in decoded.items()}
            else:
                best = {e: int(np.argmax(v)) for e, v in votes.items()}
            if ranked:
                return {e: [best[e]] + [int(c) for c in np.argsort(-v, kind="stable") if v[c] > 0 and c != best[e]]
                        for e, v in votes.items()}
            return best
        if ranked:
            return {e: [int(c) for c in np.argsort(-v, kind="stable") if v[c] > 0] for e, v in votes.items()}
        return {e: int(np.argmax(v)) for e, v in votes.items()}

    def save(self, folder, state=None, optimizer=None) -> None:
        folder = Path(folder)
        payload = {"model": cpu_state(self.net)}
        if optimizer is not None:
            payload["optimizer"] = cpu_state(optimizer)
        tmp = folder / ".tagger.pt.tmp"
        torch.save(payload, tmp)
        os.replace(tmp, folder / "tagger.pt")
        meta = {"format": "procmod-string-tagger/1", "config": asdict(self.net.config), "vocab": self.vocab.chars,
                "categories": self.categories.to_json(), "train": state or {"epoch": 0, "history": []}}
        if self.stars is not None:
            meta["stars"] = [[t, list(ks)] for t, ks in self.stars]
        write_text_atomic(folder / "tagger.json", json.dumps(meta) + "\n")

    @staticmethod
    def load(folder, with_optimizer: bool = False):
        folder = Path(folder)
        try:
            meta = json.loads((folder / "tagger.json").read_text())
            payload = torch.load(folder / "tagger.pt", weights_only=True, map_location="cpu")
        except (OSError, json.JSONDecodeError, RuntimeError) as exc:
            raise ModelFileError(f"cannot read the edge-category tagger in {folder} ({exc})") from None
        cats = EdgeCategories.from_json(meta["categories"])
        vocab = Vocab(meta["vocab"])
        # taggers saved before the tree pass existed are plain bidirectional LSTMs
        # and before the graph pass existed, taggers had none
        config = TaggerConfig(**{"tree": False, "graph_rounds": 0, **meta["config"]})
        net = Tagger(len(vocab), len(cats), config)
        net.load_state_dict(payload["model"])
        # taggers saved before structured decoding existed have no stars (rings are still checked)
        stars = [(t, tuple(ks)) for t, ks in meta["stars"]] if "stars" in meta else None
        model = TaggerModel(net, vocab, cats, stars)
        if with_optimizer:
            return model, meta["train"], payload.get("optimizer")
        return model


def train_tagger(examples: list, vocab: Vocab, categories: EdgeCategories, folder, config: TaggerConfig = TaggerConfig(),
                 seed: int = 0, progress=None, device: str | None = None) -> TaggerModel:
    """Train (or resume, on any device) the tagger on (string, targets) pairs, checkpointing
    every epoch; ``device``: see :func:`~procmod.strings.vae.training_device` (the model
    comes back on the CPU)."""
    dev = training_device(device)
    with torch_threads():
        model = _train_tagger(examples, vocab, categories, folder, config, seed, progress, dev)
    model.net.to("cpu")
    return model


def _train_tagger(examples, vocab, categories, folder, config, seed, progress, device) -> TaggerModel:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    if (folder / "tagger.json").is_file() and (folder / "tagger.pt").is_file():
        model, state, opt_state = TaggerModel.load(folder, with_optimizer=True)
        if {**asdict(model.net.config), "epochs": 0} != {**asdict(config), "epochs": 0}:
            raise ModelFileError(f"{folder} holds a tagger of another configuration; use a new --out")
    else:
        model, state, opt_state = TaggerModel(Tagger(len(vocab), len(categories), config), vocab, categories), \
            {"epoch": 0, "history": []}, None
    model.net.to(device)
    optimizer = torch.optim.Adam(model.net.parameters(), lr=config.lr)
    if opt_state is not None:
        optimizer.load_state_dict(opt_state)  # moves the moments to the parameters' device
    stars = star_set(examples)
    if model.stars != stars:  # a new tagger, or one trained before stars were kept
        model.stars = stars
        model.save(folder, state, optimizer)
    if model.categories.clearance is None and categories.clearance is not None:  # saved before clearances
        model.categories.clearance = categories.clearance
        model.save(folder, state, optimizer)
    while state["epoch"] < config.epochs:
        # a function of the epoch only, so a resumed run continues the same schedule
        progress_ = state["epoch"] / max(config.epochs - 1, 1)
        for group in optimizer.param_groups:
            # a plain float: the optimizer state is saved and loaded with weights_only=True
            scale = config.lr_final + (1 - config.lr_final) * 0.5 * (1 + np.cos(np.pi * progress_))
            group["lr"] = float(config.lr * scale)
        gen = torch.Generator().manual_seed(seed * 7919 + state["epoch"])
        order = torch.randperm(len(examples), generator=gen).tolist()
        # length buckets: sort within chunks of 8 batches, then shuffle the batches (less padding)
        chunk = 8 * config.batch
        batches = []
        for k in range(0, len(order), chunk):
            part = sorted(order[k:k + chunk], key=lambda i: len(examples[i][0]))
            batches += [part[j:j + config.batch] for j in range(0, len(part), config.batch)]
        batches = [batches[i] for i in torch.randperm(len(batches), generator=gen).tolist()]
        model.net.train()
        total, n_chars, correct, t0 = 0.0, 0, 0, time.perf_counter()
        for ids in batches:
            batch = [examples[i] for i in ids]
            tok, mask, tgt, struct = (x.to(device) for x in
                                      model._tensors([b[0] for b in batch], [b[1] for b in batch]))
            logits = model.net(tok, mask, struct)
            # -inf logits of disallowed categories: use log_softmax and gather the target's only.
            if not config.symmetric_loss:
                tgt = tgt[:, :1]
            logp = torch.log_softmax(logits, dim=2)
            valid = tgt >= 0  # (B, S, T)
            b_, s_, t_ = tgt.shape
            picked = logp[:, None].expand(b_, s_, t_, logp.shape[2]).gather(3, tgt.clamp(min=0)[..., None])[..., 0]
            per_seq = -(picked * valid).sum(2)  # (B, S): each symmetric target sequence's loss
            best = per_seq.argmin(1)
            loss = per_seq.min(1).values.sum() / valid[:, 0].sum()
            optimizer.zero_grad()
            loss.backward()
            nn.utils.clip_grad_norm_(model.net.parameters(), 5.0)
            optimizer.step()
            chosen = tgt[torch.arange(b_, device=device), best]
            edge = chosen > 0
            correct += int(((logits.argmax(2) == chosen) & edge).sum())
            n_chars += int(edge.sum())
            total += float(loss.detach()) * len(batch)
        state["epoch"] += 1
        row = {"epoch": state["epoch"], "loss": total / len(order), "train_accuracy": correct / max(n_chars, 1),
               "seconds": round(time.perf_counter() - t0, 2), "device": str(device)}
        state["history"].append(row)
        model.save(folder, state, optimizer)
        if progress is not None:
            progress(row)
    return model


def tagging_accuracy(model: TaggerModel, examples: list, all_characters: bool = False,
                     shape_set: ShapeSet | None = None, structured: bool = True,
                     predicted: list | None = None) -> float:
    """Fraction of edge characters (targets > 0) whose category is right (against
    the closest of the string's target sequences, when it has several: the shape up to the
    symmetries a string cannot tell apart), labelled by :meth:`TaggerModel.labels`
    (``shape_set``, ``structured`` as there) unless ``predicted`` gives the labels of each
    example's string; with
    ``all_characters`` every character counts, also brackets, bonds and the root, whose
    dummy category the mask makes certain (a per-timestep accuracy, for comparison only)."""
    right = total = 0
    for k in range(0, len(examples), 128):
        batch = examples[k:k + 128]
        labels = (predicted[k:k + 128] if predicted is not None
                  else model.labels([b[0] for b in batch], shape_set, structured))
        for (text, targets), pred in zip(batch, labels):
            scores = []  # (right, counted) against each symmetric target sequence
            for seq in _target_sets(targets):
                counted = [i for i, t in enumerate(seq) if t > 0 or all_characters]
                scores.append((sum(int(pred[i] == seq[i]) for i in counted), len(counted)))
            r, c = max(scores)
            right += r
            total += c
    return right / max(total, 1)


# ---------------------------------------------------------------------------------------------
# Graph instantiation


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


def instantiate_graph(g: nx.Graph, edge_cats: dict, categories: EdgeCategories, shape_set: ShapeSet,
                      rng: np.random.Generator, start_pose: dict | None = None,
                      tries_per_edge: int = 24, debug: list | None = None, budget: int = 4000) -> InstantiateResult:
    """Embed a typed graph in 3D by transplanting edges with the given categories.

    ``edge_cats`` maps ``(min, max)`` node pairs to a category, or to a list of categories
    best first (from the tagger's vote, ``ranked=True``);
    ``shape_set`` supplies the part library; ``start_pose`` maps a type to the 4x4 pose of
    the first part (default: identity). Success means the recomputed shape graph is ``g``.

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
    tol = tolerance_for(lib)
    n = g.number_of_nodes()
    types = [g.nodes[v]["type"] for v in range(n)]
    parts = [part_of[t] for t in types]
    edges = sorted(g.edges)
    if not edges:
        return InstantiateResult(Shape.of(parts, [np.eye(4)]), True)
    reach = _centre_reach(categories, shape_set)
    # Placement order: breadth first, over the 2-core (the rings and what joins them) first,
    # then the trees hanging off it: a ring that cannot close is found before any branch is
    # placed, so backtracking does not re-place branches that have nothing to do with it.
    core = set(nx.k_core(g, 2).nodes) if g.number_of_edges() >= g.number_of_nodes() else set()
    starts = [e for e in edges if e[0] in core] or edges
    u0, _ = starts[int(rng.integers(len(starts)))]
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
    place(u0, np.asarray((start_pose or {}).get(types[u0], np.eye(4)), dtype=np.float64))
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
