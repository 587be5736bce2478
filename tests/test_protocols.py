"""The declared contracts (procmod.core.protocols): every built-in output and target declares
its capabilities, each declaration is true of the object, and an object that declares too
little is refused in one line instead of failing deep inside an engine."""

import math

import numpy as np
import pytest

from procmod.core import InvalidArgumentError, Output, Target, check_declared, run_forward
from procmod.geometry import Canvas
from procmod.geometry.solid import Box, Cylinder
from procmod.geometry.camera import Camera
from procmod.geometry.voxel import VoxelGrid, voxelize
from procmod.infer import ENGINES
from procmod.models import MODELS, get_model
from procmod.render import is_2d
from procmod.targets import Circuit, ProxyVolume, ShapeMatch, Silhouette, TargetImage, Volume

from toy_models import MIX, SumTarget

GRID = VoxelGrid((-6.0, -2.0, -6.0), 0.5, (24, 16, 40))
CAM = Camera((0, 0, 20), (0, 0, 0), projection="orthographic", fov=8, width=32, height=32)


def _mask():
    mask = np.zeros((40, 40), bool)
    mask[8:36, 18:24] = True
    return mask


def _targets_2d():
    return [ShapeMatch(TargetImage("bar", _mask(), (0.5, 0.9), (0, -1))), Circuit()]


def _targets_3d():
    fill = voxelize([Box((4, 4, 8))], GRID)
    weights = np.full((32, 32), -1.0)
    weights[:, 12:20] = 1.0
    return [Volume(GRID, [(fill, 1.0, -1.0)]), ProxyVolume(GRID, fill), Silhouette([(weights, CAM)])]


@pytest.mark.parametrize("name", sorted(MODELS))
def test_every_models_output_declares_what_it_draws(name):
    model = get_model(name)
    output = model.new_output()
    check_declared(output, Output, "the output")
    assert output.dimension in (2, 3)
    assert (output.dimension == 2) == isinstance(output, Canvas)  # dimension 2 means a raster canvas
    d = run_forward(model, np.random.default_rng(0))
    assert is_2d(d) == (output.dimension == 2)


@pytest.mark.parametrize("target", _targets_2d() + _targets_3d(), ids=lambda t: type(t).__name__)
def test_every_target_and_its_output_declare_true_capabilities(target):
    check_declared(target, Target, "the target")
    model = get_model("vines" if isinstance(target, (ShapeMatch, Circuit)) else "spaceship")
    model = target.configure(model)
    output = target.new_output(model)
    check_declared(output, Output, "the output")
    if target.exact_removal:  # a score that survives removal needs an output that removes
        assert output.supports_removal
    # (ProxyVolume's ``mask`` is its voxel array, not the method a guide calls)
    assert target.has_mask == callable(getattr(target, "mask", None))
    assert target.has_overlay == callable(getattr(target, "overlay_image", None))
    if output.supports_removal:  # remove undoes add: counts and the score come back
        empty = output.copy()
        parts = [Box((1, 2, 3)), Cylinder(0.5, 4.0)]
        for part in parts:
            output.add(part)
        assert target.score(output) != target.score(empty)
        for part in reversed(parts):
            output.remove(part)
        assert not output.saturated
        assert math.isclose(target.score(output), target.score(empty), abs_tol=1e-9)
        assert output.filled_count == empty.filled_count
    else:
        assert not hasattr(output, "remove")


def test_dimension_decides_which_targets_a_model_fits():
    for target in _targets_3d():
        with pytest.raises(InvalidArgumentError, match="needs a 3D model; 'vines' is 2D"):
            target.new_output(target.configure(get_model("vines")))
    for target in _targets_2d():
        with pytest.raises(InvalidArgumentError, match="needs a 2D model"):
            target.new_output(get_model("spaceship"))


class _Undeclared:
    """A target written before capabilities were declared: the four methods only."""

    name = "undeclared"

    def configure(self, model):
        return model

    def new_output(self, model):
        return SumTarget(0.0, 1.0).new_output(model)

    def score(self, output):
        return 0.0

    def log_likelihood(self, output):
        return 0.0


def test_an_undeclared_target_is_refused_in_one_line_where_capabilities_are_read():
    with pytest.raises(InvalidArgumentError, match=r"the target \(_Undeclared\) does not declare exact_removal, "
                                                   r"has_mask, has_overlay: subclass procmod.core.Target"):
        ENGINES["ga"](MIX, _Undeclared(), population=4, seed=0)

    class Subclassed(_Undeclared, Target):  # the fix the message gives: the defaults
        pass

    result = ENGINES["ga"](MIX, Subclassed(), population=4, seed=0)
    assert result.best is not None


def test_an_undeclared_output_is_refused_before_an_engine_runs():
    class Bare:
        def add(self, geometry):
            return 0

        def copy(self):
            return Bare()

    class BareTarget(SumTarget):
        def new_output(self, model):
            return Bare()

    for engine in ENGINES:
        with pytest.raises(InvalidArgumentError, match=r"output \(Bare\) does not declare dimension"):
            ENGINES[engine](MIX, BareTarget(0.0, 1.0), seed=0)


def test_a_capability_without_its_methods_is_refused():
    class Claims(Target):
        name = "claims"
        has_overlay = True

    with pytest.raises(InvalidArgumentError, match="declares has_overlay but has no overlay_image"):
        check_declared(Claims(), Target, "the target")


@pytest.mark.parametrize("left_out", ["add", "copy"])
def test_an_output_that_leaves_out_add_or_copy_is_refused(left_out):
    # it inherited the protocol's empty body: a misnamed add dropped every emit without a
    # word (SMC scored empty outputs), a missing copy failed later in the user's own score
    class Partial(Output):
        dimension = 0

        def __init__(self):
            self.total = 0.0

        if left_out != "add":
            def add(self, value):
                self.total += float(value)

        if left_out != "copy":
            def copy(self):
                other = Partial()
                other.total = self.total
                return other

    class PartialTarget(SumTarget):
        def new_output(self, model):
            return Partial()

    for engine in ENGINES:
        with pytest.raises(InvalidArgumentError, match=rf"output \(Partial\) does not define {left_out} \(it would "
                                                       r"inherit procmod.core.Output's, which does nothing\)"):
            ENGINES[engine](MIX, PartialTarget(0.0, 1.0), seed=0)


def test_an_output_neither_2d_nor_3d_is_refused_by_the_renderers_before_any_file(tmp_path):
    # it was drawn as 3D parts: "a 3D output draws Box, Cylinder and Mesh parts, not float",
    # after write_run had made its folder
    from procmod.render import derivation_image
    from procmod.report import write_run
    result = ENGINES["smc"](MIX, SumTarget(1.0, 2.0), particles=5, seed=0)
    with pytest.raises(InvalidArgumentError, match="output of dimension 0, which procmod cannot render"):
        write_run(result, SumTarget(1.0, 2.0), tmp_path / "run")
    assert not (tmp_path / "run").exists()
    with pytest.raises(InvalidArgumentError, match="cannot render"):
        derivation_image(result.best, 64)


def test_methods_an_object_sets_on_itself_are_its_own():
    # a delegating wrapper (self.score = inner.score) was refused as inheriting the
    # protocol's empty methods
    class Wrapped(Target):
        name = "wrapped"

        def __init__(self, inner):
            for method in ("configure", "new_output", "score", "log_likelihood"):
                setattr(self, method, getattr(inner, method))

    result = ENGINES["smc"](MIX, Wrapped(SumTarget(1.0, 2.0)), particles=5, seed=0)
    assert result.best is not None
