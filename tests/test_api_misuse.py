"""The Python API's likely mistakes are one ProcmodError line, not a TypeError or an
AttributeError from deep inside (an adversarial pass found each of these)."""

import collections
import json
import tempfile
from pathlib import Path

import numpy as np
import pytest

from procmod.core import (Bernoulli, Categorical, InvalidArgumentError, Normal, ProcmodError, load_derivation,
                          regenerate, replay, run_forward, save_derivation)
from procmod.data import target_from_spec
from procmod.guide import Guide
from procmod.infer import Budget
from procmod.infer.smc import smc
from procmod.learn import load_program
from procmod.models import get_model


@pytest.fixture(scope="module")
def vines():
    return get_model("vines"), target_from_spec("glyph:a")


@pytest.mark.parametrize("kwargs, message", [
    ({"seed": "x"}, "seed must be a non-negative whole number"),
    ({"seed": -1}, "seed must be a non-negative whole number"),
    ({"seed": 1.5}, "seed must be a non-negative whole number"),
    ({"budget": 30}, r"budget must be a Budget .e.g. Budget\(seconds=30\)"),
    ({"budget": "30s"}, "parse_budget"),
    ({"guide": 5}, "guide must be a procmod Guide, its name or its path"),
    ({"guide": "no-such-guide"}, "guide file .*does not exist"),
])
def test_engine_arguments(vines, kwargs, message):
    model, target = vines
    with pytest.raises(ProcmodError, match=message):
        smc(model, target, particles=2, **kwargs)


@pytest.mark.parametrize("engine", ["smc", "forward", "ga", "mcmc", "sosmc"])
def test_a_budget_without_a_limit_is_refused_not_run_forever(vines, engine):
    from procmod.infer import ENGINES
    model, target = vines
    with pytest.raises(ProcmodError, match=r"Budget\(\) sets no limit"):
        ENGINES[engine](model, target, budget=Budget())


@pytest.mark.parametrize("kwargs, message", [
    ({"anneal_every": 0}, "anneal_every must be a positive integer"),
    ({"anneal_every": 2.5}, "anneal_every must be a positive integer"),
    ({"step_scale": float("nan")}, "step_scale must be a positive finite number"),
    ({"step_scale": 0}, "step_scale must be a positive finite number"),
    ({"annealing": float("inf")}, "annealing must be a finite number >= 1"),
])
def test_mcmc_options(vines, kwargs, message):
    from procmod.infer.mcmc import mcmc
    model, target = vines
    with pytest.raises(ProcmodError, match=message):
        mcmc(model, target, budget=Budget(generations=1), **kwargs)


@pytest.mark.parametrize("seed", [np.random.SeedSequence(5), np.array([1, 2]), [], [3, 1], np.int64(3)])
def test_every_seed_numpy_takes_is_taken(vines, seed):
    model, target = vines
    assert smc(model, target, particles=2, workers=1, seed=seed).best is not None


def _strict_json(text):
    def refuse(constant):
        raise ValueError(f"{constant} is not JSON")
    return json.loads(text, parse_constant=refuse)


def test_numpy_numbers_are_taken_as_arguments_and_recorded_as_json_numbers(tmp_path):
    """Counts, sizes and settings that come out of numpy (a grid search, np.arange) are
    taken as the numbers they are, and settings.json records them as numbers: workers,
    init_particles and size were refused ("must be a positive integer, got 1"), numpy
    floats were written as strings, and an np.float32 step size made the choices it moved
    numpy floats that could not be saved."""
    from procmod.infer import ENGINES
    from procmod.report import write_run

    model = get_model("vines").configure(size=np.int64(32), start=np.array([0.5, 0.9]), leaves=np.bool_(False))
    assert model.params["size"] == 32 and type(model.params["size"]) is int and model.params["start"] == [0.5, 0.9]
    target = target_from_spec("glyph:a")
    i64, f32 = np.int64, np.float32
    runs = {"smc": dict(particles=i64(4), workers=i64(1)),
            "mcmc": dict(budget=Budget(evaluations=40), workers=i64(1), init_particles=i64(2), step_scale=f32(0.3),
                         p_diffusion=f32(0.9), p_resample=f32(0.05), annealing=f32(1.2)),
            "ga": dict(population=i64(6), budget=Budget(generations=2), elitism=f32(0.2), mutation=f32(0.3),
                       nudge_step=f32(0.1))}
    for engine, kwargs in runs.items():
        result = ENGINES[engine](model, target, seed=i64(3), **kwargs)
        out = tmp_path / engine
        write_run(result, target, out, size=i64(48))
        settings = _strict_json((out / "settings.json").read_text())["settings"]
        for name, value in kwargs.items():
            if name != "budget":
                assert isinstance(settings[name], (int, float)) and settings[name] == pytest.approx(float(value)), name
        _strict_json((out / "best.json").read_text())
        assert load_derivation(out / "best.json", model).choice_map() == result.best.choice_map()
    with pytest.raises(ProcmodError, match="nudge_step must be a positive finite number"):
        ENGINES["ga"](model, target, population=4, budget=Budget(generations=1), nudge_step=float("inf"))
    with pytest.raises(ProcmodError, match=r"mutation must be in \[0, 1\]"):  # was an OverflowError
        ENGINES["ga"](model, target, population=4, budget=Budget(generations=1), mutation=10 ** 400)
    pair = collections.namedtuple("Pair", "x y")  # failed in the copy to the default's type
    assert model.configure(start=pair(0.25, 0.75)).params["start"] == [0.25, 0.75]


def test_a_models_name_or_a_guides_name(vines):
    _, target = vines
    with pytest.raises(ProcmodError, match="model must be a procmod Model.*get_model"):
        smc("vines", target, particles=2)
    # a guide's name is what the command line takes: the API takes it too
    result = smc(get_model("vines"), target, particles=2, guide="vines-scribbles")
    assert result.engine == "smc+guide"


@pytest.mark.parametrize("make, message", [
    (lambda: Budget(seconds="3"), "budget seconds must be a number"),
    (lambda: Budget(seconds=float("inf")), "must be positive and finite"),
    (lambda: Normal(0, "x"), "Normal needs a finite number mu and a finite number sigma > 0"),
    (lambda: Normal("a", 1), "Normal needs a finite number mu"),
    (lambda: Budget(evaluations=1.5), "budget evaluations must be a whole number"),
    (lambda: Bernoulli("x"), "Bernoulli needs a number 0 <= p <= 1"),
    (lambda: Categorical([0.5, "a"]), "Categorical needs a list of numbers"),
    (lambda: Categorical([1, 1], labels=(np.longdouble(0.1), 0.2)), "JSON, which has no numpy longdouble"),
])
def test_constructors(make, message):
    with pytest.raises(ProcmodError, match=message):
        make()


def test_runtime_and_files(vines, tmp_path):
    model, _ = vines
    with pytest.raises(ProcmodError, match=r"rng must be a numpy Generator \(np.random.default_rng\(seed\)\)"):
        run_forward(model, 0)
    rng = np.random.default_rng(0)
    with pytest.raises(ProcmodError, match="choices must be a ChoiceMap"):
        replay(model, None, rng)
    with pytest.raises(ProcmodError, match="derivation must be a procmod Derivation"):
        regenerate(model, None, (), rng)
    from procmod.core import set_maybe  # checked as regenerate is (an AttributeError; a seed taken as the rng)
    with pytest.raises(ProcmodError, match="derivation must be a procmod Derivation"):
        set_maybe(model, None, (), "leaf", True, rng)
    d = run_forward(model, rng)
    with pytest.raises(ProcmodError, match=r"rng must be a numpy Generator"):
        set_maybe(model, d, (), "leaf", True, 42)
    # a coin given as numpy's bool (an edited map: arr > 0) is the coin's value, not redrawn
    coin = next(name for (address, name), value in d.choice_map().items() if isinstance(value, bool))
    flipped = d.choice_map().with_value((), coin, np.bool_(not d.choice_map()[((), coin)]))
    assert ((), coin) not in replay(model, flipped, np.random.default_rng(1)).unused
    with pytest.raises(ProcmodError, match="cannot write the derivation to .*No such file"):
        save_derivation(d, tmp_path / "nope" / "x.json")
    with pytest.raises(ProcmodError, match="cannot write the derivation to .*"):
        save_derivation(d, tmp_path)
    with pytest.raises(ProcmodError, match="derivation must be a procmod Derivation"):
        save_derivation(None, tmp_path / "x.json")
    with pytest.raises(ProcmodError, match="must be given as a path"):
        load_derivation(5, get_model)
    with pytest.raises(ProcmodError, match="given by its name or path"):
        Guide.load(5)
    with pytest.raises(ProcmodError, match="given by its path"):
        load_program(5)
    (tmp_path / "folder.pt").mkdir()
    (tmp_path / "folder.json").write_text("{}")
    with pytest.raises(ProcmodError, match="is not a regular file"):
        Guide.load(tmp_path / "folder")
    save_derivation(d, tmp_path / "d.json")
    text = (tmp_path / "d.json").read_text().replace('"vines"', '"no-such-model"', 1)
    (tmp_path / "d.json").write_text(text)
    with pytest.raises(ProcmodError, match=r"d.json: .*no-such-model"):
        load_derivation(tmp_path / "d.json", get_model)


def _partial_root(ctx, n):
    ctx.sample("x", Normal(0, 1))
    ctx.sample("x", Normal(0, 1))


def _model(root, root_args=lambda p: (), new_output=None):
    import functools

    from procmod.core import Model
    from toy_models import canvas
    rule = functools.partial(root, n=1) if root is _partial_root else root
    return Model("mistakes", "a user's model with a bug", rule, root_args, new_output or canvas)


@pytest.mark.parametrize("root, root_args, new_output, message", [
    # each of these was an AttributeError or TypeError from inside procmod, some raised
    # while procmod built its own message
    (_partial_root, None, None, r"rule '_partial_root' .*uses the name 'x' twice"),
    (lambda ctx: ctx.spawn("c", 42), None, None, r"rule '<lambda>' at / spawns 42 at site 'c', which is not a rule"),
    (lambda ctx: ctx.sample("x", 3.0), None, None, r"rule '<lambda>' at / samples 'x' from 3.0, which is not a "
                                                   "distribution"),
    (lambda ctx: ctx.emit("hello"), None, None, r"rule '<lambda>' at / emits 'hello', which the model's output "
                                                "cannot draw"),
    (lambda ctx: None, lambda p: 1.5, None, r"root_args returned 1.5, not a tuple"),
    (lambda ctx: None, None, lambda p: None, r"new_output returned None, not an output"),
])
def test_bugs_in_a_users_model_are_model_errors_that_say_where(root, root_args, new_output, message):
    from procmod.core import ModelError
    model = _model(root, root_args or (lambda p: ()), new_output)
    with pytest.raises(ModelError, match=message):
        run_forward(model, np.random.default_rng(0))


def test_a_model_a_process_pool_cannot_be_sent_is_one_line():
    # a raw PicklingError traceback from concurrent.futures before
    from concurrent.futures import ProcessPoolExecutor

    from procmod.core import Model
    from procmod.geometry import Canvas
    from procmod.infer.forward import forward
    model = Model("lambdas", "rules as lambdas", lambda ctx: ctx.sample("x", Normal(0, 1)), lambda p: (),
                  lambda p: Canvas((-5, 5, -5, 5), 20))
    with ProcessPoolExecutor(1) as pool:
        with pytest.raises(ProcmodError, match="a process pool needs the model's rules.*defined at module level"):
            forward(model, target_from_spec("glyph:a"), executor=pool, budget=Budget(evaluations=4))


def test_a_run_that_cannot_be_saved_writes_no_file(tmp_path, monkeypatch):
    # write_run wrote best.png and best.svg, then failed on best.json (a choice named by an
    # int: now refused as it is made, so a refusal of the serializer stands in for it)
    import procmod.report
    from procmod.core.serialize import DerivationFormatError
    from procmod.geometry import Segment
    from procmod.report import write_run

    def root(ctx):
        x = ctx.sample("x", Normal(0, 1))
        ctx.emit(Segment(x, 0, x, 1, 0.5))

    def refused(derivation):
        raise DerivationFormatError("cannot be saved")

    result = smc(_model(root), target_from_spec("glyph:a"), particles=2)
    monkeypatch.setattr(procmod.report, "derivation_to_dict", refused)
    with pytest.raises(ProcmodError, match="cannot be saved"):
        write_run(result, target_from_spec("glyph:a"), tmp_path / "run")
    assert not (tmp_path / "run").exists()


@pytest.mark.parametrize("emit, message, drawn", [
    (lambda ctx: ctx.emit(__import__("procmod.geometry", fromlist=["Segment"]).Segment(0, 0, float("nan"), 1, 0.5)),
     r"emitted Segment with x1 = nan: it must hold finite numbers", "its coordinates must be finite numbers"),
    (lambda ctx: ctx.emit(__import__("procmod.geometry", fromlist=["Disc"]).Disc(0, 0, -3)),
     r"emitted Disc with radius = -3: a size must be finite and not negative", "its radius at least 0"),
])
def test_geometry_a_file_cannot_hold_is_a_model_error_naming_the_rule(tmp_path, emit, message, drawn):
    # the SVG was written with x2="nan" and r="-3"; the canvas refuses it when it is emitted
    from procmod.report import write_run
    from toy_models import canvas

    def root(ctx):
        ctx.sample("x", Normal(0, 1))
        emit(ctx)

    with pytest.raises(ProcmodError, match="rule 'root' at / emits .*which the model's output cannot draw: .*" + drawn):
        smc(_model(root), target_from_spec("glyph:a"), particles=2)

    class Permissive:  # a user's own output that draws anything: the report still refuses it
        def __init__(self, params=None):
            self.inner = canvas(params)

        def add(self, geometry):
            return 0

        def copy(self):  # a new object, as Output.copy promises (the engines refuse the output itself)
            other = Permissive.__new__(Permissive)
            other.inner = self.inner
            return other

        def __getattr__(self, name):
            if name == "inner":  # (not set yet: no recursion through __getattr__)
                raise AttributeError(name)
            return getattr(self.inner, name)

    result = smc(_model(root, new_output=Permissive), target_from_spec("glyph:a"), particles=2)
    with pytest.raises(ProcmodError, match="rule 'root' at / " + message):
        write_run(result, target_from_spec("glyph:a"), tmp_path / "run")
    assert not (tmp_path / "run").exists()


def test_a_3d_part_beyond_any_scene_is_refused_naming_the_calls_choices(tmp_path):
    """A hand-edited log-scale of 100 made a learned part 1e43 wide: written to a GLB as
    inf vertices (exit 0, trimesh's overflow warnings). A 2D picture draws a far line."""
    from procmod.geometry import Segment
    from procmod.geometry.solid import Box, new_part_bounds, translation
    from procmod.render import write_derivation

    def root(ctx, solid):
        reach = ctx.sample("reach", Normal(0, 1))
        ctx.emit(Box((1, 1, 1), translation(1e13 + reach, 0, 0)) if solid else Segment(0, 0, 1e13 + reach, 1, 0.5))

    made = {solid: run_forward(_model(root, lambda p, s=solid: (s,), new_part_bounds if solid else None),
                               np.random.default_rng(0)) for solid in (True, False)}
    with pytest.raises(ProcmodError, match=r"rule 'root' at / emitted Box with transform = .*: it is beyond "
                                           r"\+-1e\+12.*or the call's choices \(reach = "):
        write_derivation(made[True], tmp_path / "far.glb", 64)
    assert not (tmp_path / "far.glb").exists()
    write_derivation(made[False], tmp_path / "far.svg", 64)


def test_a_part_of_nan_size_against_a_volume_names_the_rule_not_the_targets_scale():
    from procmod.core import Model
    from procmod.geometry.solid import Box
    from procmod.geometry.voxel import VoxelGrid
    from procmod.targets import Volume

    def root(ctx):
        ctx.sample("x", Normal(0, 1))
        ctx.emit(Box((1.0, float("nan"), 1.0)))

    grid = VoxelGrid((0.0, 0.0, 0.0), 0.5, (4, 4, 4))
    target = Volume(grid, [(np.ones(grid.shape, bool), 1.0, -1.0)])
    model = Model("nan3d", "a 3D bug", root, lambda p: (), get_model("spaceship").new_output_from)
    with pytest.raises(ProcmodError, match=r"rule 'root' at / emits Box.*size must be three sizes of at least 0"):
        smc(model, target, particles=2)


def test_what_float_takes_and_what_drew_before_is_still_accepted():
    # a review of the checks above: each of these worked before them
    from fractions import Fraction

    from procmod.core import GaussianMixture, TruncatedNormal, Uniform
    from procmod.geometry.solid import Cylinder
    from procmod.render import write_derivation
    Categorical([1, 1], labels=(0.5, 1.5))
    Categorical([1, 1], labels=(np.False_, np.True_))
    Uniform(np.array(0.0), np.array(1.0))
    Uniform(Fraction(1, 2), 1)
    TruncatedNormal(np.array(0.0), 1.0, -1, 1)
    TruncatedNormal(0.0, 1.0, 0.0, float("inf"))
    GaussianMixture([1], [np.array(0.0)], [1.0])

    def pointing_down(ctx):
        ctx.sample("x", Normal(0, 1))
        ctx.emit(Cylinder(0.5, -2.0))  # along -z

    model = _model(pointing_down, lambda p: np.array([]), get_model("spaceship").new_output_from)  # any iterable
    write_derivation(run_forward(model, np.random.default_rng(0)), Path(tempfile.mkdtemp()) / "down.obj", 64)



def test_load_derivation_takes_the_model_itself(tmp_path):
    vines = get_model("vines")
    path = tmp_path / "d.json"
    made = run_forward(vines, np.random.default_rng(2))
    save_derivation(made, path)
    assert load_derivation(path, vines).choice_map() == made.choice_map()  # was "'Model' object is not callable"
    with pytest.raises(ProcmodError, match="a derivation of model 'vines', not 'chain'"):
        load_derivation(path, get_model("chain"))
    with pytest.raises(ProcmodError, match="resolve_model must be the Model or a function"):
        load_derivation(path, "vines")


def test_numpy_defaults_of_a_models_parameters_are_plain_numbers(tmp_path):
    # a saved derivation failed on np.int64 (not JSON), and a numpy default turned the type
    # checks of configure off (n="abc" was taken)
    from procmod.core import InvalidArgumentError, Model, Normal, run_forward, save_derivation
    from procmod.geometry import Canvas, Segment

    def rule(ctx, n, w):
        x = ctx.sample("x", Normal(0.0, 1.0))
        ctx.emit(Segment(x, 0.0, x, float(n), w[0]))

    model = Model("np-params", "numpy defaults", rule, lambda p: (p["n"], p["w"]),
                  lambda p: Canvas((-5, 5, -5, 5), 20), params={"n": np.int64(3), "w": (np.float32(0.5), 1.0)})
    assert model.params == {"n": 3, "w": (0.5, 1.0)} and type(model.params["n"]) is int
    assert type(model.params["w"][0]) is float
    save_derivation(run_forward(model, np.random.default_rng(0)), tmp_path / "d.json")
    with pytest.raises(InvalidArgumentError, match="parameter n must be an integer"):
        model.configure(n="abc")


def test_whole_numbers_stay_whole_except_a_pictures_start_and_direction():
    from procmod.core import InvalidArgumentError, Model
    from procmod.geometry import Canvas

    def rule(ctx, *args):
        pass

    canvas = lambda p: Canvas((-5, 5, -5, 5), 20)  # noqa: E731
    counts = Model("counts", "", rule, lambda p: (), canvas, params={"counts": [3, 2]})
    with pytest.raises(InvalidArgumentError, match=r"parameter counts\[0\] must be an integer, got 2.5"):
        counts.configure(counts=[2.5, 2])  # (it reached range() in the model's code)
    # a start of [1, 1] may be a grid cell: kept as written (widened at construction, it
    # reached the model's range() as floats)
    placed = Model("placed", "", rule, lambda p: (), canvas, params={"start": [0, 1], "direction": [0, -1]})
    assert placed.params == {"start": [0, 1], "direction": [0, -1]}
    # they take a picture's real numbers (refused as "must be an integer"), and whole ones stay whole
    moved = placed.configure(start=[0.375, 0.9], direction=[-0.05, -1.0])
    assert moved.params == {"start": [0.375, 0.9], "direction": [-0.05, -1.0]}
    assert placed.configure(start=[1, 0]).params["start"] == [1, 0]
    # a namedtuple keeps its kind when its numpy numbers become Python's
    import collections
    point = collections.namedtuple("Point", "x y")
    named = Model("np-named", "", rule, lambda p: (), canvas, params={"start": point(np.float64(0.5), 1.0)})
    assert named.params["start"] == point(0.5, 1.0) and isinstance(named.params["start"], point)


# ---- h57: a researcher's own proposer, GA parts, targets and outputs -----------------------

def _sum_model():
    from toy_models import MIX
    return MIX


class _FixedProposer:
    """Draws from the prior and says log q is ``log_q`` (``"prior"``: the prior's own)."""

    def __init__(self, log_q):
        self.log_q = log_q

    def propose(self, ctx, name, dist, rng):
        value = dist.sample(rng)
        return value, dist.log_prob(value) if self.log_q == "prior" else self.log_q


@pytest.mark.parametrize("log_q", [float("nan"), float("inf"), -float("inf"), None, np.array([-1.0]), True])
def test_a_proposer_of_ones_own_runs_and_its_bad_log_q_is_one_line(log_q):
    """smc took only a Guide; a proposer's NaN log q made every weight NaN without a word,
    +inf zeroed every weight (the note blamed the target), None was a TypeError inside."""
    from toy_models import SumTarget

    result = smc(_sum_model(), SumTarget(1.0, 1.0), particles=20, seed=0, guide=_FixedProposer("prior"))
    assert result.engine == "smc+guide" and result.settings["guide"] == "_FixedProposer"
    assert np.isfinite(result.log_marginal_likelihood)
    with pytest.raises(InvalidArgumentError, match=r"_FixedProposer.propose returned log q"):
        smc(_sum_model(), SumTarget(1.0, 1.0), particles=20, seed=0, guide=_FixedProposer(log_q))
    with pytest.raises(InvalidArgumentError, match=r"the class _FixedProposer \(give an instance of it\)"):
        smc(_sum_model(), SumTarget(1.0, 1.0), particles=20, seed=0, guide=_FixedProposer)


def test_the_ga_parts_refuse_what_they_cannot_use_in_one_line():
    from procmod.core import run_forward
    from procmod.infer.ga import crossover, grow, mutate, roulette_wheel, tournament
    from procmod.infer.ga.genome import Genome

    d = run_forward(get_model("tree"), np.random.default_rng(0))
    rng = np.random.default_rng(0)
    assert mutate(Genome(d), rng, (13.5, 13.5, 3.0)) is not None  # ga()'s own three weights (an IndexError)
    for call, message in ((lambda: grow(d, rng), "grow takes a Genome"),
                          (lambda: crossover(Genome(d), d, rng), "crossover takes a Genome"),
                          (lambda: mutate(Genome(d), rng, (-1, 0, 0, 5)), "non-negative weights"),
                          (lambda: roulette_wheel([]), "population of one or more"),
                          (lambda: tournament(5, 0, rng), "entrants")):
        with pytest.raises(InvalidArgumentError, match=message):
            call()


@pytest.mark.parametrize("engine", ["forward", "ga", "mcmc"])
def test_an_executor_or_progress_of_the_wrong_kind_is_one_line(engine):
    from procmod.infer import ENGINES
    from toy_models import SumTarget

    with pytest.raises(InvalidArgumentError, match="executor must be"):
        ENGINES[engine](_sum_model(), SumTarget(1.0, 1.0), seed=0, budget=Budget(evaluations=20), executor=object())
    with pytest.raises(InvalidArgumentError, match="progress must be a function"):
        ENGINES[engine](_sum_model(), SumTarget(1.0, 1.0), seed=0, budget=Budget(evaluations=20), progress=3)


@pytest.mark.parametrize("engine", ["forward", "ga", "mcmc"])
def test_a_target_that_rules_out_everything_says_so_and_write_run_refuses_in_one_line(engine, tmp_path):
    """best None and no note; write_run then failed with an AttributeError."""
    from procmod.infer import ENGINES
    from procmod.infer.common import NO_FINITE_SCORE_NOTE
    from procmod.report import write_run
    from toy_models import SumTarget

    class Never(SumTarget):
        def score(self, output):
            return -float("inf")

        def log_likelihood(self, output):
            return -float("inf")

    result = ENGINES[engine](_sum_model(), Never(0.0, 1.0), seed=0, budget=Budget(evaluations=30))
    assert result.best is None and NO_FINITE_SCORE_NOTE in result.notes
    with pytest.raises(InvalidArgumentError, match="scored -inf"):
        write_run(result, Never(0.0, 1.0), tmp_path / "run")


def test_write_run_takes_a_target_without_a_name_and_refuses_a_2d_output_that_is_no_canvas(tmp_path):
    from procmod.core import Model, Output, Target
    from procmod.geometry import Canvas, Segment
    from procmod.infer import forward
    from procmod.report import write_run

    def line(ctx):
        ctx.emit(Segment(-5.0, 0.0, ctx.sample("x", Normal(0.0, 1.0)), 5.0, 0.5))

    class Unnamed(Target):  # the README's contract names no 'name'
        def configure(self, model):
            return model

        def new_output(self, model):
            return model.new_output()

        def score(self, output):
            return float(output.pixels.mean())

        def log_likelihood(self, output):
            return 0.0

        def display_mask(self, width):
            return None

    model = Model("line", "", line, lambda p: (), lambda p: Canvas((-6, 6, -6, 6), 32))
    result = forward(model, Unnamed(), particles=3, seed=0)
    assert write_run(result, Unnamed(), tmp_path / "run", size=32).exists()

    class Flat2D(Output):  # "2" for an output of one's own: renderers read a Canvas's viewport
        dimension = 2

        def add(self, geometry):
            return 0

        def copy(self):
            return Flat2D()

    class Anything(Unnamed):
        def new_output(self, model):
            return Flat2D()

        def score(self, output):
            return 0.0

    flat = Model("flat", "", line, lambda p: (), lambda p: Flat2D())
    with pytest.raises(InvalidArgumentError, match="cannot render: dimension 2 is a procmod Canvas"):
        write_run(forward(flat, Anything(), particles=3, seed=0), Anything(), tmp_path / "flat", size=32)


def _one_choice_model(name, dist_of=lambda: Normal(0.0, 1.0), site=None):
    """A model of one call that makes the choice ``name`` (and spawns at ``site``)."""
    from procmod import Model
    from procmod.geometry import Canvas, Segment

    def rule(ctx):
        x = ctx.sample(name, dist_of())
        ctx.emit(Segment(0.0, 0.0, float(x), 1.0, 0.5))
        if site is not None:
            ctx.spawn(site, leaf)

    def leaf(ctx):
        pass

    return Model("one-choice", "one choice", rule, root_args=lambda p: (),
                 new_output_from=lambda p: Canvas((-3, 3, -3, 3), 20), rules=(rule, leaf))


@pytest.mark.parametrize("engine", ["forward", "ga", "mcmc"])
def test_a_choice_or_site_that_is_no_string_is_refused_where_it_is_made(engine):
    """An int choice name ran every engine and was refused only when the derivation was
    saved: `procmod infer --engine ga` lost its whole budget's run to it."""
    from procmod.core.errors import ModelError
    from procmod.infer import ga, mcmc

    target = target_from_spec("glyph:a")
    for model, what in ((_one_choice_model(3), "names a choice 3 .int."),
                        (_one_choice_model(("t", 1)), "names a choice .*tuple"),
                        (_one_choice_model(["a"]), "names a choice .*list"),  # unhashable: a TypeError (h76)
                        (_one_choice_model("x", site=7), "names a spawn site 7 .int.")):
        with pytest.raises(ModelError, match=what):
            if engine == "forward":
                run_forward(model, np.random.default_rng(0))
            elif engine == "ga":
                ga(model, target, population=4, budget=Budget(generations=1), seed=0)
            else:
                mcmc(model, target, init_particles=0, budget=Budget(evaluations=5), seed=0)
    run_forward(_one_choice_model(np.str_("x")), np.random.default_rng(0))  # a str all the same


@pytest.mark.parametrize("engine", ["ga", "mcmc"])
def test_a_choice_from_no_distribution_is_named_under_every_engine(engine):
    """Forward sampling and SMC named it; GA and MCMC from forward samples replay under a
    choice map, where it was an AttributeError blamed on the model's own code."""
    from procmod.core.errors import ModelError
    from procmod.infer import ga, mcmc

    model, target = _one_choice_model("x", dist_of=lambda: 0.5), target_from_spec("glyph:a")
    with pytest.raises(ModelError, match="samples 'x' from 0.5, which is not a distribution"):
        if engine == "ga":
            ga(model, target, population=4, budget=Budget(generations=1), seed=0)
        else:
            mcmc(model, target, init_particles=0, budget=Budget(evaluations=5), seed=0)


@pytest.mark.parametrize("kwargs, message", [
    ({"name": None}, "a model's name must be a non-empty string"),
    ({"name": 42}, "a model's name must be a non-empty string"),
    ({"name": " "}, "a model's name must be a non-empty string"),
    ({"params": [1, 2]}, "params must be a dict of parameter names"),
    ({"params": {1: 2}}, "params must be a dict of parameter names"),
])
def test_a_model_with_no_name_or_params_that_are_no_dict_is_refused_when_made(kwargs, message):
    """Model(name=None) ran every engine and failed saving its derivation with an
    AttributeError; params=[1, 2] was an AttributeError when made."""
    from procmod import Model
    from procmod.core.errors import ModelError

    fields = {"name": "m", "description": "", "root": lambda ctx: None, "root_args": lambda p: (),
              "new_output_from": lambda p: None, **kwargs}
    with pytest.raises(ModelError, match=message):
        Model(**fields)


def test_a_target_spec_may_be_a_path():
    """target_from_spec(Path(...)) said a spec may be a file path, refusing one."""
    scene = Path(__file__).resolve().parents[1] / "scenes" / "tree_heart"
    assert type(target_from_spec(scene)) is type(target_from_spec(str(scene)))


class _TotalOutput:
    """An Output of the protocol, no subclassing: the sum of what is emitted."""
    dimension = 0
    supports_removal = False
    supports_part_cache = False

    def __init__(self):
        self.total = 0.0

    def add(self, geometry):
        self.total += float(geometry)

    def copy(self):
        other = type(self)()
        other.total = self.total
        return other


class _TotalTarget:
    """A Target of the protocol, no subclassing, without display_mask (the protocol's
    default says None)."""
    name = "sum"
    exact_removal = has_mask = has_overlay = False

    def __init__(self, output=_TotalOutput):
        self.output = output

    def configure(self, model):
        return model

    def new_output(self, model):
        return self.output()

    def score(self, output):
        return -abs(output.total - 1.0)

    def log_likelihood(self, output):
        return -(output.total - 1.0) ** 2


class _Value(float):
    pass


def _uniform_model():
    from procmod import Model, Uniform

    def root(ctx):
        ctx.emit(_Value(ctx.sample("u", Uniform(0.0, 1.0))))

    return Model("sum", "one uniform", root, root_args=lambda p: (), new_output_from=lambda p: _TotalOutput())


def test_protocol_objects_of_ones_own_missing_a_method_are_named_or_defaulted(tmp_path):
    """h82: an Output without copy() passed the declared-protocol check and every engine
    ended in an AttributeError; a Target without display_mask() ran every engine, then the
    report failed on it (the protocol's default is None)."""
    from procmod.infer.ga import ga
    from procmod.report import write_run

    class NoCopy(_TotalOutput):
        copy = None

    with pytest.raises(ProcmodError, match=r"\(NoCopy\) has no method copy that procmod.core.Output requires"):
        smc(_uniform_model(), _TotalTarget(NoCopy), particles=3, seed=0)
    class Cover:  # a 2D target of the protocol, no subclassing, without display_mask
        name = "cover"
        exact_removal = has_mask = has_overlay = False

        def configure(self, model):
            return model

        def new_output(self, model):
            return model.new_output()

        def score(self, output):
            return float(np.count_nonzero(output.pixels)) / output.pixels.size

        def log_likelihood(self, output):
            return 20.0 * self.score(output)

    model = get_model("vines")
    result = ga(model, Cover(), population=4, budget=Budget(generations=1), seed=0)
    write_run(result, Cover(), tmp_path / "run")
    assert (tmp_path / "run" / "report.html").is_file()


def test_a_proposal_outside_its_choices_support_is_refused():
    """h82: a proposer returning 5.0 for a Uniform(0, 1) choice made every particle weigh
    nothing, and the note blamed the target."""
    class OutOfSupport:
        def propose(self, ctx, name, dist, rng):
            return 5.0, 0.0

    with pytest.raises(InvalidArgumentError, match="returned the value 5.0, outside the support of Uniform"):
        smc(_uniform_model(), _TotalTarget(), particles=3, seed=0, guide=OutOfSupport())


def test_a_json_path_with_a_nul_is_one_line_of_the_callers_error():
    from procmod.core.io import read_json
    from procmod.core.errors import DerivationFormatError

    with pytest.raises(DerivationFormatError, match="has a NUL character in its name"):
        read_json("a\0b.json")


@pytest.mark.parametrize("call, message", [
    (lambda ga, rng: ga.tournament("5", 2, rng), "tournament needs a population"),
    (lambda ga, rng: ga.tournament(5, 2.5, rng), "tournament needs a population"),
    (lambda ga, rng: ga.roulette(np.array([]), rng), "roulette takes the wheel of a population of one or more"),
    (lambda ga, rng: ga.roulette_wheel("abc"), "roulette_wheel takes the scores of a population"),
    (lambda ga, rng: ga.elite_count(1.5, 10), "elitism is the fraction of the population kept"),
    (lambda ga, rng: ga.grow(ga.Genome(run_forward(get_model("vines"), rng)), rng, count=-3), "grow turns on count"),
    (lambda ga, rng: ga.Genome(None), "a Genome wraps a derivation"),
])
def test_the_ga_operators_name_their_misuse(call, message):
    """h82: a string as a tournament's size, an empty wheel, grow(count=-3) or a Genome of
    nothing was a raw TypeError, IndexError, ValueError or AttributeError; elitism 1.5 kept
    15 of 10."""
    from types import SimpleNamespace

    from procmod.infer.ga import Genome, elite_count, grow, roulette, roulette_wheel, tournament

    ga = SimpleNamespace(Genome=Genome, elite_count=elite_count, grow=grow, roulette=roulette,
                         roulette_wheel=roulette_wheel, tournament=tournament)
    with pytest.raises(InvalidArgumentError, match=message):
        call(ga, np.random.default_rng(0))


def test_the_ga_operators_name_a_missing_generator_and_plain_derivations():
    """h82: an operator given rng=None (or a seed) raised an AttributeError wherever it first
    drew; breed given derivations instead of scored individuals, and the Evaluator given
    derivations instead of jobs, raised an AttributeError and a TypeError."""
    from procmod.infer import Budget, Tracker
    from procmod.infer.ga import (Evaluator, Genome, Genomes, alter, breed, crossover, cut, grow,
                                  initial_population, mutate, nudge, roulette, roulette_wheel, tournament)
    from procmod.targets import ShapeMatch, TargetImage

    model, rng = get_model("vines"), np.random.default_rng(0)
    derivation = run_forward(model, rng)
    genome = Genome(derivation)
    mask = np.zeros((50, 50), bool)
    mask[10:45, 22:28] = True
    target = ShapeMatch(TargetImage("bar", mask, (0.5, 0.9), (0, -1)))
    evaluate = Evaluator(model, target, None, Tracker(Budget()))
    # grow, cut and crossover of this vine return before drawing: the check is up front
    for name, call in (("grow", lambda r: grow(genome, r)), ("cut", lambda r: cut(genome, r)),
                       ("alter", lambda r: alter(genome, r)), ("nudge", lambda r: nudge(genome, r)),
                       ("mutate", lambda r: mutate(genome, r, (1, 1, 1))),
                       ("crossover", lambda r: crossover(genome, genome, r)),
                       ("roulette", lambda r: roulette(roulette_wheel([1.0, 2.0]), r)),
                       ("tournament", lambda r: tournament(5, 2, r)),
                       ("initial_population", lambda r: initial_population(evaluate, 2, 2, r, Tracker(Budget())))):
        for bad in (None, 7):
            with pytest.raises(InvalidArgumentError, match=rf"^{name}: rng must be a numpy Generator"):
                call(bad)
    breeding = dict(n_elite=0, k=2, mutation=0.3, split=(1, 1, 1), nudge_step=0.1, max_retries=3)
    with pytest.raises(InvalidArgumentError, match="breed takes the population as scored individuals"):
        breed([derivation, derivation], Genomes(), rng, **breeding)
    with pytest.raises(InvalidArgumentError, match="^breed: rng must be"):
        breed(evaluate([({}, 1, False), ({}, 2, False)]), Genomes(), None, **breeding)
    with pytest.raises(InvalidArgumentError, match=r"the Evaluator takes a list of jobs \(choices, seed"):
        evaluate([derivation])
    assert len(evaluate([[derivation.choice_map(), 3, False]])) == 1  # a job as a list is still a job
    from procmod.infer.ga import LazyRng  # the GA's own lazy generator passes (h86)
    assert tournament(5, 2, LazyRng(3)) in range(5) and grow(genome, LazyRng(3)) is None


def test_a_json_integer_of_more_digits_than_python_reads_is_named(tmp_path):
    """h90: the message ended in Python's own advice, cut off ("use sys.set...")."""
    from procmod.core.io import read_json
    from procmod.core.serialize import DerivationFormatError

    (tmp_path / "big.json").write_text('{"a": ' + "9" * 5000 + "}")
    with pytest.raises(DerivationFormatError, match="an integer of more than 4300 digits") as info:
        read_json(tmp_path / "big.json")
    assert "sys." not in str(info.value)


def test_a_target_or_model_class_given_for_an_instance_and_other_slips_are_one_line():
    """Forgetting the () of a target made every engine fail inside with "configure()
    missing 1 required positional argument"; a Canvas's bad size or viewport was a raw
    ValueError (a huge one numpy's MemoryError); set_maybe(on="no") grew the subtree; a
    maybe's probability of 1.5 was refused without the rule or its address; mcmc's
    workers=None read "got null"."""
    from toy_models import SumTarget

    from procmod.core import Model, set_maybe
    from procmod.geometry import Canvas
    from procmod.infer import forward, ga, mcmc

    model = _sum_model()
    for engine, kwargs in ((smc, {"particles": 4}), (forward, {"particles": 4}), (ga, {"population": 4}),
                           (mcmc, {})):
        with pytest.raises(InvalidArgumentError, match=r"got the class SumTarget \(give an instance of it: "
                                                       r"SumTarget\(...\)\)"):
            engine(model, SumTarget, **kwargs)
    with pytest.raises(InvalidArgumentError, match=r"got the class Model \(give an instance of it"):
        smc(Model, SumTarget(1.0, 1.0), particles=4)
    with pytest.raises(InvalidArgumentError, match=r"workers must be a positive integer, got None$"):
        mcmc(model, SumTarget(1.0, 1.0), workers=None)
    with pytest.raises(InvalidArgumentError, match=r"canvas size must be positive, got 0x0"):
        Canvas((-1, 1, -1, 1), 0)
    with pytest.raises(InvalidArgumentError, match=r"the canvas viewport is \(xmin, xmax, ymin, ymax\) with xmin"):
        Canvas((1, -1, 0, 2), 40)
    with pytest.raises(ProcmodError, match=r"a 1000000x1000000 canvas would need at least"):
        Canvas((-1, 1, -1, 1), 10**6)

    def grow(ctx, depth=0):
        ctx.maybe("more", 0.5, grow, depth + 1) if depth < 3 else None

    tree = Model("grow", "x", grow, lambda params: (), lambda params: Canvas((-1, 1, -1, 1), 8))
    derivation = run_forward(tree, np.random.default_rng(1))
    with pytest.raises(InvalidArgumentError, match=r"on must be True \(grow the subtree\) or False \(cut it\), "
                                                   r"got 'no'"):
        set_maybe(tree, derivation, (), "more", "no", np.random.default_rng(0))

    def unsure(ctx):
        ctx.maybe("coin", 1.5, unsure)

    bad = Model("unsure", "x", unsure, lambda params: (), lambda params: Canvas((-1, 1, -1, 1), 8))
    with pytest.raises(ProcmodError, match=r"rule 'unsure' at .* calls maybe\('coin', 1.5, ...\): its probability "
                                           r"must be a number from 0 to 1"):
        run_forward(bad, np.random.default_rng(0))
