"""Hostile and careless input (issue 28.2): every case exits 2 with one line on stderr, no
traceback, and leaves nothing behind (no --out, no hidden temporary folder beside it), and
is refused before the expensive work."""

import json
import os
import shutil
import struct
import sys
import zlib
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import procmod.infer
from procmod.cli import main

SETS = Path(__file__).resolve().parents[1] / "examples_sets" / "strings"


def _png_header(path: Path, width: int, height: int) -> None:
    """A PNG that claims ``width x height`` pixels in its header and holds almost none:
    the shape of a decompression bomb, in 70 bytes."""
    def chunk(kind: bytes, data: bytes) -> bytes:
        return struct.pack(">I", len(data)) + kind + data + struct.pack(">I", zlib.crc32(kind + data) & 0xFFFFFFFF)

    ihdr = struct.pack(">IIBBBBB", width, height, 1, 0, 0, 0, 0)
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", ihdr) + chunk(b"IDAT", zlib.compress(b"\0" * 64))
                     + chunk(b"IEND", b""))


def _silhouette(folder: Path, name: str, **change) -> Path:
    view = {"image": "sketch.png", "camera": {"eye": [0, 4, 20], "look_at": [0, 4, 0], "up": [0, 1, 0],
                                              "projection": "orthographic", "fov": 10}}
    for key, value in change.items():
        if key.startswith("camera_"):
            view["camera"][key[len("camera_"):]] = value
        else:
            view[key] = value
    path = folder / name
    path.write_text(json.dumps({"format": "procmod-silhouette/1", "views": [view]}))
    return path


@pytest.fixture(scope="module")
def inputs(tmp_path_factory):
    """Every hostile input file, made once."""
    d = tmp_path_factory.mktemp("inputs")
    _png_header(d / "bomb30k.png", 30000, 30000)  # Pillow: DecompressionBombError
    _png_header(d / "bomb20k.png", 20000, 20000)
    _png_header(d / "bomb10k.png", 10000, 10000)  # Pillow: only a DecompressionBombWarning
    _png_header(d / "line.png", 1_000_000, 1)  # small, but a 10^12-pixel square once padded
    wide = np.full((10, 10000), 255, np.uint8)
    wide[3:7, 100:9000] = 0
    Image.fromarray(wide).save(d / "wide.png")  # the issue's 10000x10 target
    # a mark 40 pixels long in a frame padded to 5000 x 5000: under half a pixel at 50 x 50
    # (a line across it is a stroke, read widened: targets.image.stroke_preserving_mask)
    speck = np.full((10, 5000), 255, np.uint8)
    speck[3:7, 100:140] = 0
    Image.fromarray(speck).save(d / "wide5k.png")
    sketch = np.full((64, 64), 255, np.uint8)
    sketch[20:40, 20:40] = 0
    Image.fromarray(sketch).save(d / "sketch.png")
    (d / "deep.json").write_text("[" * 100_000 + "]" * 100_000)
    shutil.copy(d / "sketch.png", d / "deep_sidecar.png")
    (d / "deep_sidecar.json").write_text("{\"start\": " + "[" * 100_000 + "]" * 100_000 + "}")
    assert main(["sample", "vines", "-n", "1", "--size", "16", "--out", str(d / "s")]) == 0
    derivation = json.loads((d / "s" / "sample_000.json").read_text())
    for name, params in {"size_huge": {"size": 10 ** 9}, "leaves_yes": {"leaves": "yes"},
                         "start_nan": {"start": [float("nan"), 0.5]}, "start_huge": {"start": [1e308, 0.5]}}.items():
        (d / f"{name}.json").write_text(json.dumps(dict(derivation, params=dict(derivation["params"], **params))))
    _silhouette(d, "sil_fov0.json", camera_fov=0)
    _silhouette(d, "sil_fov_persp.json", camera_projection="perspective", camera_fov=180)
    _silhouette(d, "sil_image_number.json", image=5)
    _silhouette(d, "sil_hit_string.json", hit="lots")
    _silhouette(d, "sil_up_zero.json", camera_up=[0, 0, 0])
    _silhouette(d, "sil_up_along.json", camera_up=[0, 0, 1])
    _silhouette(d, "sil_eye_nan.json", camera_eye=[float("nan"), 4, 20])
    _silhouette(d, "sil_bomb.json", image="bomb30k.png")
    _silhouette(d, "sil_hit_huge.json", hit=1e308)
    header = "{'descr': '<f8', 'fortran_order': False, 'shape': (1000000, 1000000), }"
    header += " " * (118 - len(header)) + "\n"
    (d / "huge.npy").write_bytes(b"\x93NUMPY\x01\x00" + len(header).to_bytes(2, "little") + header.encode())
    view = {"weights": "huge.npy", "camera": {"eye": [0, 4, 20], "look_at": [0, 4, 0]}}
    (d / "sil_npy.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [view]}))
    # guides: a checkpoint that unpickles a Python object, metadata asking for 10^9 components
    import torch

    from procmod.guide.guide import PRETRAINED
    shutil.copy(PRETRAINED / "vines-scribbles.json", d / "evil.json")
    torch.save({"x": __import__("pathlib").PurePosixPath("/etc/passwd")}, d / "evil.pt")
    meta = json.loads((PRETRAINED / "vines-scribbles.json").read_text())
    (d / "bigmix.json").write_text(json.dumps(dict(meta, mixture=10 ** 9)))
    shutil.copy(PRETRAINED / "vines-scribbles.pt", d / "bigmix.pt")
    first = sorted(meta["sites"])[0]  # labels on a site that draws no categorical
    (d / "badlabels.json").write_text(json.dumps(dict(meta, sites=dict(meta["sites"], **{
        first: dict(meta["sites"][first], labels=["a", "b"])}))))
    shutil.copy(PRETRAINED / "vines-scribbles.pt", d / "badlabels.pt")
    (d / "deepguide.json").write_text("[" * 100_000 + "]" * 100_000)
    shutil.copy(PRETRAINED / "vines-scribbles.pt", d / "deepguide.pt")
    # an integer of more digits than Python converts (4300), and a file that never ends
    (d / "bigint.json").write_text(json.dumps(dict(derivation, params=dict(derivation["params"], size=0)))
                                   .replace('"size": 0', '"size": 1' + "0" * 5000))
    if hasattr(os, "mkfifo"):
        os.mkfifo(d / "pipe.json")
    try:  # links round in a loop, and a link to nothing (Path.exists() says False to both)
        os.symlink("loop_b.png", d / "loop_a.png")
        os.symlink("loop_a.png", d / "loop_b.png")
        os.symlink("nothing.png", d / "dangling.png")
    except (OSError, NotImplementedError):  # no links here (Windows without the privilege)
        pass
    shutil.copytree(SETS.parent / "learn" / "castles", d / "nan_castles")
    (d / "nan_castles" / "parts" / "tower.obj").write_text("v nan 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (d / "traces").mkdir()
    (d / "traces" / "traces.json").write_text("[" * 100_000 + "]" * 100_000)
    return d


def _refused(capsys, tmp_path, argv, message):
    before = sorted(p.name for p in tmp_path.iterdir())
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    assert code == 2, (out, err)
    assert err.startswith("procmod: error: ") and err.count("\n") == 1, err
    assert "Traceback" not in err
    assert message in err, err
    # nothing left: no --out, no temporary folder beside it
    assert sorted(p.name for p in tmp_path.iterdir()) == before
    return err


LONG = "x" * 100_000

# (id, argv with {i} = the inputs folder and {o} = the output path, part of the message)
CASES = [
    ("infer-out-proc", ["infer", "vines", "--target", "glyph:a", "--particles", "5", "--out", "/proc/x"],
     "cannot write --out /proc/x"),
    ("sample-out-proc", ["sample", "vines", "-n", "2", "--out", "/proc/x"], "cannot write --out /proc/x"),
    ("render-missing-parent", ["render", "{i}/s/sample_000.json", "--out", "{o}/missing/x.png"],
     "does not exist; create it first"),
    ("traces-out-proc", ["guide", "traces", "vines", "--count", "1", "--particles", "5", "--workers", "1",
                         "--out", "/proc/x"], "cannot write --out /proc/x"),
    ("strings-graph-out-proc", ["strings", "graph", SETS / "castle.json", "--out", "/proc/x"],
     "cannot write --out /proc/x"),
    ("instantiate-out-proc", ["strings", "instantiate", "{i}/no-model", "DMCMD", "--out", "/proc/x/y.glb"],
     "cannot write --out /proc/x/y.glb"),
    ("train-out-proc", ["guide", "train", "vines", "--traces", "{i}/traces", "--out", "/proc/x/g"],
     "cannot write --out /proc/x/g.pt"),
    ("png-30000", ["infer", "vines", "--target", "{i}/bomb30k.png", "--out", "{o}"], "900 megapixels"),
    ("png-20000", ["infer", "vines", "--target", "{i}/bomb20k.png", "--out", "{o}"], "400 megapixels"),
    ("png-10000", ["infer", "vines", "--target", "{i}/bomb10k.png", "--out", "{o}"], "100 megapixels"),
    ("png-padded-square", ["infer", "vines", "--target", "{i}/line.png", "--out", "{o}"], "1000000x1000000"),
    # a 10000x10 target: the remedy is the picture, never a larger --size (which is the render's)
    ("target-10000x10", ["infer", "vines", "--target", "{i}/wide.png", "--out", "{o}"], "crop or scale it down"),
    ("target-vanishes", ["infer", "vines", "--target", "{i}/wide5k.png", "--out", "{o}"],
     "vanishes when the frame is scaled to the model's 50x50 canvas; crop the picture"),
    ("derivation-deep-json", ["render", "{i}/deep.json", "--out", "{o}.png"], "deep.json: JSON nested too deeply"),
    ("sidecar-deep-json", ["infer", "vines", "--target", "{i}/deep_sidecar.png", "--out", "{o}"],
     "deep_sidecar.json: JSON nested too deeply"),
    ("guide-deep-json", ["infer", "vines", "--target", "glyph:a", "--guide", "{i}/deepguide", "--out", "{o}"],
     "deepguide.json: JSON nested too deeply"),
    ("traces-deep-json", ["guide", "train", "vines", "--traces", "{i}/traces", "--out", "{o}"],
     "traces.json: JSON nested too deeply"),
    ("params-size-huge", ["render", "{i}/size_huge.json", "--out", "{o}.png"], "size_huge.json: "),
    ("params-leaves-yes", ["render", "{i}/leaves_yes.json", "--out", "{o}.png"],
     "leaves_yes.json: parameter leaves must be true or false, got \"yes\""),
    ("params-start-nan", ["render", "{i}/start_nan.json", "--out", "{o}.png"],
     "start_nan.json: parameter start[0] must be a finite number"),
    ("params-start-huge", ["render", "{i}/start_huge.json", "--out", "{o}.png"],  # was blamed on the rule
     "start_huge.json: parameter start[0] must be between -10.0 and 10.0, got 1e+308"),
    ("guide-mixture-huge", ["infer", "vines", "--target", "glyph:a", "--guide", "{i}/bigmix", "--out", "{o}"],
     "bigmix.json: mixture must be"),
    ("guide-labels-bad", ["infer", "vines", "--target", "glyph:a", "--guide", "{i}/badlabels", "--out", "{o}"],
     "which has no labels; remove its \"labels\""),
    ("guide-malicious", ["infer", "vines", "--target", "glyph:a", "--guide", "{i}/evil", "--out", "{o}"],
     "evil.pt: refused to load"),
    ("train-mixture-huge", ["guide", "train", "vines", "--traces", "{i}/traces", "--mixture", "1000000000",
                            "--out", "{o}"], "mixture must be"),
    ("scheduler-traces", ["guide", "traces", "vines", "--count", "1", "--scheduler", "not a url", "--out", "{o}"],
     "--scheduler 'not a url' is not a dask scheduler address"),
    ("scheduler-augment", ["strings", "augment", SETS / "castle.json", "--count", "3", "--scheduler", "not a url",
                           "--out", "{o}"], "is not a dask scheduler address"),
    ("augment-seconds-negative", ["strings", "augment", SETS / "castle.json", "--count", "3", "--seconds", "-1",
                                  "--out", "{o}"], "--seconds must be a positive number"),
    ("augment-seconds-nan", ["strings", "augment", SETS / "castle.json", "--count", "3", "--seconds", "nan",
                             "--out", "{o}"], "--seconds must be a positive number"),
    ("sample-n-huge", ["sample", "vines", "-n", "1000000000000", "--size", "16", "--out", "{o}"],
     "would need at least"),
    ("particles-huge", ["infer", "vines", "--target", "glyph:a", "--particles", str(10 ** 18), "--out", "{o}"],
     "--particles 1,000,000,000,000,000,000 would need at least"),
    ("long-target-name", ["infer", "vines", "--target", LONG, "--out", "{o}"], "does not exist"),
    ("long-model-name", ["sample", LONG, "--out", "{o}"], "unknown model"),
    ("derivation-long-integer", ["render", "{i}/bigint.json", "--out", "{o}.png"], "bigint.json: not valid JSON"),
    ("param-long-integer", ["sample", "vines", "-n", "1", "--param", "size=1" + "0" * 5000, "--out", "{o}"],
     "parameter size must be an integer"),
    ("derivation-fifo", ["render", "{i}/pipe.json", "--out", "{o}.png"], "pipe.json is not a regular file"),
    ("train-seed-negative", ["guide", "train", "vines", "--traces", "{i}/traces", "--seed", "-1", "--out", "{o}"],
     "seed must be an integer from 0"),
    ("train-batch-huge", ["guide", "train", "vines", "--traces", "{i}/traces", "--batch", str(10 ** 12),
                          "--out", "{o}"], "batch must be at most"),
    ("workers-infer", ["infer", "vines", "--target", "glyph:a", "--workers", "100000", "--out", "{o}"],
     "--workers 100,000 is more processes than"),
    ("workers-learn", ["learn", SETS.parent / "learn" / "castles" / "examples.json", "--workers", "100000",
                       "--out", "{o}"], "--workers 100,000 is more processes than"),
    ("workers-traces", ["guide", "traces", "vines", "--count", "1", "--workers", "100000", "--out", "{o}"],
     "--workers 100,000 is more processes than"),
    ("learn-nan-vertex", ["learn", "{i}/nan_castles/examples.json", "--workers", "1", "--out", "{o}"],
     "vertices that are not finite numbers"),
    ("learn-particles-huge", ["learn", SETS.parent / "learn" / "castles" / "examples.json", "--particles",
                              str(10 ** 12), "--workers", "1", "--out", "{o}"], "--particles 1,000,000,000,000 is more"),
    ("learn-samples-huge", ["learn", SETS.parent / "learn" / "castles" / "examples.json", "--samples",
                            str(10 ** 12), "--workers", "1", "--out", "{o}"], "--samples must be from 1 to"),
    ("traces-count-huge", ["guide", "traces", "vines", "--count", str(10 ** 12), "--workers", "1", "--out", "{o}"],
     "--count 1,000,000,000,000 traces is more than one job makes"),
    ("target-spec-typo", ["infer", "vines", "--target", "glyh:a", "--out", "{o}"], "unknown target spec 'glyh:a'"),
    ("target-spec-long-with-colon", ["infer", "vines", "--target", "a" * 300 + ":x", "--out", "{o}"],
     "unknown target spec"),
    ("target-link-loop", ["infer", "vines", "--target", "{i}/loop_a.png", "--out", "{o}"],
     "loop_a.png is a symbolic link to nothing"),
    ("target-link-dangling", ["infer", "vines", "--target", "{i}/dangling.png", "--out", "{o}"],
     "dangling.png is a symbolic link to nothing"),
    ("target-circuit-mirrored", ["infer", "vines", "--target", "circuit:mirrored", "--out", "{o}"],
     "has no mirrored copy"),
    ("size-flag-named", ["infer", "vines", "--target", "glyph:a", "--size", "100000", "--out", "{o}"],
     "--size must be between 8 and 4096"),
    ("derivation-is-a-picture", ["render", "{i}/sketch.png", "--out", "{o}.png"], "is not a JSON text file"),
    ("traces-3d-model", ["guide", "traces", "spaceship", "--count", "1", "--particles", "5", "--workers", "1",
                         "--out", "{o}"], "does not fit model 'spaceship'"),
] + [(f"silhouette-{name}", ["infer", "spaceship", "--target", f"{{i}}/sil_{name}.json", "--engine", "ga",
                             "--out", "{o}"], message) for name, message in [
    ("fov0", "views[0].camera.fov"), ("fov_persp", "views[0].camera.fov"), ("image_number", "views[0].image"),
    ("hit_string", "views[0].hit must be a finite number, got \"lots\""), ("up_zero", "views[0].camera.up"),
    ("up_along", "views[0].camera.up"), ("eye_nan", "views[0].camera.eye[0] must be a finite number"),
    ("bomb", "views[0].image: the picture is 900 megapixels"), ("hit_huge", "views[0].hit must be between"), ("npy", "the weights are 1000000x1000000")]]


@pytest.mark.parametrize("argv,message", [c[1:] for c in CASES], ids=[c[0] for c in CASES])
def test_refused_in_one_line_leaving_nothing(inputs, tmp_path, capsys, monkeypatch, argv, message):
    if "/proc/x" in argv and not Path("/proc").is_dir():
        pytest.skip("no /proc on this system")
    if any("pipe.json" in str(a) for a in argv) and not (inputs / "pipe.json").exists():
        pytest.skip("no FIFOs on this system")
    if any("loop_a" in str(a) or "dangling" in str(a) for a in argv) and not (inputs / "loop_a.png").is_symlink():
        pytest.skip("no symbolic links on this system")

    def engine_must_not_run(*args, **kwargs):
        raise AssertionError("the engine ran before the refusal")

    for name in list(procmod.infer.ENGINES):
        monkeypatch.setitem(procmod.infer.ENGINES, name, engine_must_not_run)
    argv = [str(a).replace("{i}", str(inputs)).replace("{o}", str(tmp_path / "out")) for a in argv]
    err = _refused(capsys, tmp_path, argv, message)
    assert len(err) < 700  # a 100 KB argument is echoed cut, not whole


def test_strings_encode_random_gives_up_on_a_graph_with_few_strings(tmp_path, capsys, monkeypatch):
    # "DMCMD" (a path of five parts) has 4 distinct strings: asking for 100,000 must not
    # draw 400,000 of them. The draws are counted, not timed.
    import procmod.strings.codec as codec

    assert main(["strings", "decode", "DMCMD"]) == 0
    (tmp_path / "g.json").write_text(capsys.readouterr().out)
    calls = []
    encode = codec.encode

    def counted(*args, **kwargs):
        calls.append(1)
        return encode(*args, **kwargs)

    monkeypatch.setattr(codec, "encode", counted)
    assert main(["strings", "encode", str(tmp_path / "g.json"), "--random", "100000", "--seed", "1"]) == 0
    found = capsys.readouterr().out.split()
    assert sorted(found) == sorted(set(found)) and len(found) == 4
    # a few draws find the 4, then PATIENCE (1000) draws without a new one end it; the
    # old rule drew 4 x 100,000 (a minute here, minutes on larger graphs)
    assert len(calls) < 2000, len(calls)


def test_strings_encode_random_draws_what_strings_of_draws(tmp_path, capsys):
    # on a graph with many strings, the early stop changes nothing: the same strings in the
    # same order as codec.strings_of from the same generator
    from procmod.strings.codec import strings_of
    from procmod.strings.shapes import read_graph

    assert main(["strings", "decode", "C1CC(N)CC1O"]) == 0
    (tmp_path / "g.json").write_text(capsys.readouterr().out)
    assert main(["strings", "encode", str(tmp_path / "g.json"), "--random", "12", "--seed", "3"]) == 0
    got = capsys.readouterr().out.split()
    want = strings_of(read_graph(tmp_path / "g.json"), 12, np.random.default_rng(3), canonical=False)
    assert got == want and len(got) == 12


def test_one_line_joins_and_cuts_long_messages():
    from procmod.cli import one_line
    assert one_line("first line\n  second line") == "first line second line"
    text = one_line("start " + "y" * 10_000 + " the advice")
    assert len(text) <= 600 and text.startswith("start ") and text.endswith(" the advice")


@pytest.mark.skipif(sys.platform == "win32", reason="POSIX permissions")
def test_read_only_out_folder_is_refused_up_front(tmp_path, capsys):
    import os
    if os.geteuid() == 0:
        pytest.skip("root writes anywhere")
    locked = tmp_path / "locked"
    locked.mkdir()
    locked.chmod(0o500)
    try:
        code = main(["sample", "vines", "-n", "1", "--out", str(locked / "run")])
        assert code == 2 and "cannot write --out" in capsys.readouterr().err
    finally:
        locked.chmod(0o700)


@pytest.mark.parametrize("spec", ["{file}", "{file}:PLANT", "evil.py"])
def test_render_never_runs_a_python_file_a_derivation_names(tmp_path, capsys, monkeypatch, spec):
    """A derivation file is data: a "model" naming a Python file (which procmod never
    writes there) is refused before the file is run, however it is spelled."""
    monkeypatch.chdir(tmp_path)
    ran = tmp_path / "ran"
    code = tmp_path / "evil.py"
    code.write_text(f"open({str(ran)!r}, 'w').write('ran')\nfrom procmod.models.vines import MODEL as PLANT\n")
    assert main(["sample", "vines", "-n", "1", "--size", "32", "--out", str(tmp_path / "s")]) == 0
    data = json.loads((tmp_path / "s" / "sample_000.json").read_text())
    data["model"] = spec.format(file=code)
    (tmp_path / "d.json").write_text(json.dumps(data))
    capsys.readouterr()
    assert main(["render", str(tmp_path / "d.json"), "--size", "32", "--out", str(tmp_path / "r.png")]) == 2
    err = capsys.readouterr().err
    assert not ran.exists() and not (tmp_path / "r.png").exists()
    assert len(err.strip().splitlines()) == 1 and "does not run code a file names" in err and "--model" in err
    # given on the command line, the same file is the user's own choice
    assert main(["render", str(tmp_path / "d.json"), "--model", f"{code}:PLANT", "--size", "32",
                 "--out", str(tmp_path / "r.png")]) == 0 and ran.exists()


def test_a_lone_surrogate_in_a_json_or_gltf_name_is_one_line_and_the_terminal_prints_any_text(tmp_path, capsys):
    """JSON may spell half of a UTF-16 pair alone ("\\ud800"), which is no text: a part
    named so crashed learn after its whole search (the contact sheet's colour), strings
    graph after writing its files (printing the types), a glTF node so named crashed
    inside trimesh, and any refusal quoting such a value became a traceback ("lost
    sys.stderr": surrogateescape prints only U+DC80-U+DCFF)."""
    from procmod.geometry.export import colour_of

    castle = (SETS / "castle.json").read_text().replace('"tower"', '"t\\ud800ower"')
    assert "\\ud800" in castle
    (tmp_path / "castle.json").write_text(castle)
    (tmp_path / "parts").symlink_to(SETS / "parts")
    _refused(capsys, tmp_path, ["strings", "graph", tmp_path / "castle.json", "--out", tmp_path / "g"],
             "holds a lone UTF-16 surrogate escape (a \\uD800-\\uDFFF without its pair), which is no text")
    (tmp_path / "bad.json").write_text('{"format": "x\\udc00"}')
    _refused(capsys, tmp_path, ["render", tmp_path / "bad.json", "--out", tmp_path / "o.png"],
             "bad.json: format holds a lone UTF-16 surrogate escape")
    # a pair is text (an emoji), and keeps being read
    from procmod.core.io import parse_json
    assert parse_json('{"name": "\\ud83d\\ude00"}', "x") == {"name": "\U0001F600"}
    # glTF, read by trimesh: refused before it
    from asset_writers import box_mesh, write_gltf
    path = write_gltf(tmp_path / "ship.gltf", [("hull", [box_mesh((1, 1, 2))])], [{"name": "wing\ud800", "mesh": 0}])
    assert "wing\\ud800" in path.read_text()  # (json.dumps writes the lone half as its escape)
    _refused(capsys, tmp_path, ["learn", path, "--out", tmp_path / "l", "--workers", "1"],
             "is a glTF file whose nodes[0].name holds a lone UTF-16 surrogate escape")
    # what a name can still hold on its way to a file or the terminal
    assert colour_of("t\ud800ower") == colour_of("t\ud800ower")
    assert "a\ud800b\udcffc".encode("utf-8", "procmod-printable") == b"a\\ud800b\xffc"


def test_a_urdf_transform_of_1e999_is_refused_without_numpys_warnings(tmp_path):
    import warnings

    from asset_writers import urdf
    from procmod.geometry.assets import AssetError, read_assets

    (tmp_path / "r.urdf").write_text(urdf({"a": ['<geometry><box size="1 1 1"/></geometry>'],
                                           "b": ['<geometry><box size="1 1 1"/></geometry>']},
                                          [("j", "a", "b", (1e999, 0, 0), (0, 0, 0))]))
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        with pytest.raises(AssetError, match="link 'b' has a non-finite transform"):
            read_assets(tmp_path / "r.urdf")
    assert not [w for w in said if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in said]


def test_a_missing_weights_file_is_said_to_be_missing_not_damaged(tmp_path):
    from procmod.core import ProcmodError
    from procmod.core.io import load_tensors

    with pytest.raises(ProcmodError, match=r"vae.pt: cannot read the weights: the file does not exist$"):
        load_tensors(tmp_path / "vae.pt", what="weights")
