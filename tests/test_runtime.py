import math

import numpy as np
import pytest

from procmod.core import (ChoiceMap, ModelError, finish, random_order, regenerate, replay,
                          run_forward, same_args, set_maybe, start, step)
from procmod.models import get_model

from toy_models import DUPLICATE, STOPPER, TOY, TREE, toy_log_prior


def _same(a, b):
    assert a.choice_map() == b.choice_map()
    assert a.geometry() == b.geometry()
    assert a.order() == b.order()
    assert a.log_prior == b.log_prior
    if a.output.dimension == 2:
        assert np.array_equal(a.output.pixels, b.output.pixels)


@pytest.mark.parametrize("name", ["chain", "vines", "lightning", "spaceship", "tree", "city"])
def test_replay_round_trip(name):
    model = get_model(name)
    for seed in range(20):
        d = run_forward(model, np.random.default_rng(seed))
        r = replay(model, d.choice_map(), np.random.default_rng(999))
        _same(d, r.derivation)
        assert r.log_fresh == 0.0 and r.unused == []
        assert math.isclose(r.log_reused, d.log_prior, abs_tol=1e-12)


def test_log_prior_matches_hand_computed_sum():
    for seed in range(50):
        d = run_forward(TOY.configure(x=0.8), np.random.default_rng(seed))
        assert math.isclose(d.log_prior, toy_log_prior(d), rel_tol=0, abs_tol=1e-10)
        assert math.isclose(d.log_prior, sum(n.log_prob for n in d.nodes()), abs_tol=1e-10)


def test_replay_samples_missing_and_drops_unused():
    d = run_forward(TOY, np.random.default_rng(3))
    cm = d.choice_map().raw.copy()
    del cm[((), "x0")]
    cm[(("nowhere",), "z")] = 1.0
    cm[((), "kind")] = "not-a-label"  # outside the support: resampled, reported unused
    r = replay(TOY, cm, np.random.default_rng(4))
    new = r.derivation.choice_map()
    assert ((), "x0") in new and new[((), "kind")] in ("a", "b", "c")
    assert sorted(r.unused) == sorted([(("nowhere",), "z"), ((), "kind")])
    fresh = r.derivation.tree()[()].choices
    expect_fresh = fresh["x0"].log_prob + fresh["kind"].log_prob
    assert math.isclose(r.log_fresh, expect_fresh, abs_tol=1e-12)
    assert math.isclose(r.log_reused + r.log_fresh, r.derivation.log_prior, abs_tol=1e-12)


def test_regenerate_keeps_addresses_outside_the_subtree():
    model = get_model("lightning")
    d = run_forward(model, np.random.default_rng(5))
    target = max(d.tree(), key=len)[:3]  # a call three levels down
    assert len(target) == 3
    old = d.choice_map()
    changed = 0
    for seed in range(10):
        r = regenerate(model, d, target, np.random.default_rng(seed))
        new = r.derivation.choice_map()
        for (address, name), value in old.items():
            if address[: len(target)] != target:
                assert new[(address, name)] == value
        changed += any(new.get(k) != v for k, v in old.items() if k[0][: len(target)] == target)
        assert math.isclose(r.log_reused + r.log_fresh, r.derivation.log_prior, abs_tol=1e-9)
    assert changed == 10  # continuous choices below the target always change


def test_set_maybe_grows_and_cuts():
    model = TOY
    d = None
    for seed in range(100):
        d = run_forward(model, np.random.default_rng(seed))
        if not d.choice_map()[((), "left")]:
            break
    grown = set_maybe(model, d, (), "left", True, np.random.default_rng(1))
    tree = grown.derivation.tree()
    assert ("left",) in tree and grown.log_fresh < 0
    fresh = sum(n.log_prob for a, n in tree.items() if a[:1] == ("left",))
    assert math.isclose(grown.log_fresh, fresh, abs_tol=1e-12)
    cut = set_maybe(model, grown.derivation, (), "left", False, np.random.default_rng(2))
    assert ("left",) not in cut.derivation.tree() and cut.log_fresh == 0.0
    assert all(a[0][:1] == ("left",) for a in cut.unused) and cut.unused
    assert cut.derivation.choice_map() == d.choice_map()
    with pytest.raises(ModelError):
        set_maybe(model, d, (), "right", True, np.random.default_rng(0))  # not a maybe site


@pytest.mark.parametrize("name", ["chain", "vines", "lightning", "spaceship"])
def test_stepping_in_program_order_equals_forward_run(name):
    model = get_model(name)
    for seed in range(10):
        forward = run_forward(model, np.random.default_rng(seed))
        state = start(model)
        rng = np.random.default_rng(seed)
        emits = 0
        while step(state, rng):
            emits += 1
        assert state.done and emits == forward.n_emits
        _same(forward, state)


def test_step_stops_at_each_emit():
    state = start(get_model("vines"))
    rng = np.random.default_rng(0)
    last = 0
    while step(state, rng):
        assert state.n_emits == last + 1
        last = state.n_emits


def test_copy_shares_nodes_and_is_independent():
    model = get_model("lightning")
    state = start(model)
    rng = np.random.default_rng(1)
    for _ in range(8):
        step(state, rng)
    frozen = state.choice_map(), state.output.pixels.copy(), state.log_prior
    twin = state.copy()
    assert twin._chain is state._chain  # structure sharing
    finish(twin, np.random.default_rng(2))
    assert (state.choice_map(), state.log_prior) == (frozen[0], frozen[2])
    assert np.array_equal(state.output.pixels, frozen[1])
    # Finishing the original with the same generator the twin used reproduces the twin.
    finish(state, np.random.default_rng(2))
    _same(state, twin)


def test_a_proposer_sees_the_derivation_being_built_through_ctx():
    seen, refused = [], []

    class Watching:  # a Proposer that draws from the prior and records what it saw
        def propose(self, ctx, name, dist, rng):
            seen.append((ctx.derivation, ctx.derivation.n_emits, ctx.derivation.output.filled_count))
            try:
                ctx.derivation = None
            except AttributeError:
                refused.append(name)
            value = dist.sample(rng)
            return value, dist.log_prob(value)

    state = start(TREE)
    state.proposer = Watching()
    finish(state, np.random.default_rng(3))
    assert len(seen) == len(state.choice_map()) > 1
    assert all(d is state for d, _, _ in seen)
    emits = [n for _, n, _ in seen]
    assert emits[0] == 0 and emits[-1] > 0 and emits == sorted(emits)  # it watched the output grow
    assert seen[-1][2] > 0
    assert len(refused) == len(seen)  # a read-only view


def test_fresh_choices_are_a_policy_the_derivation_holds_not_fields_of_it():
    from procmod.core import ChoicePolicy, Derivation, GuidedPolicy, ReplayPolicy
    assert Derivation.__slots__ == ("model", "output", "pending", "active", "log_prior", "stopped", "position",
                                    "n_emits", "n_nodes", "_chain", "policy")

    class Low(ChoicePolicy):  # a policy of one's own: every fresh choice at its lowest value seen so far
        __slots__ = ("calls",)

        def __init__(self):
            self.calls, self.guide_cache = 0, None

        def choose(self, ctx, name, dist):
            self.calls += 1
            value = min(dist.sample(ctx._rng) for _ in range(3))
            return value, dist.log_prob(value)

        def copy(self):
            other = Low()
            other.calls = self.calls
            return other

    state = start(TREE)
    assert state.policy is None and state.proposer is None and state.log_proposal == 0.0
    state.policy = Low()
    step(state, np.random.default_rng(0))
    twin = state.copy()
    assert twin.policy is not state.policy and twin.policy.calls == state.policy.calls > 0
    finish(state, np.random.default_rng(1))
    assert state.policy.calls == len(state.choice_map())
    assert math.isclose(state.log_prior, sum(state.choice_log_probs().values()), abs_tol=1e-12)
    # the guide's state lives in a GuidedPolicy; a cache alone gives the prior one
    bare = start(TREE)
    bare.guide_cache = (0, "pyramid")
    assert type(bare.policy) is GuidedPolicy and bare.proposer is None and bare.copy().guide_cache == (0, "pyramid")
    _same(finish(bare, np.random.default_rng(5)), run_forward(TREE, np.random.default_rng(5)))
    # a replay's bookkeeping lives in its ReplayPolicy; a proposer does not mix with it
    replaying = start(TREE, constraints={((), "v"): 0.5})
    assert type(replaying.policy) is ReplayPolicy
    with pytest.raises(ModelError, match="takes no proposer"):
        replaying.proposer = object()
    r = replay(TREE, run_forward(TREE, np.random.default_rng(2)).choice_map(), np.random.default_rng(0))
    assert r.derivation.policy is None


def test_same_args_compares_plain_arguments_and_refuses_arrays():
    args = (1.0, "a", (2, 3))
    assert same_args(args, args) and same_args(args, (1.0, "a", (2, 3)))
    assert not same_args(args, (1.0, "b", (2, 3)))
    a = (np.array([1.0, 2.0]),)
    assert same_args(a, a)  # the same tuple
    assert not same_args(a, (np.array([1.0, 2.0]),))  # equal arrays, but no plain bool


def test_random_order_reaches_same_distribution_as_program_order():
    # Statistic: number of calls and sum of all v; stop-free model, so order must not matter.
    n = 3000

    def stats(pick, seed):
        rng = np.random.default_rng(seed)
        calls, total = [], []
        for _ in range(n):
            state = start(TREE)
            while step(state, rng, pick):
                pass
            calls.append(state.n_nodes)
            total.append(sum(v for (a, name), v in state.choice_map().items() if name == "v"))
        return np.array(calls, float), np.array(total)

    c1, t1 = stats(None, 1)
    c2, t2 = stats(random_order, 2)
    for x, y in ((c1, c2), (t1, t2)):
        se = math.sqrt(x.var() / n + y.var() / n)
        assert abs(x.mean() - y.mean()) < 5 * se
    # Exact expected number of calls: 1 + E[children], E[calls at depth d] = (0.6 + 0.4)^d = 1.
    assert abs(c1.mean() - 4.0) < 5 * math.sqrt(c1.var() / n)


def test_random_order_visits_other_orders():
    rng = np.random.default_rng(0)
    orders = set()
    for _ in range(200):
        state = start(TREE)
        while step(state, rng, random_order):
            pass
        orders.add(tuple(state.order()))
    assert len(orders) > 10


def test_stop_drops_pending_calls():
    seen = set()
    for seed in range(40):
        d = run_forward(STOPPER, np.random.default_rng(seed))
        halted = d.choice_map()[(("two",), "halt")]
        assert (("three",) in d.tree()) == (not halted)
        seen.add(halted)
    assert seen == {True, False}


def test_duplicate_choice_name_is_a_model_error():
    with pytest.raises(ModelError, match="twice"):
        run_forward(DUPLICATE, np.random.default_rng(0))


def test_same_seed_same_derivation():
    model = get_model("vines")
    a = run_forward(model, np.random.default_rng(42))
    b = run_forward(model, np.random.default_rng(42))
    _same(a, b)


def test_choice_map_helpers():
    cm = ChoiceMap({((), "a"): 1.0, (("x",), "b"): 2.0, (("x", "y"), "c"): 3.0, (("z",), "d"): 4.0})
    assert set(cm.without_subtree(("x",))) == {((), "a"), (("z",), "d")}
    assert cm.with_value(("q",), "e", True)[(("q",), "e")] is True
    assert len(cm) == 4
