"""``smc`` and ``sosmc``: sequential Monte Carlo over partial derivations.

Particles are partial derivations (cheap to copy: expanded nodes are shared). Each
generation, every unfinished particle is stepped to its next emit and reweighted by the
change of the target's log-likelihood; particles are then resampled (at every emit by
default, or when the effective sample size falls below a threshold, the default of
guided runs). ``sosmc`` is the
same with a uniformly random pending future expanded at each step (stochastically-ordered
SMC, Ritchie et al. 2015; seed 002 section 7).

The log marginal-likelihood estimate is the product over resampling points of the mean
incremental weight, which is unbiased for the marginal likelihood ``Z`` (not its log).
"""

from __future__ import annotations

import math
import numbers
import os
import time
from array import array

import numpy as np

from ..core import InvalidArgumentError, Model, random_order
from ..core.errors import shown_value, whole_number
from ..core.limits import relaxed_gc
from ..core.protocols import Target
from ..core.runtime import graft_history, history, unpack_particle
# the resampler lives in core so that other particle methods (learn's search) share it
from ..core.random import RESAMPLING, BlockGenerator, normalised_weights, resample, systematic_small  # noqa: F401
from .common import (ZERO_LIKELIHOOD_NOTE, Budget, Result, Tracker, check_population, check_positive, check_run,
                     checked_value, configured_model, log_mean_exp, mean_of, recorded_seed)
from .particles import ParticleShard, WorkerShard, fork_available, plan_offspring, shared_objects, split_evenly

# Automatic worker count (``workers=None``): one more process per this many particles, up
# to the cores this process may use, so that a shard has enough steps per generation to
# outweigh its messages. A guess, not a measured crossover: on the 2-vCPU machine
# bench/smc_workers.py was measured on, two workers gained nothing at 600 particles.
PARTICLES_PER_WORKER = 100


def worker_count(workers: int | None, particles: int) -> int:
    """The processes an SMC run of ``particles`` uses for ``workers`` (None: automatic)."""
    from ..parallel import check_worker_limit, default_workers

    if workers is None:
        workers = min(default_workers(), max(1, particles // PARTICLES_PER_WORKER))
    elif whole_number(workers) is None or workers < 1:
        raise InvalidArgumentError(f"workers must be a positive integer or None (automatic), got "
                                   f"{shown_value(workers)}")
    workers = int(workers)
    check_worker_limit(workers)
    if workers > 1 and not fork_available():
        return 1  # worker shards are forked; elsewhere the run stays in this process
    return max(1, min(workers, particles))


def effective_sample_size(log_weights: np.ndarray) -> float:
    """Kish's effective sample size of a set of log-weights."""
    w = normalised_weights(log_weights)
    return float(1.0 / np.sum(w * w))


# Guided runs resample when the effective sample size falls below this fraction of the
# particles (``ess_threshold="auto"``); unguided runs resample at every emit, as the papers
# do. A guide's proposals keep the weights even for several emits, and resampling then only
# throws away distinct particles. Measured by bench/guided_resampling.py on development
# sets that are not the bench's (README, "Neural guides": mean best similarity up by about
# 0.03-0.05 at 10 and 20 particles, even at 5, 5-15% more CPU; 0.2 lost at 5 particles).
# For unguided runs the same change was mixed (docs/vines_smc.md): they keep the papers' rule.
GUIDED_ESS_THRESHOLD = 0.5


def resolve_ess_threshold(ess_threshold, guided: bool) -> float | None:
    """The ESS fraction below which a run resamples (None: at every emit), checked;
    ``"auto"`` is :data:`GUIDED_ESS_THRESHOLD` for guided runs and every emit otherwise."""
    if isinstance(ess_threshold, str) and ess_threshold == "auto":
        return GUIDED_ESS_THRESHOLD if guided else None
    if ess_threshold is None:
        return None
    if isinstance(ess_threshold, bool) or not isinstance(ess_threshold, numbers.Real) \
            or not 0 < ess_threshold <= 1:
        raise InvalidArgumentError(f"ess_threshold must be in (0, 1], None (resample at every emit) or 'auto', "
                                   f"got {ess_threshold!r}")
    return float(ess_threshold)


# Up to this many particles a step's weight arithmetic runs on Python floats: numpy's
# per-call overhead (about 20 us a step over the 6-8 calls) outweighs the arithmetic
# there, and a guided run of 1-20 particles takes a step per particle-emit.
SMALL_POPULATION = 32


# the note of a run abandoned at its deadline (smc's ``deadline``)
DEADLINE_NOTE = ("a run was stopped at its deadline before its particles were complete: the best is the best complete "
                 "derivation found before it, if any")


class _RemoteBest:
    """Stands in the tracker for a best derivation a worker shard holds (fetched at the end
    of the run)."""

    __slots__ = ("shard",)

    def __init__(self, shard):
        self.shard = shard


def unchangeable_by_resampling(particles: int, ess_threshold: float | None) -> bool:
    """Whether no resampling can change a population of ``particles``: one particle (its
    only offspring is itself), or an ESS threshold it cannot fall below (an effective
    sample size is at least 1: two particles at the guided default of 0.5). Its
    particles are then independent weighted samples, and :func:`_run_once` runs each to
    its end in one go rather than emit by emit: a call paused at an emit re-runs from its
    start (``procmod.core.runtime.step``), which with the engine's per-emit bookkeeping
    had cost ~40% of a guided 1-particle run (same derivations; README, "Neural guides")."""
    return particles == 1 or (ess_threshold is not None and ess_threshold * particles <= 1.0)


def _run_once(local: ParticleShard, workers: list, particles: int, rng, resampling, ess_threshold,
              tracker, deadline: float | None = None) -> tuple:
    """One SMC run over the shards; returns (states, final log-weights, log Z estimate),
    the estimate None for a run abandoned at ``deadline`` (see :func:`smc`)."""
    sizes = split_evenly(particles, 1 + len(workers))
    for worker, size in zip(workers, sizes[1:]):
        worker.send("reset", size)
    local.reset(sizes[0])
    if not workers and deadline is None and unchangeable_by_resampling(particles, ess_threshold):
        counted = tracker.evaluations
        target = local.target

        def looked_at(state):  # after each emit: history rows (of the particle running) and progress
            tracker.evaluations += 1
            if tracker.due():
                tracker.record(checked_value(target.score(state.output), target, "score"))

        tracker.evaluations = counted + local.run_through(looked_at)
        if tracker.due():
            tracker.record(local.score_mean()[0])
        log_w = local.log_w
        return _collect(local, workers, tracker), np.array(log_w), log_mean_exp(log_w)
    log_z = 0.0
    while True:
        for worker in workers:  # workers step while this process steps its own shard
            worker.send("step")
        log_w, finished, stepped, active = local.step()
        if workers:
            log_w, finished = list(log_w), list(finished)
            for worker in workers:
                w_log_w, w_finished, w_stepped, w_active, w_best = worker.receive()
                log_w += w_log_w
                finished += map(bool, w_finished)
                stepped += w_stepped
                active += w_active
                score, allowed = w_best
                log_likelihood = 0.0 if allowed else -math.inf
                if tracker.better(score, log_likelihood):
                    tracker.offer(_RemoteBest(worker), score, log_likelihood)
        tracker.evaluations += stepped
        if active == 0:
            break
        if deadline is not None and time.perf_counter() >= deadline:
            return _collect(local, workers, tracker), np.array(log_w), None
        ancestors = None
        if particles <= SMALL_POPULATION and resampling == "systematic":  # Python floats (above)
            top = max(log_w)
            if top == -math.inf:  # every particle has zero likelihood
                return _collect(local, workers, tracker), np.array(log_w), -math.inf
            relative = [math.exp(v - top) for v in log_w]
            total = sum(relative)
            if ess_threshold is None or total * total / sum(w * w for w in relative) < ess_threshold * particles:
                log_z += top + math.log(total / particles)
                ancestors = systematic_small(relative, total, rng)
        else:
            weights = np.array(log_w)
            if weights.max() == -math.inf:
                return _collect(local, workers, tracker), weights, -math.inf  # every particle has zero likelihood
            if ess_threshold is None or effective_sample_size(weights) < ess_threshold * particles:
                log_z += log_mean_exp(weights)
                ancestors = resample(weights, rng, resampling).tolist()
        if ancestors is not None:
            if workers:
                sizes = _regroup(local, workers, ancestors, sizes, finished)
            else:
                local.regroup(ancestors, ())
        if tracker.due():
            parts = [local.score_mean()] + [worker.call("scores") for worker in workers]
            # the shards' means weighted by their share: no sum of scores overflows
            tracker.record(math.fsum(mean * (count / particles) for mean, count in parts if count))
    # log_w is a list: log_mean_exp sums a short one in Python floats
    return _collect(local, workers, tracker), np.array(log_w), log_z + log_mean_exp(log_w)


def _regroup(local: ParticleShard, workers: list, ancestors: list, sizes: list, finished: list) -> list:
    """Regroup every shard after a resampling, moving the offspring that balance the
    shards' active particles; returns the shards' new sizes."""
    shards = [local] + workers
    keep, sends = plan_offspring(ancestors, sizes, finished)
    incoming = [[] for _ in shards]
    for s, shard_sends in enumerate(sends):
        if shard_sends:
            indices = [a for a, _, _ in shard_sends]
            packed = local.export(indices) if s == 0 else shards[s].call("export", indices)
            for (_, destination, count), (particle, lik, ratio) in zip(shard_sends, packed):
                incoming[destination].append((count, particle, lik, ratio))
    for w, worker in enumerate(workers, 1):  # answered by nothing: the pipe keeps the order
        worker.send("regroup", array("l", keep[w]), incoming[w])
    local.regroup(keep[0], incoming[0])
    return [len(k) + sum(count for count, *_ in inc) for k, inc in zip(keep, incoming)]


def _collect(local: ParticleShard, workers: list, tracker) -> list:
    """Every shard's particles, whole (histories grafted back), in shard order (the order
    of the run's log-weights); also fetches the tracker's best when a worker holds it."""
    states = list(local.states)
    if not workers:
        return states
    model = local.model
    for worker in workers:
        states += [unpack_particle(model, p) for p in worker.call("collect")]
    if isinstance(tracker.best, _RemoteBest):
        packed, _ = tracker.best.shard.call("best")
        tracker.best = unpack_particle(model, packed)
    _graft(states + [tracker.best], local, workers)
    return states


def _graft(states: list, local: ParticleShard, workers: list) -> None:
    """Put the histories that moved particles left in other shards back into ``states``."""
    cache = {}

    def unresolved(tails):
        return {(t.owner, t.key) for t in tails if t is not None and (t.owner, t.key) not in cache}

    todo = unresolved(history(s)[1] for s in states if s is not None)
    while todo:
        by_owner = {}
        for owner, key in sorted(todo):
            by_owner.setdefault(owner, []).append(key)
        fetched = []
        for owner, keys in by_owner.items():
            got = local.histories(keys) if owner == 0 else workers[owner - 1].call("histories", keys)
            for key, entry in zip(keys, got):
                cache[(owner, key)] = entry
                fetched.append(entry[1])
        todo = unresolved(fetched)
    for state in states:
        if state is not None:
            graft_history(state, lambda ref: cache[(ref.owner, ref.key)])


def smc(model: Model, target: Target, particles: int = 600, seed: int = 0, budget: Budget | None = None,
        resampling: str = "systematic", ess_threshold: float | str | None = "auto",
        order: str = "program", progress=None, guide=None, workers: int | None = 1, *,
        deadline: float | None = None) -> "Result":
    """Sequential Monte Carlo, resampling at every emit (guided: when the ESS falls below half).

    Parameters
    ----------
    particles : int
        Number of particles.
    budget : Budget, optional
        Without one, a single run. With one, independent runs are repeated until it is
        spent (each run completes; the budget is checked between runs), and the best
        derivation over all runs is returned; ``samples`` are the particles of the last
        run that had any the target allows (of the last run where none had).
    resampling : {"systematic", "multinomial", "residual"}
    ess_threshold : float, None or "auto"
        Resample only when the effective sample size drops below ``ess_threshold *
        particles``; None resamples at every emit. The default, ``"auto"``, resamples at
        every emit without a guide (as the papers do) and below
        :data:`GUIDED_ESS_THRESHOLD` with one.
    order : {"program", "random"}
        Which pending future runs next; "random" is SOSMC.
    guide : procmod.guide.Guide, its name or path, or a Proposer, optional
        Neurally-guided SMC (seeds 003/004): each fresh choice is drawn from the guide's
        proposal and particles are weighted by prior / proposal x likelihood, so the
        estimate stays unbiased however poor the guide. A proposer of one's own
        (:class:`procmod.core.protocols.Proposer`: ``propose(ctx, name, dist, rng) ->
        (value, log q)``) is used as it is.
    workers : int or None
        Processes that step the particles (default 1: this one). With ``W > 1`` the
        population is split into ``W`` shards stepped in parallel by forked worker
        processes and resampled as one population (:mod:`procmod.infer.particles`);
        ``None`` picks one per :data:`PARTICLES_PER_WORKER` particles, up to the cores
        available. A seeded run is reproducible for a given ``workers``; different
        worker counts draw different random numbers.
    deadline : float, optional
        A ``time.perf_counter()`` value at which a run still in progress is abandoned
        (unlike ``budget``, which each run completes): the result keeps the complete
        derivations found before it (``best`` may be None), its samples are the last
        complete run's particles or, where none completed, the abandoned run's, complete
        or not, and a note says so. MCMC's start
        (:func:`procmod.infer.mcmc.mcmc`'s ``init_particles``) runs under its own time
        budget so: on a slow target the start had run past the whole budget (h149).

    Returns
    -------
    Result
        ``log_weights`` are the final particles' normalised-to-the-run log-weights;
        ``log_marginal_likelihood`` is the estimate of log Z of all the runs together (the
        log of the mean of their estimates of Z, each unbiased, so their mean is too).
    """
    particles = check_positive("particles", particles)  # a plain int: numpy's too, for settings.json
    if deadline is not None and (isinstance(deadline, bool) or not isinstance(deadline, numbers.Real)
                                 or deadline != deadline):
        raise InvalidArgumentError(f"deadline must be a time.perf_counter() value or None, got {deadline!r}")
    if resampling not in RESAMPLING:
        raise InvalidArgumentError(f"resampling must be one of {', '.join(RESAMPLING)}, got {resampling!r}")
    ess_threshold = resolve_ess_threshold(ess_threshold, guide is not None)
    if order not in ("program", "random"):
        raise InvalidArgumentError(f"order must be 'program' or 'random', got {order!r}")
    pick = None if order == "program" else random_order
    check_run(model, target, seed, budget)
    model = configured_model(target, model)
    template = target.new_output(model)  # every particle starts from a copy of it
    # under a budget a finished run's particles are kept while the next runs (see below)
    check_population("particles", particles, template, copies=1 if budget is None else 2)
    proposer = None
    if isinstance(guide, (str, os.PathLike)):  # a guide's name or path, as the command line takes it
        from ..guide import Guide
        guide = Guide.load(guide)
    if guide is not None:
        if callable(getattr(guide, "proposer", None)):  # a Guide: its proposer for this model and target
            guide.check_model(model)
            proposer = guide.proposer(model, target)
        elif callable(getattr(guide, "propose", None)) and not isinstance(guide, type):  # a Proposer of one's own
            proposer = guide
        else:
            what = f"the class {guide.__name__} (give an instance of it)" if isinstance(guide, type) else \
                type(guide).__name__
            raise InvalidArgumentError(f"guide must be a procmod Guide, its name or its path, or a Proposer (an object "
                                       f"with propose(ctx, name, dist, rng) -> (value, log q)), got {what}")
    notes = []
    if guide is not None and proposer is not guide:
        # set-up, before the clock starts: the note's check imports the trace job's module
        # (~7 ms in a fresh process, more than a guided 1-particle run's inference)
        from ..guide.guide import fit_note
        misfit = fit_note(guide, template, target, model)
        if misfit is not None:
            notes.append(misfit)
    n_workers = worker_count(workers, particles)
    rng = BlockGenerator(np.random.default_rng(seed))  # scalar draws from blocks: the hot loop
    tracker = Tracker(budget, progress)  # the engine's clock starts here
    local = ParticleShard(0, model, target, template, rng, pick, proposer, tracker.offer)
    remote = []
    with relaxed_gc():
        try:
            if n_workers > 1:
                shared = shared_objects(model, target, template, proposer)
                for w in range(1, n_workers):
                    shard_rng = BlockGenerator(np.random.default_rng([seed, w]))
                    remote.append(WorkerShard(ParticleShard(w, model, target, template, shard_rng, pick,
                                                            proposer, None), shared))
            runs = 0
            log_z_sum = -math.inf  # of the runs' estimates of Z
            kept = None  # (states, log-weights, log Z) of the run whose particles are returned
            stopped = False  # whether a run was abandoned at the deadline
            while True:
                states, log_w, log_z = _run_once(local, remote, particles, rng, resampling, ess_threshold,
                                                 tracker, deadline)
                if log_z is None:
                    stopped = True
                    kept = kept or (states, log_w, -math.inf)
                    break
                runs += 1
                log_z_sum = float(np.logaddexp(log_z_sum, log_z))
                # the last run with a particle the target allows: a run that died after an
                # earlier one lived had made the whole result's samples a dead run's
                if kept is None or log_z > -math.inf or kept[2] == -math.inf:
                    kept = (states, log_w, log_z)
                tracker.generations += 1
                scores = [checked_value(target.score(s.output), target, "score") for s in states]
                tracker.record(mean_of(scores))
                if budget is None or tracker.spent():
                    break
        finally:
            for worker in remote:
                worker.close()
    # the run ends here: the notes below (global generators' states compared, ~0.08 ms)
    # are the tracker's bookkeeping, not inference (a guided 1-particle run takes ~1.5 ms)
    seconds = tracker.seconds
    states, log_w, _ = kept
    # each run's estimate of Z is unbiased, and so is their mean: the runs' estimates pooled
    log_z = log_z_sum - math.log(runs) if runs else -math.inf
    if stopped:
        notes.append(DEADLINE_NOTE)
    elif log_z == -math.inf:  # every run's every particle; once, not once a run
        notes.append(ZERO_LIKELIHOOD_NOTE)
    for note_of in ("unmatched_note", "relabelled_note"):  # a GuidedProposer's notes on the run's choices
        said = getattr(proposer, note_of, lambda: None)() if proposer is not None else None
        if said is not None:
            notes.append(said)
    notes += tracker.notes()
    engine = ("smc" if order == "program" else "sosmc") + ("+guide" if guide is not None else "")
    return Result(engine, tracker.best, tracker.best_score, states, tracker.rows, seconds,
                  tracker.evaluations,
                  settings={"particles": particles, "seed": recorded_seed(seed), "resampling": resampling,
                            "ess_threshold": ess_threshold, "order": order,
                            "budget": budget.describe() if budget is not None else "one run",
                            "guide": None if guide is None else getattr(guide, "source", None) or (
                                "(in memory)" if proposer is not guide else type(guide).__name__),
                            "guide_features": None if guide is None or proposer is guide else guide.settings.name,
                            "workers": n_workers},
                  log_weights=list(log_w), log_marginal_likelihood=log_z, notes=notes)


def sosmc(model: Model, target: Target, particles: int = 600, seed: int = 0, budget: Budget | None = None,
          resampling: str = "systematic", ess_threshold: float | str | None = "auto", progress=None,
          guide=None, workers: int | None = 1) -> Result:
    """Stochastically-ordered SMC: :func:`smc` expanding a random pending future per step."""
    return smc(model, target, particles, seed, budget, resampling, ess_threshold, "random", progress, guide,
               workers)
