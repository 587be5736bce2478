"""The grammar automaton of constrained decoding: what may follow a string's prefix.

:class:`Constraint` masks, step by step, the characters that cannot continue a valid
string: the SMILES syntax (balanced brackets, ring labels after a letter, no self-loops or
duplicate edges), node type pairs that never touch in the inputs, neighbour multisets that
no rule can still complete, a one-step look-ahead, the ring-length rule and a node budget
(docs/strings.md, "VAE"). :class:`_Prefix` is what a prefix has built so far.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from .codec import LETTERS
from .grammar import Grammar

if TYPE_CHECKING:
    from .vae import Vocab


class _Prefix:
    """What a decoded prefix has built so far, to mask impossible next tokens."""

    __slots__ = ("types", "edges", "nbrs", "prev", "stack", "rings", "after_open", "after_close", "percent",
                 "labels_here", "done", "incomplete", "parent", "depth", "ring_paths")

    def __init__(self):
        self.types: list[str] = []
        self.parent: list[int] = []  # spanning-tree parent of each atom (-1: the root)
        self.depth: list[int] = []
        self.ring_paths: list[frozenset] = []  # per closed ring: its tree edges (by child atom)
        self.edges: set = set()
        self.nbrs: list[list[str]] = []
        self.prev = None
        self.stack: list = []
        self.rings: dict[int, int] = {}
        self.after_open = self.after_close = False
        self.percent = None  # "%" or "%d" inside a two-digit label, else None
        self.labels_here: set = set()
        self.done = False
        self.incomplete: set = set()  # atoms whose neighbours are not yet a complete rule


class Constraint:
    """Per-step token masks from the string syntax and the tiling grammar."""

    def __init__(self, vocab: Vocab, grammar: Grammar, max_nodes: int | None = None):
        self.vocab, self.grammar, self.max_nodes = vocab, grammar, max_nodes
        self.pairs = set()
        self.max_count: dict[str, dict[str, int]] = {}
        for t, keys in grammar.rules.items():
            for key in keys:
                for u in key:
                    self.pairs.add((t, u))
        # Partial neighbour multisets that some rule can still complete.
        self.completable: dict[str, set] = {}
        for t, keys in grammar.rules.items():
            sub = set()
            for key in keys:
                counts = {}
                for ch in key:
                    counts[ch] = counts.get(ch, 0) + 1
                sub.add(tuple(sorted(counts.items())))
            self.completable[t] = sub
        self._fit_cache: dict = {}
        # (t, u): an atom of type u bonded to one of type t can take further neighbours
        self.through = {(t, u) for u, keys in grammar.rules.items() for key in keys if len(key) >= 2 for t in set(key)}
        self.letters = [c for c in vocab.chars if c in LETTERS]
        self.digits = [c for c in vocab.chars if c.isdigit()]

    @property
    def ring_multiple(self) -> int:
        """The grammar's ring-length rule (1: none)."""
        return self.grammar.ring_multiple

    @staticmethod
    def _tree_path(p: _Prefix, a: int, b: int) -> frozenset:
        """The spanning-tree edges between atoms ``a`` and ``b``, each named by its child
        atom; ``a`` may be the atom about to be written (``len(p.types)``, a child of ``p.prev``)."""
        path = set()
        if a == len(p.types):
            path.add(a)
            a = p.prev
        while a != b:
            if p.depth[a] < p.depth[b]:
                a, b = b, a
            path.add(a)
            a = p.parent[a]
        return frozenset(path)

    def _ring_length_ok(self, p: _Prefix, a: int, b: int) -> bool:
        """Would a ring edge from ``a`` to ``b`` keep the grammar's ring-length rule? Its
        ring (tree path + itself) and the rings closed before it are the string's cycle
        basis; see :func:`~procmod.strings.grammar.ring_rule_breaks` for the test."""
        if self.ring_multiple == 1:
            return True
        path = self._tree_path(p, a, b)
        if (len(path) + 1) % self.ring_multiple:
            return False
        return self.ring_multiple != 4 or all(len(path & q) % 2 == 0 for q in p.ring_paths)

    def _fits(self, t: str, nbrs: list[str], wild: int = 0) -> bool:
        """Can some rule of type ``t`` hold the neighbours ``nbrs`` plus ``wild`` more of
        any type (the atom's open ring labels, each a neighbour still to come)?"""
        key = (t, "".join(sorted(nbrs)), wild)
        hit = self._fit_cache.get(key)
        if hit is None:
            counts = {}
            for ch in nbrs:
                counts[ch] = counts.get(ch, 0) + 1
            hit = t in self.completable and any(
                all(dict(k).get(ch, 0) >= n for ch, n in counts.items()) and sum(n for _, n in k) >= len(nbrs) + wild
                for k in self.completable[t])
            self._fit_cache[key] = hit
        return hit

    @staticmethod
    def _pending(rings: dict, a: int) -> int:
        """Open ring labels on atom ``a``: neighbours it has promised."""
        return sum(1 for x in rings.values() if x == a)

    def _edge_ok(self, p: _Prefix, a: int, b_type: str, b: int | None) -> bool:
        """May atom ``a`` bond to a new atom of type ``b_type`` (``b`` None), or, closing a
        ring ``a`` opened, to the current atom ``b``? Open ring labels count as neighbours."""
        ta = p.types[a]
        if (ta, b_type) not in self.pairs:
            return False
        wild_a = self._pending(p.rings, a) - (b is not None)  # closing consumes one of a's labels
        if not self._fits(ta, p.nbrs[a] + [b_type], wild_a):
            return False
        if b is not None:
            if b == a or (min(a, b), max(a, b)) in p.edges:
                return False
            return self._fits(b_type, p.nbrs[b] + [ta], self._pending(p.rings, b))
        return True

    def allowed(self, p: _Prefix, wrap_nodes: int | None = None) -> list[str]:
        """Characters (and '' for end) that may follow the prefix without a dead end one
        step later (see :meth:`viable_after`). From ``wrap_nodes`` nodes on, no new ring
        label or branch is opened (unless nothing else is allowed)."""
        out = [c for c in self._allowed(p) if self.viable_after(p, c)]
        if wrap_nodes is not None and len(p.types) >= wrap_nodes and p.percent is None:
            closing = [c for c in out if self.closes(p, c) or c in LETTERS or (c == "%" and any(k >= 10 for k in p.rings))]
            out = closing or out
        return out

    @staticmethod
    def closes(p: _Prefix, c: str) -> bool:
        """Does ``c`` end something open: the string, a branch, or a ring (a label digit
        that completes an open label)?"""
        if c in ("", ")"):
            return True
        if not c.isdigit():
            return False
        if p.percent == "%":
            return False
        label = int(p.percent[1] + c) if p.percent is not None else int(c)
        return label in p.rings

    def _allowed(self, p: _Prefix) -> list[str]:
        if p.percent == "%":
            return [d for d in self.digits if d != "0"]
        if p.percent is not None:
            return [d for d in self.digits if self._label_ok(p, int(p.percent[1] + d))]
        out = []
        budget_left = self.max_nodes is None or len(p.types) < self.max_nodes
        for c in self.letters if budget_left else ():
            if p.prev is None:
                if not p.types:
                    out.append(c)
            elif self._edge_ok(p, p.prev, c, None):
                out.append(c)
        if p.prev is None:
            return out
        letter_next = bool(out)  # some letter may bond to the current atom
        if not p.after_open:
            if not p.after_close:
                out += [d for d in self.digits if d != "0" and self._label_ok(p, int(d))]
                if "%" in self.vocab.chars and any(self._label_ok(p, k) for k in range(10, 100)):
                    out.append("%")
            if letter_next:
                out.append("(")  # a branch must be able to start with a letter
        if p.stack and not p.after_open:
            out.append(")")
        if not p.stack and not p.rings and not p.after_open:
            if all("".join(sorted(n)) in self.grammar.rules.get(t, ()) for t, n in zip(p.types, p.nbrs)):
                out.append("")
        return out

    def _complete(self, t: str, nbrs: list[str]) -> bool:
        return "".join(sorted(nbrs)) in self.grammar.rules.get(t, ())

    def _has_room(self, p: _Prefix, a: int, extra: dict) -> bool:
        nb = extra.get(a, p.nbrs[a])
        return self._fits(p.types[a], nb, self._pending(p.rings, a) + 1)

    def viable_after(self, p: _Prefix, c: str) -> bool:
        """One-step look-ahead: after ``c``, can every unfinished atom still get neighbours?

        Atoms that may still gain neighbours are the current one, the branch points on the
        stack and atoms with an open ring label; an unfinished atom outside them is a dead end.
        """
        if c == "(" and p.percent is None:
            # a branch must be able to go on: some letter after it must pass this same check
            q = _Prefix()
            for name in _Prefix.__slots__:
                setattr(q, name, getattr(p, name))
            q.stack, q.after_open = p.stack + [p.prev], True
            return any(self._edge_ok(q, q.prev, l, None) and self.viable_after(q, l) for l in self.letters)
        if c in ("", "%") or (p.percent == "%"):
            return True
        current, stack, openers = p.prev, list(p.stack), dict(p.rings)
        changed: dict[int, list[str]] = {}
        new_type = None
        if c in LETTERS:
            new_type = c
            current = len(p.types)
            if p.prev is not None:
                changed[p.prev] = p.nbrs[p.prev] + [c]
        elif c == ")":
            current = stack.pop()
        else:  # a ring label digit
            label = int(p.percent[1] + c) if p.percent is not None else int(c)
            if label in openers:
                b = openers.pop(label)
                changed[b] = p.nbrs[b] + [p.types[p.prev]]
                changed[p.prev] = p.nbrs[p.prev] + [p.types[b]]
            else:
                openers[label] = p.prev
        incomplete = set(p.incomplete)
        for a, nb in changed.items():
            if self._complete(p.types[a], nb):
                incomplete.discard(a)
            else:
                incomplete.add(a)
        types = p.types if new_type is None else p.types + [new_type]
        nbrs_of = dict(changed)
        if new_type is not None:
            nbrs_of[current] = [p.types[p.prev]] if p.prev is not None else []
            if not self._complete(new_type, nbrs_of[current]):
                incomplete.add(current)
        active = {current, *stack, *openers.values()}
        if not incomplete <= active:
            return False
        if incomplete or openers:
            budget = self.max_nodes is None or len(types) < self.max_nodes
            def room(a):
                nb = nbrs_of.get(a, p.nbrs[a] if a < len(p.nbrs) else [])
                return self._fits(types[a], nb, self._pending(openers, a) + 1)
            if not any(room(a) for a in {current, *stack}):
                return False
            if openers and not self._can_close(types, nbrs_of, p, current, stack, openers):
                return False
            if not budget and incomplete - set(openers.values()) - {current, *stack}:
                return False
        return True

    def _can_close(self, types, nbrs_of, p, current, stack, openers) -> bool:
        """Can the open rings still be reached? The current atom closes one now, or some
        atom on the active path can take a neighbour that is not a leaf there (some rule of
        its type holds that atom and more): a path goes on through it, or it closes a ring
        itself. (A leaf that bonds to an opener's type closes nothing: the ring edge would be
        its second neighbour. Counting it let colonnade decoding run into dead ends — a
        column with its three beams, a floor tile left to add, a ring still open.) A
        necessary condition only."""
        nb = lambda a: nbrs_of.get(a, p.nbrs[a] if a < len(p.nbrs) else [])
        for o in set(openers.values()):
            if o != current and self._ring_length_ok(p, current, o) and (types[current], types[o]) in self.pairs and \
                    self._fits(types[current], nb(current) + [types[o]], self._pending(openers, current)) and \
                    self._fits(types[o], nb(o) + [types[current]], self._pending(openers, o) - 1):
                return True
        for a in {current, *stack}:
            for u in self.letters:
                if (types[a], u) in self.pairs and self._fits(types[a], nb(a) + [u], self._pending(openers, a)) and \
                        (types[a], u) in self.through:
                    return True
        return False

    def _label_ok(self, p: _Prefix, label: int) -> bool:
        a = p.prev
        if label in p.labels_here:
            return False
        if label in p.rings:
            b = p.rings[label]
            return self._ring_length_ok(p, a, b) and self._edge_ok(p, b, p.types[a], a)
        # opening: the atom must be able to take one more neighbour of some type, and the node
        # budget must leave room to write the ring's other end
        if self.max_nodes is not None and len(p.types) >= self.max_nodes:
            return False
        return len(p.rings) < 99 and self._fits(p.types[a], p.nbrs[a], self._pending(p.rings, a) + 1)

    def advance(self, p: _Prefix, c: str) -> None:
        if c == "":
            p.done = True
        elif c in LETTERS:
            v = len(p.types)
            p.types.append(c)
            p.nbrs.append([])
            p.parent.append(-1 if p.prev is None else p.prev)
            p.depth.append(0 if p.prev is None else p.depth[p.prev] + 1)
            p.incomplete.add(v)
            if p.prev is not None:
                self._add_edge(p, p.prev, v)
            p.prev, p.after_open, p.after_close, p.labels_here = v, False, False, set()
        elif c == "(":
            p.stack.append(p.prev)
            p.after_open = True
        elif c == ")":
            p.prev = p.stack.pop()
            p.after_close = True
        elif c == "%":
            p.percent = "%"
        elif c.isdigit():
            if p.percent == "%":
                p.percent = "%" + c
                return
            label = int(p.percent[1] + c) if p.percent is not None else int(c)
            p.percent = None
            p.labels_here.add(label)
            if label in p.rings:
                b = p.rings.pop(label)
                if self.ring_multiple > 1:
                    p.ring_paths.append(self._tree_path(p, p.prev, b))
                self._add_edge(p, b, p.prev)
            else:
                p.rings[label] = p.prev

    def _add_edge(self, p, a, b):
        p.edges.add((min(a, b), max(a, b)))
        p.nbrs[a].append(p.types[b])
        p.nbrs[b].append(p.types[a])
        for x in (a, b):
            if self._complete(p.types[x], p.nbrs[x]):
                p.incomplete.discard(x)
            else:
                p.incomplete.add(x)
