"""GA fitness evaluation on its own: incremental evaluation from a parent gives the scores
full replays give; it is used exactly where the target and the executor allow it."""

import numpy as np
import pytest

from procmod.geometry.voxel import VoxelGrid
from procmod.infer import Budget, Tracker
from procmod.infer.common import evaluate
from procmod.infer.ga import COPIES, Evaluator, Genome, LazyRng, alter, crossover, cut, grow, nudge, reusable
from procmod.models import get_model
from procmod.parallel import InlineExecutor
from procmod.targets import ShapeMatch, TargetImage, Volume


def _volume_target():
    grid = VoxelGrid((-6.0, -2.0, -6.0), 0.5, (24, 16, 40))
    fill = np.zeros(grid.shape, bool)
    fill[6:18, 2:10, 8:30] = True
    return Volume(grid, [(fill, 1.0, -1.0)], w_self=0.5)


def _offspring_jobs(model, target, seed):
    """Parents (forward samples scored on ``target``) and jobs for one offspring of each
    operator, as the GA builds them."""
    rng = np.random.default_rng(seed)
    parents = [evaluate(model, target, ({}, int(rng.integers(2 ** 31)), None)).derivation for _ in range(2)]
    g1, g2 = Genome(parents[0]), Genome(parents[1])
    children = [grow(g1, rng), grow(g2, rng, 3), cut(g1, rng), alter(g1, rng), nudge(g2, rng, 0.3)]
    crossed = crossover(g1, g2, rng, 50)
    if crossed is not None and crossed is not COPIES:
        children += list(crossed)
    return [(c, int(rng.integers(2 ** 31)), False) for c in children if c is not None]


@pytest.mark.parametrize("name,seed", [("spaceship", 0), ("spaceship", 1), ("tree", 2), ("city", 3)])
def test_incremental_and_full_evaluation_give_the_same_offspring_and_scores(name, seed):
    model, target = get_model(name), _volume_target()
    jobs = _offspring_jobs(model, target, seed)
    assert len(jobs) >= 4
    incremental = Evaluator(model, target, None, Tracker(Budget()))
    full = Evaluator(model, target, InlineExecutor(), Tracker(Budget()))
    assert incremental.incremental and not full.incremental
    a, b = incremental(jobs), full(jobs)
    for x, y in zip(a, b):
        assert x.derivation.choice_map() == y.derivation.choice_map()
        assert x.derivation.geometry() == y.derivation.geometry()
        assert x.score == pytest.approx(y.score, abs=1e-9)
        assert x.log_prior == pytest.approx(y.log_prior, abs=1e-9)
        assert x.log_likelihood == pytest.approx(y.log_likelihood, abs=1e-9)
    # both told their tracker: the evaluations and the best individual
    for ev, scored in ((incremental, a), (full, b)):
        assert ev.tracker.evaluations == len(jobs)
        assert ev.tracker.best_score == max(s.score for s in scored)


def test_evaluation_is_incremental_only_in_process_on_exact_removal_targets():
    model = get_model("vines")
    mask = np.zeros((50, 50), bool)
    mask[10:45, 22:28] = True
    picture = ShapeMatch(TargetImage("bar", mask, (0.5, 0.9), (0, -1)))  # no exact removal
    assert not Evaluator(model, picture, None, Tracker(Budget())).incremental
    assert Evaluator(get_model("spaceship"), _volume_target(), None, Tracker(Budget())).incremental
    # a derivation drawn into a canvas cannot give its parts back; a voxel scene can
    vines = evaluate(model, picture, ({}, 0, None)).derivation
    ship = evaluate(get_model("spaceship"), _volume_target(), ({}, 0, None)).derivation
    assert not reusable(vines) and reusable(ship)


def test_lazy_offspring_generator_draws_what_the_seeded_generator_draws():
    lazy, eager = LazyRng(12345), np.random.default_rng(12345)
    draws = [lambda g: g.random(), lambda g: g.standard_normal(), lambda g: g.exponential(),
             lambda g: int(g.integers(0, 100)), lambda g: g.random()]
    assert [f(lazy) for f in draws] == [f(eager) for f in draws]
