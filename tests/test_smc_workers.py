"""SMC with its population split among worker processes (procmod.infer.particles)."""

import json
import math
import multiprocessing
import os

import numpy as np
import pytest

from procmod.core import Model, ModelError, Normal, replay
from procmod.infer import smc, sosmc
from procmod.infer.particles import fork_available, plan_offspring
from procmod.infer.smc import worker_count
from procmod.models import get_model
from procmod.parallel import WorkerError
from procmod.targets import ShapeMatch
from procmod.data import scribble_set

from test_engines_exact import ORDER_OBS, ORDER_S, _count_resampling, assert_posterior_matches, assert_z_unbiased
from toy_models import COUNT, MIX, Z_CHECK_S, SumOutput, SumTarget, Value, count_evidence, mix_exact

pytestmark = pytest.mark.skipif(not fork_available(), reason="worker shards are forked processes")

OBS, S = 2.3, 0.5


# ---- the plan: who keeps which offspring ------------------------------------------------

def _check_plan(ancestors, sizes, finished):
    keep, sends = plan_offspring(ancestors, sizes, finished)
    offsets = np.cumsum([0] + sizes)[:-1]
    got = {}  # global ancestor -> offspring, wherever they went
    active = [0] * len(sizes)
    for s, kept in enumerate(keep):
        for local in kept:
            a = offsets[s] + local
            got[a] = got.get(a, 0) + 1
            active[s] += not finished[a]
        for local, destination, count in sends[s]:
            a = offsets[s] + local
            assert not finished[a], "a finished particle never moves"
            assert destination != s
            got[a] = got.get(a, 0) + count
            active[destination] += count
    want = {}
    for a in ancestors:
        want[a] = want.get(a, 0) + 1
    assert got == want  # every offspring placed exactly once
    assert max(active) - min(active) <= 1  # active particles balanced
    return keep, sends


def test_plan_keeps_offspring_home_when_balanced():
    # shard 0 holds 0..3, shard 1 holds 4..7; two offspring each side: nothing moves
    keep, sends = _check_plan([0, 0, 5, 6], [4, 4], [False] * 8)
    assert keep == [[0, 0], [1, 2]] and sends == [[], []]


def test_plan_moves_the_surplus_of_a_collapsed_population():
    # every offspring descends from particle 1 (shard 0): half of them move to shard 1
    keep, sends = _check_plan([1] * 6, [3, 3], [False] * 6)
    assert keep == [[1, 1, 1], []]
    assert sends == [[(1, 1, 3)], []]


def test_plan_balances_only_active_particles():
    finished = [False, True, False, False, False, False, True, True]
    _check_plan([1, 1, 1, 1, 2, 6, 6, 7], [4, 4], finished)
    rng = np.random.default_rng(0)
    for _ in range(200):  # random populations, 2-4 shards
        shards = int(rng.integers(2, 5))
        sizes = [int(v) for v in rng.integers(1, 9, shards)]
        n = sum(sizes)
        finished = [bool(v) for v in rng.random(n) < 0.3]
        ancestors = sorted(int(v) for v in rng.integers(0, n, n))
        _check_plan(ancestors, sizes, finished)


# ---- runs --------------------------------------------------------------------------------

def _vines_target():
    return ShapeMatch(scribble_set(1, first=49)[0])


def test_worker_count_is_checked_and_automatic():
    assert worker_count(1, 600) == 1
    assert worker_count(4, 3) == 3  # never more workers than particles
    assert 1 <= worker_count(None, 600) <= 6
    assert worker_count(None, 50) == 1
    for bad in (0, -1, 1.5, True):
        with pytest.raises(Exception, match="workers"):
            worker_count(bad, 100)


def test_a_run_with_workers_returns_whole_derivations_and_repeats_exactly():
    model, target = get_model("vines"), _vines_target()
    runs = [smc(model, target, particles=60, seed=3, workers=2) for _ in range(2)]
    a, b = runs
    assert a.settings["workers"] == 2
    assert len(a.samples) == 60 and len(a.log_weights) == 60
    for result in (a,):
        for d in [result.best] + result.samples:
            nodes = d.nodes()
            assert len(nodes) == d.n_nodes  # the histories left in the other process came back
            assert sum(len(n.geometry) for n in nodes) == d.n_emits
            assert d.done
        # the best is what its choices give when replayed from scratch, and its score is the target's
        again = replay(target.configure(model), result.best.choice_map(), np.random.default_rng(0),
                       output=target.new_output(target.configure(model))).derivation
        assert again.geometry() == result.best.geometry()
        assert target.score(again.output) == pytest.approx(result.best_score, abs=1e-12)
    # same seed, same workers: the same run
    assert a.best.choice_map() == b.best.choice_map() and a.best_score == b.best_score
    assert a.log_weights == b.log_weights and a.evaluations == b.evaluations
    assert not multiprocessing.active_children()  # the workers are gone


def test_sosmc_with_workers_runs():
    result = sosmc(get_model("vines"), _vines_target(), particles=40, seed=1, workers=2)
    assert result.best is not None and len(result.samples) == 40
    assert len(result.best.nodes()) == result.best.n_nodes


class _OffsetTarget(SumTarget):
    """SumTarget's likelihood times exp(OFFSET): the same posterior, Z scaled by exp(OFFSET).
    A particle that moved between shards with a wrong log-likelihood (0, or another
    particle's) would be off by about OFFSET at its next step: the Z check below would
    show it at once (with the plain target the error is a nat or two, within the noise)."""

    OFFSET = -40.0

    def log_likelihood(self, output):
        return super().log_likelihood(output) + self.OFFSET


def test_workers_estimate_the_marginal_likelihood_without_bias():
    # The same check as the single-process one (test_engines_exact): resampling moves
    # particles between the shards, and a bias in the weights or a lost particle shows.
    z, _ = mix_exact(OBS, Z_CHECK_S)  # a likelihood under which the estimate's variance is finite
    runs = 150
    target = _OffsetTarget(OBS, Z_CHECK_S)
    estimates = np.array([math.exp(smc(MIX, target, particles=16, seed=i, workers=2).log_marginal_likelihood
                                   - target.OFFSET) for i in range(runs)])
    se = estimates.std(ddof=1) / math.sqrt(runs)
    assert abs(estimates.mean() - z) < 4.5 * se, (estimates.mean(), z, se)
    assert se < 0.1 * z  # the check has power: a 10% bias would be caught


def test_workers_resampling_below_an_ess_threshold_estimate_z_without_bias(monkeypatch):
    # Skipped resamplings carry every shard's weights over to the next gathering (the
    # default of guided runs); COUNT emits up to five times, so skips happen.
    counts = _count_resampling(monkeypatch)
    z = count_evidence(ORDER_OBS, ORDER_S)
    runs = 500  # 150 left the check without power for a fifth of other seeds (h127)
    target = _OffsetTarget(ORDER_OBS, ORDER_S)
    estimates = np.array([math.exp(smc(COUNT, target, particles=16, seed=i, workers=2, ess_threshold=0.5)
                                   .log_marginal_likelihood - target.OFFSET) for i in range(runs)])
    assert 0 < counts["resamples"] < 0.8 * counts["steps"], counts
    assert_z_unbiased(estimates, z)


def test_workers_give_the_exact_posterior():
    _, exact = mix_exact(OBS, Z_CHECK_S)
    results = [smc(MIX, SumTarget(OBS, Z_CHECK_S), particles=300, seed=500 + i, workers=2) for i in range(40)]
    assert_posterior_matches(results, exact)


CALLER = os.getpid()


def _failing_rule(ctx, depth, how):
    # fails only in a worker process, deep into the run: the failure has to reach the caller
    ctx.emit(Value(ctx.sample("x", Normal(0.0, 1.0))))
    if depth == 3 and os.getpid() != CALLER:
        if how == "raise":
            raise ModelError("this rule is broken")
        os._exit(3)  # a worker that dies, as from a crash or the OOM killer
    ctx.spawn("next", _failing_rule, depth + 1, how)


@pytest.mark.parametrize("how,error,message", [
    ("raise", ModelError, "this rule is broken"),
    ("die", WorkerError, "SMC worker process 1 ended unexpectedly \\(exit code 3\\); rerun, with fewer workers, "
                         "or with workers=1"),  # a ProcmodError: one line
])
def test_a_failure_in_a_worker_is_raised_in_the_caller(how, error, message):
    failing = Model("failing", "a rule that fails in a worker", _failing_rule, lambda p: (0, how),
                    lambda p: SumOutput(), rules=(_failing_rule,))
    with pytest.raises(error, match=message) as raised:
        smc(failing, SumTarget(OBS, S), particles=8, seed=0, workers=2)
    assert not multiprocessing.active_children()
    if how == "raise":  # the worker's traceback, down to the user's line, comes with it
        notes = "\n".join(getattr(raised.value, "__notes__", []))
        assert "raised in SMC worker process" in notes and "in _failing_rule" in notes, notes


def test_infer_with_workers_from_the_cli(tmp_path, capsys):
    from procmod.cli import main

    out = tmp_path / "run"
    code = main(["infer", "vines", "--target", "scribble:49", "--particles", "40", "--workers", "2",
                 "--out", str(out), "--size", "64"])
    assert code == 0, capsys.readouterr().err
    settings = json.loads((out / "settings.json").read_text())
    assert settings["settings"]["workers"] == 2
    assert (out / "best.json").exists() and (out / "report.html").exists()


def _closure_tree():
    """A model whose rules a user wrote as a closure (a rule factory) and as a bound
    method: plain pickle cannot send either in a moved particle's pending calls."""
    import math as m

    from procmod.geometry import Canvas, Disc, Segment

    def make_branch(decay):
        def branch(ctx, x, y, a, w):
            a = ctx.sample("a", Normal(a, 0.3))
            x1, y1 = x + 1.5 * m.cos(a), y + 1.5 * m.sin(a)
            ctx.emit(Segment(x, y, x1, y1, w))
            if w > 0.15:
                ctx.maybe("l", 0.7, branch, x1, y1, a - 0.4, w * decay)
                ctx.maybe("r", 0.7, branch, x1, y1, a + 0.4, w * decay)
        return branch

    class Grower:
        def __init__(self, decay):
            self.branch = make_branch(decay)

        def root(self, ctx, x, y):
            ctx.emit(Disc(x, y, 0.5))
            ctx.spawn("trunk", self.branch, x, y, -m.pi / 2, 0.8)

    grower = Grower(0.8)
    return Model("closure-tree", "closures and a method", lambda ctx, x, y: ctx.spawn("g", grower.root, x, y),
                 root_args=lambda p: (0.0, -4.0), new_output_from=lambda p: Canvas((-12, 12, -22, 2), 50))


@pytest.mark.parametrize("engine", [smc, sosmc])
def test_workers_take_rules_that_are_closures_and_methods(engine, monkeypatch, tmp_path):
    """README: forked workers 'take any model'. A particle moved between shards whose
    pending call is a closure or a bound method failed with a traceback ('Can't pickle
    local object'); it now goes by value (cloudpickle), the same seed giving the same run."""
    from procmod.infer import particles
    log = tmp_path / "picklers.txt"  # appended to by the coordinator and the forked workers
    real = particles._SharedObjects._dumps

    def recording(self, message, pickler_class):
        with open(log, "a") as handle:
            handle.write(pickler_class.__module__ + "\n")
        return real(self, message, pickler_class)

    monkeypatch.setattr(particles._SharedObjects, "_dumps", recording)
    from procmod.data import target_from_spec
    model, target = _closure_tree(), target_from_spec("glyph:Y")
    first = engine(model, target, particles=40, seed=2, workers=2)
    assert "cloudpickle.cloudpickle" in log.read_text().split()  # a particle with such a call did move
    again = engine(model, target, particles=40, seed=2, workers=2)
    assert first.best_score == again.best_score
    assert first.best.choice_map() == again.best.choice_map()


def _positive_or_child(ctx):
    x = ctx.sample("x", Normal(0.0, 1.0))
    ctx.emit(x)
    if x < 0:
        ctx.spawn("child", _minus_ten)


def _minus_ten(ctx):
    ctx.emit(-10.0)


class _RuledOutOrUnscored(SumTarget):
    """A positive sum is ruled out (log-likelihood -inf) with a finite score; any other is
    allowed with a score of -inf."""

    def log_likelihood(self, output):
        return -math.inf if output.total > 0 else 0.0

    def score(self, output):
        return output.total if output.total > 0 else -math.inf


@pytest.mark.skipif(not fork_available(), reason="SMC's workers are forked")
def test_a_workers_best_is_the_derivation_its_score_describes():
    """A worker shard took an allowed derivation of score -inf over its ruled-out best after
    the coordinator had taken that best: the result's best_score and note described one
    derivation, its best was the other (h150)."""
    model = Model("twostep", "x, then a child when x < 0", _positive_or_child, root_args=lambda p: (),
                  new_output_from=lambda p: SumOutput(), rules=(_positive_or_child, _minus_ten))
    target = _RuledOutOrUnscored(0.0, 1.0)
    for seed in range(6):
        result = smc(model, target, particles=8, seed=seed, workers=2)
        if result.best is not None:
            assert target.score(result.best.output) == result.best_score, seed
