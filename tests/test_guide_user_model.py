"""Guides for a model of the user's own Python file: traces, training and guided SMC from
the command line (they took built-in models' names only)."""

import json

import pytest

from procmod.cli import main
from procmod.guide.traces import generate_traces, load_traces
from procmod.parallel import open_executor

# A plant that reports where it grows (ctx.at) and declares its arguments' ranges, as a
# model needs for the guide's local and image features (README, "Neural guides").
PLANT_FILE = """
import math
from procmod import Model, Normal
from procmod.geometry import Canvas, Segment

def plant(ctx, x, y, angle, depth):
    ctx.at((x, y, angle))
    angle = ctx.sample("angle", Normal(angle, 0.3))
    x1, y1 = x + 2 * math.cos(angle), y + 2 * math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, 0.6))
    ctx.at((x1, y1, angle))
    if depth < 6:
        ctx.maybe("left", 0.6, plant, x1, y1, angle + 0.4, depth + 1)
        ctx.maybe("right", 0.6, plant, x1, y1, angle - 0.4, depth + 1)

PLANT = Model("my-plant", "a plant", plant, root_args=lambda p: (0.0, 0.0, -math.pi / 2, 0),
              new_output_from=lambda p: Canvas((-12, 12, -22, 2), 50),
              arg_ranges={"plant": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, 6.0))},
              heading_rules=("plant",))
"""


def test_a_guide_is_made_trained_and_used_for_a_model_of_the_users_own_file(tmp_path, monkeypatch, capsys):
    (tmp_path / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(tmp_path)
    assert main(["guide", "traces", "plants.py:PLANT", "--count", "3", "--particles", "8", "--workers", "1",
                 "--out", "traces"]) == 0, capsys.readouterr().err
    job, traces = load_traces(tmp_path / "traces")
    assert job["model"] == "my-plant" and job["model_file"] == str(tmp_path / "plants.py") + ":PLANT"
    assert len(traces) == 3 and all(t["derivation"]["model"] == "my-plant" for t in traces)
    assert main(["guide", "train", "plants.py:PLANT", "--traces", "traces", "--out", "g", "--iterations", "20"]) == 0, \
        capsys.readouterr().err
    assert json.loads((tmp_path / "g.json").read_text())["model"] == "my-plant"
    assert main(["infer", "plants.py:PLANT", "--target", "scribble:3", "--particles", "4", "--guide", "g",
                 "--out", "run"]) == 0, capsys.readouterr().err
    assert json.loads((tmp_path / "run" / "settings.json").read_text())["engine"] == "smc+guide"
    # a built-in model is refused the user's guide, with the way to train one
    capsys.readouterr()
    assert main(["infer", "vines", "--target", "scribble:3", "--particles", "4", "--guide", "g", "--out", "v"]) == 2
    assert "trained for model 'my-plant', not 'vines'" in capsys.readouterr().err


def _three_traces(folder, monkeypatch):
    """The plant's file in ``folder`` (made the current folder) and 3 traces of it in ``traces``."""
    (folder / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(folder)
    assert main(["guide", "traces", "plants.py:PLANT", "--count", "3", "--particles", "8", "--workers", "1",
                 "--out", "traces"]) == 0


def test_a_guide_for_a_rule_since_renamed_says_so(tmp_path, monkeypatch, capsys):
    """The model's rule renamed after the guide was trained: a guide with local features
    blamed missing argument ranges and advised training without local state; one without
    them matched no choice and ran on the prior, silently, as "smc+guide"."""
    _three_traces(tmp_path, monkeypatch)
    for features, stem in (("all", "g"), ("target+partial", "g_image")):
        assert main(["guide", "train", "plants.py:PLANT", "--traces", "traces", "--out", stem, "--iterations", "20",
                     "--features", features]) == 0
    renamed = PLANT_FILE.replace("def plant(", "def shoot(").replace(", plant, x1", ", shoot, x1")
    renamed = renamed.replace('"a plant", plant,', '"a plant", shoot,').replace('{"plant":', '{"shoot":')
    # (another file: this process has the first one loaded)
    (tmp_path / "shoots.py").write_text(renamed.replace('heading_rules=("plant",)', 'heading_rules=("shoot",)'))
    capsys.readouterr()
    argv = ["infer", "shoots.py:PLANT", "--target", "scribble:3", "--particles", "4"]
    assert main(argv + ["--guide", "g", "--out", "run"]) == 2
    assert "declares argument ranges for rule 'shoot' but not 'plant'" in capsys.readouterr().err
    assert main(argv + ["--guide", "g_image", "--out", "run"]) == 0
    err = capsys.readouterr().err
    assert "note: the guide proposed none of this run's choices" in err and "plant:angle" in err, err
    notes = json.loads((tmp_path / "run" / "settings.json").read_text())["notes"]
    assert any("proposed none" in note for note in notes)


def test_worker_processes_import_the_model_file_from_its_absolute_path(tmp_path, monkeypatch):
    """Workers get the file's absolute path: a job started with a relative FILE.py:NAME
    makes the same traces inline and on a pool, and resumes from another directory."""
    folder = tmp_path / "models"
    folder.mkdir()
    (folder / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(folder)
    generate_traces("plants.py:PLANT", "scribble", 3, tmp_path / "inline", particles=6, seed=2)
    with open_executor(workers=2) as executor:
        generate_traces("plants.py:PLANT", "scribble", 3, tmp_path / "pool", particles=6, seed=2, executor=executor)

    def derivations(name):
        return [t["derivation"] for t in load_traces(tmp_path / name)[1]]
    assert derivations("inline") == derivations("pool")
    monkeypatch.chdir(tmp_path)
    summary = generate_traces("models/plants.py:PLANT", "scribble", 4, tmp_path / "inline", particles=6, seed=2)
    assert summary["present"] == 3 and summary["made"] == 1


@pytest.mark.parametrize("workers", ["1", "2"])
def test_traces_of_a_model_drawing_from_pythons_random_get_the_note(tmp_path, capsys, workers):
    """infer and sample say when a model draws from Python's random (the seed then fixes
    nothing); guide traces made such traces, different at every run of one seed, without
    a word (h145). The note is said once, and not written into the traces."""
    (tmp_path / "loose.py").write_text(PLANT_FILE.replace("import math\n", "import math, random\n", 1)
                                       .replace("x1, y1 = x + 2", "x1, y1 = x + random.uniform(1.5, 2.5)"))
    assert main(["guide", "traces", str(tmp_path / "loose.py:PLANT"), "--count", "3", "--particles", "4",
                 "--workers", workers, "--out", str(tmp_path / "t")]) == 0
    err = capsys.readouterr().err
    assert err.count("note: the model's rules drew from Python's random module") == 1, err
    assert not any("_global" in f.read_text() for f in (tmp_path / "t").glob("trace_*.json"))
    (tmp_path / "steady.py").write_text(PLANT_FILE)
    assert main(["guide", "traces", str(tmp_path / "steady.py:PLANT"), "--count", "2", "--particles", "4",
                 "--workers", workers, "--out", str(tmp_path / "s")]) == 0
    assert "note:" not in capsys.readouterr().err


def test_an_error_in_the_model_file_on_a_worker_process_is_one_line(tmp_path, capsys):
    """A rule's exception on a pool worker reached the command line as two tracebacks."""
    (tmp_path / "broken.py").write_text(PLANT_FILE.replace("x1, y1 = x + 2", "x1, y1 = 1 / 0 + x + 2"))
    assert main(["guide", "traces", str(tmp_path / "broken.py:PLANT"), "--count", "2", "--particles", "4",
                 "--workers", "2", "--out", str(tmp_path / "t")]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "broken.py, line 9, in plant: ZeroDivisionError: division by zero" in err, err
    assert not (tmp_path / "t").exists()


def test_overwrite_never_deletes_the_folder_holding_the_users_model_file(tmp_path, monkeypatch, capsys):
    """`guide traces proj/plants.py:PLANT --out proj --overwrite` read the model, wiped proj
    (the model file and the user's notes with it), then failed: the file was gone."""
    project = tmp_path / "proj"
    project.mkdir()
    (project / "plants.py").write_text(PLANT_FILE)
    (project / "notes.txt").write_text("mine")
    monkeypatch.chdir(tmp_path)
    for command in (["guide", "traces", "proj/plants.py:PLANT", "--count", "1", "--particles", "4", "--workers", "1"],
                    ["infer", "proj/plants.py:PLANT", "--target", "scribble:3", "--particles", "4"]):
        capsys.readouterr()
        assert main([*command, "--out", "proj", "--overwrite"]) == 2
        err = capsys.readouterr().err
        assert "holds the input" in err and "plants.py" in err and err.count("\n") == 1, err
        assert sorted(p.name for p in project.iterdir()) == ["notes.txt", "plants.py"]


def test_a_traces_folder_resumes_past_the_users_files_and_overwrite_removes_its_own_only(tmp_path, monkeypatch,
                                                                                        capsys):
    """A guide trained into its traces folder (allowed: a new file in an input folder) and a
    notes file stopped the job from resuming, and the advice, --overwrite, deleted the guide
    with every trace."""
    (tmp_path / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(tmp_path)
    traces = ["guide", "traces", "plants.py:PLANT", "--particles", "4", "--workers", "1", "--out", "tr"]
    assert main([*traces, "--count", "2"]) == 0, capsys.readouterr().err
    assert main(["guide", "train", "plants.py:PLANT", "--traces", "tr", "--out", "tr/g", "--iterations", "5"]) == 0
    (tmp_path / "tr" / "notes.txt").write_text("mine")
    first = (tmp_path / "tr" / "trace_00000.json").read_bytes()
    capsys.readouterr()
    assert main([*traces, "--count", "3"]) == 0, capsys.readouterr().err  # resumed: one more trace
    assert "1 traces made, 2 already there" in capsys.readouterr().out
    assert (tmp_path / "tr" / "trace_00000.json").read_bytes() == first
    assert main([*traces, "--count", "2", "--seed", "5", "--overwrite"]) == 0  # another job: its files replaced
    names = sorted(p.name for p in (tmp_path / "tr").iterdir())
    assert names == ["g.json", "g.npz", "g.pt", "notes.txt", "trace_00000.json", "trace_00001.json", "traces.json"]
    assert json.loads((tmp_path / "tr" / "traces.json").read_text())["seed"] == 5


def test_a_traces_job_does_not_resume_on_an_edited_model(tmp_path, monkeypatch, capsys):
    """Resumed after an edit of the model file, a job mixed the old traces with new ones, and
    training refused them one by one. A job file of before the digest still resumes."""
    (tmp_path / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(tmp_path)
    traces = ["guide", "traces", "plants.py:PLANT", "--particles", "4", "--workers", "1", "--out", "tr"]
    assert main([*traces, "--count", "2"]) == 0, capsys.readouterr().err
    job = json.loads((tmp_path / "tr" / "traces.json").read_text())
    (tmp_path / "plants.py").write_text(PLANT_FILE.replace("x1, y1 = x + 2", "x1, y1 = x + 2.5"))
    capsys.readouterr()
    assert main([*traces, "--count", "3"]) == 2
    err = capsys.readouterr().err
    assert "as its code was before an edit" in err and "--overwrite" in err and err.count("\n") == 1, err
    assert sorted(p.name for p in (tmp_path / "tr").iterdir()) == ["trace_00000.json", "trace_00001.json",
                                                                   "traces.json"]
    (tmp_path / "plants.py").write_text(PLANT_FILE)  # the code it began with: resumes
    assert main([*traces, "--count", "3"]) == 0 and "1 traces made, 2 already there" in capsys.readouterr().out
    del job["model_code"]  # a job file written before jobs recorded their code
    (tmp_path / "tr" / "traces.json").write_text(json.dumps(job))
    assert main([*traces, "--count", "4"]) == 0 and "1 traces made, 3 already there" in capsys.readouterr().out
    # an edit of a module beside the model file that it imports: its traces had been mixed too
    (tmp_path / "steps.py").write_text("STEP = 2\n")
    (tmp_path / "plants2.py").write_text("from steps import STEP\n" + PLANT_FILE.replace("x1, y1 = x + 2", "x1, y1 = x + STEP"))
    helped = ["guide", "traces", "plants2.py:PLANT", "--particles", "4", "--workers", "1", "--out", "tr2"]
    assert main([*helped, "--count", "1"]) == 0, capsys.readouterr().err
    (tmp_path / "steps.py").write_text("STEP = 3\n")
    capsys.readouterr()
    assert main([*helped, "--count", "2"]) == 2 and "as its code was before an edit" in capsys.readouterr().err


def test_a_traces_job_resumes_after_an_edit_of_comments_only(tmp_path, monkeypatch, capsys):
    """A comment added to the model file (or blank lines, trailing spaces) had stopped its
    traces job resuming, and the advice, --overwrite, threw away every finished trace. A
    job file of before, which recorded the files' bytes, still resumes on that code."""
    from procmod.guide.traces import model_code_digests
    from procmod.models import model_from_spec

    (tmp_path / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(tmp_path)
    traces = ["guide", "traces", "plants.py:PLANT", "--particles", "4", "--workers", "1", "--out", "tr"]
    assert main([*traces, "--count", "1"]) == 0, capsys.readouterr().err
    commented = PLANT_FILE.replace("* math.sin(angle)\n", "* math.sin(angle)  # one step   \n", 1)
    assert commented != PLANT_FILE
    (tmp_path / "plants.py").write_text("# my plant\n\n" + commented.replace("\n\n", "\n\n\n") + "\n# end\n")
    capsys.readouterr()
    assert main([*traces, "--count", "2"]) == 0, capsys.readouterr().err
    assert "1 traces made, 1 already there" in capsys.readouterr().out
    # a job file written when the digest was of the files' bytes
    (tmp_path / "plants.py").write_text(PLANT_FILE)
    job = json.loads((tmp_path / "tr" / "traces.json").read_text())
    model = model_from_spec(str(tmp_path / "plants.py") + ":PLANT")
    digest, byte_digest = model_code_digests(model, job["model_file"])
    assert digest != byte_digest and job["model_code"] == digest
    (tmp_path / "tr" / "traces.json").write_text(json.dumps({**job, "model_code": byte_digest}))
    assert main([*traces, "--count", "3"]) == 0, capsys.readouterr().err
    assert "1 traces made, 2 already there" in capsys.readouterr().out
    # and records today's digest, so a comment does not stop it next time (h76)
    assert json.loads((tmp_path / "tr" / "traces.json").read_text())["model_code"] == digest
    # and an edit of the code itself is still one
    (tmp_path / "plants.py").write_text(PLANT_FILE.replace("x1, y1 = x + 2", "x1, y1 = x + 2.5"))
    assert main([*traces, "--count", "4"]) == 2 and "as its code was before an edit" in capsys.readouterr().err


@pytest.mark.parametrize("before, after, same", [
    ("x = 1\n", "x = 1  # one\n\n\n", True),
    ("x = 1\n", "# head\nx = 1   \n", True),
    ("x = 1\n", "x = 2\n", False),
    ("def f():\n    return 1\n", "def f():\n  return 1\n", False),  # indentation is code
    ('s = """a\n\nb"""\n', 's = """a\nb"""\n', False),  # a blank line inside a string is its value
    ('s = """a  \nb"""\n', 's = """a\nb"""\n', False),  # and so are its spaces
    ('s = "# not a comment"\n', 's = ""\n', False),
    ("x = (1 +  # why\n     2)\n", "x = (1 +\n     2)\n", True),
    ("x = 1\n", "x = 1\n\x0c\n", True),  # a form feed between functions
    ("\ufeffx = 1  # \u00e9t\u00e9\n", "\ufeffx = 1\n", True),
    ("x = (\n", "x = (  # c\n", False),  # no tokens: the bytes decide
])
def test_the_code_digest_leaves_out_comments_and_layout_only(before, after, same):
    from procmod.guide.traces import code_text

    assert (code_text(before.encode()) == code_text(after.encode())) == same


def test_traces_drawn_at_a_param_train_a_guide_for_runs_at_it(tmp_path, monkeypatch, capsys):
    """guide traces took no --param: a guide for 64x64 runs could only be trained on 50x50
    traces (the size note then advised what the command could not do)."""
    from procmod.guide import Guide
    from procmod.infer.smc import smc
    from procmod.models import get_model
    from procmod.data import target_from_spec

    monkeypatch.chdir(tmp_path)
    traces = ["guide", "traces", "vines", "--particles", "4", "--workers", "1", "--out", "tr", "--param", "size=64"]
    assert main([*traces, "--count", "2"]) == 0, capsys.readouterr().err
    assert json.loads((tmp_path / "tr" / "traces.json").read_text())["params"] == {"size": 64}
    assert json.loads((tmp_path / "tr" / "trace_00000.json").read_text())["derivation"]["params"]["size"] == 64
    assert main([*traces, "--count", "3"]) == 0 and "1 traces made, 2 already there" in capsys.readouterr().out
    capsys.readouterr()
    assert main([*traces[:-2], "--count", "3"]) == 2  # at the defaults: another job
    assert "params {\"size\": 64} there, null now" in capsys.readouterr().err
    assert main([*traces[:-1], "sizes=64", "--count", "3"]) == 2
    assert "model 'vines' has no parameter \"sizes\"" in capsys.readouterr().err
    assert main(["guide", "train", "vines", "--traces", "tr", "--out", "g", "--iterations", "3"]) == 0
    guide = Guide.load(tmp_path / "g")
    assert guide.info["trained_on"]["canvases"] == [[64, 64]]
    vines = get_model("vines")
    at_64 = smc(vines.configure(size=64), target_from_spec("scribble:3"), particles=3, seed=0, guide=guide)
    assert not any("trained on" in n for n in at_64.notes)
    at_50 = smc(vines, target_from_spec("scribble:3"), particles=3, seed=0, guide=guide)
    (note,) = [n for n in at_50.notes if "trained on" in n]
    assert "64x64-pixel drawings and this run draws at 50x50" in note and "guide traces takes --param, none" in note
    # a default given is the default job (h78: refused as another); a picture's start cannot be given
    assert main(["guide", "traces", "vines", "--particles", "4", "--workers", "1", "--out", "tr0", "--count", "1"]) == 0
    capsys.readouterr()
    assert main(["guide", "traces", "vines", "--particles", "4", "--workers", "1", "--out", "tr0", "--count", "1",
                 "--param", "size=50"]) == 0, capsys.readouterr().err
    assert "0 traces made, 1 already there" in capsys.readouterr().out
    assert main([*traces[:-1], "start=0.5,0.9", "--count", "3"]) == 2
    assert "--param start: each training scribble places the model" in capsys.readouterr().err
    # a tuple default given as a list is the default too (h81: [0, -3] is not (0, -3) to Python)
    (tmp_path / "world.py").write_text(PLANT_FILE.replace("root_args=lambda p: (0.0, 0.0, -math.pi / 2, 0)",
                                                          "root_args=lambda p: (*p['start'], -math.pi / 2, 0)")
                                       .replace("new_output_from=", "params={'start': (0.0, -3.0)}, new_output_from="))
    world = ["guide", "traces", "world.py:PLANT", "--particles", "4", "--workers", "1", "--out", "w", "--count", "1"]
    assert main(world) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert main([*world, "--param", "start=[0,-3]"]) == 0, capsys.readouterr().err
    assert "0 traces made, 1 already there" in capsys.readouterr().out


def test_a_guide_runs_from_its_json_and_npz_alone(tmp_path, capsys):
    """The .npz is what inference reads without torch; a guide copied without its .pt was
    refused for the .pt. Without a matching .npz the .pt is still required, and named."""
    import shutil

    from procmod.guide.guide import PRETRAINED

    for suffix in (".json", ".npz"):
        shutil.copy(PRETRAINED / f"vines-scribbles{suffix}", tmp_path / f"g{suffix}")
    argv = ["infer", "vines", "--target", "glyph:a", "--particles", "3", "--out", str(tmp_path / "run")]
    assert main(argv + ["--guide", str(tmp_path / "g")]) == 0, capsys.readouterr().err
    (tmp_path / "g.npz").write_bytes(b"not the weights")
    capsys.readouterr()
    assert main(argv + ["--guide", str(tmp_path / "g"), "--overwrite"]) == 2
    assert "g.npz is not the weights written with g.json" in (err := capsys.readouterr().err) and "no g.pt" in err


def test_a_guides_json_beside_another_guides_weights_is_refused(tmp_path, monkeypatch, capsys):
    """Two guides of the same shapes: one's .json beside the other's .pt and .npz ran with
    the other's weights (the .npz digest caught it, then the .pt was read unchecked)."""
    import shutil

    _three_traces(tmp_path, monkeypatch)
    for stem, seed in (("a", "0"), ("b", "1")):
        assert main(["guide", "train", "plants.py:PLANT", "--traces", "traces", "--out", stem, "--iterations", "20",
                     "--seed", seed]) == 0
    (tmp_path / "mix").mkdir()
    shutil.copy(tmp_path / "a.json", tmp_path / "mix" / "g.json")
    for suffix in (".pt", ".npz"):
        shutil.copy(tmp_path / f"b{suffix}", tmp_path / "mix" / f"g{suffix}")
    capsys.readouterr()
    argv = ["infer", "plants.py:PLANT", "--target", "scribble:3", "--particles", "4", "--out", "run", "--guide"]
    assert main(argv + ["mix/g"]) == 2
    assert "g.pt is not the weights written with g.json" in capsys.readouterr().err
    assert main(argv + ["a"]) == 0  # the guide as written


def test_a_rule_whose_call_leaves_an_argument_to_its_default(tmp_path, monkeypatch, capsys):
    """``def plant(ctx, x, y, angle, depth=0)`` started without ``depth``: training called
    its traces damaged ('tuple index out of range', the same again after remaking them),
    and a guide trained with the argument given broke inside procmod's feature code, blamed
    on the model's own line. The features take the default, as the call does."""
    import numpy as np

    (tmp_path / "plants.py").write_text(PLANT_FILE.replace("def plant(ctx, x, y, angle, depth):",
                                                           "def plant(ctx, x, y, angle, depth=0):")
                                        .replace("(0.0, 0.0, -math.pi / 2, 0)", "(0.0, 0.0, -math.pi / 2)"))
    monkeypatch.chdir(tmp_path)
    for argv in (["guide", "traces", "plants.py:PLANT", "--count", "3", "--particles", "8", "--workers", "1",
                  "--out", "traces"],
                 ["guide", "train", "plants.py:PLANT", "--traces", "traces", "--out", "g", "--iterations", "20"],
                 ["infer", "plants.py:PLANT", "--target", "scribble:3", "--particles", "4", "--guide", "g",
                  "--out", "run"]):
        assert main(argv) == 0, capsys.readouterr().err
    from procmod.core import start
    from procmod.guide.features import FeatureExtractor, FeatureSettings, with_defaults
    from procmod.models import model_from_spec

    model = model_from_spec("plants.py:PLANT")
    assert with_defaults(model.root, (1.0, 2.0, 0.5)) == (1.0, 2.0, 0.5, 0)
    assert with_defaults(model.root, (1.0, 2.0, 0.5, 3)) == (1.0, 2.0, 0.5, 3)
    extractor = FeatureExtractor(model, FeatureSettings.condition("local"), None)
    state = start(model, model.new_output())
    np.testing.assert_array_equal(extractor.features(state, "plant", with_defaults(model.root, (1.0, 2.0, 0.5))),
                                  extractor.features(state, "plant", (1.0, 2.0, 0.5, 0)))


def test_defaults_of_a_rule_that_is_an_unhashable_callable():
    """A rule may be a callable dataclass instance (unhashable): looking its defaults up in
    a cache raised TypeError for every recorded training choice."""
    import dataclasses

    from procmod.guide.features import with_defaults

    @dataclasses.dataclass
    class Chain:
        step: float = 2.0

        def __call__(self, ctx, x, y, angle=0.5):
            pass

    assert with_defaults(Chain(), (1.0, 2.0)) == (1.0, 2.0, 0.5)
    assert with_defaults(Chain(), (1.0, 2.0, 0.1)) == (1.0, 2.0, 0.1)


@pytest.mark.parametrize("files, edited", [
    ({"model.py": "from helpers.consts import K\n", "helpers/__init__.py": "", "helpers/consts.py": "K = 1\n"},
     "helpers/consts.py"),
    ({"model.py": "from helpers.consts import K\n", "helpers/consts.py": "K = 1\n"}, "helpers/consts.py"),  # no __init__
    ({"model.py": "from helpers.consts import K\n", "helpers/__init__.py": "",  # absolute, inside the package
      "helpers/consts.py": "from helpers.util import J\nK = J\n", "helpers/util.py": "J = 1\n"}, "helpers/util.py"),
    ({"model.py": "from helpers.sub.consts import K\n", "helpers/__init__.py": "", "helpers/sub/__init__.py": "",
      "helpers/sub/consts.py": "from ..util import J\nK = J\n", "helpers/util.py": "J = 1\n"}, "helpers/util.py"),
    ({"model.py": "from helpers.consts import K\n", "helpers.py": "X = 1\n",  # the package wins, as in Python
      "helpers/__init__.py": "", "helpers/consts.py": "K = 1\n"}, "helpers/consts.py"),
    ({"model.py": "import " + "a" * 300 + "\nimport helper\n", "helper.py": "K = 1\n"}, "helper.py"),  # too long a name
])
def test_a_traces_jobs_code_digest_follows_the_imports_python_would(tmp_path, files, edited):
    """Edits of a package beside the model file (or of a module it imports in turn) had left
    the digest as it was, and a traces job resumed on stale code."""
    import types

    from procmod.guide.traces import model_code_digest

    for name, text in files.items():
        (tmp_path / name).parent.mkdir(parents=True, exist_ok=True)
        (tmp_path / name).write_text(text)
    model = types.SimpleNamespace(root=len, rules=())  # (rules without Python source: the model file alone)
    before = model_code_digest(model, str(tmp_path / "model.py"))
    assert model_code_digest(model, str(tmp_path / "model.py")) == before
    (tmp_path / edited).write_text((tmp_path / edited).read_text() + "EDITED = 1\n")
    assert model_code_digest(model, str(tmp_path / "model.py")) != before


def test_a_traces_job_resumes_under_another_name_for_the_same_model_and_names_what_differs(tmp_path, monkeypatch,
                                                                                          capsys):
    """`plants.py:PLANT` after `plants.py` (its one Model) had been refused as "another
    job", with the job's settings dumped and the one that differed left unsaid. Another
    Model of the file, even of the same name and code, or the folder moved (its data files
    may differ), is another job."""
    import shutil

    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "plants.py").write_text(PLANT_FILE)
    monkeypatch.chdir(tmp_path)
    traces = ["--particles", "4", "--workers", "1", "--out", "tr"]
    assert main(["guide", "traces", "a/plants.py", *traces, "--count", "1"]) == 0, capsys.readouterr().err
    assert main(["guide", "traces", "a/plants.py:PLANT", *traces, "--count", "2"]) == 0, capsys.readouterr().err
    assert main(["guide", "traces", "a/plants.py", *traces, "--count", "3"]) == 0, capsys.readouterr().err
    assert sorted(p.name for p in (tmp_path / "tr").glob("trace_*.json")) == [f"trace_0000{i}.json" for i in range(3)]
    capsys.readouterr()
    assert main(["guide", "traces", "a/plants.py", "--particles", "5", "--workers", "1", "--out", "tr",
                 "--count", "3"]) == 2
    err = capsys.readouterr().err
    assert "another job (particles 4 there, 5 now)" in err and err.count("\n") == 1, err
    # a second Model of the same name and rules, placed elsewhere: not this job's traces
    (tmp_path / "a" / "two.py").write_text(PLANT_FILE + "\nOTHER = Model('my-plant', 'a plant', plant, "
                                           "root_args=lambda p: (5.0, 0.0, -math.pi / 2, 0), "
                                           "new_output_from=PLANT.new_output_from, arg_ranges=PLANT.arg_ranges)\n")
    assert main(["guide", "traces", "a/two.py:PLANT", "--particles", "4", "--workers", "1", "--out", "tr2",
                 "--count", "1"]) == 0, capsys.readouterr().err
    assert main(["guide", "traces", "a/two.py:OTHER", "--particles", "4", "--workers", "1", "--out", "tr2",
                 "--count", "2"]) == 2
    assert "another job (model_file" in capsys.readouterr().err
    shutil.move(tmp_path / "a", tmp_path / "b")  # moved: another job (the data beside it may differ)
    assert main(["guide", "traces", "b/two.py:PLANT", "--particles", "4", "--workers", "1", "--out", "tr2",
                 "--count", "2"]) == 2
    assert "another job (model_file" in capsys.readouterr().err


NO_CHOICES_FILE = """
from procmod import Model
from procmod.geometry import Canvas, Segment

def line(ctx, n):
    ctx.emit(Segment(0.0, -2.0 * n, 0.0, -2.0 * n - 2.0, 0.5))
    if n < 3:
        ctx.spawn("next", line, n + 1)

LINE = Model("my-line", "a line, no choices", line, root_args=lambda p: (0,),
             new_output_from=lambda p: Canvas((-12, 12, -22, 2), 50))
"""


def test_training_on_traces_without_choices_or_without_argument_ranges_says_what_to_do(tmp_path, monkeypatch, capsys):
    """Traces of a model with no random choices ended in a traceback (the optimiser was
    handed no parameters); a model without argument ranges under local features was blamed
    on its first trace, with the advice to delete it and make it again (which changes
    nothing)."""
    (tmp_path / "line.py").write_text(NO_CHOICES_FILE)
    (tmp_path / "plants.py").write_text(PLANT_FILE.replace("arg_ranges=", "_unused="))
    (tmp_path / "plants.py").write_text((tmp_path / "plants.py").read_text().replace(
        "              _unused={\"plant\": ((-12.0, 12.0), (-22.0, 2.0), \"angle\", (0.0, 6.0))},\n", ""))
    monkeypatch.chdir(tmp_path)
    for spec, folder in (("line.py", "tl"), ("plants.py:PLANT", "tp")):
        assert main(["guide", "traces", spec, "--count", "1", "--particles", "4", "--workers", "1",
                     "--out", folder]) == 0, capsys.readouterr().err
    capsys.readouterr()
    assert main(["guide", "train", "line.py", "--traces", "tl", "--iterations", "5", "--features", "target+partial",
                 "--out", "g"]) == 2
    err = capsys.readouterr().err
    assert "hold no random choices" in err and err.count("\n") == 1 and "Traceback" not in err, err
    assert main(["guide", "train", "plants.py:PLANT", "--traces", "tp", "--iterations", "5", "--out", "g"]) == 2
    err = capsys.readouterr().err
    assert "declares no argument ranges for rule 'plant'" in err and "--features target+partial" in err, err
    assert "trace_00000" not in err and "delete it" not in err, err
    assert not list(tmp_path.glob("g.*"))
    # ranges the model declares wrongly: the model's matter too, not the first trace's
    for name, ranges in (("bad", '((5.0, 1.0), None, None, None)'), ("long", '((-12, 12), (-22, 2), "angle", (0, 6), (0, 1))')):
        (tmp_path / f"{name}.py").write_text(PLANT_FILE.replace(
            'arg_ranges={"plant": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, 6.0))}', f'arg_ranges={{"plant": {ranges}}}'))
        assert main(["guide", "train", f"{name}.py", "--traces", "tp", "--iterations", "5", "--out", "g"]) == 2
        err = capsys.readouterr().err
        assert "arg_ranges" in err and "trace_00000" not in err and "delete it" not in err, err


def test_training_flags_are_named_as_flags_and_a_guide_may_be_named_by_its_npz(tmp_path, capsys):
    """--lr and --mixture errors read "the learning rate", "mixture"; --guide G.npz looked
    for G.npz.json (the README names the weights GUIDE.npz)."""
    import shutil

    from procmod.guide.guide import PRETRAINED

    capsys.readouterr()
    for flag, value, said in (("--lr", "nan", "(--lr) must be a finite positive number"),
                              ("--mixture", "1000", "--mixture must be a whole number")):
        assert main(["guide", "train", "vines", "--traces", str(tmp_path / "none"), flag, value,
                     "--out", str(tmp_path / "g")]) == 2
        err = capsys.readouterr().err
        assert said in err, err
    for suffix in (".json", ".npz"):
        shutil.copy(PRETRAINED / f"vines-scribbles{suffix}", tmp_path / f"g{suffix}")
    assert main(["infer", "vines", "--target", "glyph:a", "--particles", "3", "--out", str(tmp_path / "run"),
                 "--guide", str(tmp_path / "g.npz")]) == 0, capsys.readouterr().err


def test_training_on_traces_of_a_model_edited_since_says_to_remake_them_all(tmp_path, monkeypatch, capsys):
    """After an edit of the model, training named one stale trace and advised deleting it
    and rerunning the traces job, which refuses to resume on the edited code: then the next
    trace, one at a time. It now says the traces predate the edit and how to remake them;
    an edit they still replay under (a comment) trains as before."""
    _three_traces(tmp_path, monkeypatch)
    train = ["guide", "train", "plants.py:PLANT", "--traces", "traces", "--iterations", "2", "--out"]
    (tmp_path / "plants.py").write_text(PLANT_FILE + "# a comment\n")
    assert main([*train, "g0"]) == 0, capsys.readouterr().err
    edited = PLANT_FILE.replace("0.6, plant", "0.7, plant")
    (tmp_path / "plants.py").write_text(edited)
    (tmp_path / "plants2.py").write_text(edited)  # the edited rules (this process holds plants.py's as first read)
    capsys.readouterr()
    assert main(["guide", "train", "plants2.py:PLANT", *train[3:], "g1"]) == 2
    err = capsys.readouterr().err
    assert "made before its code was edited" in err and "--overwrite" in err and err.count("\n") == 1, err
    assert "delete it and rerun" not in err


def test_a_guide_records_the_labels_its_categorical_sites_were_trained_on(tmp_path, monkeypatch, capsys):
    """Each categorical site's labels go into the guide's metadata in the order its network
    learned them (GuidedProposer then proposes a reordered categorical by label); a site
    whose labels come from the rule's arguments, and so vary, records none."""
    source = PLANT_FILE.replace("from procmod import Model, Normal", "from procmod import Categorical, Model, Normal")
    source = source.replace('    ctx.emit(Segment(x, y, x1, y1, 0.6))\n',
                            '    ctx.emit(Segment(x, y, x1, y1, 0.6))\n'
                            '    ctx.sample("leaf", Categorical([1, 2], labels=("round", "long")))\n'
                            '    ctx.sample("bud", Categorical([1, 1], labels=(depth, depth + 10)))\n')
    (tmp_path / "plants.py").write_text(source)
    monkeypatch.chdir(tmp_path)
    assert main(["guide", "traces", "plants.py:PLANT", "--count", "3", "--particles", "8", "--workers", "1",
                 "--out", "traces"]) == 0, capsys.readouterr().err
    assert main(["guide", "train", "plants.py:PLANT", "--traces", "traces", "--out", "g", "--iterations", "5"]) == 0, \
        capsys.readouterr().err
    sites = json.loads((tmp_path / "g.json").read_text())["sites"]
    assert sites["plant:leaf"]["labels"] == ["round", "long"]
    assert sites["plant:bud"]["kind"] == "categorical:2" and "labels" not in sites["plant:bud"]
    assert "labels" not in sites["plant:angle"]
