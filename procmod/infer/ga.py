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
* **nudge** (not in seed 002; weight 0 unless ``split`` has a fourth entry) — pick a call
  with continuous choices uniformly and move each of them by a Gaussian step of
  ``nudge_step`` x the distribution's scale, reflected into its bounds: the GA analogue of
  an MCMC diffusion move (seed 002, section 7, describes diffusion as alter mutations).
  Alter redraws a call from the prior, so it rarely improves a fitted individual; a nudge
  fine-tunes one;
* **crossover** — pick a connection of the first parent uniformly, a compatible one of
  the second, and swap the subtrees below them (up to ``max_retries`` tries when no
  compatible connection exists). Connections are compatible when they are of one type, an
  edge of the generator graph: the same parent rule and the same child rule, whatever the
  spawn sites are called (seed 002, section 5: "those that describe the same edge in the
  generator graph"). So sibling sites that spawn one rule from one rule pair — the tree's
  ``b0``/``b1``/``b2`` — and a crossover can copy a branch's partial solution onto
  another branch, which seed 002 (section 8) credits for the GA's result on the tree (on
  procmod's tree scenes it changed nothing measurable: bench/shapegenetics.py
  ``--evaluations``, README). Addresses are structural, so the donor's subtree is
  re-addressed under the receiving site and replayed there: its own choices (for the tree,
  angles, scales and offsets relative to its parent) are kept, the arguments it is called
  with are the receiving parent's, so its geometry is recomputed from the new position;
  choices that the new context no longer reaches are dropped and missing ones drawn, as in
  any replay, so the children are valid derivations. When the two
  subtrees are equal (same rule and arguments at the top, same choices below) the children
  are copies of their parents, which join the next generation without an evaluation: in a
  converging population that is a quarter of all crossovers. (Retrying for a different
  subtree instead was no better: 3960 vs 4092 after 8 CPU-s on spaceship_volume, 16 seeds.)

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
the changed calls cost rule executions and voxelization. An offspring's random generator is
seeded only when a call draws a fresh value (grow, alter), not for cut, nudge or crossover
offspring (seeding costs about 10% of an incremental evaluation). Otherwise (an executor, or a
target such as ProxyVolume that reads the bounding box) fitness evaluations are full
replays through the ``executor``. The operators do not copy choice maps either: an
offspring is its parent's map plus a few edits (:class:`_Offspring`, over a per-individual
:class:`_View` indexed once per generation), materialized only for full replays.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import InvalidArgumentError
from ..core.runtime import _same_args, replay_reusing
from .common import (Budget, Evaluation, Result, Scored, Tracker, check_population, check_positive,
                     evaluate_all, new_seed, relaxed_gc)


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


class _View:
    """What the operators read off one individual, computed once: its nodes, choice map
    (a dict the operators copy, never change), connections and mutation sites. The GA
    keeps one per individual, so a parent selected several times is indexed once."""

    __slots__ = ("d", "_nodes", "_raw", "_index", "_connections", "_grow", "_cut", "_alter", "_nudge")

    def __init__(self, d):
        self.d = d
        self._nodes = self._raw = self._index = self._connections = self._grow = self._cut = self._alter = None
        self._nudge = None

    def nodes(self) -> list:
        if self._nodes is None:
            self._nodes = self.d.nodes()
        return self._nodes

    def index(self) -> dict:
        """``node address -> node``, in program order."""
        if self._index is None:
            self._index = {n.address: n for n in self.nodes()}
        return self._index

    def get(self, key, default=None):
        """The value of choice ``key`` (a choice-map lookup without building the map)."""
        node = self.index().get(key[0])
        if node is None:
            return default
        choice = node.choices.get(key[1])
        return default if choice is None else choice.value

    def raw(self) -> dict:
        if self._raw is None:
            self._raw = {(n.address, name): c.value for n in self.nodes() for name, c in n.choices.items()}
        return self._raw

    def connections(self) -> dict:
        if self._connections is None:
            rules = {n.address: n.rule for n in self.nodes()}
            out = {}
            for n in self.nodes():
                if n.address:  # the type of a connection: its generator-graph edge, not its site
                    out.setdefault((rules[n.address[:-1]], n.rule), []).append(n.address)
            self._connections = out
        return self._connections

    def grow_sites(self) -> list:
        if self._grow is None:
            self._grow = [(n.address, s.site, s.probability) for n in self.nodes() for s in n.spawns if not s.on]
        return self._grow

    def cut_sites(self) -> list:
        if self._cut is None:
            self._cut = [(n.address, s.site, s.probability) for n in self.nodes() for s in n.spawns
                         if s.on and s.probability < 1.0]
        return self._cut

    def alter_sites(self) -> list:
        if self._alter is None:
            out = []
            for n in self.nodes():
                structural = {s.site for s in n.spawns}
                names = [name for name in n.choices if name not in structural]
                if names:
                    out.append((n.address, names))
            self._alter = out
        return self._alter

    def nudge_sites(self) -> list:
        """``(address, [(name, value, scale, low, high)])`` of the calls with continuous
        choices (float values of non-discrete distributions that have a scale; ``low`` and
        ``high`` are the bounds, None when the distribution has none)."""
        if self._nudge is None:
            out = []
            for n in self.nodes():
                structural = {s.site for s in n.spawns}
                cont = []
                for name, c in n.choices.items():
                    dist = c.dist
                    if name in structural or dist.discrete or not isinstance(c.value, float):
                        continue
                    try:
                        scale = float(dist.scale)
                    except NotImplementedError:
                        continue
                    cont.append((name, c.value, scale, getattr(dist, "low", None), getattr(dist, "high", None)))
                if cont:
                    out.append((n.address, cont))
            self._nudge = out
        return self._nudge


_DROP = object()
_MISSING = object()


class _Offspring:
    """An offspring's choice map as edits of its parent's, built lazily.

    Lookups go to ``changes`` (a value, or ``_DROP`` for a removed choice), then — for
    addresses below ``at`` — to ``donor`` (a _View) at ``source`` (a crossover graft; no
    donor: the subtree is cut), then to ``base`` (the parent's _View). So an operator costs
    O(edits), not O(choice map). :meth:`materialize` builds the full dict (what the
    public operators return and full replays use).
    """

    __slots__ = ("base", "changes", "at", "donor", "source")

    def __init__(self, base, changes=None, at=None, donor=None, source=None):
        self.base, self.changes, self.at, self.donor, self.source = base, changes or {}, at, donor, source

    def get(self, key, default=None):
        value = self.changes.get(key, _MISSING)
        if value is not _MISSING:
            return default if value is _DROP else value
        at = self.at
        if at is not None and key[0][:len(at)] == at:
            if self.donor is None:
                return default
            return self.donor.get((self.source + key[0][len(at):], key[1]), default)
        return self.base.get(key, default)

    def __contains__(self, key) -> bool:
        return self.get(key, _MISSING) is not _MISSING

    def __setitem__(self, key, value) -> None:
        self.changes[key] = value

    def materialize(self) -> dict:
        at = self.at
        if at is None:
            out = dict(self.base.raw())
        else:
            m = len(at)
            out = {k: v for k, v in self.base.raw().items() if k[0][:m] != at}
            if self.donor is not None:
                source, n = self.source, len(self.source)
                for (address, name), value in self.donor.raw().items():
                    if address[:n] == source:
                        out[(at + address[n:], name)] = value
        for key, value in self.changes.items():
            if value is _DROP:
                out.pop(key, None)
            else:
                out[key] = value
        return out


# Each operator has a private form on a _View returning ``(offspring, changed)``: ``changed``
# lists the calls whose choices differ from the parent's (what replay_reusing runs again).

def _grow(v: _View, rng, count: int = 1):
    sites = v.grow_sites()
    if count == 1:
        picks = [_weighted_pick(sites, [p for _, _, p in sites], rng)]
    else:  # successive picks without replacement, proportional to p (numpy: not quadratic)
        weights = np.array([p for _, _, p in sites], dtype=np.float64)
        live = np.flatnonzero(weights > 0)
        k = min(count, len(live))
        picks = ([sites[i] for i in rng.choice(live, size=k, replace=False, p=weights[live] / weights[live].sum())]
                 if k else [])
    changes, changed = {}, set()
    for pick in picks:
        if pick is not None:
            changes[(pick[0], pick[1])] = True
            changed.add(pick[0])
    return (_Offspring(v, changes), changed) if changes else None


def grow_choices(d, rng, count: int = 1) -> dict | None:
    """Choice map with unexpressed ``maybe`` children turned on (None if there is none).

    Each is picked with probability proportional to its spawn probability; ``count`` > 1
    applies that many grows at once (without replacement), used to build the initial
    population without one replay per added call.
    """
    out = _grow(_View(d), rng, count)
    return None if out is None else out[0].materialize()


def _cut(v: _View, rng):
    sites = v.cut_sites()
    pick = _weighted_pick(sites, [1.0 - p for _, _, p in sites], rng)
    if pick is None:
        return None
    return _Offspring(v, {(pick[0], pick[1]): False}, at=pick[0] + (pick[1],)), {pick[0]}


def cut_choices(d, rng) -> dict | None:
    """Choice map with one expressed ``maybe`` child cut (None if nothing can be cut)."""
    out = _cut(_View(d), rng)
    return None if out is None else out[0].materialize()


def _alter(v: _View, rng):
    candidates = v.alter_sites()
    if not candidates:
        return None
    address, names = candidates[int(rng.random() * len(candidates))]
    return _Offspring(v, {(address, name): _DROP for name in names}), {address}


def alter_choices(d, rng) -> dict | None:
    """Choice map with one call's parameters removed (so replay redraws them)."""
    out = _alter(_View(d), rng)
    return None if out is None else out[0].materialize()


def _reflect(x: float, low: float, high: float) -> float:
    """``x`` folded into ``[low, high]`` by reflection at the bounds."""
    width = high - low
    if width <= 0:
        return low
    y = (x - low) % (2.0 * width)
    return low + (y if y <= width else 2.0 * width - y)


def _nudge(v: _View, rng, step: float = 0.1):
    candidates = v.nudge_sites()
    if not candidates:
        return None
    address, choices = candidates[int(rng.random() * len(candidates))]
    changes = {}
    for name, value, scale, low, high in choices:
        x = value + step * scale * rng.standard_normal()
        if low is not None and high is not None:
            x = _reflect(x, low, high)
        changes[(address, name)] = x
    return _Offspring(v, changes), {address}


def nudge_choices(d, rng, step: float = 0.1) -> dict | None:
    """Choice map with one call's continuous parameters moved by a Gaussian step."""
    out = _nudge(_View(d), rng, step)
    return None if out is None else out[0].materialize()


def connections(d) -> dict:
    """``(parent rule, child rule) -> [child addresses]`` of a derivation: its connections
    grouped by type (generator-graph edge), the sets crossover pairs within."""
    return _View(d).connections()


def _same_subtree(v1: _View, a1: tuple, v2: _View, a2: tuple) -> bool:
    """Whether the subtree of ``v1`` at ``a1`` equals that of ``v2`` at ``a2`` (same rule and
    arguments at the top, same rules and choice values below): swapping them changes nothing."""
    i1, i2 = v1.index(), v2.index()
    x, y = i1[a1], i2[a2]
    if x.rule is not y.rule or not _same_args(x.args, y.args):
        return False
    stack = [(x, y)]
    while stack:
        x, y = stack.pop()
        if x.rule is not y.rule or len(x.choices) != len(y.choices):
            return False
        yc = y.choices
        for name, c in x.choices.items():
            d = yc.get(name)
            if d is None or d.value != c.value:
                return False
        for spawn in x.spawns:
            if spawn.on:
                cx, cy = i1.get(x.address + (spawn.site,)), i2.get(y.address + (spawn.site,))
                if cx is None or cy is None:  # a call that never ran (a stopped derivation)
                    return False
                stack.append((cx, cy))
    return True


COPIES = "copies"  # what _crossover returns when the swap changes nothing


def _crossover(v1: _View, v2: _View, rng, max_retries: int = 10):
    c1 = [(key, a) for key, addresses in v1.connections().items() for a in addresses]
    if not c1:
        return None
    c2 = v2.connections()
    for _ in range(max_retries):
        key, a1 = c1[int(rng.random() * len(c1))]
        matches = c2.get(key)
        if not matches:
            continue
        a2 = matches[int(rng.random() * len(matches))]
        if _same_subtree(v1, a1, v2, a2):  # the children are copies of the parents
            return COPIES
        n1, n2 = len(a1), len(a2)
        # Child i differs from parent i only below the swapped connection.
        return ((_Offspring(v1, at=a1, donor=v2, source=a2), {a for a in v1.index() if a[:n1] == a1}),
                (_Offspring(v2, at=a2, donor=v1, source=a1), {a for a in v2.index() if a[:n2] == a2}))
    return None


def crossover_choices(d1, d2, rng, max_retries: int = 10):
    """Two children's choice maps by swapping the subtrees below two connections of one
    type (same parent rule and child rule, any spawn sites; None if none found)."""
    v1, v2 = _View(d1), _View(d2)
    out = _crossover(v1, v2, rng, max_retries)
    if out is COPIES:
        return dict(v1.raw()), dict(v2.raw())
    return None if out is None else (out[0][0].materialize(), out[1][0].materialize())


class _LazyRng:
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


def evaluate_from(model, target, parent, choices, seed: int, changed=None) -> Evaluation:
    """Score the offspring ``choices`` (a dict, or an operator's lazy _Offspring) of
    ``parent`` (a complete derivation whose output supports exact removal, or its _View)
    by :func:`replay_reusing` from a copy of the parent's output; ``changed``: the calls
    whose choices differ from the parent's (None: compare them all).

    Same derivation and score as ``common.evaluate(model, target, (choices, seed, False))``,
    the score up to rounding in the last bits (see :func:`replay_reusing`).
    """
    view = parent if isinstance(parent, _View) else _View(parent)
    parent = view.d
    result = replay_reusing(model, parent, choices, _LazyRng(seed), parent.output.copy(),
                            maybe_default=False, changed=changed, unused=False, index=view.index())
    d = result.derivation
    return Evaluation(d, target.log_likelihood(d.output), target.score(d.output),
                      result.log_reused, result.log_fresh, result.unused)


def _materialize(choices) -> dict:
    return choices.materialize() if isinstance(choices, _Offspring) else choices


def _reusable(parent) -> bool:
    """Whether an offspring can be evaluated from ``parent`` incrementally."""
    output = parent.output
    return (parent.done and not parent.stopped and hasattr(output, "remove")
            and not getattr(output, "saturated", True))


def ga(model, target, population: int = 200, seed: int = 0, budget: Budget | None = None,
       mutation: float = 0.3, split=(13.5, 13.5, 3.0), elitism: float = 0.2, tournament: int = 10,
       initial_size: int | None = None, max_retries: int = 10, nudge_step: float = 0.1,
       executor=None, progress=None) -> Result:
    """Genetic algorithm over derivation trees.

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
    nudge_step : float
        Nudge step as a fraction of each choice distribution's scale.
    executor : concurrent.futures.Executor, optional
        Evaluates offspring (default: in-process).
    """
    check_positive("population", population)
    check_positive("tournament", tournament)
    if not 0.0 <= mutation <= 1.0:
        raise InvalidArgumentError(f"mutation must be in [0, 1], got {mutation!r}")
    if len(split) not in (3, 4) or any(w < 0 for w in split) or sum(split) <= 0:
        raise InvalidArgumentError("split must be three or four non-negative weights (grow, cut, alter[, nudge]), "
                                   f"got {split!r}")
    split = tuple(float(w) for w in split) + (0.0,) * (4 - len(split))
    if not nudge_step > 0:
        raise InvalidArgumentError(f"nudge_step must be positive, got {nudge_step!r}")
    if not 0.0 <= elitism < 1.0:
        raise InvalidArgumentError(f"elitism must be in [0, 1), got {elitism!r}")
    budget = budget or Budget(generations=50)
    model = target.configure(model)
    check_population("population", population, target.new_output(model))  # refuse what memory cannot hold
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    operators = (_grow, _cut, _alter, lambda v, r: _nudge(v, r, nudge_step))
    incremental = executor is None and bool(getattr(target, "exact_removal", False))
    views = {}  # id(derivation) -> _View, for the current population

    def view(d) -> _View:
        v = views.get(id(d))
        if v is None or v.d is not d:
            v = views[id(d)] = _View(d)
        return v

    def evaluate(jobs, parents=None):
        """Evaluate ``(choices, seed, maybe_default)`` jobs; ``parents[i]`` is None or
        ``(parent's _View, changed calls)``: the individual job i was derived from, reused
        when possible."""
        evaluations = [None] * len(jobs)
        if incremental and parents is not None:
            for i, (job, parent) in enumerate(zip(jobs, parents)):
                if parent is not None and job[2] is False and _reusable(parent[0].d):
                    evaluations[i] = evaluate_from(model, target, parent[0], job[0], job[1], parent[1])
        rest = [i for i, ev in enumerate(evaluations) if ev is None]
        full_jobs = [(_materialize(jobs[i][0]),) + tuple(jobs[i][1:]) for i in rest]
        for i, ev in zip(rest, evaluate_all(executor, model, target, full_jobs)):
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
                parent = _View(pop[i].derivation)
                grown = _grow(parent, rng, max(1, missing))
                if grown is not None:
                    jobs.append((grown[0], new_seed(rng), False))
                    parents.append((parent, grown[1]))
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
                        first = _weighted_pick([0, 1, 2, 3], split, rng)
                        for op in [first] + [k for k in (0, 1, 2, 3) if k != first and split[k] > 0]:
                            choices = operators[op](view(parent.derivation), rng)
                            if choices is not None:
                                break
                        if choices is None:
                            offspring.append(parent)
                        else:
                            jobs.append((choices[0], new_seed(rng), False))
                            parents.append((view(parent.derivation), choices[1]))
                else:
                    children = _crossover(view(p1.derivation), view(p2.derivation), rng, max_retries)
                    if children is None or children is COPIES:  # copies need no evaluation
                        offspring.extend([p1, p2])
                    else:
                        jobs.extend((c, new_seed(rng), False) for c, _ in children)
                        # child i is parent i but below the swapped connection
                        parents.extend([(view(p1.derivation), children[0][1]), (view(p2.derivation), children[1][1])])
            offspring.extend(evaluate(jobs, parents))
            pop = offspring[:population]
            views = {id(ind.derivation): views[id(ind.derivation)] for ind in pop if id(ind.derivation) in views}
            tracker.generations += 1
            tracker.record(float(np.mean([ind.score for ind in pop])))
    pop.sort(key=lambda ind: ind.score, reverse=True)
    return Result("ga", tracker.best, tracker.best_score, [ind.derivation for ind in pop],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={"population": population, "seed": seed, "budget": budget.describe(),
                            "mutation": mutation, "split": list(split), "elitism": elitism,
                            "tournament": tournament, "initial_size": initial_size, "nudge_step": nudge_step,
                            "incremental": incremental},
                  log_weights=[ind.log_likelihood for ind in pop])
