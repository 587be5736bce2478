"""Review of ed90c64 (SMC runs a population no resampling can change straight through):
the straight run must end, weigh and count as stepping the particle emit by emit does,
also where the target rules a partial output out (a proxy target's intersecting parts)."""

import importlib
import math

import pytest

from procmod.core import Model, Uniform
from procmod.core.errors import InvalidArgumentError
from procmod.infer import Budget, smc
from procmod.infer.common import ZERO_LIKELIHOOD_NOTE

from toy_models import SumOutput, SumTarget, Value

smc_module = importlib.import_module("procmod.infer.smc")  # (procmod.infer.smc is also the function)


def _root(ctx, n):
    for i in range(n):
        ctx.emit(Value(ctx.sample(f"u{i}", Uniform(0.0, 1.0))))  # the derivation ends on an emit


SIX = Model("six", "six emits in one call", _root, lambda p: (6,), lambda p: SumOutput(), rules=(_root,))


class Capped(SumTarget):
    """Rules out a sum above ``cap`` (as intersecting parts are ruled out: for good)."""

    def __init__(self, cap):
        super().__init__(1.0, 1.0)
        self.cap = cap

    def log_likelihood(self, output):
        return -math.inf if output.total > self.cap else super().log_likelihood(output)


class HighProposer:
    """A proposer of one's own: every choice drawn from Uniform(0.5, 1)."""

    def propose(self, ctx, name, dist, rng):
        return 0.5 + 0.5 * rng.random(), math.log(2.0)


def _summary(result):
    return (None if result.best is None else result.best.choice_map(), result.evaluations,
            result.log_marginal_likelihood, [(s.choice_map(), s.done, s.n_emits) for s in result.samples],
            result.notes, [row[1:] for row in result.history])  # the history less its seconds


@pytest.mark.parametrize("target, guide", [(SumTarget(1.0, 1.0), None), (Capped(2.0), None),
                                           (Capped(0.8), None), (Capped(2.0), HighProposer())])
def test_one_particle_run_through_is_what_stepping_gives(monkeypatch, target, guide):
    # a single particle at an ESS threshold never resamples: stepped, it was the same run,
    # history rows included (the first run-through kept one row a run: a report's
    # convergence plot of a 1-particle run was a single point)
    budget = Budget(evaluations=40)
    fast = [_summary(smc(SIX, target, particles=1, seed=s, ess_threshold=0.5, guide=guide, budget=budget))
            for s in range(6)]
    monkeypatch.setattr(smc_module, "unchangeable_by_resampling", lambda particles, threshold: False)
    stepped = [_summary(smc(SIX, target, particles=1, seed=s, ess_threshold=0.5, guide=guide, budget=budget))
               for s in range(6)]
    assert fast == stepped


def test_a_particle_ruled_out_mid_run_ends_the_run_there():
    result = smc(SIX, Capped(0.8), particles=1, seed=0, ess_threshold=0.5)
    (sample,) = result.samples
    assert not sample.done and result.best is None and ZERO_LIKELIHOOD_NOTE in result.notes
    assert result.evaluations == sample.n_emits < 6  # one step an emit, up to the one that ruled it out
    # a complete run of six emits ending on its last emit: six steps, none after it
    assert smc(SIX, SumTarget(1.0, 1.0), particles=1, seed=0).evaluations == 6


def test_two_particles_both_ruled_out_stop_together_unfinished():
    for seed in range(5):
        result = smc(SIX, Capped(1.2), particles=2, seed=seed, ess_threshold=0.5)
        assert result.log_marginal_likelihood == -math.inf and result.best is None
        # stepped together, both stop at the step that ruled the later one out
        assert [s.done for s in result.samples] == [False, False]
        assert result.samples[0].n_emits == result.samples[1].n_emits == result.evaluations // 2


class NanOnTheWay(SumTarget):
    """No number while the sum is between 0.2 and 1.5 (every run passes there; few end there)."""

    def log_likelihood(self, output):
        return math.nan if 0.2 < output.total < 1.5 else super().log_likelihood(output)


def test_a_likelihood_that_is_no_number_mid_run_is_refused():
    # stepping looks at every emit's likelihood: a straight run that looked only at its end
    # had passed a target's NaN without a word
    for seed in range(3):
        with pytest.raises(InvalidArgumentError, match="log_likelihood"):
            smc(SIX, NanOnTheWay(1.0, 1.0), particles=1, seed=seed)
