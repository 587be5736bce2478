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
    # Among calls that did not terminate and could continue: no continuation 0.34, one
    # 0.66 * 0.5 = 0.33, two 0.33 (vines.md); branch2 without branch1 never happens.
    counts = np.zeros(3)
    for s in range(3000):
        for node in run_forward(MODELS["vines"], np.random.default_rng(s)).nodes():
            if node.choices["terminate"].value:
                continue
            on = {spawn.site: spawn.on for spawn in node.spawns}
            assert on.get("branch1", False) or not on.get("branch2", False)
            if "branch1" in on:
                counts[on["branch1"] + on.get("branch2", False)] += 1
    n = counts.sum()
    expected = np.array([0.34, 0.33, 0.33])
    assert n > 2000  # about 2400: the tolerance is then about 0.05
    assert np.all(np.abs(counts / n - expected) < 5 * np.sqrt(expected * (1 - expected) / n))


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
