"""Shape graphs as strings: SMILES' topology syntax (seed 001, section 5.1).

A shape graph is an undirected :class:`networkx.Graph` whose nodes are ``0 .. n-1`` and
carry a ``"type"`` attribute, one letter ``A-Z`` / ``a-z``. Its strings are SMILES strings
made of single-letter atoms and single bonds:

- one letter per node, in depth-first order of a spanning tree;
- a branch in parentheses, the last subtree at a node unbracketed;
- each non-tree (cycle) edge as one ring-closure label written after both of its nodes:
  ``1`` .. ``9``, then ``%10`` .. ``%99``; a label is free again once its ring is closed.

Decoding also accepts what any SMILES parser accepts of that subset: the label ``0``,
explicit single bonds ``-`` (before an atom, a ring label or inside ``(``), and labels reused
after closing (``C1CC1C1CC1``). Every string :func:`encode` writes uses labels 1-9 then
``%10``..``%99`` and never reuses a label on the atom that closed it.

Decoding also maps every character to the graph edge it stands for (section 6, "edge
category mapping"): a letter to the edge to its spanning-tree parent (none for the root),
each character of a ring label to that ring's edge, and brackets / bonds to nothing.

The canonical string (:func:`encode` with no root and no ``rng``) is a function of the
graph up to isomorphism (with node types): renumbering the nodes gives the same string,
and only isomorphic graphs share one. It is written from the canonical ranks of
:func:`procmod.strings.canon.canonical_ranks` (colour refinement, with every tie left
after refinement broken by trying each tied node and keeping the smallest certificate;
see that module): the depth-first traversal starts at the node of rank 0 and goes on to
the unvisited neighbour that closes the most rings (has the most visited neighbours),
ties to the lowest rank, and everything after that (branches, ring labels) follows from
the traversal. Given a ``root`` and no ``rng``, :func:`encode` writes the string from
that root with neighbours in node-number order instead: deterministic, but a function of
the numbering, not canonical.
"""

from __future__ import annotations

import collections
import heapq
from dataclasses import dataclass

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError, ProcmodError
from .canon import canonical_ranks

LETTERS = frozenset("ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz")
MAX_LABEL = 99


class StringSyntaxError(ProcmodError):
    """A string that is not a valid shape-graph string; the message says where it breaks."""


class GraphError(ProcmodError):
    """A graph that cannot be written as a string (bad node type, disconnected, too many rings)."""


def _label_text(label: int) -> str:
    return str(label) if label < 10 else f"%{label:02d}"


def _where(text: str, i: int) -> str:
    return f"at position {i + 1} of {text!r} (…{text[max(0, i - 8):i]}>>{text[i:i + 1]}<<{text[i + 1:i + 9]}…)"


@dataclass(frozen=True)
class ParsedString:
    """A decoded string: its graph, plus the edge each character stands for.

    ``char_edges[i]`` is ``(u, v)`` for the edge character ``i`` stands for, oriented from
    the spanning-tree parent to the child (letters) or from the ring's opening node to its
    closing node (ring labels); ``None`` for brackets, bonds and the root letter.
    ``char_nodes[i]`` is the node a letter stands for (``None`` elsewhere).
    """

    text: str
    graph: nx.Graph
    char_edges: tuple
    char_nodes: tuple


def parse(text: str) -> ParsedString:
    """Decode a string into its graph and per-character edge mapping.

    Raises
    ------
    StringSyntaxError
        Naming the position of the first problem: an unknown character, an unbalanced
        parenthesis, a branch or ring label with no atom before it, an empty branch, a ring
        label left open (dangling), a ring closing onto its own atom or duplicating an edge.
    """
    if not isinstance(text, str):
        raise StringSyntaxError(f"a shape-graph string must be a str, got {type(text).__name__} {text!r:.40}")
    if not text:
        raise StringSyntaxError("empty string: a shape-graph string has at least one letter")
    g = nx.Graph()
    char_edges: list = [None] * len(text)
    char_nodes: list = [None] * len(text)
    stack: list[tuple[int | None, int]] = []  # (atom before "(", position of "(")
    prev: int | None = None  # the atom the next atom bonds to
    open_rings: dict[int, tuple[int, int]] = {}  # label -> (atom, position of the label)
    pending_bond: int | None = None  # position of a "-" waiting for its atom / label
    i, n = 0, len(text)
    after_close = False  # directly after ")": a ring label here has no atom of its own
    after_open = False  # directly after "(" (or "(-"): a ")" here is an empty branch
    while i < n:
        c = text[i]
        if c in LETTERS:
            node = g.number_of_nodes()
            g.add_node(node, type=c)
            char_nodes[i] = node
            if prev is not None:
                g.add_edge(prev, node)
                char_edges[i] = (prev, node)
            elif node > 0:
                raise StringSyntaxError(f"letter {c!r} is not bonded to anything {_where(text, i)}; "
                                        "only one connected graph per string ('.' is not supported)")
            prev, pending_bond, after_open, after_close = node, None, False, False
            i += 1
        elif c.isdigit() or c == "%":
            start = i
            if c == "%":
                digits = text[i + 1:i + 3]
                if len(digits) != 2 or not digits.isdigit():
                    raise StringSyntaxError(f"'%' must be followed by two digits (%10 .. %99) {_where(text, i)}")
                label, i = int(digits), i + 3
            else:
                label, i = int(c), i + 1
            if after_close:
                raise StringSyntaxError(f"ring label {text[start:i]!r} after ')' {_where(text, start)}; a ring "
                                        "label follows its letter directly")
            if prev is None or after_open:
                raise StringSyntaxError(f"ring label {text[start:i]!r} has no atom before it {_where(text, start)}")
            if label in open_rings:
                other, opened_at = open_rings.pop(label)
                if other == prev:
                    raise StringSyntaxError(f"ring label {text[start:i]!r} closes onto the same atom it opened "
                                            f"on, {_where(text, start)} (a self-loop)")
                if g.has_edge(other, prev):
                    raise StringSyntaxError(f"ring label {text[start:i]!r} duplicates the edge between its two "
                                            f"atoms {_where(text, start)}; shape graphs have no multi-edges")
                g.add_edge(other, prev)
                for k in range(start, i):
                    char_edges[k] = (other, prev)
                for k in range(opened_at, opened_at + (3 if text[opened_at] == "%" else 1)):
                    char_edges[k] = (other, prev)
            else:
                open_rings[label] = (prev, start)
            pending_bond = None
        elif c == "(":
            if prev is None:
                raise StringSyntaxError(f"branch '(' has no atom before it {_where(text, i)}")
            if after_open:
                raise StringSyntaxError(f"branch '(' directly after '(' {_where(text, i)}; a branch starts "
                                        "with a letter")
            if pending_bond is not None:
                raise StringSyntaxError(f"bond '-' before '(' {_where(text, pending_bond)}; write the bond "
                                        "inside the branch")
            stack.append((prev, i))
            after_open, after_close = True, False
            i += 1
        elif c == ")":
            if not stack:
                raise StringSyntaxError(f"unbalanced parenthesis: ')' without a matching '(' {_where(text, i)}")
            if after_open:
                raise StringSyntaxError(f"empty branch '()' {_where(text, i)}")
            if pending_bond is not None:
                raise StringSyntaxError(f"bond '-' with no atom after it {_where(text, pending_bond)}")
            prev, _ = stack.pop()
            after_close = True
            i += 1
        elif c == "-":
            if prev is None:
                raise StringSyntaxError(f"bond '-' has no atom before it {_where(text, i)}")
            if pending_bond is not None:
                raise StringSyntaxError(f"two bonds in a row {_where(text, i)}")
            pending_bond = i
            i += 1
        elif c in "=#$:/\\.":
            raise StringSyntaxError(f"{c!r} {_where(text, i)}: shape-graph strings use single bonds only "
                                    "(letters, '(', ')', ring labels, '-')")
        else:
            raise StringSyntaxError(f"unknown character {c!r} {_where(text, i)}; node types are single "
                                    "letters A-Z or a-z")
    if stack:
        raise StringSyntaxError(f"unbalanced parenthesis: '(' never closed {_where(text, stack[-1][1])}")
    if pending_bond is not None:
        raise StringSyntaxError(f"bond '-' with no atom after it {_where(text, pending_bond)}")
    if open_rings:
        label, (_, pos) = min(open_rings.items(), key=lambda item: item[1][1])
        raise StringSyntaxError(f"dangling ring label {_label_text(label)!r}: opened "
                                f"{_where(text, pos)} and never closed")
    if g.number_of_nodes() == 0:
        raise StringSyntaxError(f"{text!r} has no letters: a shape-graph string has at least one node")
    return ParsedString(text, g, tuple(char_edges), tuple(char_nodes))


def _check_rng(rng) -> None:
    if rng is not None and not isinstance(rng, np.random.Generator):
        raise InvalidArgumentError(f"rng must be a numpy Generator (numpy.random.default_rng(seed)), got "
                                   f"{type(rng).__name__} {rng!r:.40}")


def decode(text: str) -> nx.Graph:
    """The graph a string stands for (nodes numbered in string order, attribute ``type``).
    Whitespace around it (a line read from a file, with its CR) is not part of it."""
    return parse(text.strip() if isinstance(text, str) else text).graph


def check_graph(g: nx.Graph) -> None:
    """Raise :class:`GraphError` unless ``g`` is a connected typed graph with nodes 0..n-1."""
    if not isinstance(g, nx.Graph) or g.is_directed() or g.is_multigraph():
        what = f"a networkx {type(g).__name__}" if isinstance(g, nx.Graph) else f"{type(g).__name__} {g!r:.40}"
        raise GraphError(f"expected an undirected networkx.Graph (no DiGraph or MultiGraph), got {what}"
                         + ("; decode(text) reads a string" if isinstance(g, str) else ""))
    if g.number_of_nodes() == 0:
        raise GraphError("the graph has no nodes")
    if (not all(type(v) is int or isinstance(v, np.integer) for v in g.nodes)
            or set(g.nodes) != set(range(g.number_of_nodes()))):
        raise GraphError("graph nodes must be the whole numbers 0 .. n-1 (nx.convert_node_labels_to_integers "
                         "renumbers a graph)")
    for v, t in g.nodes(data="type"):
        if not isinstance(t, str) or len(t) != 1 or t not in LETTERS:
            raise GraphError(f"node {v} has type {t!r}; node types are single letters A-Z or a-z")
    if any(u == v for u, v in g.edges):
        raise GraphError("the graph has a self-loop; shape graphs have none")
    if not nx.is_connected(g):
        raise GraphError("the graph is not connected; a string encodes one connected graph")


def encode(g: nx.Graph, root: int | None = None, rng: np.random.Generator | None = None) -> str:
    """Write ``g`` as a string (see :func:`encode_with_order`)."""
    return encode_with_order(g, root, rng)[0]


def encode_with_order(g: nx.Graph, root: int | None = None,
                      rng: np.random.Generator | None = None) -> tuple[str, list[int]]:
    """Write ``g`` as a string; also return the graph node of each letter, in string order
    (the ``k``-th letter is node ``order[k]``; decoding numbers it ``k``).

    Parameters
    ----------
    g : networkx.Graph
        Connected, nodes ``0..n-1`` with a one-letter ``"type"``.
    root : int, optional
        Where the depth-first traversal starts. Default: the canonical string (the node of
        canonical rank 0, neighbours in canonical rank order; see the module docstring),
        or a random node when ``rng`` is given.
    rng : numpy.random.Generator, optional
        When given, neighbours are visited in random order (a random string of the graph);
        otherwise in increasing canonical rank (no ``root``) or node number (a ``root``).
    """
    check_graph(g)
    _check_rng(rng)
    key = None  # neighbour order: node number, or canonical rank for the canonical string
    if root is None:
        if rng is not None:
            root = int(rng.integers(g.number_of_nodes()))
        else:
            ranks = canonical_ranks(g)
            key = ranks.__getitem__
            root = ranks.index(0)
    if root not in g:
        raise GraphError(f"root {root} is not a node of the graph")

    def order(nbrs):
        nbrs = sorted(nbrs, key=key)
        if rng is not None:
            nbrs = [nbrs[k] for k in rng.permutation(len(nbrs))]
        return nbrs

    # Depth-first spanning tree (iterative; children in visiting order).
    children: dict[int, list[int]] = {v: [] for v in g.nodes}
    seen = {root}
    preorder = [root]
    if key is not None:
        _closing_first_tree(g, root, key, seen, preorder, children)
    stack = [] if key is not None else [(root, iter(order(g.neighbors(root))))]
    while stack:
        v, it = stack[-1]
        for u in it:
            if u not in seen:
                seen.add(u)
                children[v].append(u)
                preorder.append(u)
                stack.append((u, iter(order(g.neighbors(u)))))
                break
        else:
            stack.pop()
    try:
        return _written(g, root, children, preorder)
    except _TooManyRings:
        if key is None:  # a given root or a random walk: the caller may try another
            raise RingLimitError(f"more than {MAX_LABEL} rings open at once; the string syntax cannot write this "
                                 "graph along this walk (root and order)") from None
    # The canonical walk left more rings open than there are labels: a part touching 100 or
    # more others (a floor ringed by walls) opens one for each contact the walk does not
    # take. Its contacts as tree edges instead: still one string per graph.
    children, preorder = _star_first_tree(g, root, key)
    try:
        return _written(g, root, children, preorder)
    except _TooManyRings:
        raise RingLimitError(f"more than {MAX_LABEL} rings open at once; the string syntax cannot write this graph "
                             "(too many contacts that close no ring soon)") from None


class _TooManyRings(Exception):
    pass


class RingLimitError(GraphError):
    """A graph that a string along this walk would need more ring labels for than the
    syntax has (:data:`MAX_LABEL` open at once); another walk (root, order) may not."""


def _written(g: nx.Graph, root: int, children: dict, preorder: list) -> tuple[str, list[int]]:
    """The string of ``g`` along a spanning tree (``children``: each node's, in writing
    order; ``preorder``: the nodes in the order they are written), and the node of each
    letter."""
    pos = {v: k for k, v in enumerate(preorder)}
    tree = {(min(v, u), max(v, u)) for v in children for u in children[v]}
    opens: dict[int, list[tuple[int, int]]] = {v: [] for v in g.nodes}
    closes: dict[int, list[tuple[int, int]]] = {v: [] for v in g.nodes}
    for a, b in g.edges:
        if (min(a, b), max(a, b)) in tree:
            continue
        first, second = (a, b) if pos[a] < pos[b] else (b, a)
        opens[first].append((first, second))
        closes[second].append((first, second))
    for v in g.nodes:
        opens[v].sort(key=lambda e: pos[e[1]])
        closes[v].sort(key=lambda e: pos[e[0]])

    free = list(range(1, MAX_LABEL + 1))  # kept sorted: the lowest free label is used
    label_of: dict[tuple[int, int], int] = {}
    out: list[str] = []

    written: list[int] = []

    def write_atom(v: int) -> None:
        written.append(v)
        out.append(g.nodes[v]["type"])
        released = []
        for e in closes[v]:
            label = label_of.pop(e)
            out.append(_label_text(label))
            released.append(label)
        for e in opens[v]:
            if not free:
                raise _TooManyRings()
            label = free.pop(0)
            label_of[e] = label
            out.append(_label_text(label))
        free.extend(released)  # freed only after this atom, so no label closes and reopens on one atom
        free.sort()

    # Iterative writer over an action stack (graphs may be deeper than Python's recursion limit).
    actions: list = [("node", root)]
    while actions:
        kind, v = actions.pop()
        if kind == "text":
            out.append(v)
            continue
        write_atom(v)
        kids = children[v]
        todo: list = []
        for k, child in enumerate(kids):
            if k < len(kids) - 1:
                todo += [("text", "("), ("node", child), ("text", ")")]
            else:
                todo.append(("node", child))
        actions.extend(reversed(todo))
    return "".join(out), written


def _star_first_tree(g: nx.Graph, root: int, rank) -> tuple[dict, list]:
    """The canonical string's tree where :func:`_closing_first_tree`'s needs more ring
    labels than the syntax has: breadth first, each node takes every neighbour not yet in
    the tree as its child (a hub's contacts become branches, not rings), ordered so that each next child
    touches the most of the children before it (ties to the lowest rank): a ring of walls
    around a floor is written wall after wall, each ring closing in the next branch.
    Returns ``(children, preorder)``."""
    children: dict[int, list[int]] = {v: [] for v in g.nodes}
    seen = {root}
    pending = collections.deque([root])  # breadth first: a hub near the root claims its contacts
    while pending:
        v = pending.popleft()
        new = [u for u in g.neighbors(v) if u not in seen]
        seen.update(new)
        touches = dict.fromkeys(new, 0)
        heap = [(0, rank(u), u) for u in new]
        heapq.heapify(heap)
        ordered = []
        while heap:
            count, _, u = heapq.heappop(heap)
            if u not in touches or -count != touches[u]:  # placed already, or an outdated entry
                continue
            del touches[u]
            ordered.append(u)
            for w in g.neighbors(u):
                if w in touches:
                    touches[w] += 1
                    heapq.heappush(heap, (-touches[w], rank(w), w))
        children[v] = ordered
        pending.extend(ordered)
    preorder, stack = [], [root]
    while stack:  # the order the writer writes them: a node, then its children's subtrees in turn
        v = stack.pop()
        preorder.append(v)
        stack.extend(reversed(children[v]))
    return children, preorder


def _closing_first_tree(g: nx.Graph, root: int, rank, seen: set, preorder: list, children: dict) -> None:
    """The canonical string's depth-first tree: from each call the walk goes on to the
    unvisited neighbour with the most visited neighbours (the rings it closes), ties to the
    lowest canonical rank. A function of the graph and its canonical ranks, so still one
    string per graph; walking by rank alone left a ring open for every contact across a
    grid's rows (a 60 x 3 floor of tiles opened more than the 99 ring labels the syntax
    has), where this walk sweeps a grid row by row and keeps about its width open."""
    visited_nbrs = {v: 0 for v in g.nodes}
    for u in g.neighbors(root):
        visited_nbrs[u] += 1
    # each node on the walk's stack keeps its unvisited neighbours in a heap keyed by
    # (-visited neighbours, rank); a count that rises pushes a fresh entry into the heaps
    # of the stack's nodes beside it, and outdated entries are dropped when they surface.
    # Rescanning a node's neighbours on every return to it cost degree x children: a star
    # of 20,000 leaves took a minute to encode, now a fraction of a second.
    heaps = {}

    def open_heap(v):
        heap = [(-visited_nbrs[u], rank(u), u) for u in g.neighbors(v) if u not in seen]
        heapq.heapify(heap)
        heaps[v] = heap

    open_heap(root)
    stack = [root]
    while stack:
        v = stack[-1]
        heap = heaps[v]
        best = None
        while heap:
            count, _, u = heap[0]
            if u in seen or -count != visited_nbrs[u]:  # visited since, or an outdated count
                heapq.heappop(heap)
                continue
            best = u
            break
        if best is None:
            stack.pop()
            del heaps[v]
            continue
        seen.add(best)
        children[v].append(best)
        preorder.append(best)
        for w in g.neighbors(best):
            visited_nbrs[w] += 1
            if w not in seen:
                key = (-visited_nbrs[w], rank(w), w)
                for x in g.neighbors(w):
                    if x in heaps:
                        heapq.heappush(heaps[x], key)
        open_heap(best)
        stack.append(best)


def strings_of(g: nx.Graph, count: int, rng: np.random.Generator, canonical: bool = True) -> list[str]:
    """Up to ``count`` distinct strings of ``g``: the canonical one first (if asked), then
    random ones (random roots and neighbour orders); gives up after ``4 * count`` draws."""
    _check_rng(rng)
    out = [encode(g)] if canonical else []
    seen = set(out)
    for _ in range(4 * count):
        if len(out) >= count:
            break
        try:
            s = encode(g, rng=rng)
        except RingLimitError:  # a walk that leaves too many rings open: another draw
            continue
        if s not in seen:
            seen.add(s)
            out.append(s)
    return out[:count]
