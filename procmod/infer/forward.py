"""``forward``: importance sampling from the prior, the baseline every engine must beat."""

from __future__ import annotations

import numpy as np

from ..core import Model
from ..core.limits import relaxed_gc
from ..core.protocols import Target
from .common import (Budget, Result, Tracker, check_population, check_positive, check_run, configured_model,
                     evaluate_all, log_mean_exp, mean_of, new_seed, recorded_seed)


def forward(model: Model, target: Target, particles: int = 100, seed: int = 0, budget: Budget | None = None,
            executor=None, progress=None) -> Result:
    """Draw derivations from the prior and weight them by the target's likelihood.

    Without a budget, one batch of ``particles`` samples is drawn; with one, batches are
    drawn until it is spent, the last cut where the budget's seconds or evaluations end.
    ``samples`` are the last batch with their ``log_weights`` (the log-likelihoods);
    ``log_marginal_likelihood`` is the usual importance-sampling estimate over every
    sample drawn. Samples are evaluated through ``executor``.
    """
    particles = check_positive("particles", particles)  # a plain int: numpy's too, for settings.json
    check_run(model, target, seed, budget)
    model = configured_model(target, model)
    check_population("particles", particles, target.new_output(model),  # refuse what memory cannot hold
                     another=target.new_output(model))
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    all_log_weights = []
    batch = []
    with relaxed_gc():
        while True:
            jobs = [({}, new_seed(rng), None) for _ in range(particles)]  # seeds drawn first: a cut batch's are its own
            evaluations = evaluate_all(executor, model, target, jobs, lazy=budget is not None)
            batch = []
            for ev in evaluations:
                batch.append(ev)
                tracker.evaluations += 1
                tracker.offer(ev.derivation, ev.score, ev.log_likelihood)
                all_log_weights.append(ev.log_likelihood)
                # under a budget a batch ends where the budget's time or evaluations do (a batch
                # of 3,000 slow evaluations had run 3.6 s of a 0.3 s budget, h149)
                if budget is not None and (tracker.out_of_time() or (
                        budget.evaluations is not None and tracker.evaluations >= budget.evaluations)):
                    break
            if budget is not None:
                evaluations.close()  # the rest of the batch unevaluated
            tracker.generations += 1
            tracker.record(mean_of([ev.score for ev in batch]))
            if budget is None or tracker.spent():
                break
    return Result("forward", tracker.best, tracker.best_score, [ev.derivation for ev in batch],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={"particles": particles, "seed": recorded_seed(seed),
                            "budget": budget.describe() if budget is not None else "one batch"},
                  log_weights=[ev.log_likelihood for ev in batch],
                  log_marginal_likelihood=log_mean_exp(all_log_weights), notes=tracker.notes())
