"""GA fitness evaluation: incremental from the parent where the target allows it, full
replays otherwise.

Offspring evaluation is incremental when it runs in-process (no ``executor``) and the
target's score survives removing parts exactly (``target.exact_removal``: Volume,
Silhouette): every offspring differs from one parent in a few calls (grow, cut and alter
change one call and what hangs below it; a crossover child differs from its first parent
below the swapped connection), so it is built by :func:`procmod.core.runtime.replay_reusing`
from that parent: the parent's calls and drawn output (voxel or pixel counts) are reused,
the geometry of the replaced calls is removed and that of the new ones drawn. The result is
the derivation and score a full replay of the offspring's choice map gives (tested); only
the changed calls cost rule executions and voxelization. An offspring's random generator is
seeded only when a call draws a fresh value (grow, alter), not for cut, nudge or crossover
offspring (seeding costs about 10% of an incremental evaluation). Otherwise (an executor, or
a target such as ProxyVolume that reads the bounding box) fitness evaluations are full
replays through the ``executor``.
"""

from __future__ import annotations

import numpy as np

from ...core import InvalidArgumentError, Model
from ...core.protocols import Target, check_declared
from ...core.runtime import replay_reusing
from ..common import Evaluation, Scored, Tracker, evaluate_all, scored
from .genome import Genome, Offspring


class LazyRng:
    """``numpy.random.default_rng(seed)``, created on first use: most offspring (cut, nudge,
    crossover) replay without a fresh draw, and seeding a Generator costs more than
    replaying a few calls. Draws are those of the Generator itself."""

    def __init__(self, seed: int):
        self._seed = seed

    def __getattr__(self, name):  # only for names not bound yet
        if name.startswith("_"):
            raise AttributeError(name)
        rng = self.__dict__.get("_rng")
        if rng is None:  # first use: bind the common methods to this object
            rng = self._rng = np.random.default_rng(self._seed)
            for method in ("random", "standard_normal", "integers", "choice", "uniform", "normal"):
                setattr(self, method, getattr(rng, method))
        return getattr(rng, name)


def evaluate_from(model: Model, target: Target, parent, choices, seed: int, changed=None) -> Evaluation:
    """Score the offspring ``choices`` (a dict, or an operator's lazy Offspring) of
    ``parent`` (a complete derivation whose output supports exact removal, or its Genome)
    by :func:`replay_reusing` from a copy of the parent's output; ``changed``: the calls
    whose choices differ from the parent's (None: compare them all).

    Same derivation and score as ``common.evaluate(model, target, (choices, seed, False))``,
    the score up to rounding in the last bits (see :func:`replay_reusing`).
    """
    genome = parent if isinstance(parent, Genome) else Genome(parent)
    parent = genome.d
    result = replay_reusing(model, parent, choices, LazyRng(seed), parent.output.copy(),
                            maybe_default=False, changed=changed, unused=False, index=genome.index())
    d = result.derivation
    return Evaluation(d, *scored(target, d.output), result.log_reused, result.log_fresh, result.unused)


def reusable(parent) -> bool:
    """Whether an offspring can be evaluated from the derivation ``parent`` incrementally:
    it is complete and its output can take parts away exactly (``supports_removal``, and
    no count has saturated)."""
    output = parent.output
    return parent.done and not parent.stopped and output.supports_removal and not output.saturated


class Evaluator:
    """Scores batches of jobs ``(choices, seed, maybe_default)`` for the GA and tells the
    tracker: ``choices`` is a plain choice map (replayed in full, through ``executor``) or
    an :class:`Offspring`, evaluated from its parent when :attr:`incremental` and the
    parent allows it (:func:`reusable`; ``maybe_default`` False), else materialized and
    replayed in full."""

    def __init__(self, model: Model, target: Target, executor, tracker: Tracker):
        check_declared(target, Target, "the target")
        self.model, self.target, self.executor, self.tracker = model, target, executor, tracker
        self.incremental = executor is None and bool(target.exact_removal)

    def __call__(self, jobs: list, until_out_of_time: bool = False, at_least: int = 0) -> list:
        """The jobs' :class:`Scored` individuals, in order.

        ``until_out_of_time``: stop evaluating once the budget's time is up or a stop was
        requested (:meth:`Tracker.out_of_time`, checked between evaluations, which also keep
        the progress callback called), after ``at_least`` evaluations; the jobs not
        evaluated are ``None`` in the list.
        """
        model, target, tracker = self.model, self.target, self.tracker
        for job in jobs:
            if not (isinstance(job, (tuple, list)) and len(job) == 3):
                raise InvalidArgumentError(f"the Evaluator takes a list of jobs (choices, seed, maybe_default): "
                                           f"choices a choice map (a derivation d's d.choice_map(), {{}} to sample "
                                           f"afresh) or an Offspring, seed an int, maybe_default False; got "
                                           f"{type(job).__name__} {job!r:.40}")
        evaluations = [None] * len(jobs)
        first = tracker.evaluations  # _scored counts each evaluation there

        def stopping() -> bool:
            if not until_out_of_time or tracker.evaluations - first < at_least:
                return False
            tracker.due()  # calls the progress callback (a Stop button is read there)
            return tracker.out_of_time()

        if self.incremental:
            for i, (choices, seed, maybe_default) in enumerate(jobs):
                if isinstance(choices, Offspring) and maybe_default is False and reusable(choices.base.d):
                    if stopping():
                        break
                    evaluations[i] = self._scored(evaluate_from(model, target, choices.base, choices, seed,
                                                                choices.changed))
        rest = [i for i, ev in enumerate(evaluations) if ev is None]
        full_jobs = [(_materialize(jobs[i][0]),) + tuple(jobs[i][1:]) for i in rest]
        if not (rest and stopping()):
            results = evaluate_all(self.executor, model, target, full_jobs, lazy=until_out_of_time)
            for i, ev in zip(rest, results):
                evaluations[i] = self._scored(ev)
                if stopping():
                    results.close()  # a pool's jobs not yet started are cancelled
                    break
        return evaluations

    def _scored(self, evaluation) -> Scored:
        ind = Scored.from_evaluation(evaluation)
        self.tracker.evaluations += 1
        self.tracker.offer(ind.derivation, ind.score, ind.log_likelihood)
        return ind


def _materialize(choices) -> dict:
    return choices.materialize() if isinstance(choices, Offspring) else choices
