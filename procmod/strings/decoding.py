"""Structured decoding of a string's edge categories (a design extension to seed 001).

The tagger gives each character a distribution over edge categories, one character at a
time. Taken one by one (the argmax), the labels of one string need not describe any shape:
a wall whose two neighbours both sit on its left, or a ring of walls whose turns do not
close. Seed 001 leaves such labellings to the instantiation, which then falls back to
other categories part by part. This module instead picks, per string, the labelling with
the highest total log-probability among those that

1. give every part a **star** (the multiset of its edges' categories) that some training
   shape shows for a part of its type and number of neighbours, and
2. **close every ring**: placing the parts along the string's spanning tree by the
   relative pose of each tree edge's category (the transplanting of section 6, one
   example per category), every ring edge's two ends must sit in the relative pose of its
   category, and
3. **keep parts apart**: in that placement, two parts that are not neighbours must be no
   closer than any two parts of their types that are not neighbours in the training shapes
   (the categories' ``clearance``): a wrong turn of a chain that closes its ring can still
   put two columns on one spot.

All are soft: each part with an unseen star, each ring edge that does not close and each
pair of parts too close costs ``penalty`` nats, so a string that no labelling fits (a
novel graph with a new kind of part neighbourhood) still gets the best one. The search is
a beam search over the string's edges in the order their last character is written (so
both ends of a ring edge are placed when it is decided), keeping ``beam`` partial
labellings, each edge trying its ``candidates`` most probable categories.

Measured on held-out strings (bench/strings.py, docs/strings.md): the tagger's argmax ->
decoded, per character: castle 94.1% -> 97.3%, moon base 89.3% -> 95.1%, colonnade
82.8% -> 88.3% (labellings equal up to turns, mirrors and graph automorphisms).
"""

from __future__ import annotations

import heapq
from collections import Counter
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..core.errors import InvalidArgumentError
from .codec import parse

# (type letter, the sorted categories of its edges)
Star = tuple[str, tuple[int, ...]]

# where the search keeps a part not placed yet: far from everything (no clash), and finite
_UNPLACED = 1e9


@dataclass(frozen=True)
class DecoderParams:
    beam: int = 128  # partial labellings kept
    retry_beam: int = 512  # when the best labelling found has a fault, search again this wide (0: never)
    candidates: int = 6  # categories tried per edge, most probable first
    penalty: float = 20.0  # nats per fault: a part with an unseen star, a ring edge that does not
    # close, two parts closer than their types' clearance
    clearance_slack: float = 0.1  # a part may sit this fraction of the clearance closer (placing by
    # one example per category drifts a little on sets off a grid)

    def __post_init__(self):
        # the search's bound (a fault only lowers a score) needs a finite penalty >= 0
        if not (np.isfinite(self.penalty) and self.penalty >= 0):
            raise InvalidArgumentError(f"penalty must be a finite number >= 0 (got {self.penalty})")
        if self.beam < 1 or self.candidates < 1:
            raise InvalidArgumentError(f"beam and candidates must be at least 1 (got {self.beam}, {self.candidates})")


def stars_of_labelling(text: str, labels) -> list[Star]:
    """The star of every node of ``text``'s graph under per-character ``labels`` (a category
    per character; characters that stand for no edge are ignored)."""
    parsed = parse(text)
    edge_label = {}
    for i, e in enumerate(parsed.char_edges):
        if e is not None:
            edge_label[(min(e), max(e))] = int(labels[i])
    incident: dict[int, list[int]] = {v: [] for v in parsed.graph.nodes}
    for (a, b), k in edge_label.items():
        incident[a].append(k)
        incident[b].append(k)
    return [(parsed.graph.nodes[v]["type"], tuple(sorted(ks))) for v, ks in incident.items() if ks]


def star_set(examples) -> list[Star]:
    """Every star the (string, targets) training pairs show, under every target sequence a
    string has (the shape's symmetric copies), sorted."""
    out: set = set()
    for text, targets in examples:
        seqs = targets if targets and isinstance(targets[0], (list, tuple)) else [targets]
        for seq in seqs:
            out.update(stars_of_labelling(text, seq))
    return sorted(out)


class CategoryDecoder:
    """Joint labelling of one string's edges (see the module docstring).

    ``categories`` is the :class:`~procmod.strings.categories.EdgeCategories`; ``stars``
    the stars seen in training (None: no star check); ``frame_of(letter, pose)`` the
    canonical frame of a part of that type placed at ``pose``, and ``root_poses`` per type
    the poses a string's first part may have (identity when missing) — without ``frame_of``
    rings are not checked.

    A string does not say how its shape is turned, and the categories of a turned or
    mirrored copy of a shape differ (a symmetric part's canonical frame is the one closest to
    the world axes), so the search starts from every root pose given: a part's pose in the
    inputs under each turn and mirror about the vertical axis.
    """

    def __init__(self, categories, stars: list[Star] | None = None,
                 frame_of: Callable[[str, np.ndarray], np.ndarray] | None = None,
                 root_poses: dict | None = None, params: DecoderParams = DecoderParams()):
        self.categories = categories
        self.frame_of = frame_of
        self.root_poses = root_poses or {}
        self.params = params
        self._stars: dict[tuple[str, int], list[Counter]] | None = None
        if stars is not None:
            self._stars = {}
            for t, ks in stars:
                self._stars.setdefault((t, len(ks)), []).append(Counter(ks))
        self._extendable: dict = {}
        self._steps: dict = {}

    def extendable(self, t: str, degree: int, partial: tuple[int, ...]) -> bool:
        """Can a part of type ``t`` with ``degree`` edges, of which ``partial`` (sorted
        categories) are decided, still get a seen star?"""
        key = (t, degree, partial)
        hit = self._extendable.get(key)
        if hit is None:
            have = Counter(partial)
            hit = self._extendable[key] = any(all(star[k] >= n for k, n in have.items())
                                              for star in self._stars.get((t, degree), []))
        return hit

    @staticmethod
    def _turn_key(f: np.ndarray) -> bytes:
        """A frame's rotation, rounded, as a dictionary key."""
        return np.round(f[:3, :3], 4).tobytes()

    def _steps_to(self, fx: np.ndarray, turn_x: bytes, tx: str, ty: str, k: int) -> list[tuple]:
        """``(frame, turn key)`` of a ``ty`` part joined to a ``tx`` part at frame ``fx``
        (turn key ``turn_x``) by category ``k``, relative to ``fx``'s origin: the frame's
        translation is y's offset from x (add ``fx[:3, 3]`` to place it); two when both types
        are the same: either end may be the category's first part."""
        # canonical frames depend on the orientation only: cache by (k, x's type, x's rotation)
        key = (k, tx, turn_x)
        steps = self._steps.get(key)
        if steps is None:
            a, b = self.categories.names[k][:2]
            turn = np.eye(4)
            turn[:3, :3] = fx[:3, :3]
            rel = self.categories.examples[k][0]  # B's pose in A's frame, A's pose in B's frame
            steps = []
            for side, x_plays in ((0, a), (1, b)):
                if tx == x_plays:
                    f = self.frame_of(ty, turn @ rel[side])  # at x's origin: f's offset is y's from x
                    steps.append((f, self._turn_key(f)))
            self._steps[key] = steps
        return steps

    def decode(self, text: str, prob: np.ndarray) -> np.ndarray:
        """Category per character of ``text`` given the tagger's per-character
        probabilities ``prob`` ``(len(text), K)``; characters that stand for no edge keep
        their argmax (the dummy category)."""
        parsed = parse(text)
        with np.errstate(divide="ignore"):
            logprob = np.log(prob)
        logp: dict[tuple, np.ndarray] = {}
        for i, e in enumerate(parsed.char_edges):
            if e is not None:
                key = (min(e), max(e))
                logp[key] = logp.get(key, 0.0) + logprob[i]  # a ring edge is written twice
        labels = self._best(parsed, logp)
        out = prob.argmax(1)
        for i, e in enumerate(parsed.char_edges):
            if e is not None:
                out[i] = labels[(min(e), max(e))]
        return out

    def decode_edges(self, text: str, logp: dict) -> dict:
        """The best labelling of ``text``'s edges given, per edge ``(min, max)`` of its
        parsed nodes (string order), the log-probability of each category (e.g. summed over
        several strings of one graph): ``{(min, max): category}``."""
        return self._best(parse(text), logp)

    def faults(self, text: str, labels) -> int:
        """How many parts of ``text`` get a star no training shape shows, plus how many ring
        edges do not close and how many pairs of parts clash, under per-character ``labels``
        (a diagnostic; 0 for the labels of a training shape). A ring edge's two characters
        must agree."""
        parsed = parse(text)
        size = len(self.categories) if self.categories is not None else int(max(labels, default=0)) + 1
        logp: dict[tuple, np.ndarray] = {}
        for i, e in enumerate(parsed.char_edges):
            if e is not None:
                key = (min(e), max(e))
                one = logp.setdefault(key, np.zeros(size))
                one[[k for k in range(len(one)) if k != int(labels[i])]] = -np.inf
        _, faults, _ = self._search(parsed, logp, max(len(self._root_frames(parsed)), 1), 1)
        return faults

    def _root_frames(self, parsed) -> list[tuple[int, np.ndarray, bytes]]:
        """The frames the search starts from: ``(root, frame, turn key)`` per root pose
        (empty without geometry)."""
        if self.frame_of is None or parsed.graph.number_of_edges() == 0:
            return []
        root = next(v for v in parsed.char_nodes if v is not None)
        t = parsed.graph.nodes[root]["type"]
        out, seen = [], set()
        for pose in self.root_poses.get(t) or [np.eye(4)]:
            f = self.frame_of(t, np.asarray(pose, dtype=np.float64))
            key = self._turn_key(f)
            if key not in seen:  # poses a symmetric part cannot tell apart
                seen.add(key)
                out.append((root, f, key))
        return out

    def _too_near(self, types: list[str], g) -> np.ndarray | None:
        """Per pair of parts, the *squared* distance below which their frame origins clash:
        their types' clearance less the slack for parts that are not neighbours, 0 for
        neighbours and for type pairs without one (None: no clearances, or no geometry)."""
        clearance = getattr(self.categories, "clearance", None)
        if not clearance or self.frame_of is None:
            return None
        keep = 1.0 - self.params.clearance_slack
        kinds = sorted(set(types))
        code = np.array([kinds.index(t) for t in types])
        table = np.zeros((len(kinds), len(kinds)))
        for i, a in enumerate(kinds):
            for j, b in enumerate(kinds):
                table[i, j] = keep * clearance.get((min(a, b), max(a, b)), 0.0)
        near = table[code[:, None], code[None, :]]
        for a, b in g.edges:
            near[a, b] = near[b, a] = 0.0
        return near ** 2

    def _closes(self, fx: np.ndarray, fy: np.ndarray, tx: str, ty: str, k: int) -> bool:
        """Do parts at frames ``fx``, ``fy`` sit in a pose of category ``k``? Its nearest
        cluster centre must be ``k``'s and within one bandwidth of it: the nearest alone would
        let a ring "close" with its last part metres away."""
        return self.categories.category_of_frames(fx, fy, tx, ty, seen_only=True) == k

    @staticmethod
    def _clashes(parts: np.ndarray, at: np.ndarray, origins: np.ndarray, near2: np.ndarray) -> np.ndarray:
        """For each candidate placement ``i`` of part ``parts[i]`` with its frame origin at
        ``at[i]`` among the placed parts ``origins[i]`` ``(n, 3)`` (parts not placed sit at
        ``_UNPLACED``): how many of them it would clash with (``near2``: :meth:`_too_near`)."""
        d = origins - at[:, None, :]
        return np.count_nonzero((d * d).sum(-1) < near2[parts], axis=1)

    def _best(self, parsed, logp: dict) -> dict:
        """The labelling :meth:`_search` finds with the configured beam, or, when that one
        has a fault, the better of it and a search ``retry_beam`` wide: most strings have a
        labelling without faults (every training shape's has none), and the fault-free one is
        often lost from a narrow beam because a clash shows only many edges after its cause."""
        p = self.params
        labels, faults, score = self._search(parsed, logp, p.beam, p.candidates)
        if faults and p.retry_beam > p.beam:
            wide, _, wide_score = self._search(parsed, logp, p.retry_beam, p.candidates)
            if wide_score > score:
                return wide
        return labels

    def _search(self, parsed, logp: dict, beam_size: int, candidates: int) -> tuple[dict, int, float]:
        """Beam search for the labelling of ``parsed``'s edges (``logp``: per edge, the
        log-probability of each category) with the highest log-probability less
        ``penalty`` per fault; returns it, its number of faults and its score."""
        g = parsed.graph
        n = g.number_of_nodes()
        types = [g.nodes[v]["type"] for v in g.nodes]
        degree = dict(g.degree)
        last = {}
        for i, e in enumerate(parsed.char_edges):
            if e is not None:
                last[(min(e), max(e))] = i
        # decided in the order the string finishes writing them: a tree edge when its child is
        # written (its parent is placed by then), a ring edge at its second label (both placed)
        edges = sorted(logp, key=last.get)
        near2 = self._too_near(types, g)  # (n, n) squared distances below which two parts clash
        # A partial labelling: (score, faults, category per decided edge, star per part (the
        # sorted categories decided at it), parts with a fault, (frame, turn key) per part
        # (None: not placed), frame origins (n, 3)). Lists indexed by edge order and node,
        # copied whole when a kept extension changes them.
        beam = []
        for root, f, key in self._root_frames(parsed) or [(None, None, None)]:
            frames = [None] * n
            origins = np.full((n, 3), _UNPLACED)
            if root is not None:
                frames[root] = (f, key)
                origins[root] = f[:3, 3]
            beam.append((0.0, 0, [], [()] * n, frozenset(), frames, origins))
        for e in edges:
            lp = logp[e]
            order = np.argsort(-lp, kind="stable")
            cands = [int(c) for c in order[:candidates] if np.isfinite(lp[c])]
            if not cands:
                raise ValueError("an edge of the string has no category of positive probability")
            # Extending partial labelling h by category k scores at most score_h + lp[k] (a
            # fault only subtracts), so extensions are built best bound first, and the rest
            # skipped once none can enter the beam: the beam (and its order: score, then h, k,
            # placement) is the one building every extension gives, at a fraction of the work.
            bound = np.array([b[0] for b in beam])[:, None] + lp[cands][None, :]
            hs, cs = np.nonzero(np.ones_like(bound, dtype=bool))
            units = np.lexsort((cs, hs, -bound[hs, cs]))
            # The step cache keeps the first frame computed for a rounded rotation; filled here
            # in (h, k) order, as building every extension would, so which extensions are built
            # cannot move a frame in its last digits (and flip a closure or clash test).
            for h in range(len(beam)):
                frames = beam[h][5]
                x, y = e
                if frames[y] is not None and frames[x] is None:
                    x, y = y, x
                if frames[x] is not None and frames[y] is None:
                    for k in cands:
                        if self.categories.examples.get(k):
                            self._steps_to(*frames[x], types[x], types[y], k)
            # extensions built: (score, faults, h, category, new part, (x's origin, (its frame
            # relative to that origin, turn key)), the edge's ends' new stars, parts whose star broke)
            grown = []
            best_keys: list = []  # heap of the beam_size best keys so far, worst on top: (score, -h, -ci, -j, index)
            placed = np.stack([b[6] for b in beam])  # every partial labelling's frame origins (B, n, 3)
            start = 0
            while start < len(units):
                if len(best_keys) >= beam_size:
                    s_w, h_w, c_w, j_w, _ = best_keys[0]
                    unit = units[start]
                    if (-bound[hs[unit], cs[unit]], hs[unit], cs[unit], 0) > (-s_w, -h_w, -c_w, -j_w):
                        break  # this extension and every later one rank below the beam
                # in chunks (the first fills the beam), so clashes are counted for many at once
                chunk = units[start:start + (beam_size if start == 0 else 32)]
                start += len(chunk)
                pending = []  # (score, faults, faults but clashes, h, ci, j, y, placement as in grown, ends, broken)
                for unit in chunk:
                    h, ci = int(hs[unit]), int(cs[unit])
                    k = cands[ci]
                    score, faults, _, stars, broken, frames, _ = beam[h]
                    x, y = e
                    if frames[y] is not None and frames[x] is None:
                        x, y = y, x
                    f = faults
                    ends, newly_broken = (), ()
                    if self._stars is not None:
                        for v in e:
                            star = tuple(sorted(stars[v] + (k,)))
                            ends += ((v, star),)
                            if v not in broken and not self.extendable(types[v], degree[v], star):
                                f += 1  # counted once, when the part's star can no longer be a seen one
                                newly_broken += (v,)
                    new_frames: list = [None]  # the new part's placement (as in grown), for each way
                    if frames[x] is not None and frames[y] is not None:  # a ring edge: does it close?
                        f += not self._closes(frames[x][0], frames[y][0], types[x], types[y], k)
                    elif frames[x] is not None and self.categories.examples.get(k):  # a tree edge: place y
                        # (a type pair without categories leaves the part unplaced)
                        fx = frames[x][0]
                        new_frames = [(fx[:3, 3], step) for step in self._steps_to(*frames[x], types[x], types[y], k)] \
                            or new_frames
                    for j, fy in enumerate(new_frames):
                        pending.append((score, faults, f, h, ci, j, y, fy, ends, newly_broken))
                clashes = np.zeros(len(pending), dtype=np.int64)
                moved = [i for i, o in enumerate(pending) if o[7] is not None]
                if near2 is not None and moved:
                    clashes[moved] = self._clashes(np.array([pending[i][6] for i in moved]),
                                                   np.array([pending[i][7][0] + pending[i][7][1][0][:3, 3]
                                                             for i in moved]),
                                                   placed[[pending[i][3] for i in moved]], near2)
                for (score, faults, f, h, ci, j, y, fy, ends, newly_broken), extra in zip(pending, clashes):
                    f_ = f + int(extra)
                    s_ = score + float(lp[cands[ci]]) - self.params.penalty * (f_ - faults)
                    heapq.heappush(best_keys, (s_, -h, -ci, -j, len(grown)))
                    if len(best_keys) > beam_size:
                        heapq.heappop(best_keys)
                    grown.append((s_, f_, h, cands[ci], y, fy, ends, newly_broken))
            kept = []
            for _, _, _, _, index in sorted(best_keys, key=lambda o: (-o[0], -o[1], -o[2], -o[3])):
                s_, f, h, k, y, fy, ends, newly_broken = grown[index]
                _, _, labels, stars, broken, frames, origins = beam[h]
                if fy is not None:
                    at, (f0, turn_y) = fy
                    frame = f0.copy()
                    frame[:3, 3] += at
                    origins = origins.copy()
                    origins[y] = frame[:3, 3]
                    frames = frames.copy()
                    frames[y] = (frame, turn_y)
                if ends:
                    stars = stars.copy()
                    for v, star in ends:
                        stars[v] = star
                kept.append((s_, f, labels + [k], stars, broken.union(newly_broken) if newly_broken else broken,
                             frames, origins))
            beam = kept
        best = beam[0]
        return dict(zip(edges, best[2])), best[1], best[0]
