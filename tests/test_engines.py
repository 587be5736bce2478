"""Engine contract, genetic operators and MCMC proposals on the built-in models."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from procmod.core import InvalidArgumentError, replay, run_forward
from procmod.infer import ENGINES, Budget, parse_budget
from procmod.infer.common import Scored, evaluate
from procmod.infer.ga import (COPIES, _crossover, _View, alter_choices, connections, crossover_choices,
                              cut_choices, grow_choices, nudge_choices)
from procmod.infer.mcmc import propose, temperature_ladder
from procmod.models import get_model
from procmod.targets import ShapeMatch, TargetImage

from toy_models import TREE


def _bar_target():
    mask = np.zeros((50, 50), bool)
    mask[10:45, 22:28] = True
    return ShapeMatch(TargetImage("bar", mask, (0.5, 0.9), (0, -1)))


def _valid(model, d):
    """A derivation is valid if replaying its choice map reproduces it with finite log-prior."""
    assert math.isfinite(d.log_prior)
    r = replay(model, d.choice_map(), np.random.default_rng(0))
    assert r.log_fresh == 0.0 and r.unused == []
    assert r.derivation.choice_map() == d.choice_map()


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), name=st.sampled_from(["vines", "lightning", "chain"]))
def test_every_ga_offspring_is_a_valid_derivation(seed, name):
    model = get_model(name)
    rng = np.random.default_rng(seed)
    d1, d2 = run_forward(model, rng), run_forward(model, rng)
    v1, v2 = _View(d1), _View(d2)
    # An operator may return None only when the derivation offers it nothing to do.
    possible = {grow_choices: any(p > 0 for _, _, p in v1.grow_sites()), cut_choices: bool(v1.cut_sites()),
                alter_choices: bool(v1.alter_sites()), nudge_choices: bool(v1.nudge_sites())}
    maps = []
    for op, can in possible.items():
        choices = op(d1, rng)
        assert (choices is not None) == can, op.__name__
        if choices is not None:
            maps.append(choices)
    # Crossover retries random connections of d1; with 50 x as many tries as d1 has
    # connections, missing a compatible one that exists has probability below e^-50.
    n1 = sum(len(a) for a in v1.connections().values())
    children = crossover_choices(d1, d2, rng, max_retries=50 * max(n1, 1))
    assert (children is not None) == bool(set(v1.connections()) & set(v2.connections()))
    if children:
        maps.extend(children)
    assert maps  # every model here has a root with parameters: alter always applies
    for choices in maps:
        d = replay(model, choices, rng, maybe_default=False).derivation
        _valid(model, d)


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), name=st.sampled_from(["vines", "lightning", "chain"]))
def test_every_mcmc_proposal_is_a_valid_derivation(seed, name):
    model = get_model(name)
    target = _bar_target()
    rng = np.random.default_rng(seed)
    state = Scored.from_evaluation(evaluate(model, target, ({}, seed, None)))
    for _ in range(5):
        p = propose(state, rng, 0.5, 0.1)
        ev = evaluate(model, target, (p.choices, int(rng.integers(2 ** 62)), None))
        _valid(model, ev.derivation)


def test_grow_and_cut_follow_spawn_probabilities():
    # Lightning's maybe sites: fork (p = 0.22) and next (p = 0.96 or 0.8). Grow picks an
    # unexpressed child with probability proportional to p; cut proportional to 1 - p.
    model = get_model("lightning")
    rng = np.random.default_rng(3)
    d = run_forward(model, rng)
    off = [(n.address, s.site, s.probability) for n in d.nodes() for s in n.spawns if not s.on]
    assert off
    counts = {}
    n = 3000
    for _ in range(n):
        choices = grow_choices(d, rng)
        new = [k for k, v in choices.items() if v is True and d.choice_map().get(k) is False]
        counts[new[0]] = counts.get(new[0], 0) + 1
    total = sum(p for _, _, p in off)
    for address, site, p in off:
        expected = p / total
        got = counts.get((address, site), 0) / n
        assert abs(got - expected) < 5 * math.sqrt(expected * (1 - expected) / n)


def test_crossover_swaps_compatible_subtrees():
    model = get_model("lightning")
    rng = np.random.default_rng(11)
    d1, d2 = run_forward(model, rng), run_forward(model, rng)
    c1, c2 = crossover_choices(d1, d2, rng)
    r1 = replay(model, c1, rng).derivation
    # The child keeps every connection of the model's generator graph: parent rule, site, child rule.
    for (parent_rule, child_rule), addresses in connections(r1).items():
        for address in addresses:
            assert (parent_rule.__name__, address[-1], child_rule.__name__) in {
                ("bolt", "next", "bolt"), ("bolt", "fork", "fork"), ("fork", "bolt", "bolt")}


def _cross_site_crossover(model, seed: int, top_level: bool):
    """Search crossovers of forward samples for one that swaps subtrees at two different
    spawn sites: ``(v1, v2, offspring 1)`` with ``offspring.at`` (receiving site in parent 1)
    and ``offspring.source`` (donor site in parent 2), or None."""
    rng = np.random.default_rng(seed)
    for _ in range(300):
        v1, v2 = _View(run_forward(model, rng)), _View(run_forward(model, rng))
        out = _crossover(v1, v2, rng)
        if out is None or out is COPIES:
            continue
        child = out[0][0]
        if child.at[-1] != child.source[-1] and (not top_level or len(child.at) == len(child.source) == 1):
            return v1, v2, child
    return None


def test_crossover_pairs_sibling_sites_of_one_connection_type():
    # Seed 002: compatible connections are those of one generator-graph edge. The tree's
    # trunk spawns a branch at b0, b1 and b2: one edge (trunk -> branch), so a crossover
    # can put parent 2's b1 subtree under parent 1's b0 (a site-keyed match never could).
    model = get_model("tree")
    found = _cross_site_crossover(model, 0, top_level=True)
    assert found is not None
    v1, v2, child = found
    at, source = child.at, child.source
    child_map = child.materialize()
    donor = {(a[len(source):], name): value for (a, name), value in v2.raw().items() if a[:len(source)] == source}
    below = {(a[len(at):], name): value for (a, name), value in child_map.items() if a[:len(at)] == at}
    assert donor and below == donor  # re-addressed under the receiving site, all of it
    outside = {k: v for k, v in child_map.items() if k[0][:len(at)] != at}
    assert outside == {k: v for k, v in v1.raw().items() if k[0][:len(at)] != at}
    # Replayed, the subtree keeps its choices and runs from the receiving parent's context.
    r = replay(model, child_map, np.random.default_rng(0), maybe_default=False)
    assert r.log_fresh == 0.0 and r.unused == []
    nodes = {n.address: n for n in r.derivation.nodes()}
    assert nodes[at].args == v1.index()[at].args  # the receiving trunk's position, radius, length
    assert {n: c.value for n, c in nodes[at].choices.items()} == {
        n: c.value for n, c in v2.index()[source].choices.items()}
    _valid(model, r.derivation)


def test_crossover_pairs_sibling_sites_of_a_recursive_rule():
    # The toy tree spawns itself at "a" and at "b" (as vines' branch1 / branch2 once were):
    # one connection type, so subtrees move between the two sites, at any depth.
    found = _cross_site_crossover(TREE, 1, top_level=False)
    assert found is not None
    v1, v2, child = found
    assert {child.at[-1], child.source[-1]} == {"a", "b"}
    r = replay(TREE, child.materialize(), np.random.default_rng(0), maybe_default=False)
    _valid(TREE, r.derivation)
    top = {n.address: n for n in r.derivation.nodes()}[child.at]
    assert top.args == v1.index()[child.at].args  # the receiving site's depth
    assert top.choices["v"].value == v2.index()[child.source].choices["v"].value


def test_nudge_moves_one_calls_continuous_choices_within_their_support():
    model = get_model("spaceship")
    rng = np.random.default_rng(2)
    d = run_forward(model, rng)
    before = d.choice_map().raw
    dists = {(n.address, name): c.dist for n in d.nodes() for name, c in n.choices.items()}
    moved_calls, steps = set(), []
    for _ in range(300):
        after = nudge_choices(d, rng, step=0.5)
        changed = [k for k in before if after[k] != before[k]]
        assert changed and set(after) == set(before)
        assert len({k[0] for k in changed}) == 1  # one call
        for k in changed:
            dist = dists[k]
            assert not dist.discrete and dist.contains(after[k])  # reflected into the support
            steps.append(abs(after[k] - before[k]) / dist.scale)
        moved_calls.add(changed[0][0])
    assert len(moved_calls) > 1
    # Gaussian steps of 0.5 x scale (folded at the bounds): mean |step| is at most 0.5 * sqrt(2 / pi)
    assert 0.2 < float(np.mean(steps)) < 0.45


def test_crossover_of_equal_subtrees_gives_copies():
    # A derivation crossed with itself: a swap at the same connection changes nothing and
    # gives COPIES (no evaluation needed); any other swap gives children that differ.
    model = get_model("spaceship")
    rng = np.random.default_rng(0)
    kinds = []
    for _ in range(40):
        d = run_forward(model, rng)
        out = _crossover(_View(d), _View(d), rng)
        if out is None:
            continue
        kinds.append(out is COPIES)
        if out is not COPIES:
            raw = d.choice_map().raw
            assert out[0][0].materialize() != raw and out[1][0].materialize() != raw
    assert any(kinds) and not all(kinds)


@pytest.mark.parametrize("engine,kwargs", [
    ("forward", {"particles": 20}), ("smc", {"particles": 20}), ("sosmc", {"particles": 20}),
    ("mcmc", {"chains": 3}), ("ga", {"population": 12}),
    ("ga", {"population": 12, "split": (10.0, 10.0, 3.0, 10.0), "nudge_step": 0.2})])
def test_engine_contract_and_determinism(engine, kwargs):
    model = get_model("vines")
    target = _bar_target()
    budget = Budget(evaluations=400)
    a = ENGINES[engine](model, target, seed=4, budget=budget, **kwargs)
    b = ENGINES[engine](model, target, seed=4, budget=budget, **kwargs)
    assert a.best is not None and a.best.done
    assert a.best_score == max(r.best_score for r in a.history)
    assert a.best_score == pytest.approx(target.score(replay(target.configure(model), a.best.choice_map(),
                                                             np.random.default_rng(0), order=a.best.order(),
                                                             output=target.new_output(model)).derivation.output))
    assert a.samples and all(s.done for s in a.samples)
    rows = a.history
    assert all(r2.seconds >= r1.seconds and r2.evaluations >= r1.evaluations and r2.best_score >= r1.best_score
               for r1, r2 in zip(rows, rows[1:]))
    assert a.evaluations >= 400
    # Same seed, same result.
    assert a.best.choice_map() == b.best.choice_map() and a.evaluations == b.evaluations
    assert [s.choice_map() for s in a.samples] == [s.choice_map() for s in b.samples]


def _population_key(d):
    return repr(sorted(d.choice_map().raw.items()))


def test_ga_elite_individuals_are_in_the_next_population():
    # The GA is deterministic in its seed, so a run of g + 1 generations goes through the
    # very population a run of g generations ends with (result.samples, best first). The
    # best fifth of it (population 20: 4 individuals) must be in the next generation, as
    # often as it occurs. Without elitism they would survive only if crossover or a failed
    # mutation happened to copy them.
    model, target = get_model("lightning"), _bar_target()
    pops = [ENGINES["ga"](model, target, population=20, seed=1, elitism=0.2, budget=Budget(generations=g)).samples
            for g in range(1, 6)]
    from collections import Counter
    for before, after in zip(pops, pops[1:]):
        elite = Counter(_population_key(d) for d in before[:4])
        kept = Counter(_population_key(d) for d in after)
        assert all(kept[k] >= n for k, n in elite.items())
        # not vacuous: the population changes from one generation to the next
        assert kept != Counter(_population_key(d) for d in before)


def test_all_zero_likelihood_is_reported_not_nan():
    class Impossible:
        name = "impossible"

        def configure(self, model):
            return model

        def new_output(self, model):
            return model.new_output()

        def log_likelihood(self, output):
            return -math.inf

        def score(self, output):
            return 0.0

    result = ENGINES["smc"](TREE, Impossible(), particles=10, seed=0)
    assert result.log_marginal_likelihood == -math.inf
    assert result.notes and "zero likelihood" in result.notes[0]
    assert not any(math.isnan(w) for w in result.log_weights)


def test_smc_resampling_options():
    target = _bar_target()
    model = get_model("vines")
    for resampling in ("systematic", "multinomial", "residual"):
        r = ENGINES["smc"](model, target, particles=30, seed=0, resampling=resampling, ess_threshold=0.5)
        assert r.best is not None and math.isfinite(r.log_marginal_likelihood)
    with pytest.raises(InvalidArgumentError):
        ENGINES["smc"](model, target, particles=30, resampling="stratified-ish")
    with pytest.raises(InvalidArgumentError):
        ENGINES["smc"](model, target, particles=0)


@pytest.mark.parametrize("method", ["systematic", "multinomial", "residual"])
def test_resampling_offspring_counts_follow_the_weights(method):
    from procmod.infer.smc import resample
    w = np.array([0.0625, 0.375, 0.0, 0.3125, 0.25])  # exact in binary: floor(10 w) is exact
    log_w = np.log(np.where(w > 0, w, 1.0)) + np.where(w > 0, 0.0, -np.inf)
    rng = np.random.default_rng(3)
    draws = 4000
    counts = np.zeros(5)
    for _ in range(draws):
        ancestors = resample(log_w, rng, method, count=10)
        assert len(ancestors) == 10 and np.all(np.diff(ancestors) >= 0)
        c = np.bincount(ancestors, minlength=5)
        if method != "multinomial":  # residual and systematic keep floor(m w) copies at least
            assert np.all(c >= np.floor(10 * w))
        if method == "systematic":  # ... and systematic at most ceil(m w)
            assert np.all(c <= np.ceil(10 * w))
        counts += c
    # unbiased: mean offspring 10 w_i; the per-draw sd is at most sqrt(10 w (1 - w)) (multinomial)
    assert np.all(np.abs(counts / draws - 10 * w) < 5 * np.sqrt(10 * w * (1 - w) / draws) + 1e-12)


def test_temperature_ladder_matches_seed_002():
    betas = temperature_ladder(5)
    assert betas[0] == 1.0
    # A likelihood ratio accepted 70% in the hottest chain is accepted 1% in the coldest.
    r = 0.7 ** (1 / betas[-1])
    assert r ** betas[0] == pytest.approx(0.01)


def test_parse_budget():
    assert parse_budget("30s") == Budget(seconds=30)
    assert parse_budget("2m") == Budget(seconds=120)
    assert parse_budget("5000evals") == Budget(evaluations=5000)
    assert parse_budget("100gens+10s") == Budget(seconds=10, generations=100)
    for bad in ("", "fast", "-3s", "0evals"):
        with pytest.raises(InvalidArgumentError):
            parse_budget(bad)


def test_engines_run_through_a_process_pool_with_the_same_results():
    import concurrent.futures

    from procmod.targets import load_target_file
    from pathlib import Path
    scene = load_target_file(Path(__file__).resolve().parents[1] / "scenes" / "spaceship_volume" / "target.json")
    cases = [(ENGINES["forward"], get_model("vines"), _bar_target(), {"particles": 6}),
             (ENGINES["ga"], get_model("spaceship"), scene, {"population": 6, "budget": Budget(generations=2)}),
             (ENGINES["mcmc"], get_model("lightning"), _bar_target(), {"chains": 2, "budget": Budget(generations=3)})]
    with concurrent.futures.ProcessPoolExecutor(2) as pool:
        for engine, model, target, kwargs in cases:
            pooled = engine(model, target, seed=3, executor=pool, **kwargs)
            inline = engine(model, target, seed=3, **kwargs)
            assert pooled.best.choice_map() == inline.best.choice_map()
            assert pooled.best_score == inline.best_score
