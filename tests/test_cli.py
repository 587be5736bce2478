import json
import subprocess
import sys

import pytest

from procmod.cli import main


def _run(capsys, *argv):
    code = main(list(argv))
    out, err = capsys.readouterr()
    return code, out, err


def test_models_lists_all(capsys):
    code, out, _ = _run(capsys, "models")
    assert code == 0
    names = [line.split()[0] for line in out.splitlines()]
    assert names == ["chain", "city", "lightning", "spaceship", "tree", "vines"]


def test_sample_writes_files_and_is_byte_identical(tmp_path, capsys):
    a, b = tmp_path / "a", tmp_path / "b"
    assert _run(capsys, "sample", "vines", "-n", "4", "--seed", "7", "--out", str(a), "--size", "64")[0] == 0
    assert _run(capsys, "sample", "vines", "-n", "4", "--seed", "7", "--out", str(b), "--size", "64")[0] == 0
    names = sorted(p.name for p in a.iterdir())
    assert names == sorted(["contact_sheet.png"] + [f"sample_{i:03d}.{ext}" for i in range(4)
                                                     for ext in ("png", "svg", "json")])
    for name in names:
        assert (a / name).read_bytes() == (b / name).read_bytes()
    # Sample i depends only on (seed, i).
    c = tmp_path / "c"
    _run(capsys, "sample", "vines", "-n", "2", "--seed", "7", "--out", str(c), "--size", "64")
    assert (c / "sample_001.json").read_bytes() == (a / "sample_001.json").read_bytes()
    d = tmp_path / "d"
    _run(capsys, "sample", "vines", "-n", "4", "--seed", "8", "--out", str(d), "--size", "64")
    assert any((d / f"sample_{i:03d}.json").read_bytes() != (a / f"sample_{i:03d}.json").read_bytes()
               for i in range(4))


def test_render_png_and_svg(tmp_path, capsys):
    _run(capsys, "sample", "lightning", "-n", "1", "--out", str(tmp_path))
    src = tmp_path / "sample_000.json"
    assert _run(capsys, "render", str(src), "--size", "100", "--out", str(tmp_path / "r.png"))[0] == 0
    assert (tmp_path / "r.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert _run(capsys, "render", str(src), "--out", str(tmp_path / "r.svg"))[0] == 0
    assert (tmp_path / "r.svg").read_text().startswith("<svg")
    # an existing file is replaced only with --overwrite (h52: a photo of the user's was replaced)
    kept = (tmp_path / "r.png").read_bytes()
    code, _, err = _run(capsys, "render", str(src), "--size", "64", "--out", str(tmp_path / "r.png"))
    assert code == 2 and "already exists; give --overwrite" in err and (tmp_path / "r.png").read_bytes() == kept
    assert _run(capsys, "render", str(src), "--size", "64", "--out", str(tmp_path / "r.png"), "--overwrite")[0] == 0
    assert (tmp_path / "r.png").read_bytes() != kept


def _bad(tmp_path, capsys, *argv, out_name="out"):
    code, out, err = _run(capsys, *argv)
    assert code == 2
    assert err.startswith("procmod: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert not (tmp_path / out_name).exists()
    return err


@pytest.mark.parametrize("argv,message", [
    (["sample", "teapot"], "unknown model"),
    (["sample", "my_model.py"], "model file my_model.py does not exist"),
    (["sample", "vines", "-n", "-3"], "-n must be a positive"),
    (["sample", "vines", "-n", "0"], "-n must be a positive"),
    (["sample", "vines", "--seed", "-1"], "--seed"),
    (["sample", "vines", "-n", "many"], "expected an integer"),
    (["sample", "vines", "--size", "2"], "size must be"),
])
def test_bad_sample_arguments(tmp_path, capsys, argv, message):
    err = _bad(tmp_path, capsys, *argv, "--out", str(tmp_path / "out"))
    assert message in err


def test_bad_derivation_files(tmp_path, capsys):
    out = str(tmp_path / "out.png")
    assert "none.json does not exist" in _bad(tmp_path, capsys, "render", str(tmp_path / "none.json"), "--out", out,
                                 out_name="out.png")
    (tmp_path / "bad.json").write_text("{oops")
    assert "not valid JSON" in _bad(tmp_path, capsys, "render", str(tmp_path / "bad.json"), "--out", out,
                                    out_name="out.png")
    (tmp_path / "wrong.json").write_text(json.dumps({"format": "procmod-derivation/1", "model": "vines",
                                                     "params": {}, "order": [], "choices": [[[], "x", 1]]}))
    assert "does not replay" in _bad(tmp_path, capsys, "render", str(tmp_path / "wrong.json"), "--out", out,
                                     out_name="out.png")
    _run(capsys, "sample", "chain", "-n", "1", "--out", str(tmp_path / "s"))
    assert ".png or .svg" in _bad(tmp_path, capsys, "render", str(tmp_path / "s" / "sample_000.json"),
                                  "--out", str(tmp_path / "out.gif"), out_name="out.gif")


def test_usage_errors_are_one_line(tmp_path, capsys):
    _bad(tmp_path, capsys)
    _bad(tmp_path, capsys, "frobnicate")


def test_control_characters_from_an_input_are_shown_not_acted_on(capsys):
    """A string's ESC [2J cleared the user's terminal; a CR overwrote the message's start."""
    assert main(["strings", "decode", "CC\x1b[2J"]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\\x1b[2J" in err and err.count("\n") == 1
    assert main(["strings", "graph", "no\x1b[31mred\r.json", "--out", "x"]) == 2
    err = capsys.readouterr().err
    assert "\x1b" not in err and "\r" not in err and "\\x1b[31mred\\r.json" in err


def test_console_script_exit_code(tmp_path):
    proc = subprocess.run([sys.executable, "-m", "procmod.cli", "sample", "nope", "--out", str(tmp_path / "o")],
                          capture_output=True, text=True)
    assert proc.returncode == 2
    assert proc.stderr.strip().splitlines() == [proc.stderr.strip()]
    assert not (tmp_path / "o").exists()


def test_python_dash_m_procmod_is_the_command_line(tmp_path):
    ok = subprocess.run([sys.executable, "-m", "procmod", "models"], capture_output=True, text=True)
    assert ok.returncode == 0 and "vines" in ok.stdout
    bad = subprocess.run([sys.executable, "-m", "procmod", "sample", "nope", "--out", str(tmp_path / "o")],
                         capture_output=True, text=True)
    assert bad.returncode == 2 and bad.stderr.startswith("procmod: error:") and bad.stderr.count("\n") == 1


def test_infer_writes_a_report(tmp_path, capsys):
    out = tmp_path / "run"
    code, stdout, err = _run(capsys, "infer", "vines", "--target", "glyph:a", "--engine", "smc",
                             "--particles", "20", "--seed", "1", "--out", str(out), "--size", "64")
    assert code == 0, err
    names = {p.name for p in out.iterdir()}
    assert {"best.png", "best.svg", "best.json", "history.csv", "convergence.svg", "samples.png",
            "report.html", "target.png", "settings.json"} <= names
    assert "report:" in stdout
    html = (out / "report.html").read_text()
    assert "best.png" in html and "convergence.svg" in html and "glyph:dejavu-sans/a" in html
    # The best derivation replays through `procmod render`.
    assert _run(capsys, "render", str(out / "best.json"), "--out", str(tmp_path / "b.png"))[0] == 0
    lines = (out / "history.csv").read_text().splitlines()
    assert lines[0] == "seconds,evaluations,best_score,mean_score" and len(lines) > 1


@pytest.mark.parametrize("engine,option", [("ga", "--population"), ("mcmc", "--chains"), ("sosmc", "--particles"),
                                           ("forward", "--particles")])
def test_infer_engines_run_from_the_cli(tmp_path, capsys, engine, option):
    code, _, err = _run(capsys, "infer", "lightning", "--target", "scribble:2", "--engine", engine, option, "6",
                        "--budget", "60evals", "--out", str(tmp_path / engine), "--size", "48")
    assert code == 0, err
    assert (tmp_path / engine / "best.json").exists()


def test_infer_circuit_target(tmp_path, capsys):
    code, _, err = _run(capsys, "infer", "lightning", "--target", "circuit", "--engine", "smc", "--particles", "5",
                        "--out", str(tmp_path / "c"), "--size", "48")
    assert code == 0, err
    assert not (tmp_path / "c" / "target.png").exists()


@pytest.mark.parametrize("given,used", [(None, None), ("every", None), ("0.3", 0.3)])
def test_the_ess_threshold_reaches_the_engine(tmp_path, capsys, given, used):
    argv = ["infer", "lightning", "--target", "scribble:2", "--particles", "4", "--out", str(tmp_path / "r"),
            "--size", "48"]
    code, _, err = _run(capsys, *argv, *(["--ess-threshold", given] if given else []))
    assert code == 0, err
    assert json.loads((tmp_path / "r" / "settings.json").read_text())["settings"]["ess_threshold"] == used


@pytest.mark.parametrize("argv,message", [
    (["infer", "vines", "--target", "glyph:a", "--engine", "annealing"], "unknown engine"),
    (["infer", "vines", "--target", "glyph:a", "--engine", "smc", "--population", "5"], "does not apply"),
    (["infer", "vines", "--target", "glyph:a", "--particles", "0"], "positive"),
    (["infer", "vines", "--target", "glyph:a", "--budget", "soon"], "cannot read budget"),
    # argparse took "-1s" for an option: "expected one argument"
    (["infer", "vines", "--target", "glyph:a", "--budget", "-1s"], "cannot read budget '-1s': a budget is positive"),
    (["infer", "vines", "--target", "glyph:a", "--budget", "30s+-5evals"], "a budget is positive"),
    (["infer", "vines", "--target", "glyph:i"], "connected parts"),
    (["infer", "vines", "--target", "missing.png"], "does not exist"),
    (["infer", "teapot", "--target", "glyph:a"], "unknown model"),
    (["infer", "vines", "--target", "glyph:a", "--engine", "ga", "--workers", "2"], "--workers applies"),
    (["infer", "vines", "--target", "glyph:a", "--workers", "0"], "--workers must be a positive"),
    (["infer", "vines", "--target", "glyph:a", "--init-particles", "10"], "--init-particles applies"),
    (["infer", "vines", "--target", "glyph:a", "--engine", "mcmc", "--init-particles", "-1"], "0 or more"),
    (["infer", "vines", "--target", "glyph:a", "--engine", "mcmc", "--init-particles", "900000000"],
     "--init-particles 900,000,000 would need"),
    (["infer", "vines", "--target", "glyph:a", "--ess-threshold", "1.5"], "--ess-threshold takes a fraction"),
    (["infer", "vines", "--target", "glyph:a", "--ess-threshold", "half"], "--ess-threshold takes a fraction"),
    (["infer", "vines", "--target", "glyph:a", "--engine", "ga", "--ess-threshold", "0.5"],
     "--ess-threshold applies"),
])
def test_bad_infer_arguments(tmp_path, capsys, argv, message):
    err = _bad(tmp_path, capsys, *argv, "--out", str(tmp_path / "out"))
    assert message in err


def test_sample_and_render_a_3d_model(tmp_path, capsys):
    out = tmp_path / "ships"
    assert _run(capsys, "sample", "spaceship", "-n", "2", "--seed", "3", "--out", str(out), "--size", "64")[0] == 0
    names = sorted(p.name for p in out.iterdir())
    assert names == sorted(["contact_sheet.png", "contact_sheet.html"] + [f"sample_{i:03d}.{ext}" for i in range(2)
                                                     for ext in ("png", "obj", "glb", "json")])
    import trimesh
    mesh = trimesh.load(out / "sample_000.glb", force="mesh")
    assert len(mesh.faces) > 12
    assert _run(capsys, "render", str(out / "sample_000.json"), "--out", str(tmp_path / "s.obj"))[0] == 0
    assert "a 3D derivation is not written as .svg: name the file .png or .obj or .glb" in _bad(tmp_path, capsys, "render", str(out / "sample_000.json"),
                                                  "--out", str(tmp_path / "s.svg"), out_name="s.svg")


def test_infer_3d_volume_scene(tmp_path, capsys):
    from pathlib import Path
    scene = Path(__file__).resolve().parents[1] / "scenes" / "spaceship_volume"
    out = tmp_path / "ship"
    code, _, err = _run(capsys, "infer", "spaceship", "--target", str(scene), "--engine", "ga",
                        "--population", "8", "--budget", "3gens", "--out", str(out), "--size", "64")
    assert code == 0, err
    assert {"best.png", "best.obj", "best.glb", "best.json", "report.html"} <= {p.name for p in out.iterdir()}
    assert "does not exist" in _bad(tmp_path, capsys, "infer", "spaceship", "--target",
                                    str(tmp_path / "none.json"), "--out", str(tmp_path / "x"), out_name="x")


def test_help_and_models_import_nothing_heavy():
    # `procmod --help` and `procmod models` must start in a fraction of a second: building the
    # parser and listing models may not import torch, matplotlib, trimesh, scipy or numba.
    code = ("import sys, contextlib, io\n"
            "from procmod.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            "    assert main(['models']) == 0\n"
            "    try:\n"
            "        main(['--help'])\n"
            "    except SystemExit:\n"
            "        pass\n"
            "heavy = ('torch', 'matplotlib', 'trimesh', 'scipy', 'numba', 'PIL', 'sklearn', 'networkx', 'dask')\n"
            "print(sorted(m for m in sys.modules if m.split('.')[0] in heavy))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


def test_a_glyph_target_imports_neither_matplotlib_nor_scipy_ndimage():
    """matplotlib (to find its fonts) and scipy.ndimage (to count a glyph's parts) took about
    0.35 s of every `procmod infer --target glyph:X`: the fonts are found beside its
    package, and the parts counted by procmod's own kernel."""
    code = ("import sys\n"
            "from procmod.data import target_from_spec\n"
            "target_from_spec('glyph:a'); target_from_spec('glyph:stix/g')\n"
            "print(sorted(m for m in ('matplotlib', 'scipy.ndimage') if m in sys.modules))\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "[]"


@pytest.mark.parametrize("ground", ["transparent", "white"])
def test_a_clean_drawing_imports_no_scipy_ndimage(tmp_path, ground):
    """A picture on a transparent ground (as bench/vs_webppl.py writes its targets, and as
    drawing apps export), or black on white with no grey, needs none of scipy.ndimage's
    checks: its import (~0.13-0.19 s of every run) now comes after the cheap tests that
    rule them out (a frame along all four sides, a page, faint strokes, a band along an
    edge, a fill inside the ink)."""
    import numpy as np
    from PIL import Image

    shape = np.zeros((50, 50), dtype=bool)
    shape[5:45, 22:27] = True  # a stem ...
    shape[20:24, 10:40] = True  # ... and a branch across it
    if ground == "transparent":
        Image.fromarray(np.dstack([np.zeros((50, 50, 3), np.uint8), np.where(shape, 255, 0).astype(np.uint8)])).save(
            tmp_path / "plant.png")
    else:
        Image.fromarray(np.where(shape, 0, 255).astype(np.uint8)).save(tmp_path / "plant.png")
    code = ("import sys, contextlib, io\n"
            "from procmod.cli import main\n"
            "with contextlib.redirect_stdout(io.StringIO()):\n"
            f"    assert main(['infer', 'vines', '--target', {str(tmp_path / 'plant.png')!r}, '--particles', '2',\n"
            f"                 '--out', {str(tmp_path / 'run')!r}]) == 0\n"
            "print('scipy.ndimage' in sys.modules)\n")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True).stdout
    assert out.strip() == "False"


def test_param_sets_model_parameters(tmp_path, capsys):
    out = tmp_path / "s"
    assert _run(capsys, "sample", "vines", "-n", "2", "--param", "leaves=false", "--param", "size=64",
                "--out", str(out), "--size", "64")[0] == 0
    params = json.loads((out / "sample_000.json").read_text())["params"]
    assert params["leaves"] is False and params["size"] == 64
    # a shell user's spellings of a flag, a count and a pair (refused before, "must be true or false")
    assert _run(capsys, "sample", "vines", "-n", "1", "--param", "leaves=False", "--param", "size=48.0",
                "--param", "start=.25 .75", "--out", str(tmp_path / "t"), "--size", "16")[0] == 0
    params = json.loads((tmp_path / "t" / "sample_000.json").read_text())["params"]
    assert params["leaves"] is False and params["size"] == 48 and params["start"] == [0.25, 0.75]
    for bad, words in (("leaves=yes", "leaves"), ("colour=red", "colour"), ("nonsense", "NAME=VALUE"),
                       ("start=a,b", "start[0] must be a number, got \"a\""),
                       ("start=1", "start must be a list of 2 items, e.g. [0.5, 0.9166]"), ("size=48.5", "integer")):
        code, _, err = _run(capsys, "sample", "vines", "-n", "1", "--param", bad, "--out", str(tmp_path / "x"))
        assert code == 2 and words in err and len(err.strip().splitlines()) == 1
    assert not (tmp_path / "x").exists()


def test_sample_of_a_3d_model_writes_a_page_to_turn_in_a_browser(tmp_path, capsys):
    out = tmp_path / "ships"
    assert _run(capsys, "sample", "spaceship", "-n", "2", "--out", str(out), "--size", "32")[0] == 0
    page = (out / "contact_sheet.html").read_text()
    assert page.count("sample_0") >= 2 and "<script" in page  # one view per sample, the viewer inline
    assert _run(capsys, "sample", "spaceship", "-n", "2", "--out", str(out), "--size", "32")[0] == 0  # a rerun replaces it
    two_d = tmp_path / "vines"
    code, out_text, _ = _run(capsys, "sample", "vines", "-n", "1", "--out", str(two_d), "--size", "32")
    assert code == 0 and out_text.startswith("wrote 1 sample of vines")  # not "1 samples"
    assert not (two_d / "contact_sheet.html").exists()


def test_a_contact_page_of_more_samples_than_it_shows_says_so(tmp_path, capsys, monkeypatch):
    """The page's title said "70 samples" over 64 views."""
    import procmod.cli
    monkeypatch.setattr(procmod.cli, "CONTACT_SHEET_TILES", 2)
    out = tmp_path / "ships"
    assert _run(capsys, "sample", "spaceship", "-n", "3", "--out", str(out), "--size", "16")[0] == 0
    assert "spaceship: 3 samples, seed 0 (the first 2 shown)" in (out / "contact_sheet.html").read_text()


@pytest.mark.parametrize("given, placed", [
    (["start=0.1,0.2", "direction=1,0"], {"start": [0.1, 0.2], "direction": [1.0, 0.0]}),
    (["start=0.3,0.6"], {"start": [0.3, 0.6], "direction": [0.0, -1.0]}),  # as a sidecar's start alone
])
def test_param_start_and_direction_place_the_model_on_a_picture_target(tmp_path, capsys, given, placed):
    """A picture target places the model itself (its sidecar, or its drawing's lowest
    point); the start and direction given on the command line were silently replaced."""
    argv = ["infer", "vines", "--target", "glyph:a", "--particles", "3", "--seed", "1", "--out", str(tmp_path / "r")]
    for item in given:
        argv += ["--param", item]
    assert main(argv) == 0
    params = json.loads((tmp_path / "r" / "best.json").read_text())["params"]
    assert {key: params[key] for key in placed} == placed


def test_param_start_is_in_the_pictures_coordinates_as_a_sidecars_is(tmp_path, capsys):
    """On a 400 x 200 picture a sidecar's start [0.5, 1.0] (the bottom middle) was mapped
    into the square the picture is padded to, 0.75, but --param start=0.5,1.0 was used as
    given: the vine started in the padding below the drawing."""
    from PIL import Image, ImageDraw
    picture = Image.new("RGB", (400, 200), "white")
    ImageDraw.Draw(picture).line([(200, 195), (200, 20)], fill="black", width=20)
    for name in ("side", "flag"):
        picture.save(tmp_path / f"{name}.png")
    (tmp_path / "side.json").write_text('{"start": [0.5, 1.0]}')
    starts = []
    for name, extra in (("side", []), ("flag", ["--param", "start=0.5,1.0"])):
        assert main(["infer", "vines", "--target", str(tmp_path / f"{name}.png"), "--particles", "2",
                     "--out", str(tmp_path / f"r_{name}"), *extra]) == 0, capsys.readouterr().err
        starts.append(json.loads((tmp_path / f"r_{name}" / "best.json").read_text())["params"]["start"])
    assert starts[0] == starts[1] == [0.5, 0.75]
    # a square picture is its own square: the start is kept exactly (0.9166 became 0.9166000000000001)
    square = Image.new("RGB", (300, 300), "white")
    ImageDraw.Draw(square).line([(150, 290), (150, 20)], fill="black", width=20)
    square.save(tmp_path / "square.png")
    assert main(["infer", "vines", "--target", str(tmp_path / "square.png"), "--particles", "2", "--param",
                 "start=0.5,0.9166", "--out", str(tmp_path / "r_square")]) == 0
    assert json.loads((tmp_path / "r_square" / "best.json").read_text())["params"]["start"] == [0.5, 0.9166]


USER_START_MODEL = """
import math
from procmod import Model, Normal
from procmod.geometry import Canvas, Segment

def grow(ctx, x, y, angle, n):
    angle = ctx.sample("angle", Normal(angle, 0.3))
    x1, y1 = x + 2 * math.cos(angle), y + 2 * math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, 0.6))
    if n < 5:
        ctx.spawn("next", grow, x1, y1, angle, n + 1)

def root_args(p):
    x, y = p["start"]
    heading = p["direction"] if isinstance(p["direction"], float) else math.atan2(*p["direction"][::-1])
    return (float(x), float(y), heading, 0)

M = Model("mine", "grows from its own start", grow, root_args, lambda p: Canvas((-12, 12, -22, 2), 50),
          params={"start": START, "direction": DIRECTION})
"""


@pytest.mark.parametrize("start, direction, placed", [
    ("[0, -2]", "-1.5707963", False),  # a world point and a heading in radians: the model's own
    ("[0.0, -2.0]", "[0.0, 1.0]", False),  # a world point: its direction (a world vector) kept too
    ("[0.5, 0.9]", "[0.0, -1.0]", True),  # normalised image coordinates, as the built-in models take
    # the same written in whole numbers: typed as integers, the picture's point was refused
    # ("direction[0] must be an integer, got -0.049")
    ("[0.5, 1]", "[0, -1]", True),
    ("[0, 1]", "[0, -1]", True),
])
def test_a_users_start_and_direction_are_its_own_unless_they_are_the_pictures_kind(tmp_path, capsys, start,
                                                                                  direction, placed):
    """A picture target wrote its placement over any model's ``start``/``direction``: a
    world start [0, -2] was refused ('start[0] must be an integer, got 0.505', a value the
    user never gave) or silently moved to the picture's normalised coordinates."""
    (tmp_path / "mine.py").write_text(USER_START_MODEL.replace("START", start).replace("DIRECTION", direction))
    code = main(["infer", str(tmp_path / "mine.py"), "--target", "glyph:Y", "--particles", "3", "--out",
                 str(tmp_path / "r")])
    assert code == 0, capsys.readouterr().err
    params = json.loads((tmp_path / "r" / "best.json").read_text())["params"]
    assert (params["start"] != json.loads(start)) == placed, params
    # and the run's derivation reads back (its real start had been refused against [0, 1]'s integers)
    assert main(["render", str(tmp_path / "r" / "best.json"), "--model", f"{tmp_path / 'mine.py'}:M", "--out",
                 str(tmp_path / "again.png")]) == 0, capsys.readouterr().err


def test_an_integer_for_a_real_parameter_takes_a_later_real_change(tmp_path, capsys):
    """``--param direction=[0,-1]`` (what the message for [0,0] suggests) was stored as
    integers, so the target's real start was then refused as "must be an integer"."""
    code = main(["infer", "vines", "--target", "glyph:a", "--param", "direction=[0,-1]", "--particles", "2",
                 "--size", "16", "--out", str(tmp_path / "run")])
    assert code == 0, capsys.readouterr().err


def test_a_reader_that_closes_stdout_ends_the_command_quietly():
    # `procmod strings decode ... | head -c 10` printed a BrokenPipeError traceback
    import subprocess
    import sys
    run = subprocess.Popen([sys.executable, "-m", "procmod.cli", "strings", "decode", "C" + "(C)" * 30000],
                           stdout=subprocess.PIPE, stderr=subprocess.PIPE)
    run.stdout.close()
    err = run.stderr.read().decode()
    assert run.wait(timeout=120) == 141 and err == "", err


def test_param_values_are_read_as_their_parameters_default_is_typed():
    from procmod.cli import _as_param, _read_param

    def read(text, default):
        return _as_param(_read_param(text), text, default)

    assert read("1", "a") == "1" and read("true", "a") == "true" and read('"x"', "a") == "x"  # a string parameter
    assert read("True,0", [False, True]) == [True, False] and read("3.0,4", [1, 2]) == [3, 4]
    assert read(".5 .9", [0.5, 0.9]) == [0.5, 0.9] and read("p,q", ["a", "b"]) == ["p", "q"]
    assert read("c,d", "label") == "c,d"  # a string parameter is never split
    assert read('"0.5,0.9"', [0.5, 0.9]) == [0.5, 0.9] and read("0.5;0.9", [0.5, 0.9]) == [0.5, 0.9]


def test_fewer_workers_than_asked_is_said(tmp_path, capsys):
    """--particles 1 --workers 2 ran on one process without a word (settings.json only)."""
    assert main(["infer", "vines", "--target", "glyph:a", "--particles", "1", "--workers", "2",
                 "--out", str(tmp_path / "r")]) == 0
    said = "--workers 2 ran on 1: a worker steps particles of its own, and there was 1"
    assert f"note: {said}" in capsys.readouterr().err
    # recorded too, beside the command line that asked for 2 (settings.json had only "workers": 1)
    assert said in json.loads((tmp_path / "r" / "settings.json").read_text())["notes"]


def test_sample_of_a_3d_model_names_its_page_and_a_programs_page_hides_its_path(tmp_path, capsys):
    """The 3D contact page was written but never named; a learned program's page title
    held the program's absolute path."""
    from procmod.cli import _page_name

    assert main(["sample", "spaceship", "-n", "1", "--size", "32", "--out", str(tmp_path / "s")]) == 0
    assert f"{tmp_path / 's' / 'contact_sheet.html'} (turn them in a browser)" in capsys.readouterr().out
    assert _page_name(str(tmp_path / "castles" / "program.json")) == "castles/program.json"
    assert _page_name("spaceship") == "spaceship"


TWO_MODELS = """
import math
from procmod import Model, Normal
from procmod.geometry import Canvas, Segment

def grow(ctx, n):
    a = ctx.sample("a", Normal(0.0, 1.0))
    ctx.emit(Segment(0.0, 0.0, math.cos(a), math.sin(a), 0.2))

NARROW = Model("narrow", "one segment", grow, lambda p: (0,), lambda p: Canvas((-2, 2, -2, 2), 32))
WIDE = Model("wide", "the same rule on a wider canvas", grow, lambda p: (0,), lambda p: Canvas((-9, 9, -9, 9), 32))
"""


def test_render_with_another_model_of_the_same_rule_is_refused(tmp_path, capsys):
    """--model was a name lookup that ignored the name: a derivation of one model was drawn
    with another built on the same root rule (another canvas), where the library refuses it."""
    (tmp_path / "two.py").write_text(TWO_MODELS)
    assert main(["sample", f"{tmp_path / 'two.py'}:NARROW", "-n", "1", "--size", "32", "--out",
                 str(tmp_path / "s")]) == 0
    capsys.readouterr()
    sample = str(tmp_path / "s" / "sample_000.json")
    assert main(["render", sample, "--model", f"{tmp_path / 'two.py'}:WIDE", "--out", str(tmp_path / "w.png")]) == 2
    assert "it is a derivation of model 'narrow', not 'wide'" in capsys.readouterr().err
    assert not (tmp_path / "w.png").exists()
    assert main(["render", sample, "--model", f"{tmp_path / 'two.py'}:NARROW", "--out", str(tmp_path / "n.png")]) == 0


def test_a_stop_that_a_librarys_clean_up_fails_on_is_one_line(tmp_path, capsys, monkeypatch):
    """SIGTERM during torch.save: its zip writer's clean-up raised RuntimeError ("unexpected
    pos") as the stop passed through it, and a 40-line traceback was printed (h75)."""
    import procmod.cli as cli

    def stopped_while_saving(args):
        try:
            raise cli.Terminated()
        finally:
            raise RuntimeError("[enforce fail at inline_container.cc:672] . unexpected pos 3847104 vs 3846996")

    monkeypatch.setitem(cli._COMMANDS, "sample", stopped_while_saving)
    assert main(["sample", "vines", "--out", str(tmp_path / "s")]) == 143
    assert capsys.readouterr().err == "procmod: terminated\n"

    def broken(args):
        raise RuntimeError("a bug of procmod's own")  # no stop behind it: the traceback stays

    monkeypatch.setitem(cli._COMMANDS, "sample", broken)
    with pytest.raises(RuntimeError, match="a bug of procmod's own"):
        main(["sample", "vines", "--out", str(tmp_path / "s")])


def test_only_a_value_with_a_unit_is_joined_to_its_option():
    """--budget -1s is joined (argparse took it for an option); a plain negative number is
    argparse's own to read (a positional after a flag), and nothing after "--" (h76)."""
    from procmod.cli import _negative_values_joined

    assert _negative_values_joined(["infer", "--budget", "-1s"]) == ["infer", "--budget=-1s"]
    assert _negative_values_joined(["learn", "x.json", "--overwrite", "-1"]) == ["learn", "x.json", "--overwrite", "-1"]
    assert _negative_values_joined(["x", "--", "--a", "-1s"]) == ["x", "--", "--a", "-1s"]
