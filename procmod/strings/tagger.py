"""The edge-category tagger (seed 001, section 6): a recurrent net that maps a string to
one edge category per character (a dummy one for brackets, bonds and the root); logits of
categories the edge's type pair does not have are set to -inf. A string's labels are
decoded jointly (:mod:`procmod.strings.decoding`: every part's star of categories seen in
training, every ring closed, parts kept apart), then several strings of one graph vote
(:meth:`TaggerModel.vote`). Training targets, training with checkpoints and resume, and
the held-out accuracy are here too.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import networkx as nx
import numpy as np
import torch
from torch import nn

from ..core.errors import InvalidArgumentError, argument
from ..core.io import fingerprint, load_tensors, read_json, write_text_atomic
from .automorphisms import type_automorphisms
from .categories import EdgeCategories, shape_labelings
from .codec import RingLimitError, encode_with_order, parse
from .decoding import CategoryDecoder, star_set
from .frames import canonical_frame, proper_placement
from .shapes import ShapeSet, first_poses
from .torch_utils import (ModelFileError, OtherTrainingError, check_finite_weights, config_from_json, load_weights,
                          reading_model_file, save_weights, torch_threads, training_device, training_state)
from .vae import Vocab, _characters, check_sizes


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

    def check(self) -> None:
        if self.cell not in ("gru", "lstm"):
            raise InvalidArgumentError(f"cell must be 'gru' or 'lstm', got {self.cell!r}")
        check_sizes(self, {"embed": 4096, "hidden": 4096, "layers": 16, "epochs": 1_000_000, "batch": 1_000_000})
        if not 0 <= self.graph_rounds <= 64:
            raise InvalidArgumentError(f"graph_rounds must be from 0 to 64, got {self.graph_rounds}")
        if not (0 < self.lr < math.inf and 0 < self.lr_final <= 1 and 0 <= self.dropout < 1):
            raise InvalidArgumentError(f"lr must be a finite number > 0 (got {self.lr}), lr_final in (0, 1], dropout "
                                       "in [0, 1)")


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


def drawn_string(g, k: int, rng: np.random.Generator) -> tuple[str, list[int]] | None:
    """The ``k``-th string a tagger reads of graph ``g`` and its node order: the walk from
    node 0 first, then random walks; None for a walk that leaves more rings open than the
    syntax has labels (a part touching a hundred others), the walk from node 0 then
    replaced by the canonical string, which never does."""
    try:
        return encode_with_order(g, None if k else 0, rng if k else None)
    except RingLimitError:
        return encode_with_order(g) if k == 0 else None


def tagging_examples(shape_set: ShapeSet, shapes, graphs, categories: "EdgeCategories", per_shape: int,
                     rng: np.random.Generator, every_symmetry: bool = False,
                     automorphisms: int = 64) -> list[tuple[str, list]]:
    """(string, target category per character) pairs from shapes, ``per_shape`` strings each
    (targets by :func:`canonical_targets`); with ``every_symmetry`` the targets are the list
    of :func:`symmetric_targets` instead (the canonical one first). The labellings are the
    shape's up to its turns, mirrors and graph automorphisms (``automorphisms``, as
    :func:`~procmod.strings.categories.shape_labelings`); the strings drawn do not depend on them."""
    out = []
    for shape, g in zip(shapes, graphs):
        labelings = shape_labelings(shape_set, shape, g, categories, automorphisms)
        if not labelings:
            continue
        seen = set()
        for k in range(4 * per_shape):
            if len(seen) >= per_shape:
                break
            drawn = drawn_string(g, k, rng)
            if drawn is None:
                continue
            text, order = drawn
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
    its input pose under every turn and mirror of ``categories.symmetries``."""
    frame_of, roots = None, None
    if shape_set is not None:
        lib, part_of = shape_set.library, shape_set.part_of_letter
        frame_of = lambda t, pose: canonical_frame(lib, part_of[t], pose, categories.groups)  # noqa: E731
        roots = {t: [m for g in categories.symmetries
                     if (m := proper_placement(lib, part_of[t], g @ pose)) is not None]
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
            text, order = drawn_string(g, k, rng) or encode_with_order(g)  # (the canonical one always fits)
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
        save_weights(folder / "tagger.pt", self.net, optimizer)
        meta = {"format": "procmod-string-tagger/1", "config": asdict(self.net.config), "vocab": self.vocab.chars,
                "categories": self.categories.to_json(), "train": state or {"epoch": 0, "history": []}}
        if self.stars is not None:
            meta["stars"] = [[t, list(ks)] for t, ks in self.stars]
        write_text_atomic(folder / "tagger.json", json.dumps(meta) + "\n")

    @staticmethod
    def load(folder, with_optimizer: bool = False):
        folder = Path(folder)
        meta = read_json(folder / "tagger.json", ModelFileError, "edge-category tagger metadata")
        payload = load_tensors(folder / "tagger.pt", ModelFileError, "edge-category tagger's weights")
        where = str(folder / "tagger.json")
        if not isinstance(meta, dict):
            raise ModelFileError(f"{where} must hold a JSON object, got {type(meta).__name__}")
        given = meta.get("config")
        # taggers saved before the tree pass existed are plain bidirectional LSTMs
        # and before the graph pass existed, taggers had none
        config = config_from_json(TaggerConfig, {"tree": False, "graph_rounds": 0, **given}
                                  if isinstance(given, dict) else given, f"{where}: config")
        with reading_model_file(where):
            cats = EdgeCategories.from_json(meta["categories"])
            vocab = Vocab(_characters(meta["vocab"], f"{where}: vocab"))
            net = Tagger(len(vocab), len(cats), config)
            load_weights(net, payload["model"], folder / "tagger.pt", where)
            check_finite_weights(net, str(folder / "tagger.pt"))
            # taggers saved before structured decoding existed have no stars (rings are still checked)
            stars = [(t, tuple(ks)) for t, ks in meta["stars"]] if "stars" in meta else None
            model = TaggerModel(net, vocab, cats, stars)
            state = training_state(meta.get("train"), f"{where}: train")
        if with_optimizer:
            return model, state, payload.get("optimizer")
        return model


def train_tagger(examples: list, vocab: Vocab, categories: EdgeCategories, folder, config: TaggerConfig = TaggerConfig(),
                 seed: int = 0, progress=None, device: str | None = None) -> TaggerModel:
    """Train (or resume, on any device) the tagger on (string, targets) pairs, checkpointing
    every epoch; ``device``: see :func:`~procmod.strings.torch_utils.training_device` (the model
    comes back on the CPU)."""
    dev = training_device(device)
    with torch_threads():
        model = _train_tagger(examples, vocab, categories, folder, config, seed, progress, dev)
    model.net.to("cpu")
    return model


def examples_fingerprint(examples: list) -> str:
    """The fingerprint of (string, targets) training pairs (targets may hold numpy ints)."""
    plain = lambda o: o.tolist() if hasattr(o, "tolist") else int(o)  # noqa: E731
    return fingerprint(json.dumps([[text, targets] for text, targets in examples], default=plain))


def _train_tagger(examples, vocab, categories, folder, config, seed, progress, device) -> TaggerModel:
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(seed)
    data = examples_fingerprint(examples)
    if (folder / "tagger.json").is_file() and (folder / "tagger.pt").is_file():
        model, state, opt_state = TaggerModel.load(folder, with_optimizer=True)
        if {**asdict(model.net.config), "epochs": 0} != {**asdict(config), "epochs": 0}:
            raise OtherTrainingError(f"{folder} holds a tagger of another configuration; use a new "
                                 f"{argument('folder')}")
        if state.get("data") not in (None, data):  # None: saved before the fingerprint was kept
            raise OtherTrainingError(f"{folder} holds a tagger trained on other strings: another collection (or one "
                                 f"grown again), or other {argument('seed')} / {argument('tagger_strings_per_shape')} "
                                 f"/ {argument('held_out')} than it was trained with; repeat those, or use a new "
                                 f"{argument('folder')}")
        if state["epoch"] > config.epochs:  # it would be kept as it is, recorded as trained for fewer
            raise OtherTrainingError(f"{folder} holds a tagger trained {state['epoch']} epochs, more than the "
                                 f"{config.epochs} asked: ask for at least {state['epoch']} to go on from it, or "
                                 f"use a new {argument('folder')}")
        adopt = state.get("data") is None  # saved before the fingerprint was kept: keep it from now on
        state["data"] = data
    else:
        adopt = False
        model, state, opt_state = TaggerModel(Tagger(len(vocab), len(categories), config), vocab, categories), \
            {"epoch": 0, "history": [], "data": data}, None
    model.net.to(device)
    optimizer = torch.optim.Adam(model.net.parameters(), lr=config.lr)
    if opt_state is not None:
        optimizer.load_state_dict(opt_state)  # moves the moments to the parameters' device
    if adopt:
        model.save(folder, state, optimizer)
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
        gen = torch.Generator().manual_seed((seed * 7919 + state["epoch"]) % 2 ** 63)  # see vae.train_vae
        # dropout draws from torch's global generators: seeded by the epoch too, so a resumed
        # training draws the masks an uninterrupted one would (seeded once at the start, a
        # resume had trained another tagger)
        torch.manual_seed((seed * 104729 + state["epoch"] + 1) % 2 ** 63)
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
