"""Incremental MCMC (procmod/infer/traced.py): a move replayed from the state's checkpoints
is the full replay, bit for bit, its acceptance ratio is the full one, and chains built
from it (with the single-site resample move) sample exact posteriors."""

import dataclasses
import importlib
import math
from itertools import product

import numpy as np
import pytest

from procmod.core import InvalidArgumentError, replay
from procmod.infer import Budget, mcmc
from procmod.infer.common import Scored, evaluate
from procmod.infer.mcmc import Chains, _edited_dict, log_acceptance, log_acceptance_traced, propose
from procmod.infer.traced import EditedChoices, replay_traced, trace
from procmod.models import get_model
from procmod.targets import ShapeMatch, TargetImage

from test_engines_incremental import TARGETS
from test_mcmc_exact import assert_matches, fan_key, gate_key, visit_frequencies
from toy_models import (FAN, FAN_N, GATE, MIX, SWITCH, FlatTarget, SumTarget, gate_exact, mix_exact, switch_exact,
                        switch_key)


def _bar_target():
    mask = np.zeros((50, 50), bool)
    mask[10:45, 22:28] = True
    return ShapeMatch(TargetImage("bar", mask, (0.5, 0.9), (0, -1)))


def _walk(model, target, steps, seed, p_diffusion=0.3, p_resample=0.3, step_scale=0.3):
    """A chain of ``steps`` moves; each move is replayed incrementally and in full from the
    same seed, compared, and accepted with the incremental ratio."""
    model = target.configure(model)
    rng = np.random.default_rng(seed)
    state = trace(model, target, {}, np.random.default_rng(seed + 1))
    kinds = set()
    for _ in range(steps):
        p = propose(state, rng, p_diffusion, step_scale, p_resample)
        seed_replay = int(rng.integers(2 ** 62))
        inc = replay_traced(model, target, state, EditedChoices(state, p.overrides, p.removed),
                            np.random.default_rng(seed_replay), edited=p.address)
        choices = _edited_dict(state.derivation, p.overrides, p.removed)
        full = evaluate(model, target, (choices, seed_replay, None))
        n, f = inc.state.derivation, full.derivation
        assert n.order() == f.order()
        assert n.choice_map() == f.choice_map()
        assert n.geometry() == f.geometry()
        assert (n.n_nodes, n.n_emits, n.stopped) == (f.n_nodes, f.n_emits, f.stopped)
        # bit for bit: the same sums in the same order
        assert inc.state.log_prior == f.log_prior
        assert inc.state.log_likelihood == full.log_likelihood
        assert inc.state.score == full.score
        if getattr(n.output, "pixels", None) is not None and model.name != "spaceship":
            assert np.array_equal(np.asarray(n.output.pixels), np.asarray(f.output.pixels))
        scored = Scored(state.derivation, state.log_prior, state.log_likelihood, state.score)
        a_inc = log_acceptance_traced(state, p, inc, 1.0)
        a_full = log_acceptance(scored, dataclasses.replace(p, choices=choices), full, 1.0)
        assert a_inc == pytest.approx(a_full, abs=1e-9) or a_inc == a_full == -math.inf
        kinds.add(p.kind)
        if math.log(rng.random() + 1e-300) < a_inc:
            state = inc.state
    return state, kinds


@pytest.mark.parametrize("name,seed", [("vines", 0), ("vines", 7), ("lightning", 1), ("chain", 2)])
def test_incremental_move_is_the_full_replay_bit_for_bit(name, seed):
    state, kinds = _walk(get_model(name), _bar_target(), 150, seed)
    assert kinds == {"diffusion", "resample", "regenerate", "toggle"} or name != "vines"


def test_incremental_move_on_a_grown_vine():
    # a long vine (a state of a run), so that moves restore checkpoints deep in the derivation
    model, target = get_model("vines"), _bar_target()
    grown = mcmc(model, target, chains=1, seed=1, budget=Budget(evaluations=1500), p_resample=0.3,
                 p_diffusion=0.3)
    assert grown.samples[0].n_nodes >= 15
    configured = target.configure(model)
    state = trace(configured, target, grown.samples[0].choice_map().raw, np.random.default_rng(0))
    assert state.derivation.choice_map() == grown.samples[0].choice_map()
    rng = np.random.default_rng(3)
    for _ in range(60):
        p = propose(state, rng, 0.3, 0.3, 0.3)
        inc = replay_traced(configured, target, state, EditedChoices(state, p.overrides, p.removed),
                            np.random.default_rng(5), edited=p.address)
        full = evaluate(configured, target, (_edited_dict(state.derivation, p.overrides, p.removed), 5, None))
        assert inc.state.derivation.choice_map() == full.derivation.choice_map()
        assert (inc.state.log_prior, inc.state.log_likelihood) == (full.derivation.log_prior, full.log_likelihood)


@pytest.mark.parametrize("name", ["spaceship", "city"])
def test_incremental_move_on_3d_models(name):
    # 3D outputs are large: checkpoints every few calls, the calls between drawn again
    state, _ = _walk(get_model(name), TARGETS["volume"], 12, 4)
    assert state.stride >= 1


@pytest.mark.parametrize("kwargs", [{"chains": 3}, {"chains": 1, "p_resample": 0.3, "p_diffusion": 0.3},
                                    {"chains": 2, "p_resample": 0.5, "p_diffusion": 0.0, "annealing": None}])
def test_incremental_engine_is_the_full_replay_engine(kwargs):
    # the same random numbers in the same order: the same chain, bit for bit
    model, target = get_model("vines"), _bar_target()
    a = mcmc(model, target, seed=3, budget=Budget(generations=120), incremental=True, **kwargs)
    b = mcmc(model, target, seed=3, budget=Budget(generations=120), incremental=False, **kwargs)
    assert a.settings["incremental"] and not b.settings["incremental"]
    assert a.best_score == b.best_score
    assert [s.choice_map() for s in a.samples] == [s.choice_map() for s in b.samples]
    assert a.settings["acceptance_rates"] == b.settings["acceptance_rates"]
    assert [r[1:] for r in a.history] == [r[1:] for r in b.history]


@pytest.mark.parametrize("p_diffusion,p_resample", [(0.0, 0.5), (0.3, 0.3)])
def test_resample_move_on_gate(p_diffusion, p_resample):
    exact = gate_exact(FlatTarget())
    keys = list(exact)
    assert_matches(visit_frequencies(GATE, FlatTarget(), gate_key, keys, seed=11, incremental=True,
                                     p_diffusion=p_diffusion, p_resample=p_resample), exact, keys)


@pytest.mark.parametrize("p_resample", [0.3, 0.8])
def test_resample_move_on_switch(p_resample):
    obs, s = 1.5, 0.7
    exact = switch_exact(obs, s)
    keys = list(exact)
    assert_matches(visit_frequencies(SWITCH, SumTarget(obs, s), switch_key, keys, seed=12, incremental=True,
                                     p_diffusion=0.2, p_resample=p_resample, step_scale=0.5), exact, keys)


def test_resample_move_on_fan():
    # FAN's calls come and go with n: the choice count enters the reverse move's probability
    target = SumTarget(0.5, 0.5)
    keys = list(range(len(FAN_N)))
    exact = _fan_exact(target)
    assert_matches(visit_frequencies(FAN, target, fan_key, keys, seed=13, incremental=True, p_diffusion=0.0,
                                     p_resample=0.5), exact, keys)


def _fan_exact(target):
    """P(n) of FAN under ``target`` by enumeration over its coins."""
    joint = {}
    for n, pn in enumerate(FAN_N):
        total = 0.0
        for bs in product([False, True], repeat=n):
            choices = {((), "n"): n}
            choices.update({((f"c{i}",), "b"): b for i, b in enumerate(bs)})
            d = replay(FAN, choices, np.random.default_rng(0)).derivation
            total += math.exp(d.log_prior + target.log_likelihood(d.output))
        joint[n] = total
    z = sum(joint.values())
    return {n: v / z for n, v in joint.items()}


def test_resample_move_on_mix_marginals():
    obs, s = 1.2, 0.8
    _, exact = mix_exact(obs, s)
    keys = list(exact)

    def key(d):
        cm = d.choice_map()
        return cm[((), "k")], cm[((), "child")]

    assert_matches(visit_frequencies(MIX, SumTarget(obs, s), key, keys, seed=14, incremental=True,
                                     p_diffusion=0.3, p_resample=0.4, step_scale=0.5), exact, keys)


def test_resample_needs_room_beside_diffusion():
    with pytest.raises(InvalidArgumentError, match="p_resample"):
        mcmc(MIX, SumTarget(0.0, 1.0), p_diffusion=0.7, p_resample=0.5)


def test_chain_memory_check_counts_the_checkpoints(monkeypatch):
    """An incremental chain holds a checkpoint and a proposal beside its state: a chain
    count whose states alone fit but whose three outputs each do not is refused before
    any chain is made (the full-replay engine, one output per chain, is let through)."""
    from procmod.core import limits
    from procmod.infer.common import MEMBER_OVERHEAD, output_bytes

    model, target = get_model("vines"), _bar_target()
    per_copy = output_bytes(target.new_output(target.configure(model)))
    chains = 1000
    # room for 2 copies per chain: enough for the full replay's one, not the incremental three
    room = chains * (2 * per_copy + MEMBER_OVERHEAD)
    monkeypatch.setattr(limits, "physical_memory", lambda: int(room / limits.MEMORY_SHARE))
    with pytest.raises(limits.ResourceLimitError, match="chains 1,000 would need at least"):
        mcmc(model, target, chains=chains, budget=Budget(generations=1))
    mcmc(model, target, chains=2, budget=Budget(generations=1))  # a small ladder still runs
    limits.check_memory("one copy per chain", chains * (per_copy + MEMBER_OVERHEAD))  # what incremental=False asks


def test_redrawing_a_coins_old_value_costs_no_replay(monkeypatch):
    # GATE's choices are all fair coins, so a single-site resample redraws the old value
    # half the time; those moves keep the state without a replay (WebPPL's MH shortcut)
    engine = importlib.import_module("procmod.infer.mcmc")  # the module (the package exports the function)
    replays = []
    real = engine.replay_traced

    def counting(*args, **kwargs):
        replays.append(1)
        return real(*args, **kwargs)

    monkeypatch.setattr(engine, "replay_traced", counting)
    moves = 2000
    result = mcmc(GATE, FlatTarget(), seed=5, budget=Budget(evaluations=moves + 1), p_diffusion=0.0,
                  p_resample=1.0, annealing=None)
    assert result.evaluations == moves + 1  # the first state, then one proposal per move
    # Binomial(moves, 1/2) replays; five standard deviations either side
    assert abs(len(replays) - moves / 2) < 5 * math.sqrt(moves / 4)


def test_chains_start_from_the_best_derivations_of_an_smc_run():
    from procmod.infer import smc
    from procmod.infer.common import new_seed

    model, target = get_model("vines"), _bar_target()
    # a budget of one evaluation: the chains' first states (an MCMC evaluation is a proposal;
    # the SMC run's particle-steps are reported apart), so they are where they started
    result = mcmc(model, target, chains=3, seed=4, budget=Budget(evaluations=1), tempering=False)
    start = smc(model, target, particles=100, seed=new_seed(np.random.default_rng(4)))
    assert result.evaluations == 3 and result.settings["init_evaluations"] == start.evaluations
    assert result.best_score == start.best_score
    assert result.samples[0].choice_map() == start.best.choice_map()
    ranked = sorted(start.samples, key=lambda s: -target.score(s.output))
    assert result.samples[1].choice_map() != result.samples[0].choice_map()
    assert target.score(result.samples[1].output) <= start.best_score
    assert target.score(result.samples[2].output) <= target.score(ranked[0].output) + 1e-12
    # init_particles=0: forward samples, as before
    prior = mcmc(model, target, chains=3, seed=4, budget=Budget(evaluations=1), tempering=False, init_particles=0)
    assert prior.evaluations == 3 and prior.best_score < start.best_score
    assert prior.settings["init_evaluations"] == 0
    # an evaluations budget is one in moves, whatever the start cost
    moved = mcmc(model, target, seed=4, budget=Budget(evaluations=200))
    assert moved.evaluations == 200 and sum(p for _, p in moved.settings["moves"].values()) == 199
    with pytest.raises(InvalidArgumentError, match="init_particles"):
        mcmc(model, target, init_particles=-1)
