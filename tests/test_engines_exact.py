"""Engines against exact answers on toy models (tolerances from the sample sizes)."""

import importlib
import math

import numpy as np
import pytest

from procmod.core import Bernoulli, program_order
from procmod.infer import Budget, mcmc, smc, sosmc
from procmod.infer.particles import ParticleShard

from toy_models import (COUNT, MIX, ORDER, Z_CHECK_S, SumOutput, SumTarget, count_evidence, count_exact,
                        mix_exact)

OBS, S = 2.3, 0.5


def test_smc_marginal_likelihood_is_unbiased():
    z, _ = mix_exact(OBS, Z_CHECK_S)  # a likelihood under which the estimate's variance is finite
    runs = 400
    estimates = np.array([math.exp(smc(MIX, SumTarget(OBS, Z_CHECK_S), particles=8, seed=i).log_marginal_likelihood)
                          for i in range(runs)])
    se = estimates.std(ddof=1) / math.sqrt(runs)
    assert abs(estimates.mean() - z) < 4.5 * se, (estimates.mean(), z, se)
    assert se < 0.1 * z  # the check has power: a 10% bias would be caught


def assert_z_unbiased(estimates, z: float, limit: float = 4.5) -> None:
    """The runs' mean estimate of Z within ``limit`` standard errors of ``z``, and the check
    has power: ``limit`` standard errors under a tenth of ``z``, the spread for that read
    robustly (the median absolute deviation). Z-hat is heavy-tailed: one large estimate
    among 40-400 runs pushed the sample's standard error past that bound for 13-20% of
    other seeds (h127), a fact of the seeds, not of the check's design."""
    estimates = np.asarray(estimates, dtype=np.float64)
    runs = len(estimates)
    se = estimates.std(ddof=1) / math.sqrt(runs)
    assert abs(estimates.mean() - z) < limit * se, ("Z", estimates.mean(), z, se)
    spread = 1.4826 * float(np.median(np.abs(estimates - np.median(estimates))))
    assert limit * spread / math.sqrt(runs) < 0.1 * z, ("power", spread, z)


def _posterior_from_smc(result):
    w = np.exp(np.array(result.log_weights) - max(result.log_weights))
    w /= w.sum()
    out = {}
    for weight, d in zip(w, result.samples):
        cm = d.choice_map()
        key = (cm[((), "k")], cm[((), "child")])
        out[key] = out.get(key, 0.0) + weight
    return out


def assert_posterior_matches(results, exact: dict, limit: float = 4.5, power: float = 0.03) -> None:
    """The runs' posterior P(k, child) of MIX against ``exact``, each run's estimate weighted
    by its estimate of Z: the mean of Z-hat x (Z-hat-normalised estimate) is unbiased
    at any particle count (seed 004's SMC; Del Moral), so their ratio is consistent over
    runs with no O(1/N) bias. The plain mean of the runs' normalised estimates is biased
    (by ~6/N on MIX under sd 0.5, heavy-tailed besides): a fixed allowance for it
    passed or failed by the seeds (a change of random streams found it). Needs a
    likelihood under which Z-hat has a finite variance (``Z_CHECK_S``). ``power``: the
    least error the check must catch."""
    log_z = np.array([r.log_marginal_likelihood for r in results])
    z_hat = np.exp(log_z - log_z.max())
    estimates = [_posterior_from_smc(r) for r in results]
    for key, p in exact.items():
        values = np.array([e.get(key, 0.0) for e in estimates])
        ratio = float((z_hat * values).sum() / z_hat.sum())
        se = math.sqrt(float(((z_hat * (values - ratio)) ** 2).sum())) / z_hat.sum()  # delta method
        assert abs(ratio - p) < limit * se, (key, ratio, p, se)
        # the check has power: the prior's P(0, *) = 0.15 against the posterior's 0.114
        assert limit * se < power, (key, se)


@pytest.mark.parametrize("engine", [smc, sosmc])
def test_smc_posterior_marginals_match_exact(engine):
    _, exact = mix_exact(OBS, Z_CHECK_S)
    results = [engine(MIX, SumTarget(OBS, Z_CHECK_S), particles=300, seed=100 + i) for i in range(40)]
    assert_posterior_matches(results, exact)


# SOSMC where the order of the futures matters. On MIX at most one future is ever pending,
# so SOSMC runs there as SMC does. ORDER is MIX split over two sibling calls (a draws k
# and maybe the child, b draws x): after the root both are pending, and whichever SOSMC
# expands first is scored first, so the order changes every intermediate weight. The
# final target does not depend on the order, so the weighted particles must show the
# exact P(k, child), an unbiased Z, and the order drawn as SOSMC draws it: a before b
# with probability 1/2, whatever the data.
ORDER_OBS, ORDER_S = 1.5, 1.0  # a gentle likelihood: a sharp one of the first partial sum
# would starve the states the second emit favours, a finite-N bias far beyond O(1/N)


def _count_resampling(monkeypatch):
    """Counts generations (shard steps) and resamplings (both resamplers) of later runs."""
    smc_module = importlib.import_module("procmod.infer.smc")
    counts = {"steps": 0, "resamples": 0}

    def counted(real, key):
        def wrapper(*args):
            counts[key] += 1
            return real(*args)
        return wrapper

    monkeypatch.setattr(ParticleShard, "step", counted(ParticleShard.step, "steps"))
    monkeypatch.setattr(smc_module, "resample", counted(smc_module.resample, "resamples"))
    monkeypatch.setattr(smc_module, "systematic_small", counted(smc_module.systematic_small, "resamples"))
    return counts


def test_smc_resampling_below_an_ess_threshold_matches_exact(monkeypatch):
    # COUNT emits up to five times. Resampling only when the effective sample size falls
    # below a share of the particles carries weights over the emits it skips (half is the
    # default of guided runs); the weighted particles must still show the exact posterior over the
    # number of calls and an unbiased Z, and skips must happen, or this is the every-emit
    # test again. The likelihood is ORDER's gentle one (above): a sharp one of the first
    # partial sum starves the longer derivations' states at 200 particles, every emit or not.
    # Under it the ESS stays near half the particles, so at the guided default (0.5) 40 runs
    # resampled 0-2 times in all (as the random streams fell): 0.6 resamples at about a third
    # of the emits, and skips the rest.
    counts = _count_resampling(monkeypatch)
    exact, z = count_exact(ORDER_OBS, ORDER_S), count_evidence(ORDER_OBS, ORDER_S)
    runs, particles = 40, 200
    estimates, zs = [], []
    for i in range(runs):
        result = smc(COUNT, SumTarget(ORDER_OBS, ORDER_S), particles=particles, seed=700 + i, ess_threshold=0.6)
        zs.append(math.exp(result.log_marginal_likelihood))
        w = np.exp(np.array(result.log_weights) - max(result.log_weights))
        w /= w.sum()
        posterior = {}
        for weight, d in zip(w, result.samples):
            n = sum(1 for _, name in d.choice_map() if name == "v")
            posterior[n] = posterior.get(n, 0.0) + weight
        estimates.append(posterior)
    assert 0 < counts["resamples"] < 0.8 * counts["steps"], counts
    for n, p in exact.items():
        values = np.array([e.get(n, 0.0) for e in estimates])
        se = values.std(ddof=1) / math.sqrt(runs)
        assert abs(values.mean() - p) < 5 * se + 2.0 / particles, (n, values.mean(), p, se)
    assert_z_unbiased(zs, z)


def test_a_small_population_resampling_below_an_ess_threshold_estimates_z_without_bias(monkeypatch):
    # Up to 32 particles the weights are Python floats (smc.SMALL_POPULATION): the same
    # check of Z on that path, where guided runs of a few particles go.
    counts = _count_resampling(monkeypatch)
    z = count_evidence(ORDER_OBS, ORDER_S)
    runs = 400
    zs = np.array([math.exp(smc(COUNT, SumTarget(ORDER_OBS, ORDER_S), particles=8, seed=i,
                                ess_threshold=0.5).log_marginal_likelihood) for i in range(runs)])
    assert 0 < counts["resamples"] < 0.8 * counts["steps"], counts
    assert_z_unbiased(zs, z)


class _CeilingTarget(SumTarget):
    """SumTarget, but a running sum above 1 is impossible (log-likelihood -inf), as a
    target may declare an output it cannot accept."""

    def log_likelihood(self, output):
        return -math.inf if output.total > 1.0 else super().log_likelihood(output)


def test_an_impossible_particle_left_unresampled_keeps_weight_zero():
    # Skipping a resampling leaves a particle of zero likelihood in the population; its
    # next step must keep its weight at zero, not turn it into NaN (-inf - -inf), which
    # would stop all later resampling and poison Z.
    for seed in range(20):
        result = smc(COUNT, _CeilingTarget(0.5, 1.0), particles=50, seed=seed, ess_threshold=0.1)
        assert not any(math.isnan(w) for w in result.log_weights), seed
        assert not math.isnan(result.log_marginal_likelihood), seed
        assert all(d.output.total <= 1.0 for d, w in zip(result.samples, result.log_weights) if w > -math.inf)


def _sosmc_on_order(target, runs=40, particles=200):
    """Per run of SOSMC on ORDER: the Z estimate, weighted P(k, child), weighted P(a first)."""
    zs, posteriors, a_first = [], [], []
    for i in range(runs):
        result = sosmc(ORDER, target, particles=particles, seed=300 + i)
        zs.append(math.exp(result.log_marginal_likelihood))
        w = np.exp(np.array(result.log_weights) - max(result.log_weights))
        w /= w.sum()
        posterior, first = {}, 0.0
        for weight, d in zip(w, result.samples):
            cm = d.choice_map()
            key = (cm[(("a",), "k")], cm[(("a",), "child")])
            posterior[key] = posterior.get(key, 0.0) + weight
            if d.order()[1] == ("a",):  # calls are recorded in the order they ran
                first += weight
        posteriors.append(posterior)
        a_first.append(first)
    return np.array(zs), posteriors, np.array(a_first)


def _check_sosmc_on_order(target=None, particles=200):
    """Runs are independent, so their spread gives each standard error; 5 of them, plus
    2 / particles for SMC's O(1/N) bias in ratio estimates (none for Z, which is unbiased)."""
    target = target or SumTarget(ORDER_OBS, ORDER_S)
    z, exact = mix_exact(ORDER_OBS, ORDER_S)
    zs, posteriors, a_first = _sosmc_on_order(target, particles=particles)
    runs = len(zs)
    assert_z_unbiased(zs, z, limit=5)
    se = a_first.std(ddof=1) / math.sqrt(runs)
    assert abs(a_first.mean() - 0.5) < 5 * se + 2.0 / particles, ("a first", a_first.mean(), se)
    for key, p in exact.items():
        values = np.array([e.get(key, 0.0) for e in posteriors])
        se = values.std(ddof=1) / math.sqrt(runs)
        assert abs(values.mean() - p) < 5 * se + 2.0 / particles, (key, values.mean(), p, se)


def test_sosmc_matches_exact_where_the_order_of_futures_matters():
    _check_sosmc_on_order()


class _Misweighted:
    """Makes SOSMC weigh each random pick by 1 / (number pending), as if the order were an
    importance proposal to correct for (it is part of the target; no correction is due).
    The pick charges the derivation being stepped through its output's ``log_penalty``,
    which the target adds to the log-likelihood, so the engine's own weights carry it."""

    def __init__(self, stepping_module):
        self.step, self.current = stepping_module.step, None

    def stepping(self, state, rng, pick=None):
        self.current = state
        return self.step(state, rng, pick)

    def pick(self, pending, rng):
        self.current.output.log_penalty -= math.log(len(pending))
        return int(rng.random() * len(pending))


class _PenalisedOutput(SumOutput):
    log_penalty = 0.0

    def copy(self):
        other = _PenalisedOutput()
        other.total, other.log_penalty = self.total, self.log_penalty
        return other


class _PenalisedTarget(SumTarget):
    def new_output(self, model):
        return _PenalisedOutput()

    def log_likelihood(self, output):
        return super().log_likelihood(output) + output.log_penalty


@pytest.mark.parametrize("bug", ["program order", "mis-weighted picks"])
def test_the_sosmc_check_catches_a_wrong_sosmc(bug, monkeypatch):
    # Both bugs pass the MIX check above (one future pending at a time: nothing to order,
    # and 1 / (number pending) = 1).
    smc_module = importlib.import_module("procmod.infer.smc")
    target = None
    if bug == "program order":  # a valid SMC, but not one that draws the order
        monkeypatch.setattr(smc_module, "random_order", program_order)
    else:
        particles_module = importlib.import_module("procmod.infer.particles")  # where particles step
        wrong = _Misweighted(particles_module)
        monkeypatch.setattr(particles_module, "step", wrong.stepping)
        monkeypatch.setattr(smc_module, "random_order", wrong.pick)
        target = _PenalisedTarget(ORDER_OBS, ORDER_S)
    # caught by a check of the result (Z, a first, a key's posterior), not by the power check
    with pytest.raises(AssertionError, match=r"^\(('Z'|'a first'|\()"):
        _check_sosmc_on_order(target)

def _chain_means(samples_per_chain, keys, key_of):
    means = []
    for samples in samples_per_chain:
        counts = {k: 0 for k in keys}
        for d in samples:
            counts[key_of(d)] += 1
        means.append([counts[k] / len(samples) for k in keys])
    return np.array(means)


def _run_chains(model, chains, sweeps, seed, **kwargs):
    """Independent chains' second halves, sampled every sweep (via many short runs)."""
    from procmod.infer.common import Scored, evaluate
    from procmod.infer.mcmc import log_acceptance, propose
    target = SumTarget(OBS, S)
    rng = np.random.default_rng(seed)
    per_chain = []
    for c in range(chains):
        state = Scored.from_evaluation(evaluate(model, target, ({}, int(rng.integers(2 ** 62)), None)))
        kept = []
        for sweep in range(sweeps):
            p = propose(state, rng, kwargs.get("p_diffusion", 0.5), kwargs.get("step_scale", 0.5))
            ev = evaluate(model, target, (p.choices, int(rng.integers(2 ** 62)), None))
            if math.log(rng.random() + 1e-300) < log_acceptance(state, p, ev, 1.0):
                state = Scored.from_evaluation(ev)
            if sweep >= sweeps // 2:
                kept.append(state.derivation)
        per_chain.append(kept)
    return per_chain


def test_mcmc_moves_leave_the_trans_dimensional_posterior_invariant():
    exact = count_exact(OBS, S)
    keys = sorted(exact)
    chains = _run_chains(COUNT, chains=40, sweeps=400, seed=5)
    means = _chain_means(chains, keys, lambda d: d.n_nodes)
    for j, n in enumerate(keys):
        se = means[:, j].std(ddof=1) / math.sqrt(len(means))
        assert abs(means[:, j].mean() - exact[n]) < 5 * se + 0.01, (n, means[:, j].mean(), exact[n], se)


def test_mcmc_engine_posterior_marginals_match_exact():
    _, exact = mix_exact(OBS, S)
    keys = sorted(exact)
    per_chain = []
    for seed in range(24):
        result = mcmc(MIX, SumTarget(OBS, S), chains=4, seed=seed, budget=Budget(generations=300),
                      tempering=True, annealing=None, step_scale=0.5)
        per_chain.append(result.samples[:1])  # the cold chain's final state
    states = [d for chain in per_chain for d in chain]
    counts = {k: 0 for k in keys}
    for d in states:
        cm = d.choice_map()
        counts[(cm[((), "k")], cm[((), "child")])] += 1
    n = len(states)
    for key, p in exact.items():
        se = math.sqrt(p * (1 - p) / n)
        assert abs(counts[key] / n - p) < 5 * se + 0.02, (key, counts[key] / n, p)


def test_mcmc_tempered_cold_chain_targets_posterior():
    exact = count_exact(OBS, S)
    finals = []
    for seed in range(60):
        result = mcmc(COUNT, SumTarget(OBS, S), chains=3, seed=seed, budget=Budget(generations=150),
                      tempering=True, annealing=None, step_scale=0.5)
        finals.append(result.samples[0].n_nodes)
    n = len(finals)
    for k, p in exact.items():
        freq = finals.count(k) / n
        assert abs(freq - p) < 5 * math.sqrt(p * (1 - p) / n) + 0.02, (k, freq, p)


def test_delayed_rejection_keeps_the_posterior():
    exact = count_exact(OBS, S)
    finals = []
    for seed in range(60):
        result = mcmc(COUNT, SumTarget(OBS, S), chains=1, seed=seed, budget=Budget(generations=150),
                      tempering=False, annealing=None, delayed_rejection=True, p_diffusion=0.3)
        finals.append(result.samples[0].n_nodes)
    n = len(finals)
    for k, p in exact.items():
        freq = finals.count(k) / n
        assert abs(freq - p) < 5 * math.sqrt(p * (1 - p) / n) + 0.02, (k, freq, p)


def _coin_then_stop(ctx):
    from toy_models import Value
    on = ctx.maybe("m", 0.5, _never)
    ctx.stop()
    ctx.emit(Value(1.0))
    on_too = ctx.sample("y", Bernoulli(0.5))  # SMC pauses the call before it, and re-runs it to resume
    if on:
        ctx.emit(Value(2.0))
    if on_too:
        ctx.emit(Value(1.0))


def _never(ctx):  # its spawn is cut by the stop
    from toy_models import Value
    ctx.emit(Value(100.0))


@pytest.mark.parametrize("engine", ["smc", "sosmc"])
def test_a_call_resumed_after_its_own_stop_replays_the_coins_it_made_before_it(engine):
    """SMC re-runs a paused call from its start; its ctx.stop() (before the emit it paused
    at) acted from the start of the re-run, so the maybe before it returned False without
    its coin: the rule took the other branch (P(c) 0 where it is 1/2), and the coin's
    log-probability stayed in log_prior with no coin in the choice map."""
    from procmod.core import Model
    from procmod.infer import ENGINES
    from toy_models import FlatTarget, SumOutput

    model = Model("coin-then-stop", "", _coin_then_stop, lambda p: (), lambda p: SumOutput(),
                  rules=(_coin_then_stop, _never))
    coins = []
    for seed in range(4):
        for d in ENGINES[engine](model, FlatTarget(), particles=400, seed=seed).samples:
            coin = d.choice_map()[((), "m")]
            assert (d.output.total >= 3) == coin
            assert d.log_prior == pytest.approx(sum(d.choice_log_probs().values()))
            coins.append(coin)
    # a flat likelihood: resampling keeps every particle once, so the coins are independent
    se = math.sqrt(0.25 / len(coins))
    assert abs(np.mean(coins) - 0.5) < 5 * se
