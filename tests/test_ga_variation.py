"""The GA's variation operators, each on its own: what it changes, what it keeps, and
with which probabilities it picks where to act."""

import math

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from procmod.core import replay, run_forward
from procmod.infer.ga import (COPIES, DROP, Genome, alter, crossover, cut, grow, mutate, nudge, reflect,
                              weighted_pick)
from procmod.models import get_model

from toy_models import TOY, TREE


def _toy(**on):
    """The toy model with kind 'a' (so the right leaf has a ``more`` site) and its three
    ``maybe`` sites set: ``left``, ``left_more``, ``right_more``."""
    choices = {((), "kind"): "a", ((), "left"): on.get("left", False),
               (("left",), "more"): on.get("left_more", False), (("right",), "more"): on.get("right_more", False)}
    return replay(TOY, choices, np.random.default_rng(0), maybe_default=False).derivation


def _valid(model, d):
    """A derivation is valid if replaying its choice map reproduces it with finite log-prior."""
    assert math.isfinite(d.log_prior)
    r = replay(model, d.choice_map(), np.random.default_rng(0))
    assert r.log_fresh == 0.0 and r.unused == []
    assert r.derivation.choice_map() == d.choice_map()


def _frequencies(draw, n):
    counts = {}
    for _ in range(n):
        key = draw()
        counts[key] = counts.get(key, 0) + 1
    return {k: v / n for k, v in counts.items()}


def _close(got: float, expected: float, n: int) -> bool:
    # 5 binomial standard errors: a correct sampler fails this with probability ~6e-7
    return abs(got - expected) < 5 * math.sqrt(expected * (1 - expected) / n)


def test_weighted_pick_follows_the_weights_and_skips_zero_weights():
    rng = np.random.default_rng(0)
    n = 4000
    freq = _frequencies(lambda: weighted_pick("abcd", [1.0, 0.0, 3.0, 0.0], rng), n)
    assert set(freq) == {"a", "c"}
    assert _close(freq["a"], 0.25, n)
    state = rng.bit_generator.state
    assert weighted_pick([], [], rng) is None and weighted_pick("ab", [0.0, 0.0], rng) is None
    assert rng.bit_generator.state == state  # nothing to pick: nothing drawn


def test_grow_turns_on_one_site_proportionally_to_p_and_keeps_the_rest():
    d = _toy(right_more=False)  # off: left (p 0.7) and right/more (p 0.4)
    g, before = Genome(d), d.choice_map().raw
    rng = np.random.default_rng(1)
    n = 4000
    picks = []
    for _ in range(n):
        child = grow(g, rng)
        (key,) = child.changes
        assert child.changes[key] is True and before[key] is False
        assert child.changed == {key[0]}
        assert child.materialize() == {**before, key: True}  # every other choice kept
        picks.append(key)
    freq = {k: picks.count(k) / n for k in set(picks)}
    assert set(freq) == {((), "left"), (("right",), "more")}
    assert _close(freq[((), "left")], 0.7 / 1.1, n)
    # The grown call's own choices are drawn in the replay, its maybe children start off.
    grown = replay(TOY, grow(g, rng).materialize(), rng, maybe_default=False)
    new = [n for n in grown.derivation.nodes() if n.address not in g.index()]
    assert len(new) == 1 and all(not s.on for s in new[0].spawns)
    _valid(TOY, grown.derivation)


def test_grow_with_a_count_turns_on_distinct_sites():
    d = _toy()
    g = Genome(d)
    rng = np.random.default_rng(2)
    assert len(g.grow_sites()) == 2
    for count, expected in ((2, 2), (5, 2)):  # at most as many as there are sites
        child = grow(g, rng, count)
        assert len(child.changes) == expected and all(v is True for v in child.changes.values())
    assert grow(Genome(_toy(left=True, left_more=True, right_more=True)), rng) is None  # nothing off


def test_cut_turns_off_one_site_proportionally_to_one_minus_p_and_drops_its_subtree():
    d = _toy(left=True, left_more=True, right_more=True)  # on: left (0.7), left/more (0.4), right/more (0.4)
    g, before = Genome(d), d.choice_map().raw
    rng = np.random.default_rng(3)
    n = 4000
    picks = []
    for _ in range(n):
        child = cut(g, rng)
        (key,) = child.changes
        below = key[0] + (key[1],)
        assert child.changes[key] is False and child.at == below and child.changed == {key[0]}
        expected = {k: v for k, v in before.items() if k[0][:len(below)] != below}
        assert child.materialize() == {**expected, key: False}  # the subtree goes, the rest stays
        picks.append(key)
    freq = {k: picks.count(k) / n for k in set(picks)}
    # right (a spawn, p = 1) is never cut; the others in proportion to 1 - p: 0.3, 0.6, 0.6
    assert set(freq) == {((), "left"), (("left",), "more"), (("right",), "more")}
    assert _close(freq[((), "left")], 0.3 / 1.5, n)
    assert _close(freq[(("left",), "more")], 0.6 / 1.5, n)
    assert cut(Genome(_toy()), rng) is None  # only the spawned right leaf is on


def test_alter_drops_one_calls_parameters_and_keeps_its_structure():
    d = _toy(left=True, right_more=True)
    g, before = Genome(d), d.choice_map().raw
    rng = np.random.default_rng(4)
    n = 4000
    picks = []
    for _ in range(n):
        child = alter(g, rng)
        (address,) = child.changed
        assert all(v is DROP and k[0] == address for k, v in child.changes.items())
        # every non-structural choice of that call is dropped (so replay redraws it), nothing else
        node = g.index()[address]
        structural = {s.site for s in node.spawns}
        assert {k[1] for k in child.changes} == set(node.choices) - structural
        assert child.materialize() == {k: v for k, v in before.items() if k not in child.changes}
        picks.append(address)
    calls = [a for a, _ in g.alter_sites()]
    assert sorted(calls) == sorted(n.address for n in d.nodes())  # every toy call has parameters
    for a in calls:  # uniform over the calls
        assert _close(picks.count(a) / n, 1 / len(calls), n)


def test_nudge_moves_one_calls_continuous_choices_by_scaled_gaussian_steps():
    d = _toy(left=True)
    g, before = Genome(d), d.choice_map().raw
    for seed in range(20):
        rng, twin = np.random.default_rng(seed), np.random.default_rng(seed)
        child = nudge(g, rng, step=0.3)
        sites = g.nudge_sites()
        address, choices = sites[int(twin.random() * len(sites))]
        assert child.changed == {address}
        for name, value, scale, low, high in choices:  # the twin generator replays the draws
            x = value + 0.3 * scale * twin.standard_normal()
            assert child.changes[(address, name)] == (x if low is None else reflect(x, low, high))
        # the root's categorical kind and the maybe coins are never nudged
        assert all(not isinstance(before[k], (bool, str)) for k in child.changes)
        assert {k: v for k, v in child.materialize().items() if k not in child.changes} == {
            k: v for k, v in before.items() if k not in child.changes}


def test_nudge_stays_within_the_support_on_spaceship():
    model = get_model("spaceship")
    rng = np.random.default_rng(2)
    d = run_forward(model, rng)
    g, before = Genome(d), d.choice_map().raw
    dists = {(n.address, name): c.dist for n in d.nodes() for name, c in n.choices.items()}
    moved_calls, steps = set(), []
    for _ in range(300):
        after = nudge(g, rng, step=0.5).materialize()
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


def test_reflect_folds_into_the_interval():
    assert reflect(0.5, 0.0, 1.0) == 0.5
    assert reflect(1.25, 0.0, 1.0) == pytest.approx(0.75)
    assert reflect(-0.25, 0.0, 1.0) == pytest.approx(0.25)
    assert reflect(2.25, 0.0, 1.0) == pytest.approx(0.25)
    assert reflect(3.0, 2.0, 2.0) == 2.0
    # an infinite bound reflects nothing (h82: the fold of width infinity gave NaN or inf)
    assert reflect(-0.5, 0.0, math.inf) == 0.5 and reflect(2.0, 0.0, math.inf) == 2.0
    assert reflect(0.5, -math.inf, 0.0) == -0.5 and reflect(-3.0, -math.inf, 0.0) == -3.0
    assert reflect(7.0, -math.inf, math.inf) == 7.0


def test_a_nudge_keeps_half_bounded_choices_finite_in_their_support_and_refuses_a_bad_step():
    """A TruncatedNormal with one infinite bound was nudged to NaN or inf every time, which
    the replay redrew from the prior: nudge was alter for those choices, without a word."""
    from procmod import Model, TruncatedNormal
    from procmod.core import InvalidArgumentError
    from procmod.geometry import Canvas, Segment

    def rule(ctx):
        pos = ctx.sample("pos", TruncatedNormal(0.0, 1.0, 0.0, math.inf))
        neg = ctx.sample("neg", TruncatedNormal(0.0, 1.0, -math.inf, 0.0))
        ctx.emit(Segment(pos, neg, 0.0, 0.0, 0.5))

    model = Model("half", "half-bounded", rule, root_args=lambda p: (),
                  new_output_from=lambda p: Canvas((-4, 4, -4, 4), 16))
    rng = np.random.default_rng(3)
    g = Genome(run_forward(model, rng))
    for _ in range(300):
        child = nudge(g, rng, step=1.0)
        values = dict(((name, v) for (_, name), v in child.changes.items()))
        assert math.isfinite(values["pos"]) and values["pos"] >= 0.0
        assert math.isfinite(values["neg"]) and values["neg"] <= 0.0
    for step in (-1.0, math.nan, "0.1"):
        with pytest.raises(InvalidArgumentError, match="step"):
            nudge(g, rng, step=step)


def test_mutate_picks_operators_by_split_and_falls_back_when_one_has_nothing_to_do():
    rng = np.random.default_rng(5)
    full = Genome(_toy(left=True, left_more=True, right_more=True))  # nothing to grow
    n = 4000

    def kind(child):
        if child.at is not None:
            return "cut"
        values = set(child.changes.values())
        return "alter" if values == {DROP} else "grow" if values == {True} else "nudge"

    some = Genome(_toy(left=True))  # something to do for every operator
    freq = _frequencies(lambda: kind(mutate(some, rng, (1.0, 2.0, 3.0, 4.0))), n)
    for name, w in zip(("grow", "cut", "alter", "nudge"), (1.0, 2.0, 3.0, 4.0)):
        assert _close(freq[name], w / 10.0, n)
    # Grow has nothing to do on a full derivation: its share goes to the next operator
    # with a positive weight (cut: 0.5 + 0.1), and an operator of weight 0 never runs.
    freq = _frequencies(lambda: kind(mutate(full, rng, (5.0, 1.0, 4.0, 0.0))), n)
    assert set(freq) == {"cut", "alter"} and _close(freq["cut"], 0.6, n)
    assert {kind(mutate(full, rng, (5.0, 0.0, 5.0, 0.0))) for _ in range(200)} == {"alter"}


@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(seed=st.integers(0, 2 ** 32 - 1), name=st.sampled_from(["vines", "lightning", "chain"]))
def test_every_offspring_is_a_valid_derivation(seed, name):
    model = get_model(name)
    rng = np.random.default_rng(seed)
    g1, g2 = Genome(run_forward(model, rng)), Genome(run_forward(model, rng))
    # An operator may return None only when the derivation offers it nothing to do.
    possible = {grow: any(p > 0 for _, _, p in g1.grow_sites()), cut: bool(g1.cut_sites()),
                alter: bool(g1.alter_sites()), nudge: bool(g1.nudge_sites())}
    maps = []
    for op, can in possible.items():
        child = op(g1, rng)
        assert (child is not None) == can, op.__name__
        if child is not None:
            maps.append(child.materialize())
    # Crossover retries random connections of g1; with 50 x as many tries as g1 has
    # connections, missing a compatible one that exists has probability below e^-50.
    n1 = sum(len(a) for a in g1.connections().values())
    children = crossover(g1, g2, rng, max_retries=50 * max(n1, 1))
    assert (children is not None) == bool(set(g1.connections()) & set(g2.connections()))
    if children is COPIES:
        maps.extend([dict(g1.raw()), dict(g2.raw())])
    elif children:
        maps.extend(c.materialize() for c in children)
    assert maps  # every model here has a root with parameters: alter always applies
    for choices in maps:
        _valid(model, replay(model, choices, rng, maybe_default=False).derivation)


def test_crossover_swaps_compatible_subtrees():
    model = get_model("lightning")
    rng = np.random.default_rng(11)
    g1, g2 = Genome(run_forward(model, rng)), Genome(run_forward(model, rng))
    c1, c2 = crossover(g1, g2, rng)
    for child, parent, donor in ((c1, g1, g2), (c2, g2, g1)):
        assert child.base is parent and child.donor is donor
        # what changed is the receiving parent's subtree below the swapped connection
        assert child.changed == {a for a in parent.index() if a[:len(child.at)] == child.at}
    r1 = replay(model, c1.materialize(), rng).derivation
    # The child keeps every connection of the model's generator graph: parent rule, site, child rule.
    for (parent_rule, child_rule), addresses in Genome(r1).connections().items():
        for address in addresses:
            assert (parent_rule.__name__, address[-1], child_rule.__name__) in {
                ("bolt", "next", "bolt"), ("bolt", "fork", "fork"), ("fork", "bolt", "bolt")}


def _cross_site_crossover(model, seed: int, top_level: bool):
    """Search crossovers of forward samples for one that swaps subtrees at two different
    spawn sites: ``(g1, g2, offspring 1)`` with ``offspring.at`` (receiving site in parent 1)
    and ``offspring.source`` (donor site in parent 2), or None."""
    rng = np.random.default_rng(seed)
    for _ in range(300):
        g1, g2 = Genome(run_forward(model, rng)), Genome(run_forward(model, rng))
        out = crossover(g1, g2, rng)
        if out is None or out is COPIES:
            continue
        child = out[0]
        if child.at[-1] != child.source[-1] and (not top_level or len(child.at) == len(child.source) == 1):
            return g1, g2, child
    return None


def test_crossover_pairs_sibling_sites_of_one_connection_type():
    # Seed 002: compatible connections are those of one generator-graph edge. The tree's
    # trunk spawns a branch at b0, b1 and b2: one edge (trunk -> branch), so a crossover
    # can put parent 2's b1 subtree under parent 1's b0 (a site-keyed match never could).
    model = get_model("tree")
    found = _cross_site_crossover(model, 0, top_level=True)
    assert found is not None
    g1, g2, child = found
    at, source = child.at, child.source
    child_map = child.materialize()
    donor = {(a[len(source):], name): value for (a, name), value in g2.raw().items() if a[:len(source)] == source}
    below = {(a[len(at):], name): value for (a, name), value in child_map.items() if a[:len(at)] == at}
    assert donor and below == donor  # re-addressed under the receiving site, all of it
    outside = {k: v for k, v in child_map.items() if k[0][:len(at)] != at}
    assert outside == {k: v for k, v in g1.raw().items() if k[0][:len(at)] != at}
    # Replayed, the subtree keeps its choices and runs from the receiving parent's context.
    r = replay(model, child_map, np.random.default_rng(0), maybe_default=False)
    assert r.log_fresh == 0.0 and r.unused == []
    nodes = {n.address: n for n in r.derivation.nodes()}
    assert nodes[at].args == g1.index()[at].args  # the receiving trunk's position, radius, length
    assert {n: c.value for n, c in nodes[at].choices.items()} == {
        n: c.value for n, c in g2.index()[source].choices.items()}
    _valid(model, r.derivation)


def test_crossover_pairs_sibling_sites_of_a_recursive_rule():
    # The toy tree spawns itself at "a" and at "b" (as vines' branch1 / branch2 once were):
    # one connection type, so subtrees move between the two sites, at any depth.
    found = _cross_site_crossover(TREE, 1, top_level=False)
    assert found is not None
    g1, g2, child = found
    assert {child.at[-1], child.source[-1]} == {"a", "b"}
    r = replay(TREE, child.materialize(), np.random.default_rng(0), maybe_default=False)
    _valid(TREE, r.derivation)
    top = {n.address: n for n in r.derivation.nodes()}[child.at]
    assert top.args == g1.index()[child.at].args  # the receiving site's depth
    assert top.choices["v"].value == g2.index()[child.source].choices["v"].value


def test_crossover_of_equal_subtrees_gives_copies():
    # A derivation crossed with itself: a swap at the same connection changes nothing and
    # gives COPIES (no evaluation needed); any other swap gives children that differ.
    model = get_model("spaceship")
    rng = np.random.default_rng(0)
    kinds = []
    for _ in range(40):
        d = run_forward(model, rng)
        out = crossover(Genome(d), Genome(d), rng)
        if out is None:
            continue
        kinds.append(out is COPIES)
        if out is not COPIES:
            raw = d.choice_map().raw
            assert out[0].materialize() != raw and out[1].materialize() != raw
    assert any(kinds) and not all(kinds)


def test_crossover_without_a_compatible_connection_gives_none():
    # Connections between two models' rules are of different types: none matches.
    rng = np.random.default_rng(6)
    toy, tree = Genome(_toy()), Genome(run_forward(TREE, rng))
    assert crossover(toy, tree, rng) is None
    assert crossover(Genome(run_forward(TREE, rng)), toy, rng) is None
