"""What the strings commands write, and where: the up axis of their GLB files, outputs that
would overwrite their inputs, '..' in --out, damaged model files met when training resumes."""

import json
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
import trimesh

from procmod.cli import main

sys.path.insert(0, str(Path(__file__).resolve().parent))
from test_strings_assets import fence_folder  # noqa: E402  (y-up glTF fences: posts 2.0 tall)

TINY = ["--epochs", 1, "--tagger-epochs", 1, "--hidden", 16, "--latent", 4, "--strings-per-shape", 4,
        "--tagger-strings-per-shape", 4]


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _one_line_error(code, err, *words):
    assert code == 2 and len(err.strip().splitlines()) == 1 and "Traceback" not in err, err
    for w in words:
        assert w in err, err


@pytest.fixture(scope="module")
def fence_model(tmp_path_factory):
    """A tiny model of the y-up glTF fences (mesh parts: model/parts/post.obj, rail.obj)."""
    root = tmp_path_factory.mktemp("fence")
    fences = fence_folder(root / "fences")
    assert main(["strings", "augment", str(fences), "--count", "5", "--rounds", "8", "--out", str(root / "col")]) == 0
    assert main(["strings", "train", str(root / "col"), "--out", str(root / "model"), *map(str, TINY)]) == 0
    return root


def _copy(fence_model, tmp_path, name="model"):
    shutil.copytree(fence_model / name, tmp_path / name)
    return tmp_path / name


def test_glb_and_obj_output_are_y_up_as_the_glb_input_was(fence_model, tmp_path, capsys):
    """A y-up glTF scene read in (turned z-up for strings) comes back out of instantiate as a
    y-up GLB or OBJ, standing: its posts (2.0 tall) along y, not lying along z. (The OBJ had
    been z-up, and lay on its side in Blender imported with its defaults.)"""
    stood = trimesh.load(fence_model / "fences" / "a_ring.glb", force="mesh").extents
    assert stood[1] == pytest.approx(2.0, abs=1e-4) and min(stood[0], stood[2]) > 4  # the input: y-up
    model = fence_model / "model"
    for text in (model / "strings.txt").read_text().split()[:5]:
        code, out, err = _run(capsys, "strings", "instantiate", model, text, "--out", tmp_path / "x.glb")
        if code == 0:
            break
    assert code == 0, err
    extents = trimesh.load(tmp_path / "x.glb", force="mesh").extents
    assert extents[1] == pytest.approx(2.0, abs=1e-4) and min(extents[0], extents[2]) > 4, extents
    code, out, err = _run(capsys, "strings", "instantiate", model, text, "--out", tmp_path / "x.obj")
    assert code == 0, err
    obj = trimesh.load(tmp_path / "x.obj", force="mesh")
    assert obj.extents[1] == pytest.approx(2.0, abs=1e-4) and min(obj.extents[0], obj.extents[2]) > 4, obj.extents
    glb = trimesh.load(tmp_path / "x.glb", force="mesh")
    assert np.allclose(obj.bounds, glb.bounds, atol=1e-6)  # the same place, not only the same extents


def test_instantiate_never_overwrites_the_model_it_reads(fence_model, tmp_path, capsys):
    model = _copy(fence_model, tmp_path)
    text = (model / "strings.txt").read_text().split()[0]
    before = {p: p.read_bytes() for p in model.rglob("*") if p.is_file()}
    for out in (model / "parts" / "post.obj", model / "parts" / "rail.obj"):
        code, _, err = _run(capsys, "strings", "instantiate", model, text, "--out", out)
        _one_line_error(code, err, "would overwrite the input")
    # a new file in the model folder: 'strings train' into it no longer resumed, and the
    # --overwrite it advised deleted the trained model
    for out in (model / "castle.glb", model / "shapes" / "one.obj"):
        code, _, err = _run(capsys, "strings", "instantiate", model, text, "--out", out)
        _one_line_error(code, err, "is inside the model folder")
    assert {p: p.read_bytes() for p in model.rglob("*") if p.is_file()} == before
    code, _, err = _run(capsys, "strings", "instantiate", model, text, "--out", tmp_path / "elsewhere.glb")
    assert code == 0, err
    # a string pasted with spaces around it, as 'strings decode' reads it (refused here)
    code, _, err = _run(capsys, "strings", "instantiate", model, f" {text} ", "--out", tmp_path / "spaced.glb")
    assert code == 0, err


def test_dot_dot_in_out_leaves_no_stray_folders(fence_model, tmp_path, capsys, monkeypatch):
    shutil.copytree(fence_model / "col", tmp_path / "col")
    model = _copy(fence_model, tmp_path)
    monkeypatch.chdir(tmp_path)
    text = (model / "strings.txt").read_text().split()[0]
    code, _, err = _run(capsys, "strings", "instantiate", "model", text, "--out", "q1/../q.glb")
    assert code == 0, err
    code, _, err = _run(capsys, "strings", "sample", "model", "-n", 1, "--no-meshes", "--out", "r1/r2/../../Rr")
    assert code == 0, err
    code, _, err = _run(capsys, "strings", "graph", fence_model / "fences", "--out", "g1/g2/../../G")
    assert code == 0, err
    code, _, err = _run(capsys, "strings", "augment", fence_model / "fences", "--count", 3, "--rounds", 4,
                        "--out", "a1/../A")
    assert code == 0, err
    code, _, err = _run(capsys, "strings", "train", "col", "--out", "t1/t2/../../T", *TINY)
    assert code == 0, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["A", "G", "Rr", "T", "col", "model", "q.glb"]


def _edit(name, change):
    def apply(folder):
        data = json.loads((folder / name).read_text())
        change(data)
        (folder / name).write_text(json.dumps(data))
    return apply


def _rename_part(old, new):
    def rename(data):
        data["parts"][new] = data["parts"].pop(old)
        for shape in data["shapes"]:
            for node in shape["nodes"]:
                node["part"] = new if node["part"] == old else node["part"]
    return rename


def _write(name, text):
    return lambda folder: (folder / name).write_text(text)


@pytest.mark.parametrize("damage, words", [
    (_write("categories.json", "garbage\n"), ["categories.json: not valid JSON", "delete it"]),
    (_write("categories.json", '{"names": []}'), ["categories.json is malformed", "lack 'centres'", "delete it"]),
    (_write("categories.json", "[1, 2]"), ["categories.json is malformed", "must be a JSON object"]),
    (_edit("categories.json", lambda d: d.update(centres={})), ["categories.json is malformed", "no centres"]),
    (_edit("categories.json", lambda d: d["examples"].update({"1": [[[1, 2]]]})),
     ["categories.json is malformed", "examples[1] must hold nx4x4 arrays"]),
    (_edit("categories.json", lambda d: d.update(length="x")), ["length must be a positive number"]),
    # (unreadable, it no longer says which of the folder's entries are its part meshes: the
    # folder is refused as another's, still in one line)
    (_write("collection.json", "garbage\n"), ["--overwrite"]),
    (_edit("collection.json", lambda d: d.update(shapes=5)), ["collection.json", "--overwrite"]),
    (_write("tagger.json", "garbage\n"), ["tagger.json: not valid JSON"]),
    (_edit("tagger.json", lambda d: d.update(train={"epoch": "x", "history": []})), ["train.epoch must be a whole"]),
    (_edit("tagger.json", lambda d: d.update(train=[1])), ["tagger.json: train must be an object"]),
    (_edit("tagger.json", lambda d: d["categories"].update(names=[])), ["tagger.json is malformed", "names must"]),
    (_write("vae.json", "garbage\n"), ["vae.json", "not valid JSON"]),
    (_edit("vae.json", lambda d: d["train"].update(history=5)), ["train.history must be a list"]),
], ids=["categories-garbage", "categories-no-centres", "categories-list", "categories-centres-empty",
        "categories-example-shape", "categories-length", "collection-garbage", "collection-shapes",
        "tagger-garbage", "tagger-epoch", "tagger-train-list", "tagger-categories", "vae-garbage", "vae-history"])
def test_damaged_model_files_are_one_line_when_training_resumes(fence_model, tmp_path, capsys, damage, words):
    model = _copy(fence_model, tmp_path)
    damage(model)
    code, _, err = _run(capsys, "strings", "train", fence_model / "col", "--out", model, *TINY)
    _one_line_error(code, err, *words)


@pytest.mark.parametrize("damage, words", [
    (_write("model.json", "garbage\n"), ["model.json", "not valid JSON"]),
    (_edit("model.json", lambda d: d.update(grammar=[1])), ["model.json is malformed", "grammar must be"]),
    (_edit("model.json", lambda d: d["grammar"].update(P=5)), ["model.json is malformed", "rule for 'P'"]),
    (_edit("tagger.json", lambda d: d["categories"].update(symmetries=[[1]])), ["symmetries must hold 4x4"]),
    (_edit("vae.json", lambda d: d["train"].update(data=5)), ["train.data must be"]),
    # a part renamed in the collection: a KeyError traceback when a shape was built
    (_edit("collection.json", _rename_part("rail", "beam")), ["collection.json lacks part types the model was "
                                                             "trained on", "not the collection"]),
], ids=["model-garbage", "model-grammar-list", "model-grammar-rule", "tagger-symmetries", "vae-data",
        "collection-renamed-part"])
def test_damaged_model_files_are_one_line_when_read(fence_model, tmp_path, capsys, damage, words):
    model = _copy(fence_model, tmp_path)
    damage(model)
    code, _, err = _run(capsys, "strings", "sample", model, "-n", 1, "--no-meshes", "--out", tmp_path / "s")
    _one_line_error(code, err, *words)
    assert not (tmp_path / "s").exists()


def test_sample_reads_an_edited_strings_file_and_names_a_bad_line(fence_model, tmp_path, capsys):
    """A BOM and CRLF ends (an editor's save) failed 'strings sample' with "unknown
    character '\\ufeff'", and a bad line with a message that named no file."""
    model = _copy(fence_model, tmp_path)
    text = (model / "strings.txt").read_text()
    (model / "strings.txt").write_bytes(("\ufeff" + text.replace("\n", "\r\n")).encode())
    code, _, err = _run(capsys, "strings", "sample", model, "-n", 2, "--no-meshes", "--out", tmp_path / "s")
    assert code == 0, err
    lines = len(text.split())
    (model / "strings.txt").write_text(text + "C1CC\n")
    code, _, err = _run(capsys, "strings", "sample", model, "-n", 2, "--no-meshes", "--out", tmp_path / "t")
    _one_line_error(code, err, f"strings.txt, string {lines + 1}: dangling ring label")
    assert not (tmp_path / "t").exists()


def test_overwrite_trains_afresh_over_a_model_of_another_training(fence_model, tmp_path, capsys):
    """`strings train --overwrite` over a model folder of other settings was refused as without
    it (the README: resumable jobs replace another job's folder whole with --overwrite), and
    the refusal never named --overwrite."""
    model = _copy(fence_model, tmp_path)
    other = [str(a) for a in TINY]
    other[other.index("--hidden") + 1] = "8"
    code, _, err = _run(capsys, "strings", "train", fence_model / "col", "--out", model, *other)
    _one_line_error(code, err, "another configuration", "pass --overwrite to train afresh")
    code, _, err = _run(capsys, "strings", "train", fence_model / "col", "--out", model, *other, "--overwrite")
    assert code == 0, err
    assert json.loads((model / "model.json").read_text())["vae"]["hidden"] == 8
    fewer = [*other[:other.index("--tagger-epochs")], *other[other.index("--tagger-epochs") + 2:]]
    more_tagger = [*fewer, "--tagger-epochs", "2"]
    assert _run(capsys, "strings", "train", fence_model / "col", "--out", model, *more_tagger)[0] == 0
    code, _, err = _run(capsys, "strings", "train", fence_model / "col", "--out", model, *fewer, "--tagger-epochs",
                        "1")  # a tagger trained 2 epochs: refused, then retrained alone with --overwrite
    _one_line_error(code, err, "tagger trained 2 epochs", "--overwrite")
    vae = (model / "vae.pt").read_bytes()
    code, _, err = _run(capsys, "strings", "train", fence_model / "col", "--out", model, *fewer, "--tagger-epochs",
                        "1", "--overwrite")
    assert code == 0, err
    assert (model / "vae.pt").read_bytes() == vae  # the VAE was this training's: kept
    assert json.loads((model / "model.json").read_text())["tagger"]["epochs"] == 1


def test_overwrite_with_another_collection_replaces_the_model_whole(fence_model, tmp_path, capsys):
    """--overwrite over a fence model with another collection left the fence's copied meshes
    (parts/) behind, and the folder then refused to resume as a stranger's; a folder killed
    before its first checkpoint kept the fence's collection.json through --overwrite, and
    the model trained on the other shapes could not be used with it."""
    other = Path(__file__).resolve().parents[1] / "examples_sets" / "strings" / "moonbase.json"
    model = _copy(fence_model, tmp_path)
    assert (model / "parts").is_dir()
    code, _, err = _run(capsys, "strings", "train", other, "--out", model, *TINY)
    _one_line_error(code, err, "--overwrite")
    code, _, err = _run(capsys, "strings", "train", other, "--out", model, *TINY, "--overwrite")
    assert code == 0, err
    assert not (model / "parts").exists()  # the fence's meshes went with the fence model
    code, _, err = _run(capsys, "strings", "train", other, "--out", model, *TINY)  # the same job: resumes
    assert code == 0, err
    killed = tmp_path / "killed"
    shutil.copytree(fence_model / "model", killed)
    for name in ("vae.json", "vae.pt", "tagger.json", "tagger.pt", "model.json", "strings.txt", "categories.json"):
        (killed / name).unlink(missing_ok=True)  # killed in the first VAE epoch: the collection alone
    code, _, err = _run(capsys, "strings", "train", other, "--out", killed, *TINY)
    _one_line_error(code, err, "holds a model of another collection")
    code, _, err = _run(capsys, "strings", "train", other, "--out", killed, *TINY, "--overwrite")
    assert code == 0, err
    code, _, err = _run(capsys, "strings", "sample", killed, "-n", 1, "--out", tmp_path / "s")
    assert code == 0, err
