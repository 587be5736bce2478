import numpy as np
import pytest

from procmod.core import run_forward
from procmod.geometry.solid import matrix
from procmod.models import get_model


def _runs(name, n=40):
    return [run_forward(get_model(name), np.random.default_rng(s)) for s in range(n)]


def test_spaceship_wings_are_mirrored_and_the_hull_starts_at_the_rear():
    for d in _runs("spaceship"):
        first = d.tree()[()].geometry[0]
        m = matrix(first.transform)
        rear = m[2, 3] - (0.5 * first.size[2] if hasattr(first, "size") else 0.0)
        assert rear == pytest.approx(-5.0)
        wings = [matrix(g.transform)[:3, 3] for g in d.geometry() if g.tag in ("wing", "gun")]
        for x, y, z in wings:
            assert any(np.allclose((-x, y, z), other) for other in wings)


def test_tree_branches_have_at_most_three_children_and_final_ones_carry_foliage():
    for d in _runs("tree"):
        for node in d.nodes():
            if node.rule.__name__ not in ("trunk", "branch"):
                continue
            children = [s for s in node.spawns if s.on and s.site.startswith("b")]
            assert len(children) <= 3
            has_foliage = any(s.site == "foliage" for s in node.spawns)
            if node.rule.__name__ == "branch":
                assert has_foliage == (not children)


def test_city_buildings_are_the_only_geometry_one_per_lot():
    for d in _runs("city", 10):
        lots = []
        for node in d.nodes():
            if node.rule.__name__ == "building":
                assert len(node.geometry) == 1
                lots.append(tuple(node.args))
            else:
                assert node.geometry == ()
        assert len(lots) == len(set(lots))
