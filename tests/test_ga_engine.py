"""The GA loop's parts: argument checks, the initial population, and breeding (selection
composed with variation). The engine contract and determinism are in test_engines.py."""

import math

import numpy as np
import pytest

from procmod.core import InvalidArgumentError
from procmod.infer import Budget, Tracker
from procmod.infer.ga import Evaluator, Genomes, breed, ga, initial_population
from procmod.models import get_model
from procmod.targets import ShapeMatch, TargetImage


def _bar_target():
    mask = np.zeros((50, 50), bool)
    mask[10:45, 22:28] = True
    return ShapeMatch(TargetImage("bar", mask, (0.5, 0.9), (0, -1)))


@pytest.mark.parametrize("kwargs,argument", [
    ({"population": 0}, "population"), ({"tournament": 0}, "tournament"), ({"max_retries": 0}, "max_retries"),
    ({"mutation": 1.5}, "mutation"), ({"mutation": math.nan}, "mutation"), ({"elitism": 1.0}, "elitism"),
    ({"nudge_step": 0.0}, "nudge_step"), ({"initial_size": 0}, "initial_size"),
    ({"split": (1.0, 1.0)}, "split"), ({"split": (1.0, -1.0, 1.0)}, "split"), ({"split": (0, 0, 0)}, "split"),
    ({"split": (math.nan, 1.0, 1.0)}, "split"), ({"split": (math.inf, 1.0, 1.0)}, "split"),
    ({"split": ("a", 1, 1)}, "split"), ({"split": 3.0}, "split")])
def test_bad_arguments_are_refused_by_their_api_name(kwargs, argument):
    with pytest.raises(InvalidArgumentError, match=rf"^{argument} must") as info:
        ga(get_model("vines"), _bar_target(), budget=Budget(generations=1), **{"population": 4, **kwargs})
    assert "--" not in str(info.value)  # the library speaks of arguments, not of CLI flags


def test_initial_population_grows_minimal_derivations_to_their_goal_sizes():
    model, target = get_model("lightning"), _bar_target()
    tracker = Tracker(Budget())
    evaluate = Evaluator(target.configure(model), target, None, tracker)
    pop = initial_population(evaluate, 30, 12, np.random.default_rng(0), tracker)
    # The goals are drawn after the 30 evaluation seeds, uniform in [1, 12]: a twin
    # generator replays those draws.
    twin = np.random.default_rng(0)
    for _ in range(30):
        twin.integers(0, 2 ** 63 - 1)
    goals = twin.integers(1, 13, size=30)
    assert len(pop) == 30 and all(ind.derivation.done for ind in pop)
    for ind, goal in zip(pop, goals):
        # grown until it reaches its goal (a round's grows may overshoot it), unless it has
        # no unexpressed child left
        d = ind.derivation
        assert d.n_nodes >= goal or not any(not s.on for n in d.nodes() for s in n.spawns)
    assert len({ind.derivation.n_nodes for ind in pop}) > 3
    assert tracker.evaluations > 30 and tracker.rows  # grows were evaluated; the population recorded


def _link(ctx, i):
    from procmod.core import Normal
    from procmod.geometry import Segment
    x = ctx.sample("x", Normal(0, 1))
    ctx.emit(Segment(x, 0, x, 1, 0.2))
    ctx.maybe("next", 0.998, _link, i + 1)


def test_a_chain_grows_its_initial_population_in_a_bounded_number_of_replays():
    # one call a replay: a chain model of ~500 calls took over a minute before generation 1
    import importlib

    from procmod.core import Model
    from procmod.geometry import Canvas
    engine = importlib.import_module("procmod.infer.ga.engine")
    chain = Model("long-chain", "a maybe chain", _link, lambda p: (0,), lambda p: Canvas((-5, 5, -5, 5), 50))
    target = _bar_target()
    tracker = Tracker(Budget())
    counted = []

    class Counting(Evaluator):
        def __call__(self, jobs, **kwargs):
            counted.append(len(jobs))
            return super().__call__(jobs, **kwargs)

    evaluate = Counting(target.configure(chain), target, None, tracker)
    pop = initial_population(evaluate, 4, 600, np.random.default_rng(0), tracker)
    assert len(counted) == 1 + engine.MAX_GROW_ROUNDS  # the minimal derivations, then the rounds
    assert all(ind.derivation.n_nodes == 1 + engine.MAX_GROW_ROUNDS for ind in pop)  # the goals are far above


@pytest.mark.parametrize("when", ["initial population", "generation"])
def test_a_stop_ends_the_ga_between_evaluations_not_generations(when, monkeypatch):
    # Blender's Stop button requests a stop from the progress callback; a generation on a
    # large volume target takes minutes, and the worker was killed (its run lost) before the
    # GA reached the end of the generation it was in.
    import importlib
    engine = importlib.import_module("procmod.infer.ga.engine")

    class EveryCall(Tracker):  # the progress callback at every check, not every 0.1 s
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **{**kwargs, "progress_interval": 0.0})

    monkeypatch.setattr(engine, "Tracker", EveryCall)
    seen = {}

    def progress(tracker):
        if when == "generation":
            if tracker.generations < 1:
                return
            seen.setdefault("from", tracker.evaluations)  # the second generation starts here
        else:
            seen.setdefault("from", 20)  # default_initial_size's 20 samples come first
        if tracker.evaluations >= seen["from"] + 5:
            tracker.request_stop()

    result = ga(get_model("lightning"), _bar_target(), population=100, budget=Budget(generations=3), seed=0,
                progress=progress)
    assert result.evaluations == seen["from"] + 5  # no evaluation starts after the stop
    assert result.best is not None and len(result.samples) == (5 if when == "initial population" else 100)


def test_a_stop_before_the_first_individual_still_leaves_a_population(monkeypatch):
    # a Stop pressed while the target was built: no individual was scored, and writing the
    # run failed ("a contact sheet needs at least one image")
    import importlib
    engine = importlib.import_module("procmod.infer.ga.engine")

    class EveryCall(Tracker):
        def __init__(self, *args, **kwargs):
            super().__init__(*args, **{**kwargs, "progress_interval": 0.0})

    monkeypatch.setattr(engine, "Tracker", EveryCall)
    result = ga(get_model("lightning"), _bar_target(), population=50, budget=Budget(generations=3), seed=0,
                progress=lambda tracker: tracker.request_stop())
    assert result.evaluations == 20 + 1 and len(result.samples) == 1 and result.history


@pytest.mark.parametrize("mutation", [0.0, 1.0])
def test_breed_keeps_the_elite_and_fills_the_generation(mutation):
    model, target = get_model("lightning"), _bar_target()
    tracker = Tracker(Budget())
    evaluate = Evaluator(target.configure(model), target, None, tracker)
    pop = initial_population(evaluate, 20, 10, np.random.default_rng(1), tracker)
    pop.sort(key=lambda ind: ind.score, reverse=True)
    members = {id(ind) for ind in pop}
    kept, jobs = breed(pop, Genomes(), np.random.default_rng(2), n_elite=4, k=10, mutation=mutation,
                       split=(0.0, 0.0, 1.0, 0.0), nudge_step=0.1, max_retries=10)
    assert kept[:4] == pop[:4]  # the elite, best first
    assert all(id(ind) in members for ind in kept)  # the others kept are unchanged parents
    assert len(kept) + len(jobs) in (20, 21)  # pairs of parents: one too many at most
    assert jobs and all(maybe_default is False for _, _, maybe_default in jobs)
    for child, _, _ in jobs:
        assert child.base.d in [ind.derivation for ind in pop]
        if mutation == 1.0:  # only alter has weight: one call's parameters dropped
            assert child.at is None and len(child.changed) == 1
        else:  # only crossovers: a graft from the other parent
            assert child.at is not None and child.donor is not None
