import inspect
import math

import numpy as np
import pytest

from procmod.core import InvalidArgumentError, run_forward
from procmod.geometry import Segment
from procmod.models import MODELS, get_model
from procmod.models.frame import to_world


@pytest.mark.parametrize("name", sorted(MODELS))
def test_every_choice_is_documented(name):
    model = MODELS[name]
    names = set()
    for seed in range(30):
        d = run_forward(model, np.random.default_rng(seed))
        names.update(n for (_, n) in d.choice_map())
    assert names, "the model made no choices"
    for choice in names:
        assert f"``{choice}" in model.choices_doc, f"{name}: choice {choice!r} is not documented"


@pytest.mark.parametrize("name", ["chain", "lightning", "vines"])
def test_start_and_direction_are_honoured(name):
    model = get_model(name).configure(start=[0.25, 0.5], direction=[1.0, 0.0])
    x, y = to_world([0.25, 0.5])
    angles = []
    for seed in range(200):
        d = run_forward(model, np.random.default_rng(seed))
        first = d.geometry()[0]
        assert isinstance(first, Segment)
        assert math.isclose(first.x0, x) and math.isclose(first.y0, y)
        angles.append(math.atan2(first.y1 - first.y0, first.x1 - first.x0))
    # Mean direction along +x: mean angle near 0 within 5 standard errors.
    angles = np.array(angles)
    assert abs(angles.mean()) < 5 * angles.std() / math.sqrt(len(angles))


def test_vines_depth_is_bounded_by_width():
    from procmod.models import vines
    bound = math.ceil(math.log(vines.MIN_WIDTH / vines.INITIAL_WIDTH) / math.log(vines.WIDTH_DECAY))
    deepest = 0
    for seed in range(300):
        d = run_forward(vines.MODEL, np.random.default_rng(seed))
        deepest = max(deepest, max(len(a) for a in d.tree()))
        for g in d.geometry():
            if g.tag == "stem":
                assert g.width > vines.MIN_WIDTH
    assert deepest <= bound


def test_vines_segment_count_matches_termination_probability():
    # Each segment terminates the whole derivation with probability 1/2; otherwise branch1
    # (0.66) decides whether anything continues (branch2 is drawn only inside branch1's
    # true case, vines.md). So P(exactly one segment) = 1/2 + 1/2 * 0.34 = 0.67; drawing
    # branch2 regardless of branch1 (a different model) gives 0.585, 11 standard errors off.
    n = 4000
    ones = sum(run_forward(MODELS["vines"], np.random.default_rng(s)).n_nodes == 1 for s in range(n))
    p = 0.5 + 0.5 * 0.34
    assert abs(ones - n * p) < 5 * math.sqrt(n * p * (1 - p))


def test_vines_continues_with_none_one_or_two_branches_about_equally():
    # A call that neither terminated nor hit the width bound continues with branch1
    # (0.66); only then, once branch1's subtree has run without stopping the vine, does
    # ``second_branch`` draw branch2 (0.5): no, one or two branches about 1/3 each (vines.md).
    first = second = 0
    n_first = n_second = 0
    for s in range(3000):
        d = run_forward(MODELS["vines"], np.random.default_rng(s))
        for node in d.nodes():
            if node.rule.__name__ == "second_branch":
                n_second += 1
                second += node.choices["branch2"].value
            elif "branch1" in node.choices:
                n_first += 1
                first += node.choices["branch1"].value
                assert "branch2" not in node.choices  # never drawn with branch1
    assert n_first > 2000 and n_second > 300
    assert abs(first / n_first - 0.66) < 5 * math.sqrt(0.66 * 0.34 / n_first)
    assert abs(second / n_second - 0.5) < 5 * math.sqrt(0.25 / n_second)


def test_bad_parameters():
    with pytest.raises(InvalidArgumentError, match="no parameter"):
        get_model("vines").configure(colour="red")
    with pytest.raises(InvalidArgumentError, match="direction"):
        run_forward(get_model("chain").configure(direction=[0, 0]), np.random.default_rng(0))
    with pytest.raises(InvalidArgumentError, match="size"):
        get_model("chain").configure(size=-4).new_output()


def test_rules_are_plain_functions():
    for model in MODELS.values():
        for rule in model.rules:
            assert list(inspect.signature(rule).parameters)[0] == "ctx"
