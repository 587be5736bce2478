"""``ga()``: the generational loop that composes selection, variation and evaluation."""

from __future__ import annotations

import math

import numpy as np

from ...core import InvalidArgumentError, Model
from ...core.errors import argument, shown_value, whole_number
from ...core.protocols import Target
from ...core.runtime import check_rng
from ...core.limits import relaxed_gc
from ...core.errors import check_real
from ..common import (Budget, Result, Scored, Tracker, best_first, check_population, check_positive, check_run,
                      configured_model, mean_of, new_seed, recorded_seed)
from .evaluation import Evaluator
from .genome import Genome, Genomes
from .selection import elite_count, roulette, roulette_wheel, tournament
from .variation import COPIES, check_split, crossover, grow, mutate


def ga(model: Model, target: Target, population: int = 200, seed: int = 0, budget: Budget | None = None,
       mutation: float = 0.3, split=(13.5, 13.5, 3.0), elitism: float = 0.2, tournament: int = 10,
       initial_size: int | None = None, max_retries: int = 10, nudge_step: float = 0.1,
       executor=None, progress=None) -> Result:
    """Genetic algorithm over derivation trees (seed 002, sections 4-6).

    Parameters
    ----------
    population : int
        Individuals per generation.
    budget : Budget
        Default: 50 generations.
    mutation : float
        Probability that a selected pair is mutated instead of crossed over.
    split : (grow, cut, alter[, nudge])
        Relative weights of the mutation operators (seed 002: 13.5 / 13.5 / 3.0, no nudge).
    elitism : float
        Fraction of the best individuals copied unchanged into the next generation.
    tournament : int
        k of the k-tournament selection.
    initial_size : int, optional
        Initial individuals are grown to sizes uniform in [1, initial_size] calls
        (default: twice the mean size of 20 forward samples, at least 5).
    max_retries : int
        Connections of the first parent a crossover tries before giving up.
    nudge_step : float
        Nudge step as a fraction of each choice distribution's scale.
    executor : concurrent.futures.Executor, optional
        Evaluates offspring (default: in-process, incrementally where the target allows).
    """
    population = check_positive("population", population)  # a plain int: numpy's too, for settings.json
    tournament = check_positive("tournament", tournament)
    max_retries = check_positive("max_retries", max_retries)
    mutation = check_real("mutation", mutation, "in [0, 1]", lambda v: 0.0 <= v <= 1.0)
    split = check_split(split)
    nudge_step = check_real("nudge_step", nudge_step, "a positive finite number (a fraction of each choice's "
                            "scale)", lambda v: 0.0 < v < math.inf)
    elitism = check_real("elitism", elitism, "in [0, 1)", lambda v: 0.0 <= v < 1.0)
    if elite_count(elitism, population) >= population:
        # (population 1 with any elitism: its one individual was kept every generation, no
        # offspring was ever made, and a budget in evaluations was never reached)
        raise InvalidArgumentError(f"{argument('population')} {population} with elitism {elitism:g} keeps every "
                                   f"individual as an elite ({elite_count(elitism, population)}), so no offspring are "
                                   f"ever made; give a larger {argument('population')} (2 or more"
                                   + (", or a smaller elitism)" if argument("population") == "population" else ")"))
    budget = budget or Budget(generations=50)
    check_run(model, target, seed, budget)
    model = configured_model(target, model)
    check_population("population", population, target.new_output(model),  # refuse what memory cannot hold
                     another=target.new_output(model))
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    evaluate = Evaluator(model, target, executor, tracker)
    genomes = Genomes()

    with relaxed_gc():
        if initial_size is None:
            initial_size = default_initial_size(evaluate, rng)
        initial_size = check_positive("initial_size", initial_size)
        pop = initial_population(evaluate, population, initial_size, rng, tracker)
        n_elite = elite_count(elitism, population)
        while not tracker.spent():
            pop.sort(key=_rank, reverse=True)
            kept, jobs = breed(pop, genomes, rng, n_elite=n_elite, k=tournament, mutation=mutation, split=split,
                               nudge_step=nudge_step, max_retries=max_retries)
            offspring = [ind for ind in evaluate(jobs, until_out_of_time=True) if ind is not None]
            # a generation cut short by the clock or a stop is topped up from the last one
            if len(kept) + len(offspring) < population:
                kept_ids = {id(ind) for ind in kept}
                offspring += [ind for ind in pop if id(ind) not in kept_ids]
            pop = (kept + offspring)[:population]
            genomes.keep(ind.derivation for ind in pop)
            tracker.generations += 1
            _record(tracker, pop)
    pop.sort(key=_rank, reverse=True)
    return Result("ga", tracker.best, tracker.best_score, [ind.derivation for ind in pop],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={"population": population, "seed": recorded_seed(seed), "budget": budget.describe(),
                            "mutation": mutation, "split": list(split), "elitism": elitism,
                            "tournament": tournament, "initial_size": initial_size, "nudge_step": nudge_step,
                            "incremental": evaluate.incremental},
                  log_weights=[ind.log_likelihood for ind in pop], notes=tracker.notes())


MAX_GROW_ROUNDS = 64  # replays that grow the initial population (see initial_population)


def default_initial_size(evaluate: Evaluator, rng) -> int:
    """Twice the mean size (in calls) of 20 forward samples, at least 5."""
    sizes = [ind.derivation.n_nodes for ind in evaluate([({}, new_seed(rng), None) for _ in range(20)])]
    return max(5, int(round(2 * np.mean(sizes))))


def initial_population(evaluate: Evaluator, population: int, initial_size: int, rng, tracker: Tracker) -> list:
    """Minimal derivations (every ``maybe`` off) grown to sizes uniform in [1, initial_size]
    calls (seed 002, section 6). Each round applies as many of an individual's missing
    grows as it has unexpressed children (children created in a round become candidates in
    the next), so a large individual costs a few replays instead of one per call.

    A chain (each call's one child a ``maybe`` of the last) has one unexpressed child a
    round, so it grew by one call a replay: quadratic in its length (a chain model of ~500
    calls took over a minute before its first generation). Growth stops after
    :data:`MAX_GROW_ROUNDS` rounds, leaving such individuals shorter than their goal (the
    generations' mutations, drawn from the prior, make them longer); the built-in models
    reach their goals in at most 8 rounds."""
    for name, value in (("population", population), ("initial_size", initial_size)):
        if whole_number(value) is None or value < 1:
            raise InvalidArgumentError(f"initial_population takes a {name} of one or more, got {shown_value(value)}")
    check_rng(rng, "initial_population")
    # fewer only when the time ran out or a stop came; one at least, so that a run has a population
    pop = [ind for ind in evaluate([({}, new_seed(rng), False) for _ in range(population)], until_out_of_time=True,
                                   at_least=1) if ind is not None]
    goals = rng.integers(1, initial_size + 1, size=population)
    growing = [i for i in range(len(pop)) if pop[i].derivation.n_nodes < goals[i]]
    rounds = 0
    while growing and not tracker.spent() and rounds < MAX_GROW_ROUNDS:
        rounds += 1
        jobs, owners = [], []
        for i in growing:
            missing = int(goals[i] - pop[i].derivation.n_nodes)
            child = grow(Genome(pop[i].derivation), rng, max(1, missing))
            if child is not None:
                jobs.append((child, new_seed(rng), False))
                owners.append(i)
        for i, ind in zip(owners, evaluate(jobs, until_out_of_time=True)):
            if ind is not None:
                pop[i] = ind
        growing = [i for i in owners if pop[i].derivation.n_nodes < goals[i]]
        if tracker.due():
            _record(tracker, pop)
    _record(tracker, pop)
    return pop


def breed(pop: list, genomes: Genomes, rng, *, n_elite: int, k: int, mutation: float, split, nudge_step: float,
          max_retries: int) -> tuple[list, list]:
    """Selection and variation for the next generation of ``pop`` (ranked best first):
    ``(kept, jobs)``, the individuals that pass unchanged (the elite, then parents that a
    mutation or crossover left as they were) and the offspring to evaluate, as jobs
    ``(Offspring, seed, False)``; together they are at least as many as ``pop``.

    Each pair of parents is one roulette pick and one k-tournament pick; with probability
    ``mutation`` both are mutated (:func:`mutate`), otherwise crossed over."""
    check_rng(rng, "breed")
    for ind in pop:
        if not isinstance(ind, Scored):
            raise InvalidArgumentError(f"breed takes the population as scored individuals, best first (what the "
                                       f"Evaluator returns for jobs (choices, seed, False)), got {type(ind).__name__}")
    size = len(pop)
    # an individual the target rules out (a proxy target's intersecting ship) gets no share
    wheel = roulette_wheel([ind.score if ind.log_likelihood != -math.inf else -math.inf for ind in pop])
    kept, jobs = list(pop[:n_elite]), []
    while len(kept) + len(jobs) < size:
        p1, p2 = pop[roulette(wheel, rng)], pop[tournament(size, k, rng)]
        if rng.random() < mutation:
            for parent in (p1, p2):
                child = mutate(genomes.of(parent.derivation), rng, split, nudge_step)
                if child is None:
                    kept.append(parent)
                else:
                    jobs.append((child, new_seed(rng), False))
        else:
            children = crossover(genomes.of(p1.derivation), genomes.of(p2.derivation), rng, max_retries)
            if children is None or children is COPIES:  # copies need no evaluation
                kept.extend([p1, p2])
            else:
                jobs.extend((child, new_seed(rng), False) for child in children)
    return kept, jobs


def _rank(ind: Scored) -> tuple:
    """:func:`best_first` of an individual: one the target rules out is never an elite, nor
    the best-ranked entrant of a tournament."""
    return best_first(ind.score, ind.log_likelihood)


def _record(tracker: Tracker, pop: list) -> None:
    if pop:  # empty when a stop came before the first individual was scored
        tracker.record(mean_of([ind.score for ind in pop]))
