"""Incremental GA offspring: replay_reusing and exact part removal agree with full replays."""

import math
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from procmod.core import InvalidArgumentError, ModelError, replay
from procmod.core.runtime import replay_reusing
from procmod.geometry.camera import Camera, Silhouettes
from procmod.geometry.solid import Box, Cylinder, translation
from procmod.geometry.voxel import VoxelGrid, VoxelScene
from procmod.infer import ENGINES, Budget
from procmod.infer.common import evaluate
from procmod.infer.ga import COPIES, Genome, alter, crossover, cut, evaluate_from, grow, nudge, same_subtree
from procmod.models import get_model
from procmod.parallel import InlineExecutor
from procmod.targets import Silhouette, Volume, load_target_file

ROOT = Path(__file__).resolve().parents[1]


def _volume_target():
    grid = VoxelGrid((-6.0, -2.0, -6.0), 0.5, (24, 16, 40))
    fill = np.zeros(grid.shape, bool)
    fill[6:18, 2:10, 8:30] = True
    return Volume(grid, [(fill, 1.0, -1.0)], w_self=0.5)


def _silhouette_target():
    weights = -np.ones((24, 20))
    weights[4:20, 5:15] = 1.0
    camera = Camera((0.0, 4.0, 30.0), (0.0, 4.0, 0.0), projection="orthographic", fov=14.0)
    return Silhouette([(weights, camera)])


TARGETS = {"volume": _volume_target(), "silhouette": _silhouette_target()}


def _same_output(a, b):
    if isinstance(a, VoxelScene):
        assert np.array_equal(a.counts, b.counts)
        assert (a.filled_count, a.overlaps, a.outside, a.n_parts) == (b.filled_count, b.overlaps, b.outside, b.n_parts)
    else:
        assert all(np.array_equal(p, q) for p, q in zip(a.pixels, b.pixels))
        assert (a.filled_count, a.n_parts) == (b.filled_count, b.n_parts)
    assert a.gain_total == pytest.approx(b.gain_total, abs=1e-9)


def _check_against_full_replay(model, target, ev):
    """``ev`` (an incremental evaluation) is what a full replay of its choice map gives."""
    d = ev.derivation
    full = evaluate(model, target, (d.choice_map().raw, 0, False))
    assert full.log_fresh == 0.0 and full.unused == []
    f = full.derivation
    assert f.order() == d.order()
    assert f.choice_map() == d.choice_map()
    assert f.geometry() == d.geometry()
    assert (f.n_nodes, f.n_emits) == (d.n_nodes, d.n_emits)
    assert d.log_prior == pytest.approx(f.log_prior, abs=1e-9)
    assert ev.log_reused + ev.log_fresh == pytest.approx(d.log_prior, abs=1e-9)
    assert ev.score == pytest.approx(full.score, abs=1e-9)
    _same_output(d.output, f.output)


@settings(max_examples=25, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), name=st.sampled_from(["spaceship", "tree", "city"]),
       kind=st.sampled_from(sorted(TARGETS)), hinted=st.booleans())
def test_incremental_offspring_equal_full_replays(seed, name, kind, hinted):
    model, target = get_model(name), TARGETS[kind]
    rng = np.random.default_rng(seed)
    parents = [evaluate(model, target, ({}, int(rng.integers(2 ** 31)), None)).derivation for _ in range(2)]
    genomes = [Genome(p) for p in parents]
    offspring = [op(genomes[0], rng) for op in (grow, cut, alter, nudge)]
    offspring.append(grow(genomes[1], rng, 4))
    pairs = [(parents[0], o) for o in offspring[:4]] + [(parents[1], offspring[4])]
    crossed = crossover(genomes[0], genomes[1], rng)
    if crossed is not None and crossed is not COPIES:
        pairs += list(zip(parents, crossed))
    for parent, choices in pairs:
        if choices is None:
            continue
        full_map = choices.materialize()  # what the operator means, as a plain choice map
        ev = evaluate_from(model, target, parent, choices if hinted else full_map, int(rng.integers(2 ** 31)),
                           choices.changed if hinted else None)
        _check_against_full_replay(model, target, ev)
        direct = evaluate(model, target, (full_map, 0, False))
        if all(k in full_map and full_map[k] == v for k, v in direct.derivation.choice_map().raw.items()):
            # nothing was drawn fresh: the very same derivation
            assert ev.derivation.choice_map() == direct.derivation.choice_map()
            assert ev.score == pytest.approx(direct.score, abs=1e-9)
        # and once more from the offspring (its output was itself built incrementally)
        again = grow(Genome(ev.derivation), rng) or cut(Genome(ev.derivation), rng)
        if again is not None:
            _check_against_full_replay(model, target, evaluate_from(model, target, ev.derivation, again,
                                                                    1, again.changed if hinted else None))


def test_same_subtree_tells_equal_subtrees_from_changed_ones():
    model, target = get_model("spaceship"), TARGETS["volume"]
    parent = max((evaluate(model, target, ({}, s, None)).derivation for s in range(8)), key=lambda d: d.n_nodes)
    genome = Genome(parent)
    assert all(same_subtree(genome, a, genome, a) for a in genome.index())
    for seed in range(8):
        choices = nudge(genome, np.random.default_rng(seed), 0.5)
        (address,) = choices.changed
        child = Genome(evaluate_from(model, target, genome, choices, 0, choices.changed).derivation)
        for a in genome.index():
            if address[:len(a)] == a:  # the nudged call and the calls above it changed
                assert not same_subtree(genome, a, child, a)
            elif a[:len(address)] != address:  # calls beside it did not (those below may)
                assert same_subtree(genome, a, child, a)


def test_replay_reusing_checks_the_map_when_not_told_what_changed():
    model, target = get_model("tree"), TARGETS["silhouette"]
    parent = evaluate(model, target, ({}, 3, None)).derivation
    assert parent.n_nodes > 3
    choices = dict(parent.choice_map().raw)
    key = next(k for k in choices if k[0] and k[1] == "psi")
    choices[key] = 0.5 * (choices[key] + 0.25)  # a change deep in the tree, not announced
    result = replay_reusing(model, parent, choices, np.random.default_rng(0), parent.output.copy(), False)
    assert result.derivation.choice_map()[key] == choices[key]
    full = replay(model, choices, np.random.default_rng(0), output=target.new_output(model), maybe_default=False)
    assert result.derivation.geometry() == full.derivation.geometry()
    _same_output(result.derivation.output, full.derivation.output)
    assert result.unused == full.unused


def test_replay_reusing_needs_a_complete_derivation():
    from procmod.core import start
    model = get_model("tree")
    with pytest.raises(ModelError, match="complete"):
        replay_reusing(model, start(model), {}, np.random.default_rng(0), None)


def _parts(rng, n):
    out = []
    for _ in range(n):
        x, y, z = rng.uniform(-1.5, 1.5, 3)
        if rng.random() < 0.5:
            out.append(Box(tuple(rng.uniform(0.3, 2.0, 3)), translation(x, y, z)))
        else:
            out.append(Cylinder(float(rng.uniform(0.2, 1.0)), float(rng.uniform(0.5, 3.0)), translation(x, y, z)))
    return out


@pytest.mark.parametrize("cached", [False, True])
def test_voxel_and_pixel_removal_is_the_exact_inverse_of_adding(cached):
    rng = np.random.default_rng(5)
    parts = _parts(rng, 12)
    grid = VoxelGrid((-2.0, -2.0, -2.0), 0.2, (18, 18, 18))  # parts poke out: outside counts too
    gain, pixel_gain = rng.normal(size=grid.shape), rng.normal(size=1200)
    camera = Camera((0.0, 0.0, 12.0), (0.0, 0.0, 0.0), projection="perspective", fov=30.0, width=40, height=30)
    for make in (lambda: VoxelScene(grid, gain), lambda: Silhouettes([camera], [pixel_gain])):
        everything, rest = make(), make()
        if cached:
            everything.use_part_cache()
        for p in parts:
            everything.add(p)
        for p in parts[::2]:
            rest.add(p)
        for p in parts[1::2]:
            everything.remove(p)
        assert rest.filled_count > 0 and everything.n_parts == 6
        if isinstance(everything, VoxelScene):
            assert rest.overlaps > 0 and rest.outside > 0
        _same_output(everything, rest)


def test_saturated_counts_refuse_removal():
    grid = VoxelGrid((-1.0, -1.0, -1.0), 0.5, (4, 4, 4))
    scene = VoxelScene(grid)
    box = Box((1.0, 1.0, 1.0))
    for _ in range(255):
        scene.add(box)
    assert not scene.saturated
    scene.remove(box)
    scene.add(box)
    scene.add(box)  # the 256th hit cannot be counted
    assert scene.saturated
    with pytest.raises(InvalidArgumentError, match="saturated"):
        scene.remove(box)


def test_ga_is_incremental_only_where_removal_is_exact():
    model = get_model("spaceship")
    proxy = load_target_file(ROOT / "scenes" / "spaceship_proxy" / "target.json")
    budget = Budget(generations=2)
    assert not ENGINES["ga"](model, proxy, population=8, seed=1, budget=budget).settings["incremental"]
    target = TARGETS["volume"]
    inline = ENGINES["ga"](model, target, population=8, seed=1, budget=budget, executor=InlineExecutor())
    assert not inline.settings["incremental"]
    result = ENGINES["ga"](model, target, population=12, seed=1, budget=Budget(generations=4))
    assert result.settings["incremental"]
    # every reported score is what a full replay of the individual scores
    best = evaluate(model, target, (result.best.choice_map().raw, 0, False))
    assert best.score == pytest.approx(result.best_score, abs=1e-9)
    for d in result.samples[:5]:
        full = evaluate(model, target, (d.choice_map().raw, 0, False))
        assert full.score == pytest.approx(target.score(d.output), abs=1e-9)
        assert math.isfinite(d.log_prior)

