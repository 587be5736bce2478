"""Seed 000 Table 2 measures."""

import numpy as np

from procmod.learn.evaluate import StructureSimilarity, VisualSimilarity, signature
from procmod.learn.examples import ExampleNode


def n(part, *children, x=0.0):
    m = np.eye(4)
    m[0, 3] = x
    return ExampleNode(part, m, list(children))


def test_largest_common_rooted_subtree():
    s = StructureSimilarity()
    a = n("body", n("wing", n("gun")), n("wing"), n("engine"))
    b = n("body", n("wing"), n("wing", n("gun"), n("gun")), n("fin"))
    # common: body + two wings + one gun = 4; sizes 5 and 6
    assert s.common(a, b) == 4
    assert s(a, b) == 4 / 6
    assert s(a, a) == 1.0
    assert s(a, n("hub")) == 0.0
    assert signature(n("a", n("b"), n("c"))) == signature(n("a", n("c"), n("b")))


def test_visual_similarity_orders_objects_sensibly():
    library = {"body": __import__("procmod.geometry.part_library", fromlist=["PartShape"]).PartShape(
        "body", "box", size=(2.0, 1.0, 1.0), source=[2, 1, 1])}
    a = n("body", n("body", x=2.0))
    b = n("body", n("body", x=2.1))
    c = n("body", n("body", x=-2.0))
    vis = VisualSimilarity(library, [a, b, c])
    fa, fb, fc = (vis.features(h) for h in (a, b, c))
    assert vis.similarity(fa, fa) == 1.0
    assert vis.similarity(fa, fb) > vis.similarity(fa, fc)
