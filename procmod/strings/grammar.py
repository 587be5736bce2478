"""Tiling-grammar rules (seed 001, section 3) and the ring-length rule.

The tiling grammar (:class:`Grammar`) is what the input shapes show: for each node type,
the multisets of neighbour types a node of that type may have. A graph is valid when it is
connected and every node's neighbour multiset was seen for its type; a shape is valid when
the graph recomputed from its geometry is (:func:`validate_shape`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import networkx as nx

from .codec import GraphError
from .contacts import shape_graph
from .shapes import Shape, ShapeSet


def neighbour_key(g: nx.Graph, v) -> str:
    """The sorted letters of ``v``'s neighbours' types (its neighbour multiset)."""
    return "".join(sorted(g.nodes[u]["type"] for u in g.neighbors(v)))


RING_MULTIPLE_KEY = "ring_length_multiple"  # in the rules' JSON: never a type letter


# A ring-length rule "every ring is a multiple of m parts long" is adopted only when the
# graphs it is learned from would show it by chance with at most this probability (see
# ring_multiple_of).
RING_RULE_CHANCE = 0.05


def forced_ring_multiple(rules: dict) -> int:
    """2 when the type rules alone make every ring even (the types that touch split in two
    classes, every contact across: cells and links), else 1. No data is needed for that."""
    types = nx.Graph()
    for t, keys in rules.items():
        types.add_node(t)
        for key in keys:
            for u in key:
                types.add_edge(t, u)
    return 2 if types.number_of_nodes() and nx.is_bipartite(types) else 1


def ring_multiple_of(lengths, forced: int = 1) -> int:
    """The ring-length rule learned from the cycle-basis lengths of some graphs: the largest
    ``m`` in 4, 2 that divides every length, that the data support and that the type rules
    do not force already (``forced``, :func:`forced_ring_multiple`: what they make every
    ring a multiple of, which needs no rule); else 1 (no rule).

    The data support ``m`` when so many rings being multiples of ``m`` would be unlikely
    were it no rule: if each ring's length were as likely to leave any remainder mod ``m``
    that the type rules allow (``forced`` of them fixed), ``k`` rings would all be
    multiples with probability ``(forced / m) ** k``; the rule is adopted when that is at
    most :data:`RING_RULE_CHANCE` (5%). So 4 needs 5 rings when the rules force even rings
    (3 when they do not), 2 needs 5. Grids of cells and links have rings of 4n parts, but
    two rings of 8 and 12 parts prove nothing: another set may close a ring of 10 parts.

    Only 2 and 4: for them "every cycle" can be checked on a cycle basis (see
    :func:`ring_rule_breaks`); a larger common divisor is what a handful of rings happen to
    share (one input ring 28 long must not make every ring 28 long)."""
    lengths = [int(n) for n in lengths]
    g = 0
    for n in lengths:
        g = math.gcd(g, n)
    for m in (4, 2):
        if m <= forced:
            break
        if g and g % m == 0 and (forced / m) ** len(lengths) <= RING_RULE_CHANCE:
            return m
    return 1


def ring_rule_note(graphs, grammar: "Grammar") -> str:
    """One line on the ring-length rule ``grammar`` learned from ``graphs``, and why."""
    lengths = [len(c) for g in graphs for c in nx.cycle_basis(g)]
    forced = forced_ring_multiple(grammar.rules)
    m = grammar.ring_multiple
    g = 0
    for n in lengths:
        g = math.gcd(g, n)
    top = math.gcd(g, 4) if g else 1
    # (of rings the shapes lack, what the type rules would make of any)
    even = (f"; {'every ring is' if lengths else 'any ring would be'} even: the types that touch alternate in two "
            "classes") if forced == 2 else ""
    if m > 1:
        return (f"rings: every ring is a multiple of {m} parts long ({len(lengths)} rings, all multiples: chance "
                f"{(forced / m) ** len(lengths):.2g} <= {RING_RULE_CHANCE} were it no rule)")
    if top > forced:
        return (f"rings: all {len(lengths)} are multiples of {top} parts long, too few to make that a rule "
                f"(chance {(forced / top) ** len(lengths):.2g} > {RING_RULE_CHANCE})" + even)
    return f"rings: no ring-length rule ({len(lengths)} rings{', all even' if lengths and g % 2 == 0 else ''})" + even


def ring_rule_breaks(cycles: list[set], multiple: int) -> list[str]:
    """Why the cycles spanned by a cycle basis (each basis cycle as its set of edges) are not
    all a multiple of ``multiple`` (2 or 4) long; empty when they are.

    Every cycle is a sum (symmetric difference) of basis cycles, and
    ``|A + B| = |A| + |B| - 2 |A & B|`` (further terms are multiples of 4), so every cycle is
    a multiple of 2 long iff every basis cycle is, and a multiple of 4 iff every basis cycle
    is and every two share an even number of edges."""
    rule = f"every ring of the shapes the grammar was learned from is a multiple of {multiple} parts long"
    out = [f"a ring of {len(c)} parts; {rule}" for c in cycles if len(c) % multiple]
    if multiple == 4 and not out:
        for i, a in enumerate(cycles):
            for b in cycles[i + 1:]:
                k = len(a & b)
                if k % 2:
                    out.append(f"rings of {len(a)} and {len(b)} parts share {k} contacts, so the ring around "
                               f"both is {len(a) + len(b) - 2 * k} long; {rule}")
    return out


@dataclass
class Grammar:
    """Tiling-grammar rules: node type -> the neighbour multisets seen for it (sorted letters);
    and the ring-length rule: every cycle's length (parts) is a multiple of
    ``ring_multiple`` (learned by :func:`ring_multiple_of` from the graphs' cycle bases; 1:
    no rule).

    The neighbour multisets say nothing about how long a ring is, yet a ring of the wrong
    length has no embedding: in the example sets every ring alternates cells (towers,
    modules, columns) and links (walls, corridors, beams) on a square grid, so every ring
    is a multiple of 4 long, and before this rule most novel VAE samples had a ring that no
    placement of the parts realises (docs/strings.md, "Ring-length rule")."""

    rules: dict
    ring_multiple: int = 1

    @staticmethod
    def from_graphs(graphs) -> "Grammar":
        """The rules the graphs show; the ring-length rule where the type rules force it or
        the graphs' rings (every cycle-basis ring of every graph) support it
        (:func:`ring_multiple_of`)."""
        rules: dict[str, set] = {}
        lengths = []
        for g in graphs:
            for v in g.nodes:
                rules.setdefault(g.nodes[v]["type"], set()).add(neighbour_key(g, v))
            lengths += [len(c) for c in nx.cycle_basis(g)]
        rules = {t: frozenset(keys) for t, keys in rules.items()}
        return Grammar(rules, ring_multiple_of(lengths, forced_ring_multiple(rules)))

    def bad_rings(self, g: nx.Graph) -> list[str]:
        """Why ``g``'s rings break the ring-length rule (empty: they keep it)."""
        if self.ring_multiple == 1:
            return []
        cycles = [{frozenset(e) for e in zip(c, c[1:] + c[:1])} for c in nx.cycle_basis(g)]
        return ring_rule_breaks(cycles, self.ring_multiple)

    @property
    def types(self) -> list[str]:
        return sorted(self.rules)

    def violations(self, g: nx.Graph, limit: int = 5) -> list[str]:
        """Why ``g`` breaks the grammar (empty when it is valid); at most ``limit`` reasons."""
        if not isinstance(g, nx.Graph):
            raise GraphError(f"violations takes a shape graph (a networkx.Graph), got {type(g).__name__} "
                             f"{g!r:.40}" + ("; decode(text) reads a string" if isinstance(g, str) else ""))
        out = []
        if g.number_of_nodes() == 0:
            return ["the graph has no nodes"]
        if not nx.is_connected(g):
            out.append(f"the graph has {nx.number_connected_components(g)} connected parts, not one")
        for v in g.nodes:
            t = g.nodes[v]["type"]
            if t not in self.rules:
                out.append(f"node {v}: type {t!r} does not occur in the input shapes")
            else:
                key = neighbour_key(g, v)
                if key not in self.rules[t]:
                    allowed = ", ".join(sorted(k or "-" for k in self.rules[t]))
                    out.append(f"node {v} ({t}) has neighbours {key or '-'}; the rules allow {allowed}")
            if len(out) >= limit:
                return out
        return out + self.bad_rings(g)[:limit - len(out)]

    def is_valid(self, g: nx.Graph) -> bool:
        if g.number_of_nodes() == 0 or not nx.is_connected(g):
            return False
        return all(g.nodes[v]["type"] in self.rules and neighbour_key(g, v) in self.rules[g.nodes[v]["type"]]
                   for v in g.nodes) and not self.bad_rings(g)

    def node_ok(self, g: nx.Graph, v) -> bool:
        t = g.nodes[v]["type"]
        return t in self.rules and neighbour_key(g, v) in self.rules[t]

    def to_json(self) -> dict:
        """``{type: [neighbour keys]}``, plus ``"ring_length_multiple"`` when there is a ring rule."""
        out = {t: sorted(keys) for t, keys in sorted(self.rules.items())}
        if self.ring_multiple > 1:
            out[RING_MULTIPLE_KEY] = self.ring_multiple
        return out

    @staticmethod
    def from_json(data) -> "Grammar":
        """The inverse of :meth:`to_json` (grammars saved before the ring rule have none).
        Content of another shape (an edited model file) is a ValueError saying what is wrong."""
        if not isinstance(data, dict):
            raise ValueError(f"a grammar must be a JSON object of node types, got {type(data).__name__}")
        for t, keys in data.items():
            if t != RING_MULTIPLE_KEY and (not isinstance(keys, list) or not all(isinstance(k, str) for k in keys)):
                raise ValueError(f"the grammar's rule for {t!r:.20} must be a list of neighbour keys (strings), got "
                                 f"{keys!r:.40}")
        rules = {t: frozenset(keys) for t, keys in data.items() if t != RING_MULTIPLE_KEY}
        multiple = data.get(RING_MULTIPLE_KEY, 1)
        if isinstance(multiple, bool) or not isinstance(multiple, int) or not 1 <= multiple <= 1_000_000:
            raise ValueError(f"{RING_MULTIPLE_KEY} must be a whole number from 1 (no ring rule) up, got "
                             f"{multiple!r:.40}")
        return Grammar(rules, multiple)


def validate_shape(shape_set: ShapeSet, shape: Shape, grammar: Grammar, tol: float | None = None) -> list[str]:
    """Geometric validation: recompute the shape graph and check it against ``grammar``."""
    return grammar.violations(shape_graph(shape_set, shape, tol))
