"""A model author's likely mistakes end in one ModelError naming the rule, not in a hang,
a raw AttributeError or a silently wrong result (an adversarial pass with hand-written
models found each of these)."""

import functools
import json
import math
import re

import numpy as np
import pytest

from procmod.core import Categorical, Model, ModelError, Normal, load_derivation, run_forward, save_derivation
from procmod.core.errors import DerivationFormatError
from procmod.core.runtime import rule_name, start, step
from procmod.data import target_from_spec
from procmod.geometry import Canvas, Disc, Ellipse, Polygon, Segment
from procmod.geometry.solid import Box, Cylinder, Mesh, new_part_bounds, translation
from procmod.infer.smc import smc, sosmc
from procmod.models import get_model


def _canvas(params):
    return Canvas((-12, 12, -22, 2), 50)


def _model(root, name="mine", output=_canvas, **limits):
    return Model(name, "a user's model", root, root_args=lambda p: (), new_output_from=output, **limits)


def _bush(ctx, x=0.0, y=0.0, angle=-math.pi / 2):
    """Forgot a depth limit: 1.4 children a call, so it grows forever with probability ~0.8."""
    angle = ctx.sample("angle", Normal(angle, 0.4))
    x1, y1 = x + math.cos(angle), y + math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, 0.3))
    ctx.maybe("left", 0.7, _bush, x1, y1, angle + 0.5)
    ctx.maybe("right", 0.7, _bush, x1, y1, angle - 0.5)


def test_a_model_that_never_stops_growing_is_stopped_at_its_depth_limit():
    bush = _model(_bush, "bush")
    with pytest.raises(ModelError, match=r"model 'bush' went more than 10,000 levels of spawns deep \(rule '_bush'.*"
                                         r"Model\(max_depth=...\)"):
        run_forward(bush, np.random.default_rng(0))
    # ... also under an engine (which would otherwise grow every particle until memory ran out)
    with pytest.raises(ModelError, match="levels of spawns deep"):
        smc(bush, target_from_spec("glyph:Y"), particles=4, seed=0)
    # a deep model that is meant to be so raises the limit
    def chain(ctx, i=0):
        ctx.emit(Disc(0, -10, 0.5))
        if i < 1500:
            ctx.spawn("next", chain, i + 1)
    with pytest.raises(ModelError, match="more than 1,000 levels"):
        run_forward(_model(chain, max_depth=1000), np.random.default_rng(0))
    assert run_forward(_model(chain), np.random.default_rng(0)).n_nodes == 1501  # the default is 10,000


def test_a_model_that_makes_too_many_calls_is_stopped_at_max_calls():
    def fan(ctx):
        for i in range(30):
            ctx.spawn(f"leaf{i}", lambda c: c.emit(Disc(0, -10, 0.5)))
    with pytest.raises(ModelError, match=r"more than 20 rule calls in one derivation .*Model\(max_calls=...\)"):
        run_forward(_model(fan, max_calls=20), np.random.default_rng(0))
    assert run_forward(_model(fan, max_calls=31), np.random.default_rng(0)).n_nodes == 31


def test_smc_refuses_a_call_queuing_more_calls_than_max_calls_at_once():
    """SMC runs one call of each particle a step: a root queuing 5,001 children under
    max_calls 5,000 was refused only after every particle had run 5,000 steps (79 s and
    1 GB with the default particles; forward sampling took 1 s), whatever the budget.
    The queued calls count: it is refused at the root's first step."""
    def wide(ctx):
        for i in range(5001):
            ctx.spawn(f"leaf{i}", lambda c: c.emit(Disc(0, -10, 0.5)))
    model = _model(wide, max_calls=5000)
    target = target_from_spec("glyph:Y")
    for engine in (smc, sosmc):
        with pytest.raises(ModelError, match=r"queued more than 5,000 rule calls .*5,001 calls waiting after 1 made"):
            engine(model, target, particles=20, seed=0)
    wide_ok = _model(lambda ctx: [ctx.spawn(f"leaf{i}", lambda c: c.emit(Disc(0, -10, 0.5))) for i in range(4999)],
                     max_calls=5000)
    assert run_forward(wide_ok, np.random.default_rng(0)).n_nodes == 5000


def test_emits_of_one_call_are_limited():
    def spiral(ctx):
        i = 0
        while True:  # a loop that never ends
            ctx.emit(Disc(math.cos(i), -10 + math.sin(i), 0.3))
            i += 1
    for run in (lambda m: run_forward(m, np.random.default_rng(0)),
                lambda m: smc(m, target_from_spec("glyph:o"), particles=2, seed=0)):
        with pytest.raises(ModelError, match=r"rule 'spiral' at / emits more than 50 times in one call.*"
                                             r"Model\(max_call_emits=...\)"):
            run(_model(spiral, max_call_emits=50))

    def stipple(ctx):  # a long loop that ends: 12,000 dots, under the default 20,000
        for i in range(12_000):
            ctx.emit(Disc(-5 + (i % 100) * 0.1, -20 + (i // 100) * 0.15, 0.05))
    assert run_forward(_model(stipple), np.random.default_rng(0)).n_emits == 12_000


def test_emits_of_one_call_under_smc_are_limited_before_the_reruns_take_hours():
    """SMC re-runs a call from its start after each of its emits: a loop that never ends
    took 142 s for 2 particles to reach max_call_emits (20,000), hours at the default 600.
    Under SMC a call may emit max_resumed_emits times (default 500); straight through,
    max_call_emits; a model that means a long loop raises the first."""
    def stipple(ctx):  # 1,500 dots in one call
        for i in range(1_500):
            ctx.emit(Disc(-5 + (i % 50) * 0.2, -20 + (i // 50) * 0.5, 0.05))
    assert run_forward(_model(stipple), np.random.default_rng(0)).n_emits == 1_500
    for engine in (smc, sosmc):
        with pytest.raises(ModelError, match=r"rule 'stipple' at / emits more than 500 times in one call under "
                                             r"SMC.*Model\(max_resumed_emits=...\)"):
            engine(_model(stipple), target_from_spec("glyph:o"), particles=2, seed=0)
    result = smc(_model(stipple, max_resumed_emits=2_000), target_from_spec("glyph:o"), particles=2, seed=0)
    assert result.best.n_emits == 1_500
    with pytest.raises(ModelError, match="max_resumed_emits must be a whole number from 1"):
        _model(stipple, max_resumed_emits=0)


def test_choices_of_one_call_are_limited():
    """A loop of choices that never ends ran every engine, its budget unread, until memory
    ran out (~30 MB a second)."""
    def waiting(ctx):
        i = 0
        while not ctx.sample(f"stop{i}", Categorical([1.0, 0.0])):  # a coin that never comes up
            i += 1
        ctx.emit(Disc(0, -10, 1))
    for run in (lambda m: run_forward(m, np.random.default_rng(0)),
                lambda m: smc(m, target_from_spec("glyph:o"), particles=2, seed=0)):
        with pytest.raises(ModelError, match=r"rule 'waiting' at / makes more than 50 random choices in one call.*"
                                             r"Model\(max_call_choices=...\)"):
            run(_model(waiting, max_call_choices=50))

    def many(ctx):  # a long loop that ends: 30,000 choices, under the default 100,000
        ctx.emit(Disc(0, -10, 1 + sum(ctx.sample(f"c{i}", Normal(0, 1e-6)) for i in range(30_000))))
    assert len(run_forward(_model(many), np.random.default_rng(0)).choice_map().raw) == 30_000


def test_a_resolver_that_knows_no_model_is_named(tmp_path):
    chain = get_model("chain")
    path = tmp_path / "d.json"
    save_derivation(run_forward(chain, np.random.default_rng(0)), path)
    with pytest.raises(DerivationFormatError, match=r"resolve_model\('chain'\) returned NoneType, not a procmod "
                                                    "Model"):
        load_derivation(path, {}.get)


def _stale(ctx, i=0):
    ctx.emit(Disc(0, -10 + 2 * i, 1.0))
    if i < 3:
        ctx.maybe("n", 0.9, lambda c, j: _stale(ctx, j), i + 1)  # ctx, not c


def test_a_context_used_outside_its_own_call_is_refused():
    """It made SMC loop forever (each resume paused at once) and forward runs misreport a
    duplicate name."""
    model = _model(_stale)
    message = r"rule '<lambda>' at /n used a context that is not its own"
    with pytest.raises(ModelError, match=message):
        run_forward(model, np.random.default_rng(0))
    derivation, rng = start(model), np.random.default_rng(0)
    with pytest.raises(ModelError, match=message):
        for _ in range(10):  # one step draws the root's disc, the next would loop
            step(derivation, rng)
    with pytest.raises(ModelError, match=message):
        smc(model, target_from_spec("glyph:l"), particles=4, seed=1)


def test_a_generator_or_coroutine_rule_is_refused():
    def generator(ctx):
        ctx.emit(Disc(0, -10, 1.0))
        yield 1

    async def coroutine(ctx):
        ctx.emit(Disc(0, -10, 1.0))
    for rule in (generator, coroutine):
        with pytest.raises(ModelError, match=f"rule '{rule.__name__}' at / returned a generator or coroutine"):
            run_forward(_model(rule), np.random.default_rng(0))


def test_a_model_built_wrong_is_refused_when_built():
    with pytest.raises(ModelError, match="model 'mine': root must be a function, got 42"):
        _model(42)
    with pytest.raises(ModelError, match="model 'mine': max_calls must be a whole number from 1 to 1,000,000,000, "
                                         "got 0"):
        _model(_bush, max_calls=0)
    with pytest.raises(ModelError, match="max_depth must be a whole number .*got true"):
        _model(_bush, max_depth=True)


@pytest.mark.parametrize("primitive, message", [
    (Segment(0, -10, float("nan"), -5, 0.5), "its coordinates must be finite numbers .* and its width at least 0"),
    (Segment(0, -10, 1, -5, -0.5), "its width at least 0"),
    (Segment(0, -10, float("inf"), -5, 0.5), "finite numbers"),
    (Disc(float("nan"), -10, 1.0), "its radius at least 0"),
    (Disc(0, -10, -1.0), "its radius at least 0"),
    (Ellipse(0, -10, float("nan"), 2.0, 1.0), "its length and width at least 0"),
    (Polygon(((0, -10), (1, float("nan")), (0, -9))), "a Polygon's points must be finite numbers"),
])
def test_bad_numbers_on_a_2d_canvas_are_refused_at_the_emit(primitive, message):
    """A NaN drew nothing (and a run's report was refused only at its very end)."""
    with pytest.raises(ModelError, match=r"rule '<lambda>' at / emits .*which the model's output cannot draw: .*"
                                         + message):
        run_forward(_model(lambda ctx: ctx.emit(primitive)), np.random.default_rng(0))


def test_the_refused_part_is_shown_with_its_value_at_fault_whole():
    """Cut at 60 characters of the repr, a Disc with long coordinates was shown as
    `Disc(x=12.803456789012345, y=-10.961234567890123, radius=-0.` (read as radius 0, next
    to "its radius at least 0")."""
    disc = Disc(12.803456789012345, -10.961234567890123, -0.0031234567)
    with pytest.raises(ModelError) as caught:
        run_forward(_model(lambda ctx: ctx.emit(disc)), np.random.default_rng(0))
    assert "emits Disc(x=12.8035, y=-10.9612, radius=-0.00312346, tag='disc'), which" in str(caught.value), \
        str(caught.value)


@pytest.mark.parametrize("part, message", [
    (Disc(0, 0, 1), "a 3D output draws Box, Cylinder and Mesh parts, not Disc .a 2D primitive"),
    (Box((1, 1, 1), translation(float("nan"), 0, 0)), "the part's position or size is not finite"),
    (Box((-1, 1, 1), translation(0, 1, 0)), r"a Box's size must be three sizes of at least 0, got \(-1, 1, 1\)"),
    (Box((1, 1, 1), (1, 2, 3)), "a part's transform must be 16 numbers .*got 3"),
    (Cylinder(-1.0, 2.0, translation(0, 1, 0)), "a Cylinder's radii must be at least 0"),
    (Mesh(np.zeros((3, 3)), np.array([[0, 1, 5]]), translation(0, 0, 0)),
     "a Mesh's face refers to vertex 5, but it has vertices 0 to 2"),
    (Mesh(np.zeros((3, 2)), np.array([[0, 1, 2]]), translation(0, 0, 0)), r"a Mesh needs vertices \(\(x, y, z\)"),
])
def test_parts_a_3d_output_cannot_draw_are_refused_at_the_emit(part, message):
    with pytest.raises(ModelError, match=r"rule '<lambda>' at / emits .*which the model's output cannot draw: .*"
                                         + message):
        run_forward(_model(lambda ctx: ctx.emit(part), output=new_part_bounds), np.random.default_rng(0))


def test_numpy_labels_round_trip(tmp_path):
    def rule(ctx):
        big = ctx.sample("big", Categorical([0.5, 0.5], labels=np.array([True, False])))
        count = ctx.sample("count", Categorical([0.5, 0.5], labels=np.array([2, 3])))
        ctx.emit(Disc(0, -10, (2.0 if big else 1.0) + 0.1 * count))
    model = _model(rule)
    for seed in range(4):
        derivation = run_forward(model, np.random.default_rng(seed))
        assert type(derivation.choice_map()[((), "big")]) is bool
        save_derivation(derivation, tmp_path / "d.json")
        again = load_derivation(tmp_path / "d.json", lambda name: model)
        assert again.choice_map() == derivation.choice_map()


def test_large_finite_coordinates_and_numpy_number_labels_are_kept():
    """The checks refuse what is not finite, not what is merely far away; numpy number
    labels keep their type (a float32 label's arithmetic stays float32)."""
    far = _model(lambda ctx: [ctx.emit(Segment(1e300, 1e300, 1e300, 1e300, 0.5)), ctx.emit(Disc(1e300, 0, 1.0)),
                              ctx.emit(Ellipse(0, 0, 1e301, 1.0, 1.0))])
    assert run_forward(far, np.random.default_rng(0)).n_emits == 3
    boxes = _model(lambda ctx: [ctx.emit(Box((1, 2, 3), np.eye(4))), ctx.emit(Cylinder(1.0, 2.0, np.eye(4)))],
                   output=new_part_bounds)  # a 4x4 array as a transform, as matrix() reads it
    assert run_forward(boxes, np.random.default_rng(0)).n_emits == 2
    label = Categorical([1, 1], labels=np.array([0.1, 0.2], np.float32)).sample(np.random.default_rng(0))
    assert type(label) is np.float32


def test_a_partial_rule_is_named_by_its_function():
    """Guides name sites by rule; a functools.partial has no __name__ (training called its
    traces damaged)."""
    def piece(ctx, x, kind="thin"):
        pass
    assert rule_name(functools.partial(piece, kind="thick")) == "piece"
    assert rule_name(functools.partial(functools.partial(piece), 1.0)) == "piece"


def test_a_users_model_named_like_a_built_in_one_is_not_replayed_by_it(tmp_path):
    """procmod render drew the built-in chain's picture from a user's 'chain' run."""
    def chain(ctx, x=0.0, y=-2.0, angle=-math.pi / 2):  # the built-in's names, other geometry
        angle = ctx.sample("angle", Normal(angle, math.pi / 8))
        x1, y1 = x + 2 * math.cos(angle), y + 2 * math.sin(angle)
        ctx.emit(Disc(x1, y1, 1.5))
        ctx.maybe("next", 0.5, chain, x1, y1, angle)
    mine = _model(chain, "chain")
    save_derivation(run_forward(mine, np.random.default_rng(3)), tmp_path / "best.json")
    with pytest.raises(DerivationFormatError, match=r"best.json: was made by model 'chain', whose root rule is "
                                                  r"test_model_mistakes:.*chain, but the model here, 'chain', starts "
                                                  r"at procmod.models.chain:chain: another model of the same name"):
        load_derivation(tmp_path / "best.json", get_model)
    assert load_derivation(tmp_path / "best.json", lambda name: mine).n_emits >= 1
    # the same script's rule, run as __main__ when saved and imported when loaded
    text = (tmp_path / "best.json").read_text()
    (tmp_path / "main.json").write_text(text.replace('"test_model_mistakes:', '"__main__:'))
    assert load_derivation(tmp_path / "main.json", lambda name: mine).n_emits >= 1
    # ... or saved from a package's module and loaded from the module itself
    (tmp_path / "pkg.json").write_text(text.replace('"test_model_mistakes:', '"pkg.mymodels:'))
    assert load_derivation(tmp_path / "pkg.json", lambda name: mine).n_emits >= 1


MODEL_FILE = """
import math
from procmod import Model, Normal
from procmod.geometry import Canvas, Segment

def plant(ctx, x, y, angle, depth):
    angle = ctx.sample("angle", Normal(angle, 0.3))
    x1, y1 = x + 2 * math.cos(angle), y + 2 * math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, 0.6))
    if depth < 5:
        ctx.maybe("left", 0.6, plant, x1, y1, angle + 0.4, depth + 1)
        ctx.maybe("right", 0.6, plant, x1, y1, angle - 0.4, depth + 1)

def root_args(p):
    return (0.0, 0.0, -math.pi / 2, 0)

def canvas(p):
    return Canvas((-12, 12, -22, 2), 50)

PLANT = Model("plant", "a plant", plant, root_args=root_args, new_output_from=canvas)

if __name__ == "__main__":
    raise SystemExit("the file's main block does not run")
"""


def test_the_command_line_runs_a_model_of_the_users_own_python_file(tmp_path, capsys):
    """It refused FILE.py, so a model written as plain Python could not use the CLI."""
    from procmod.cli import main

    (tmp_path / "mymodels.py").write_text(MODEL_FILE)
    spec = str(tmp_path / "mymodels.py") + ":PLANT"
    assert main(["sample", spec, "-n", "3", "--out", str(tmp_path / "s")]) == 0
    assert main(["infer", str(tmp_path / "mymodels.py"), "--target", "glyph:Y", "--particles", "20",
                 "--out", str(tmp_path / "r")]) == 0
    capsys.readouterr()
    # render: the derivation names model 'plant', which only the file has
    assert main(["render", str(tmp_path / "r" / "best.json"), "--out", str(tmp_path / "x.png")]) == 2
    assert "for a model of your own, give it: --model FILE.py:NAME" in capsys.readouterr().err
    assert main(["render", str(tmp_path / "r" / "best.json"), "--model", spec, "--out", str(tmp_path / "x.png")]) == 0
    assert (tmp_path / "x.png").is_file()
    # and from Python, with the file imported as a module of its own name
    import importlib.util
    module_spec = importlib.util.spec_from_file_location("mymodels", tmp_path / "mymodels.py")
    module = importlib.util.module_from_spec(module_spec)
    module_spec.loader.exec_module(module)
    assert load_derivation(tmp_path / "r" / "best.json", lambda name: module.PLANT).n_emits >= 1


def test_a_model_file_imports_its_neighbours_and_its_errors_are_one_line(tmp_path, capsys, monkeypatch):
    """A model file importing a module beside it failed (its folder was not on sys.path);
    an exception in its rules while they ran was a traceback."""
    from procmod.cli import main

    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "helper.py").write_text("DEPTH = 5\n")
    (folder / "plants.py").write_text(MODEL_FILE.replace("import math\n", "import math\nfrom helper import DEPTH\n", 1)
                                      .replace("if depth < 5:", "if depth < DEPTH:"))
    monkeypatch.chdir(tmp_path)  # not the file's folder
    assert main(["sample", "models/plants.py:PLANT", "-n", "2", "--out", "s"]) == 0
    (folder / "broken.py").write_text(MODEL_FILE.replace("x1, y1 = x + 2", "x1, y1 = 1 / 0 + x + 2"))
    assert main(["infer", "models/broken.py", "--target", "glyph:Y", "--particles", "4", "--out", "r"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "broken.py, line 8, in plant: ZeroDivisionError: division by zero (an error " \
        "in the model's own code)" in err, err
    assert not (tmp_path / "r").exists()


@pytest.mark.parametrize("engine", ["forward", "smc"])
@pytest.mark.parametrize("line, said", [
    ("import sys; sys.exit(0)", "the model called sys.exit(0) while it ran; a model cannot end procmod's run"),
    ("import sys; sys.exit(5)", "the model called sys.exit(5) while it ran"),
    ("raise SystemExit(type('B', (), {'__repr__': lambda self: 1 / 0})())", "the model called sys.exit(<a B>)"),
    ("next(iter([]))", "StopIteration (an error in the model's own code)"),
    ("raise type('Done', (BaseException,), {})()", "Done (an error in the model's own code)"),
    ("raise type('Odd', (Exception,), {'__str__': lambda self: 1 / 0})()",
     "Odd: (its message could not be shown: its __str__ raised an error)"),
])
def test_a_rule_that_exits_or_raises_oddly_is_one_line_naming_it(tmp_path, capsys, line, said, engine):
    """A rule calling sys.exit(0) ended every engine with status 0, no word and no output;
    a StopIteration (PEP 479 made it a RuntimeError in the forward and GA engines'
    generators), an exception on BaseException of the user's own, and one whose __str__
    fails were tracebacks (h145)."""
    from procmod.cli import main

    (tmp_path / "m.py").write_text(MODEL_FILE.replace("    if depth < 5:", f"    {line}\n    if depth < 5:"))
    code = main(["infer", str(tmp_path / "m.py"), "--target", "glyph:Y", "--engine", engine, "--budget", "20evals",
                 "--out", str(tmp_path / "r")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and "m.py, line 10, in plant: " in err and said in err, err
    assert not (tmp_path / "r").exists()


def test_a_model_file_of_any_suffix_loads(tmp_path):
    """A model file named Plant.PY was an AttributeError traceback: no loader is found for
    the suffix by name (h145)."""
    from procmod.cli import main

    (tmp_path / "Plant.PY").write_text(MODEL_FILE)
    assert main(["sample", str(tmp_path / "Plant.PY"), "-n", "2", "--seed", "1", "--out", str(tmp_path / "s")]) == 0


def test_a_derivation_is_not_replayed_by_another_model_of_the_users(tmp_path):
    """render --model with the wrong model of the same file drew a picture, exit 0."""
    def chain(ctx, x=0.0, y=-2.0, angle=-math.pi / 2):
        angle = ctx.sample("angle", Normal(angle, 0.4))
        ctx.emit(Disc(x + math.cos(angle), y, 1.0))
        ctx.maybe("next", 0.5, chain, x + 1, y - 1, angle)

    def blobs(ctx, x=0.0, y=-2.0, angle=-math.pi / 2):  # the same choice names, another rule
        angle = ctx.sample("angle", Normal(angle, 0.4))
        ctx.emit(Disc(x, y + angle, 2.0))
        ctx.maybe("next", 0.5, blobs, x + 1, y - 1, angle)
    save_derivation(run_forward(_model(chain, "a-model"), np.random.default_rng(1)), tmp_path / "d.json")
    with pytest.raises(DerivationFormatError, match=r"was made by model 'a-model', whose root rule is .*chain, but "
                                                  r"the model here, 'b-model', starts at .*blobs"):
        load_derivation(tmp_path / "d.json", lambda name: _model(blobs, "b-model"))


def test_a_neighbour_file_hidden_by_a_standard_library_module_is_named(tmp_path, capsys):
    """``from types import LENGTH`` with a ``types.py`` beside the model: Python imports its
    own ``types``, and the error had blamed the model file without naming the neighbour."""
    from procmod.cli import main

    (tmp_path / "types.py").write_text("LENGTH = 3.0\n")
    (tmp_path / "m.py").write_text("from types import LENGTH\n" + MODEL_FILE)
    assert main(["sample", str(tmp_path / "m.py"), "-n", "1", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "line 1: running it raised ImportError" in err
    assert "types.py beside it is hidden by Python's own module types: rename it" in err
    # without the neighbour, the plain message
    (tmp_path / "types.py").unlink()
    assert main(["sample", str(tmp_path / "m.py"), "-n", "1", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert "is hidden by" not in err and err.rstrip().endswith("fix the model file")


@pytest.mark.parametrize("content, spec, message", [
    (None, "missing.py", "model file .*missing.py does not exist"),
    ("x = (\n", "m.py", r"m.py, line 1: '\(' was never closed; fix the model file"),
    ("import math\nraise ValueError('no')\n", "m.py", r"m.py, line 2: running it raised ValueError: no"),
    (MODEL_FILE, "m.py:NOPE", r"m.py has no 'NOPE' at its top level \(its Model objects: PLANT\)"),
    (MODEL_FILE, "m.py:math", r"m.py:math is a module, not a procmod Model"),
    ("x = 1\n", "m.py", r"m.py defines no Model at its top level \(a name bound to a procmod Model, e.g. MODEL = .*\); add one$"),
    (MODEL_FILE, "m.py:bad-name", r"'bad-name' is not a Python name; give FILE.py:NAME"),
])
def test_a_model_file_that_cannot_be_used_is_one_line(tmp_path, capsys, content, spec, message):
    from procmod.cli import main

    if content is not None:
        (tmp_path / spec.split(":")[0]).write_text(content)
    assert main(["sample", str(tmp_path / spec), "-n", "1", "--out", str(tmp_path / "s")]) == 2
    err = capsys.readouterr().err
    assert re.search(message, err) and err.count("\n") == 1 and not (tmp_path / "s").exists(), err


def test_a_model_name_whose_file_is_here_is_pointed_to_it(tmp_path, monkeypatch, capsys):
    """'procmod sample mine' beside mine.py: the name is no built-in model, and the file
    it meant is named in the message."""
    from procmod.cli import main

    monkeypatch.chdir(tmp_path)
    (tmp_path / "mine.py").write_text("x = 1\n")
    assert main(["sample", "mine", "--out", str(tmp_path / "o")]) == 2
    assert "unknown model 'mine'" in (err := capsys.readouterr().err) and "give mine.py" in err
    # a derivation naming that model is rendered with --model mine.py:NAME, which it says
    assert main(["sample", "vines", "-n", "1", "--size", "32", "--out", str(tmp_path / "s")]) == 0
    data = json.loads((tmp_path / "s" / "sample_000.json").read_text())
    (tmp_path / "d.json").write_text(json.dumps({**data, "model": "mine"}))
    capsys.readouterr()
    assert main(["render", str(tmp_path / "d.json"), "--out", str(tmp_path / "r.png")]) == 2
    err = capsys.readouterr().err
    assert "give mine.py" not in err and "--model FILE.py:NAME" in err


def test_a_part_whose_tag_is_no_string_is_refused_at_the_emit():
    """A Categorical's index passed as a part's tag ran a whole inference and then ended in a
    traceback while the outputs were written (colour_of: 'int' object has no attribute
    'encode'), and nothing was written."""
    with pytest.raises(ModelError, match=r"whose tag is 5 \(int\): a tag names the part's kind and must be a string"):
        run_forward(_model(lambda ctx: ctx.emit(Box((1, 1, 1), translation(0, 0, 0), 5)), output=new_part_bounds),
                    np.random.default_rng(0))
    with pytest.raises(ModelError, match="must be a string"):
        run_forward(_model(lambda ctx: ctx.emit(Disc(0, -10, 1.0, 3))), np.random.default_rng(0))


def test_a_4x4_array_transform_is_read_by_volume_targets_as_by_everything_else(tmp_path):
    """sample and silhouettes read a part placed by a 4x4 numpy array; a volume target took its
    first 12 values as numbers ("not enough values to unpack (expected 12, got 4)")."""
    from procmod.geometry.voxel import VoxelGrid, VoxelScene

    placed = np.eye(4)
    placed[0, 3] = 0.5
    grid = VoxelGrid((-2.0, -2.0, -2.0), 0.25, (16, 16, 16))
    as_array, as_tuple = VoxelScene(grid), VoxelScene(grid)
    as_array.add(Box((1, 1, 1), placed))
    as_tuple.add(Box((1, 1, 1), translation(0.5, 0, 0)))
    assert as_array.counts.sum() == as_tuple.counts.sum() > 0
    assert np.array_equal(as_array.counts, as_tuple.counts)


def test_a_settle_step_that_returns_no_derivation_of_the_model_is_refused_naming_it():
    """``Model.settle`` (what run_forward does to a finished sample: learned programs set
    it on their examples' ground) must give back a complete derivation of the model: a
    step returning None, or another model's derivation, failed later in whatever read it."""
    def root(ctx):
        ctx.emit(Segment(0.0, 0.0, ctx.sample("x", Normal(0.0, 1.0)), 1.0, 0.3))

    other = _model(root, name="other")
    with pytest.raises(ModelError, match="settle must be a function"):
        _model(root, settle="ground")
    for settle, says in ((lambda d: None, "got NoneType"),
                         (lambda d: run_forward(other, np.random.default_rng(0)), "of model 'other'")):
        with pytest.raises(ModelError, match=f"model 'mine': settle must return a complete derivation.*{says}"):
            run_forward(_model(root, settle=settle), np.random.default_rng(0))
    kept = run_forward(_model(root, settle=lambda d: d), np.random.default_rng(0))
    assert kept.done and len(kept.geometry()) == 1


def _bad_sigma(ctx):
    ctx.emit(Disc(ctx.sample("x", Normal(0.0, -1.0)), 0.0, 1.0))


def _spawns_bad_sigma(ctx):
    ctx.spawn("kid", _bad_sigma)


def test_a_distribution_with_bad_parameters_names_the_rule_its_address_and_its_line():
    """A Normal with sigma -1 said only what was wrong (h123): in a model of dozens of
    Normal(...) calls, not where."""
    with pytest.raises(ModelError) as caught:
        run_forward(_model(_spawns_bad_sigma), np.random.default_rng(0))
    line = _bad_sigma.__code__.co_firstlineno + 1
    assert str(caught.value).startswith(f"rule '_bad_sigma' at /kid (test_model_mistakes.py, line {line}): "
                                        "Normal needs a finite number mu and a finite number sigma > 0")


def _spawns_with_a_keyword(ctx):
    ctx.spawn("kid", _bush, 0.0, 0.0, angle=1.0)


def _spawns_with_too_many(ctx):
    ctx.maybe("kid", 1.0, _bad_sigma, 1, 2)


class RenderContext:
    def spawn(self, count):
        return count


def _calls_its_own_spawn(ctx):
    RenderContext().spawn(1, scale=2)  # a TypeError of the user's own, naming a class ending in Context


def test_a_keyword_to_spawn_and_a_wrong_argument_count_say_what_to_do():
    """A keyword argument to ctx.spawn was a raw TypeError; a wrong count said "2 arguments"
    beside Python's "3 were given" (h123)."""
    with pytest.raises(ModelError, match=r"rule '_spawns_with_a_keyword' at / passes the keyword argument 'angle' "
                       r"to ctx\.spawn, which passes a rule's arguments by position \(ctx\.spawn\(site, rule, a, b\)\)"):
        run_forward(_model(_spawns_with_a_keyword), np.random.default_rng(0))
    # a TypeError of the user's own, as it is
    with pytest.raises(TypeError, match=r"^RenderContext\.spawn\(\) got an unexpected keyword"):
        run_forward(_model(_calls_its_own_spawn), np.random.default_rng(0))
    with pytest.raises(ModelError, match=r"rule '_bad_sigma' at /kid was called with 2 arguments after ctx, which it "
                       r"does not take \(.*3 were given: Python counts ctx too\)"):
        run_forward(_model(_spawns_with_too_many), np.random.default_rng(0))
