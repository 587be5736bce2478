"""``forward``: importance sampling from the prior, the baseline every engine must beat."""

from __future__ import annotations

import numpy as np

from ..core import Model
from ..core.limits import relaxed_gc
from ..core.protocols import Target
from .common import (Budget, Result, Tracker, check_population, check_positive, check_run, configured_model,
                     evaluate_all, log_mean_exp, new_seed, recorded_seed)


def forward(model: Model, target: Target, particles: int = 100, seed: int = 0, budget: Budget | None = None,
            executor=None, progress=None) -> Result:
    """Draw derivations from the prior and weight them by the target's likelihood.

    Without a budget, one batch of ``particles`` samples is drawn; with one, batches are
    drawn until it is spent. ``samples`` are the last batch with their ``log_weights``
    (the log-likelihoods); ``log_marginal_likelihood`` is the usual importance-sampling
    estimate over every sample drawn. Samples are evaluated through ``executor``.
    """
    particles = check_positive("particles", particles)  # a plain int: numpy's too, for settings.json
    check_run(model, target, seed, budget)
    model = configured_model(target, model)
    check_population("particles", particles, target.new_output(model))  # refuse what memory cannot hold
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    all_log_weights = []
    batch = []
    with relaxed_gc():
        while True:
            batch = evaluate_all(executor, model, target, [({}, new_seed(rng), None) for _ in range(particles)])
            tracker.evaluations += len(batch)
            tracker.generations += 1
            for ev in batch:
                tracker.offer(ev.derivation, ev.score, ev.log_likelihood)
                all_log_weights.append(ev.log_likelihood)
            tracker.record(float(np.mean([ev.score for ev in batch])))
            if budget is None or tracker.spent():
                break
    return Result("forward", tracker.best, tracker.best_score, [ev.derivation for ev in batch],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={"particles": particles, "seed": recorded_seed(seed),
                            "budget": budget.describe() if budget is not None else "one batch"},
                  log_weights=[ev.log_likelihood for ev in batch],
                  log_marginal_likelihood=log_mean_exp(all_log_weights), notes=tracker.notes())
