"""SMC populations that no resampling can change run each particle straight through
(procmod.infer.smc.unchangeable_by_resampling): one particle, or two at the guided ESS
threshold of 0.5. Same derivations as stepping emit by emit, without re-running a call
from its start after each of its emits."""

import math

import numpy as np

from procmod.core import Model, Normal
from procmod.core.random import BlockGenerator
from procmod.core.runtime import start, step
from procmod.infer import smc
from procmod.infer.smc import unchangeable_by_resampling

from test_engines_exact import assert_z_unbiased
from toy_models import MIX, Z_CHECK_S, SumOutput, SumTarget, Value, mix_exact

OBS = 2.3
RUNS = []  # (address of each execution of a rule call): a call paused at an emit runs again


def _chain(ctx, depth):
    """Two emits a call with a choice between them, then a coin for one more call (none at
    depth 6: a derivation that reaches it ends on an emit, which stepping counts no extra
    step for)."""
    RUNS.append(ctx.address)
    ctx.emit(Value(ctx.sample("a", Normal(0.0, 1.0))))
    ctx.emit(Value(ctx.sample("b", Normal(0.0, 0.5))))
    if depth < 6:
        ctx.maybe("more", 0.7, _chain, depth + 1)


CHAIN = Model("chain", "two emits a call, up to seven calls", _chain, lambda p: (0,), lambda p: SumOutput(),
              rules=(_chain,))


def _stepped(model, target, seed):
    """One particle stepped emit by emit with the engine's generator, as the engine steps it
    (until it is complete): (choice map, steps)."""
    rng = BlockGenerator(np.random.default_rng(seed))
    state = start(model, target.new_output(model))
    steps = 0
    while not state.done:
        step(state, rng)
        steps += 1
    return state.choice_map(), steps


def test_which_populations_no_resampling_can_change():
    assert unchangeable_by_resampling(1, None) and unchangeable_by_resampling(1, 0.5)
    assert unchangeable_by_resampling(2, 0.5)  # an ESS is at least 1
    assert not unchangeable_by_resampling(2, None)  # every emit: offspring of the better one
    assert not unchangeable_by_resampling(3, 0.5) and not unchangeable_by_resampling(2, 0.6)


def test_one_particle_runs_each_call_once_and_draws_what_stepping_draws():
    target = SumTarget(OBS, 1.0)
    for seed in range(12):
        RUNS.clear()
        result = smc(CHAIN, target, particles=1, seed=seed)
        calls = result.best.nodes()
        assert len(RUNS) == len(calls) and len(set(RUNS)) == len(RUNS), seed  # no call ran twice
        choices, steps = _stepped(CHAIN, target, seed)
        # the same random numbers for the same choices: a single particle's resampling
        # (every emit, unguided) had drawn one of them a step and changed what followed
        assert result.best.choice_map() == choices, seed
        assert result.evaluations == steps, seed
        assert result.log_marginal_likelihood == result.log_weights[0]
        assert math.isclose(result.log_weights[0], target.log_likelihood(result.best.output))


def test_two_particles_under_the_guided_threshold_run_through_and_three_step():
    target = SumTarget(OBS, 1.0)
    RUNS.clear()
    result = smc(CHAIN, target, particles=2, seed=3, ess_threshold=0.5)
    assert len(RUNS) == sum(len(s.nodes()) for s in result.samples)
    RUNS.clear()
    result = smc(CHAIN, target, particles=3, seed=3, ess_threshold=0.5)
    assert len(RUNS) > sum(len(s.nodes()) for s in result.samples)  # paused calls re-run: stepped


def test_run_through_estimates_z_without_bias():
    # one particle: Z-hat is the likelihood of a prior draw; two at the guided threshold:
    # the mean of two. Both unbiased, as stepped SMC's estimates are (1,000 runs: the
    # spread of one particle's estimate needs more than 400 for the check to have power)
    z, _ = mix_exact(OBS, Z_CHECK_S)
    target = SumTarget(OBS, Z_CHECK_S)
    for particles, threshold in ((1, None), (2, 0.5)):
        estimates = [math.exp(smc(MIX, target, particles=particles, seed=i, ess_threshold=threshold)
                              .log_marginal_likelihood) for i in range(1000)]
        assert_z_unbiased(estimates, z)
