import re

import networkx as nx
import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from procmod.strings.codec import GraphError, StringSyntaxError, decode, encode, parse


def _iso(a, b):
    return nx.is_isomorphic(a, b, node_match=lambda x, y: x["type"] == y["type"])


def _graph(types, edges):
    g = nx.Graph()
    g.add_nodes_from((i, {"type": t}) for i, t in enumerate(types))
    g.add_edges_from(edges)
    return g


def test_known_smiles_ring_with_branches():
    g = decode("C1CC(N)CC1O")
    expected = _graph("CCCNCCO", [(0, 1), (1, 2), (2, 3), (2, 4), (4, 5), (5, 0), (5, 6)])
    assert sorted(g.edges) == sorted(tuple(sorted(e)) for e in expected.edges)
    assert [g.nodes[v]["type"] for v in g] == list("CCCNCCO")


@pytest.mark.parametrize("text, n, m", [
    ("C1CCCCC1", 6, 6),                   # cyclohexane
    ("c1ccccc1", 6, 6),                   # lower-case letters are node types too
    ("C1CC1C1CC1", 6, 7),                 # label 1 reused after its ring closed
    ("C12CC1C2", 4, 5),                   # two rings on one atom
    ("C%10CC%10", 3, 3),                  # two-digit labels
    ("C-C(-N)-C", 4, 3),                  # explicit single bonds
    ("CDA0(DC)DCDBDCDCD0", 14, 14),       # the paper's figure 1 (label 0)
    ("B(DCDCDA0CD)DCDCDC0", 15, 15),
    ("CDA(DC)(DC)(DCDCDCDCDCDADADADADCD0)DCDCDCDC0", 36, 36),  # the paper's figure 8
])
def test_decodes_smiles(text, n, m):
    g = decode(text)
    assert (g.number_of_nodes(), g.number_of_edges()) == (n, m)


def test_ring_label_reuse_gives_two_rings():
    g = decode("C1CC1C1CC1")
    assert len(nx.cycle_basis(g)) == 2
    assert all(len(c) == 3 for c in nx.cycle_basis(g))


@pytest.mark.parametrize("text, words", [
    ("C(C", ["unbalanced", "position 2"]),
    ("CC)C", ["unbalanced", "position 3"]),
    ("C1CC", ["dangling ring label '1'", "position 2"]),
    ("CC%12C", ["dangling ring label '%12'"]),
    ("CC?", ["unknown character '?'", "position 3"]),
    ("C=C", ["single bonds"]),
    ("C.C", ["single bonds"]),
    ("(C)", ["no atom before"]),
    ("1CC1", ["no atom before"]),
    ("C()", ["empty branch"]),
    ("C11", ["self-loop"]),
    ("C1C1", ["duplicates the edge"]),
    ("C%1C", ["two digits"]),
    ("C(N)1CC1", ["after ')'"]),
    ("", ["empty"]),
])
def test_errors_say_where(text, words):
    with pytest.raises(StringSyntaxError) as info:
        parse(text)
    for w in words:
        assert w in str(info.value)


def test_canonical_is_deterministic_and_random_strings_differ():
    g = decode("C1CC(N)CC1O")
    assert encode(g) == encode(g)
    strings = {encode(g, rng=np.random.default_rng(i)) for i in range(30)}
    assert len(strings) > 5
    for s in strings:
        assert _iso(decode(s), g)


def test_encode_rejects_bad_graphs():
    with pytest.raises(GraphError, match="not connected"):
        encode(_graph("AB", []))
    with pytest.raises(GraphError, match="single letters"):
        encode(_graph(["AB"], []))


def test_many_rings_use_percent_labels():
    # A wheel with 30 spokes from the hub's far side keeps many rings open at once.
    n = 30
    g = _graph("H" + "R" * n, [(0, i) for i in range(1, n + 1)] + [(i, i + 1) for i in range(1, n)])
    s = encode(g, root=1)
    assert _iso(decode(s), g)
    big = nx.complete_graph(16)
    nx.set_node_attributes(big, "K", "type")
    s = encode(big)
    assert "%" in s and _iso(decode(s), big)


def test_char_edges_map_letters_and_labels():
    p = parse("C1CC(N)CC1O")
    # root letter has no edge; the N's edge is its parent C (node 2); both '1's are the ring edge
    assert p.char_edges[0] is None
    assert p.char_edges[p.text.index("N")] == (2, 3)
    assert p.char_edges[1] == p.char_edges[9] == (0, 5)
    assert p.char_edges[p.text.index("(")] is None


@st.composite
def typed_graphs(draw):
    n = draw(st.integers(1, 25))
    types = draw(st.lists(st.sampled_from("ABCDxyz"), min_size=n, max_size=n))
    g = _graph(types, [])
    for v in range(1, n):  # a random spanning tree keeps it connected
        g.add_edge(v, draw(st.integers(0, v - 1)))
    extra = draw(st.lists(st.tuples(st.integers(0, n - 1), st.integers(0, n - 1)), max_size=3 * n))
    g.add_edges_from((a, b) for a, b in extra if a != b)
    return g


@settings(max_examples=150, deadline=None)
@given(typed_graphs(), st.integers(0, 2**32 - 1))
def test_round_trip_isomorphic(g, seed):
    rng = np.random.default_rng(seed)
    for s in (encode(g), encode(g, rng=rng)):
        back = decode(s)
        assert _iso(back, g), s
        assert encode(back) == encode(back)
        # labels written are 1-9 then %10..%99, never 0
        assert "0" not in re.sub(r"%[0-9][0-9]", "", s)
