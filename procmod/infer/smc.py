"""``smc`` and ``sosmc``: sequential Monte Carlo over partial derivations.

Particles are partial derivations (cheap to copy: expanded nodes are shared). Each
generation, every unfinished particle is stepped to its next emit and reweighted by the
change of the target's log-likelihood; particles are then resampled (at every emit by
default, or when the effective sample size falls below a threshold). ``sosmc`` is the
same with a uniformly random pending future expanded at each step (stochastically-ordered
SMC, Ritchie et al. 2015; seed 002 section 7).

The log marginal-likelihood estimate is the product over resampling points of the mean
incremental weight, which is unbiased for the marginal likelihood ``Z`` (not its log).
"""

from __future__ import annotations

import math

import numpy as np

from ..core import InvalidArgumentError, Model, random_order, start, step
from ..core.protocols import Proposer, Target
# the resampler lives in core so that other particle methods (learn's search) share it
from ..core.random import RESAMPLING, BlockGenerator, normalised_weights, resample  # noqa: F401
from .common import Budget, Result, Tracker, check_population, check_positive, log_mean_exp, relaxed_gc

def effective_sample_size(log_weights: np.ndarray) -> float:
    """Kish's effective sample size of a set of log-weights."""
    w = normalised_weights(log_weights)
    return float(1.0 / np.sum(w * w))


def _run_once(model: Model, target: Target, particles, rng, pick, resampling, ess_threshold, tracker,
              proposer: Proposer | None = None):
    """One SMC run; returns (states, final log-weights, log Z estimate)."""
    states = [start(model, target.new_output(model)) for _ in range(particles)]
    for state in states:
        state.proposer = proposer
    # Plain lists in the per-particle loop: numpy scalar indexing would cost more than the step.
    log_lik = [0.0] * particles
    log_w = [0.0] * particles
    # Guided: each step also weighs by prior / proposal of the choices it made.
    log_ratio = [0.0] * particles if proposer is not None else None
    finished = [False] * particles
    log_z = 0.0
    log_likelihood = target.log_likelihood
    while True:
        active = stepped = 0
        for i, state in enumerate(states):
            if finished[i]:
                continue
            stepped += 1
            step(state, rng, pick)
            new = log_likelihood(state.output)
            log_w[i] += new - log_lik[i]
            log_lik[i] = new
            if log_ratio is not None:
                ratio = state.log_prior - state.log_proposal
                log_w[i] += ratio - log_ratio[i]
                log_ratio[i] = ratio
            if state.done:
                finished[i] = True
                tracker.offer(state, target.score(state.output))
            else:
                active += 1
        tracker.evaluations += stepped
        if active == 0:
            break
        weights = np.array(log_w)
        if weights.max() == -math.inf:
            return states, weights, -math.inf  # every particle has zero likelihood
        if ess_threshold is None or effective_sample_size(weights) < ess_threshold * particles:
            log_z += log_mean_exp(weights)
            ancestors = resample(weights, rng, resampling).tolist()
            taken = set()
            new_states = []
            for a in ancestors:
                # The first offspring of an ancestor takes it over; the rest are copies.
                if a in taken:
                    new_states.append(states[a].copy())
                else:
                    taken.add(a)
                    new_states.append(states[a])
            states = new_states
            log_lik = [log_lik[a] for a in ancestors]
            if log_ratio is not None:
                log_ratio = [log_ratio[a] for a in ancestors]
            finished = [finished[a] for a in ancestors]
            log_w = [0.0] * particles
        if tracker.due():
            tracker.record(float(np.mean([target.score(s.output) for s in states])))
    weights = np.array(log_w)
    return states, weights, log_z + log_mean_exp(weights)


def smc(model: Model, target: Target, particles: int = 600, seed: int = 0, budget: Budget | None = None,
        resampling: str = "systematic", ess_threshold: float | None = None,
        order: str = "program", progress=None, guide=None) -> "Result":
    """Sequential Monte Carlo, resampling at every emit.

    Parameters
    ----------
    particles : int
        Number of particles.
    budget : Budget, optional
        Without one, a single run. With one, independent runs are repeated until it is
        spent (each run completes; the budget is checked between runs), and the best
        derivation over all runs is returned; ``samples`` are the last run's particles.
    resampling : {"systematic", "multinomial", "residual"}
    ess_threshold : float, optional
        Resample only when the effective sample size drops below ``ess_threshold *
        particles`` (default: resample at every emit).
    order : {"program", "random"}
        Which pending future runs next; "random" is SOSMC.
    guide : procmod.guide.Guide, optional
        Neurally-guided SMC (seeds 003/004): each fresh choice is drawn from the guide's
        proposal and particles are weighted by prior / proposal x likelihood, so the
        estimate stays unbiased however poor the guide.

    Returns
    -------
    Result
        ``log_weights`` are the final particles' normalised-to-the-run log-weights;
        ``log_marginal_likelihood`` is the last run's estimate of log Z.
    """
    check_positive("particles", particles)
    if resampling not in RESAMPLING:
        raise InvalidArgumentError(f"resampling must be one of {', '.join(RESAMPLING)}, got {resampling!r}")
    if ess_threshold is not None and not 0 < ess_threshold <= 1:
        raise InvalidArgumentError(f"ess_threshold must be in (0, 1], got {ess_threshold!r}")
    if order not in ("program", "random"):
        raise InvalidArgumentError(f"order must be 'program' or 'random', got {order!r}")
    pick = None if order == "program" else random_order
    model = target.configure(model)
    check_population("particles", particles, target.new_output(model))  # refuse what memory cannot hold
    proposer = None
    if guide is not None:
        proposer = guide.proposer(model, target)
    rng = BlockGenerator(np.random.default_rng(seed))  # scalar draws from blocks: the hot loop
    tracker = Tracker(budget, progress)
    notes = []
    with relaxed_gc():
        while True:
            states, log_w, log_z = _run_once(model, target, particles, rng, pick, resampling,
                                             ess_threshold, tracker, proposer)
            tracker.generations += 1
            tracker.record(float(np.mean([target.score(s.output) for s in states])))
            if log_z == -math.inf:
                notes.append("every particle reached zero likelihood; the log marginal-likelihood is -inf")
            if budget is None or tracker.spent():
                break
    engine = ("smc" if order == "program" else "sosmc") + ("+guide" if guide is not None else "")
    return Result(engine, tracker.best, tracker.best_score, states, tracker.rows, tracker.seconds,
                  tracker.evaluations,
                  settings={"particles": particles, "seed": seed, "resampling": resampling,
                            "ess_threshold": ess_threshold, "order": order,
                            "budget": (budget or Budget()).describe(),
                            "guide": None if guide is None else guide.settings.name},
                  log_weights=list(log_w), log_marginal_likelihood=log_z, notes=notes)


def sosmc(model: Model, target: Target, particles: int = 600, seed: int = 0, budget: Budget | None = None,
          resampling: str = "systematic", ess_threshold: float | None = None, progress=None,
          guide=None) -> Result:
    """Stochastically-ordered SMC: :func:`smc` expanding a random pending future per step."""
    return smc(model, target, particles, seed, budget, resampling, ess_threshold, "random", progress, guide)
