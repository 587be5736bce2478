"""Instantiation search (seed 001, section 6): wrong votes repaired, impossible graphs proven so."""
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

from procmod.core.errors import InvalidArgumentError
from procmod.strings.codec import decode
from procmod.strings.categories import EdgeCategories
from procmod.strings.instantiate import instantiate_graph
from procmod.strings.contacts import shape_graph
from procmod.strings.shapes import read_shapes

SETS = Path(__file__).resolve().parents[1] / "examples_sets" / "strings"


@pytest.fixture(scope="module")
def moonbase():
    ss = read_shapes(SETS / "moonbase.json")
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    return ss, graphs, EdgeCategories.fit(ss, ss.shapes, graphs)


def _same_graph(ss, shape, g):
    return nx.is_isomorphic(shape_graph(ss, shape), g, node_match=lambda a, b: a["type"] == b["type"])


def test_search_repairs_wrong_categories_on_rings(moonbase):
    ss, graphs, cats = moonbase
    rng = np.random.default_rng(0)
    for s, g in zip(ss.shapes[:1], graphs[:1]):  # one input shape: 3 rings
        truth = cats.edge_categories(ss, s, g)
        # a third of the module-corridor edges (they make the rings) get another category
        ring_edges = [e for e in sorted(truth) if len(cats.allowed(*(g.nodes[v]["type"] for v in e))) > 1]
        wrong = dict(truth)
        for e in [ring_edges[i] for i in rng.permutation(len(ring_edges))[:len(ring_edges) // 3]]:
            wrong[e] = next(c for c in cats.allowed(*(g.nodes[v]["type"] for v in e)) if c != truth[e])
        assert sum(wrong[e] != truth[e] for e in truth) >= 3
        result = instantiate_graph(g, wrong, cats, ss, np.random.default_rng(1), budget=4000)
        assert result.success and _same_graph(ss, result.shape, g)
        assert result.fallbacks >= 1  # some wrong category had to be replaced
        # ranked lists: the true category second behind the wrong one
        ranked = {e: [wrong[e], truth[e]] if wrong[e] != truth[e] else [truth[e]] for e in truth}
        again = instantiate_graph(g, ranked, cats, ss, np.random.default_rng(1), budget=4000)
        assert again.success and _same_graph(ss, again.shape, g)


def test_search_proves_an_odd_ring_impossible(moonbase):
    ss, graphs, cats = moonbase
    # three modules in a ring: grammar-valid (each module has two corridors) but a grid of
    # corridors only closes rings of an even number of modules
    g = decode("M1CMCMC1")
    result = instantiate_graph(g, {}, cats, ss, np.random.default_rng(0), budget=20000)
    assert not result.success and "every candidate pose tried" in result.reason
    assert result.tries < 20000
    # four modules close
    square = instantiate_graph(decode("M1CMCMCMC1"), {}, cats, ss, np.random.default_rng(0), budget=20000)
    assert square.success


def test_search_budget_is_checked(moonbase):
    ss, graphs, cats = moonbase
    with pytest.raises(InvalidArgumentError):
        instantiate_graph(graphs[0], {}, cats, ss, np.random.default_rng(0), budget=0)
    small = instantiate_graph(graphs[0], {}, cats, ss, np.random.default_rng(0), budget=3)
    assert not small.success and "budget" in small.reason and small.tries == 3


def test_a_lone_part_is_posed_as_a_first_part_is(moonbase):
    """A one-letter string was built at the identity, not at the first part's pose from the
    collection: a board lay on its edge, off the ground (h69)."""
    ss, _, cats = moonbase
    letter = decode("M").nodes[0]["type"]
    pose = np.eye(4)
    pose[:3, :3] = [[1, 0, 0], [0, 0, -1], [0, 1, 0]]  # turned a quarter about x
    pose[:3, 3] = [1.0, 2.0, 3.0]
    result = instantiate_graph(decode("M"), {}, cats, ss, np.random.default_rng(0), start_pose={letter: pose})
    assert result.success and np.allclose(result.shape.transforms[0], pose)
