"""``ga``: the genetic algorithm of ShapeGenetics (seed 002, sections 4-6).

The genome is the derivation tree itself: an individual is a complete derivation, and
every genetic operation edits its choice map and replays it under the model, so every
offspring is a valid derivation by construction.

* **grow** — express a ``maybe`` child that is off, chosen with probability proportional
  to its spawn probability ``p``; the new call's own parameters are drawn from the prior
  and its own ``maybe`` children start unexpressed (one gene is added);
* **cut** — unexpress a ``maybe`` child that is on, chosen proportionally to ``1 - p``
  (children spawned with probability 1 are never cut), removing its subtree;
* **alter** — pick a call uniformly and redraw all its parameters (its non-structural
  choices) from the prior;
* **crossover** — pick a connection (parent rule, spawn site, child rule) of the first
  parent uniformly, a compatible one of the second, and swap the subtrees below them
  (up to ``max_retries`` tries when no compatible connection exists).

Selection: one parent by roulette wheel on fitness shifted to be positive (``score -
min score``), the other by k-tournament (k = 10); the best fifth of the population is
kept unchanged (elitism). Mutation probability 30%, split 13.5 / 13.5 / 3.0 between grow,
cut and alter. The initial population starts from minimal derivations (every ``maybe``
off) grown repeatedly to random sizes; each round applies as many of an individual's
missing grows as it has unexpressed children (children created in a round become
candidates in the next), so large initial individuals cost a few replays instead of one
replay per call.

Offspring evaluation is incremental when it runs in-process (no ``executor``) and the
target's score survives removing parts exactly (``target.exact_removal``: Volume,
Silhouette): every offspring differs from one parent in a few calls (grow, cut and alter
change one call and what hangs below it; a crossover child differs from its first parent
below the swapped connection), so it is built by :func:`procmod.core.runtime.replay_reusing`
from that parent: the parent's calls and drawn output (voxel or pixel counts) are reused,
the geometry of the replaced calls is removed and that of the new ones drawn. The result is
the derivation and score a full replay of the offspring's choice map gives (tested); only
the changed calls cost rule executions and voxelization. Otherwise (an executor, or a
target such as ProxyVolume that reads the bounding box) fitness evaluations are full
replays through the ``executor``.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import InvalidArgumentError, is_within
from ..core.runtime import replay_reusing
from .common import (Budget, Evaluation, Result, Scored, Tracker, check_positive, evaluate_all,
                     new_seed, relaxed_gc)


def _weighted_pick(items, weights, rng):
    total = float(sum(weights))
    if not items or total <= 0:
        return None
    u = rng.random() * total
    acc = 0.0
    for item, w in zip(items, weights):
        acc += w
        if u < acc:
            return item
    return items[-1]


# Each operator has a private form returning ``(choices, changed)``: ``changed`` lists the
# calls whose choices differ from the parent's (what replay_reusing must run again).

def _grow(d, rng, count: int = 1):
    sites = [(n.address, s.site, s.probability) for n in d.nodes() for s in n.spawns if not s.on]
    choices, changed = None, set()
    for _ in range(count):
        pick = _weighted_pick(sites, [p for _, _, p in sites], rng)
        if pick is None:
            break
        if choices is None:
            choices = dict(d.choice_map().raw)
        choices[(pick[0], pick[1])] = True
        changed.add(pick[0])
        sites.remove(pick)
    return None if choices is None else (choices, changed)


def grow_choices(d, rng, count: int = 1) -> dict | None:
    """Choice map with unexpressed ``maybe`` children turned on (None if there is none).

    Each is picked with probability proportional to its spawn probability; ``count`` > 1
    applies that many grows at once (without replacement), used to build the initial
    population without one replay per added call.
    """
    out = _grow(d, rng, count)
    return None if out is None else out[0]


def _cut(d, rng):
    sites = [(n.address, s.site, s.probability) for n in d.nodes() for s in n.spawns
             if s.on and s.probability < 1.0]
    pick = _weighted_pick(sites, [1.0 - p for _, _, p in sites], rng)
    if pick is None:
        return None
    child = pick[0] + (pick[1],)
    n = len(child)
    choices = {k: v for k, v in d.choice_map().raw.items() if k[0][:n] != child}
    choices[(pick[0], pick[1])] = False
    return choices, {pick[0]}


def cut_choices(d, rng) -> dict | None:
    """Choice map with one expressed ``maybe`` child cut (None if nothing can be cut)."""
    out = _cut(d, rng)
    return None if out is None else out[0]


def _alter(d, rng):
    candidates = []
    for n in d.nodes():
        structural = {s.site for s in n.spawns}
        names = [name for name in n.choices if name not in structural]
        if names:
            candidates.append((n.address, names))
    if not candidates:
        return None
    address, names = candidates[int(rng.random() * len(candidates))]
    removed = {(address, name) for name in names}
    return {k: v for k, v in d.choice_map().raw.items() if k not in removed}, {address}


def alter_choices(d, rng) -> dict | None:
    """Choice map with one call's parameters removed (so replay redraws them)."""
    out = _alter(d, rng)
    return None if out is None else out[0]


def connections(d) -> dict:
    """``(parent rule, site, child rule) -> [child addresses]`` of a derivation."""
    tree = d.tree()
    out = {}
    for address, node in tree.items():
        if address:
            key = (tree[address[:-1]].rule, address[-1], node.rule)
            out.setdefault(key, []).append(address)
    return out


def _graft(base: dict, at: tuple, donor: dict, source: tuple) -> dict:
    """``base`` with the subtree at ``at`` replaced by ``donor``'s subtree at ``source``."""
    m = len(at)
    out = {k: v for k, v in base.items() if k[0][:m] != at}
    n = len(source)
    for (address, name), value in donor.items():
        if address[:n] == source:
            out[(at + address[n:], name)] = value
    return out


def _crossover(d1, d2, rng, max_retries: int = 10):
    c1 = [(key, a) for key, addresses in connections(d1).items() for a in addresses]
    if not c1:
        return None
    c2 = connections(d2)
    for _ in range(max_retries):
        key, a1 = c1[int(rng.random() * len(c1))]
        matches = c2.get(key)
        if not matches:
            continue
        a2 = matches[int(rng.random() * len(matches))]
        m1, m2 = d1.choice_map().raw, d2.choice_map().raw
        # Child i differs from parent i only below the swapped connection.
        return ((_graft(m1, a1, m2, a2), {n.address for n in d1.nodes() if is_within(n.address, a1)}),
                (_graft(m2, a2, m1, a1), {n.address for n in d2.nodes() if is_within(n.address, a2)}))
    return None


def crossover_choices(d1, d2, rng, max_retries: int = 10):
    """Two children's choice maps by swapping compatible subtrees (None if none found)."""
    out = _crossover(d1, d2, rng, max_retries)
    return None if out is None else (out[0][0], out[1][0])


def evaluate_from(model, target, parent, choices, seed: int, changed=None) -> Evaluation:
    """Score the offspring ``choices`` of ``parent`` (a complete derivation whose output
    supports exact removal) by :func:`replay_reusing` from a copy of the parent's output;
    ``changed``: the calls whose choices differ from the parent's (None: compare them all).

    Same derivation and score as ``common.evaluate(model, target, (choices, seed, False))``
    up to the values of fresh choices (drawn from ``seed`` in another order).
    """
    result = replay_reusing(model, parent, choices, np.random.default_rng(seed), parent.output.copy(),
                            maybe_default=False, changed=changed, unused=False)
    d = result.derivation
    return Evaluation(d, target.log_likelihood(d.output), target.score(d.output),
                      result.log_reused, result.log_fresh, result.unused)


def _reusable(parent) -> bool:
    """Whether an offspring can be evaluated from ``parent`` incrementally."""
    output = parent.output
    return (parent.done and not parent.stopped and hasattr(output, "remove")
            and not getattr(output, "saturated", True))


def ga(model, target, population: int = 200, seed: int = 0, budget: Budget | None = None,
       mutation: float = 0.3, split=(13.5, 13.5, 3.0), elitism: float = 0.2, tournament: int = 10,
       initial_size: int | None = None, max_retries: int = 10, executor=None, progress=None) -> Result:
    """Genetic algorithm over derivation trees.

    Parameters
    ----------
    population : int
        Individuals per generation.
    budget : Budget
        Default: 50 generations.
    mutation : float
        Probability that a selected pair is mutated instead of crossed over.
    split : (grow, cut, alter)
        Relative weights of the mutation operators (seed 002: 13.5 / 13.5 / 3.0).
    elitism : float
        Fraction of the best individuals copied unchanged into the next generation.
    tournament : int
        k of the k-tournament selection.
    initial_size : int, optional
        Initial individuals are grown to sizes uniform in [1, initial_size] calls
        (default: twice the mean size of 20 forward samples, at least 5).
    executor : concurrent.futures.Executor, optional
        Evaluates offspring (default: in-process).
    """
    check_positive("population", population)
    check_positive("tournament", tournament)
    if not 0.0 <= mutation <= 1.0:
        raise InvalidArgumentError(f"mutation must be in [0, 1], got {mutation!r}")
    if len(split) != 3 or any(w < 0 for w in split) or sum(split) <= 0:
        raise InvalidArgumentError(f"split must be three non-negative weights (grow, cut, alter), got {split!r}")
    if not 0.0 <= elitism < 1.0:
        raise InvalidArgumentError(f"elitism must be in [0, 1), got {elitism!r}")
    budget = budget or Budget(generations=50)
    model = target.configure(model)
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    operators = (_grow, _cut, _alter)
    incremental = executor is None and bool(getattr(target, "exact_removal", False))

    def evaluate(jobs, parents=None):
        """Evaluate ``(choices, seed, maybe_default)`` jobs; ``parents[i]`` is None or
        ``(derivation, changed calls)``: the individual job i was derived from, reused
        when possible."""
        evaluations = [None] * len(jobs)
        if incremental and parents is not None:
            for i, (job, parent) in enumerate(zip(jobs, parents)):
                if parent is not None and job[2] is False and _reusable(parent[0]):
                    evaluations[i] = evaluate_from(model, target, parent[0], job[0], job[1], parent[1])
        rest = [i for i, ev in enumerate(evaluations) if ev is None]
        for i, ev in zip(rest, evaluate_all(executor, model, target, [jobs[i] for i in rest])):
            evaluations[i] = ev
        out = [Scored.from_evaluation(ev) for ev in evaluations]
        tracker.evaluations += len(out)
        for ind in out:
            tracker.offer(ind.derivation, ind.score)
        return out

    with relaxed_gc():
        if initial_size is None:
            sizes = [ind.derivation.n_nodes for ind in evaluate([({}, new_seed(rng), None) for _ in range(20)])]
            initial_size = max(5, int(round(2 * np.mean(sizes))))
        check_positive("initial_size", initial_size)
        pop = evaluate([({}, new_seed(rng), False) for _ in range(population)])
        goals = rng.integers(1, initial_size + 1, size=population)
        growing = [i for i in range(population) if pop[i].derivation.n_nodes < goals[i]]
        while growing and not tracker.spent():
            # Grow every unfinished individual; a round applies as many of the missing
            # grows as there are unexpressed children, so reaching size n takes a few
            # replays (the candidates multiply each round) rather than n.
            jobs, owners, parents = [], [], []
            for i in growing:
                missing = int(goals[i] - pop[i].derivation.n_nodes)
                grown = _grow(pop[i].derivation, rng, max(1, missing))
                if grown is not None:
                    jobs.append((grown[0], new_seed(rng), False))
                    parents.append((pop[i].derivation, grown[1]))
                    owners.append(i)
            for i, ind in zip(owners, evaluate(jobs, parents)):
                pop[i] = ind
            growing = [i for i in owners if pop[i].derivation.n_nodes < goals[i]]
            if tracker.due():
                tracker.record(float(np.mean([ind.score for ind in pop])))
        tracker.record(float(np.mean([ind.score for ind in pop])))

        n_elite = int(math.ceil(elitism * population)) if elitism > 0 else 0
        while not tracker.spent():
            pop.sort(key=lambda ind: ind.score, reverse=True)
            scores = np.array([ind.score for ind in pop], dtype=np.float64)
            finite = np.isfinite(scores)
            floor = scores[finite].min() if finite.any() else 0.0
            fitness = np.where(finite, scores, floor) - floor  # -inf scores get no wheel share
            fitness = fitness / fitness.sum() if fitness.sum() > 0 else np.full(population, 1.0 / population)
            cumulative = np.cumsum(fitness)

            def roulette():
                return pop[min(int(np.searchsorted(cumulative, rng.random() * cumulative[-1], side="right")),
                               population - 1)]

            def tournament_pick():
                return pop[int(min(rng.integers(0, population, size=tournament)))]  # sorted: lowest index wins

            offspring, jobs, parents = list(pop[:n_elite]), [], []
            while len(offspring) + len(jobs) < population:
                p1, p2 = roulette(), tournament_pick()
                if rng.random() < mutation:
                    for parent in (p1, p2):
                        choices = None
                        first = _weighted_pick([0, 1, 2], split, rng)
                        for op in [first] + [k for k in (0, 1, 2) if k != first and split[k] > 0]:
                            choices = operators[op](parent.derivation, rng)
                            if choices is not None:
                                break
                        if choices is None:
                            offspring.append(parent)
                        else:
                            jobs.append((choices[0], new_seed(rng), False))
                            parents.append((parent.derivation, choices[1]))
                else:
                    children = _crossover(p1.derivation, p2.derivation, rng, max_retries)
                    if children is None:
                        offspring.extend([p1, p2])
                    else:
                        jobs.extend((c, new_seed(rng), False) for c, _ in children)
                        # child i is parent i but below the swapped connection
                        parents.extend([(p1.derivation, children[0][1]), (p2.derivation, children[1][1])])
            offspring.extend(evaluate(jobs, parents))
            pop = offspring[:population]
            tracker.generations += 1
            tracker.record(float(np.mean([ind.score for ind in pop])))
    pop.sort(key=lambda ind: ind.score, reverse=True)
    return Result("ga", tracker.best, tracker.best_score, [ind.derivation for ind in pop],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={"population": population, "seed": seed, "budget": budget.describe(),
                            "mutation": mutation, "split": list(split), "elitism": elitism,
                            "tournament": tournament, "initial_size": initial_size,
                            "incremental": incremental},
                  log_weights=[ind.log_likelihood for ind in pop])
