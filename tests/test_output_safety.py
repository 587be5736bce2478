"""What a command writes or removes stays where the user said (follow-ups of issue 28):
``--overwrite`` never removes a file an input names, a name of a shipped guide never
writes into the package, resumable jobs never mix into an unrelated folder nor write
through a link inside it."""

import hashlib
import json
import os
import shutil
from pathlib import Path

import pytest

from procmod.cli import main
from procmod.core.runfolder import (COLLECTION, LEARN_RUN, TRACES_JOB, OutputLocationError, RunFolder,
                                    check_output_file)
from procmod.guide import Guide, guide_paths
from procmod.guide.guide import PRETRAINED

ROOT = Path(__file__).resolve().parents[1]


def _run(capsys, *argv):
    code = main([str(a) for a in argv])
    out, err = capsys.readouterr()
    return code, out, err


def _digest(folder: Path) -> dict:
    return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir()) if p.is_file()}


def test_a_shipped_guide_name_writes_in_the_current_folder_not_the_package(tmp_path, monkeypatch):
    before = _digest(PRETRAINED)
    monkeypatch.chdir(tmp_path)
    assert guide_paths("vines-scribbles")[0].parent == PRETRAINED  # reading: the shipped guide
    weights, meta = guide_paths("vines-scribbles", for_writing=True)
    assert (weights, meta) == (Path("vines-scribbles.pt"), Path("vines-scribbles.json"))
    Guide.load("vines-scribbles").save("vines-scribbles")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["vines-scribbles.json", "vines-scribbles.npz",
                                                          "vines-scribbles.pt"]
    assert _digest(PRETRAINED) == before


def test_overwrite_never_removes_a_picture_the_target_names(tmp_path, capsys):
    scene, pictures = tmp_path / "scene", tmp_path / "pictures"
    scene.mkdir()
    pictures.mkdir()
    shutil.copy(ROOT / "scenes" / "city_skyline" / "sketch.png", pictures / "sketch.png")
    target = json.loads((ROOT / "scenes" / "city_skyline" / "target.json").read_text())
    target["views"][0]["image"] = "../pictures/sketch.png"
    (scene / "target.json").write_text(json.dumps(target))
    code, _, err = _run(capsys, "infer", "city", "--target", scene / "target.json", "--engine", "forward",
                        "--particles", "2", "--size", "32", "--out", pictures, "--overwrite")
    assert code == 2 and err.count("\n") == 1 and "holds the input" in err and "sketch.png" in err, err
    assert sorted(p.name for p in pictures.iterdir()) == ["sketch.png"]


def test_overwrite_never_removes_a_guide_given_as_a_stem(tmp_path, capsys):
    guides = tmp_path / "guides"
    guides.mkdir()
    for suffix in (".pt", ".json", ".npz"):
        shutil.copy(PRETRAINED / f"vines-scribbles{suffix}", guides / f"mine{suffix}")
    code, _, err = _run(capsys, "infer", "vines", "--target", "glyph:a", "--particles", "2", "--size", "32",
                        "--guide", guides / "mine", "--out", guides, "--overwrite")
    assert code == 2 and "holds the input" in err, err
    assert sorted(p.name for p in guides.iterdir()) == ["mine.json", "mine.npz", "mine.pt"]


def test_a_collection_with_other_things_in_it_is_not_taken_for_an_earlier_one(tmp_path, capsys):
    shapes = ROOT / "examples_sets" / "strings" / "pavilion.json"
    out = tmp_path / "col"
    code, _, err = _run(capsys, "strings", "augment", shapes, "--count", "4", "--out", out)
    assert code == 0, err
    assert COLLECTION.recognises(out)  # its own mesh folder (named by its shapes file) belongs to it
    (out / "my_notes").mkdir()
    (out / "my_notes" / "todo.txt").write_text("keep me")
    assert not COLLECTION.recognises(out)
    code, _, err = _run(capsys, "strings", "augment", shapes, "--count", "4", "--out", out)
    assert code == 2 and "--overwrite" in err and "my_notes" in err, err
    assert (out / "my_notes" / "todo.txt").read_text() == "keep me"


def test_learn_refuses_an_unrelated_folder_and_one_holding_its_input(tmp_path, capsys):
    castles = tmp_path / "castles"
    shutil.copytree(ROOT / "examples_sets" / "learn" / "castles", castles)
    before = _digest(castles / "parts")
    code, _, err = _run(capsys, "learn", castles / "examples.json", "--out", castles, "--workers", "1")
    assert code == 2 and err.count("\n") == 1 and "--overwrite" in err, err
    code, _, err = _run(capsys, "learn", castles / "examples.json", "--out", castles, "--workers", "1",
                        "--overwrite")
    assert code == 2 and "holds the input" in err, err
    assert _digest(castles / "parts") == before


def test_learn_never_writes_through_a_link_inside_its_folder(tmp_path, capsys):
    out, victim = tmp_path / "out", tmp_path / "victim"
    out.mkdir()
    victim.mkdir()
    for name in ("checkpoint", "parts"):
        os.symlink(victim, out / name)
    assert not LEARN_RUN.recognises(out)
    code, _, err = _run(capsys, "learn", ROOT / "examples_sets" / "learn" / "castles" / "examples.json",
                        "--out", out, "--workers", "1")
    assert code == 2 and "--overwrite" in err, err
    assert list(victim.iterdir()) == []


def test_a_resumable_job_replaces_a_linked_out_folder_not_what_it_points_to(tmp_path):
    real = tmp_path / "real"
    real.mkdir()
    (real / "keep.txt").write_text("keep me")
    link = tmp_path / "link"
    os.symlink(real, link)
    folder = RunFolder(link, TRACES_JOB, overwrite=True)
    folder.prepare_in_place(keep=True)
    assert link.is_dir() and not link.is_symlink()
    assert (real / "keep.txt").read_text() == "keep me"


def test_an_output_file_inside_an_input_folder_is_refused(tmp_path):
    traces = tmp_path / "traces"
    traces.mkdir()
    (traces / "traces.json").write_text("{}")
    with pytest.raises(OutputLocationError, match="would overwrite the input"):
        check_output_file(traces / "traces.json", inputs=[traces])
    with pytest.raises(OutputLocationError, match="would overwrite the input"):
        check_output_file(traces / "traces.json", inputs=[traces / "traces.json"])
    check_output_file(traces / "guide.json", inputs=[traces])  # a new file there is fine
    check_output_file(tmp_path / "guide.json", inputs=[traces])


def test_an_out_name_too_long_for_the_file_system_is_one_line(tmp_path, capsys):
    code, _, err = _run(capsys, "sample", "chain", "-n", "1", "--size", "16", "--out", tmp_path / ("a" * 300))
    assert code == 2 and err.count("\n") == 1, err
    with pytest.raises(OutputLocationError):
        check_output_file(tmp_path / ("b" * 300 + ".png"))


def test_a_collection_naming_its_meshes_with_dot_slash_or_as_gltf_is_still_its_own(tmp_path, capsys):
    import base64

    import trimesh
    from asset_writers import gltf_json

    pavilion = json.loads((ROOT / "examples_sets" / "strings" / "pavilion.json").read_text())
    shutil.copytree(ROOT / "examples_sets" / "strings" / "parts", tmp_path / "parts")
    post = trimesh.load(tmp_path / "parts" / "post.obj", force="mesh", process=False)  # the same post, as glTF
    data = gltf_json([("post", [(post.vertices, post.faces)])], [{"name": "post", "mesh": 0}], (0,))
    blob = base64.b64decode(data["buffers"][0]["uri"].split(",", 1)[1])
    (tmp_path / "parts" / "post.bin").write_bytes(blob)
    data["buffers"][0]["uri"] = "post.bin"
    (tmp_path / "parts" / "post.gltf").write_text(json.dumps(data))
    pavilion["parts"]["post"]["mesh"] = "./parts/post.gltf"
    (tmp_path / "pav.json").write_text(json.dumps(pavilion))
    out = tmp_path / "col"
    for _ in range(2):  # the second run replaces the first: it is recognised as one
        code, _, err = _run(capsys, "strings", "augment", tmp_path / "pav.json", "--count", "3", "--out", out)
        assert code == 0, err
    assert (out / "parts" / "post.bin").read_bytes() == blob
    assert COLLECTION.recognises(out)


def test_an_earlier_run_holding_a_named_input_is_refused_before_the_work(tmp_path, capsys, monkeypatch):
    import procmod.infer

    run = tmp_path / "run"
    code, _, err = _run(capsys, "infer", "vines", "--target", "glyph:a", "--particles", "2", "--size", "16",
                        "--out", run)
    assert code == 0, err
    target = json.loads((ROOT / "scenes" / "city_skyline" / "target.json").read_text())
    target["views"][0]["image"] = "run/target.png"  # a picture inside the earlier run
    (tmp_path / "t.json").write_text(json.dumps(target))

    def engine_must_not_run(*args, **kwargs):
        raise AssertionError("the engine ran before the refusal")

    monkeypatch.setitem(procmod.infer.ENGINES, "forward", engine_must_not_run)
    code, _, err = _run(capsys, "infer", "city", "--target", tmp_path / "t.json", "--engine", "forward",
                        "--particles", "2", "--size", "16", "--out", run)
    assert code == 2 and "holds the input" in err, err
    assert (run / "target.png").exists()


def test_an_absolute_gltf_buffer_name_is_read_from_beside_the_file(tmp_path):
    import base64

    from asset_writers import box_mesh, gltf_json

    from procmod.geometry.mesh_files import load_mesh_file

    data = gltf_json([("post", [box_mesh((0.2, 0.2, 2.0))])], [{"name": "post", "mesh": 0}], (0,))
    (tmp_path / "post.bin").write_bytes(base64.b64decode(data["buffers"][0]["uri"].split(",", 1)[1]))
    data["buffers"][0]["uri"] = "/home/someone/export/post.bin"  # where the exporter ran
    (tmp_path / "post.gltf").write_text(json.dumps(data))
    assert len(load_mesh_file(tmp_path / "post.gltf", force="mesh", process=False).faces) == 12


def test_render_never_writes_over_its_input_and_a_guide_never_over_a_users_json(tmp_path, capsys):
    """``render in.svg --out in.svg`` replaced the derivation it read; ``guide train --out
    mytarget`` replaced a user's unrelated mytarget.json with guide metadata."""
    code, _, err = _run(capsys, "sample", "vines", "-n", 1, "--out", tmp_path / "s")
    assert code == 0, err
    derivation = tmp_path / "in.svg"  # a derivation whatever its name
    shutil.copy(next((tmp_path / "s").glob("*.json")), derivation)
    kept = derivation.read_bytes()
    code, _, err = _run(capsys, "render", derivation, "--out", derivation)
    assert code == 2 and "would overwrite the input" in err and derivation.read_bytes() == kept
    mine = tmp_path / "mytarget.json"
    mine.write_text('{"format": "procmod-volume/1"}')
    code, _, err = _run(capsys, "guide", "train", "vines", "--traces", tmp_path / "s", "--iterations", 1,
                        "--out", tmp_path / "mytarget")
    assert code == 2 and "which is not part of a guide" in err and mine.read_text() == '{"format": "procmod-volume/1"}'


def test_dot_dot_in_out_makes_no_folders_outside_it(tmp_path, capsys, monkeypatch):
    """--out a/b/../../R wrote R and left empty folders a/b beside it: the parents were
    made on the path as given, before the system resolved its '..'."""
    monkeypatch.chdir(tmp_path)
    assert main(["sample", "chain", "-n", "1", "--out", "a/b/../../S"]) == 0
    assert main(["render", "S/sample_000.json", "--out", "c/d/../../r.png"]) == 0
    assert main(["sample", "chain", "-n", "1", "--out", "e/f/../../S", "--overwrite"]) == 0
    assert sorted(p.name for p in tmp_path.iterdir()) == ["S", "r.png"]
    folder = RunFolder(tmp_path / "g" / ".." / "T", LEARN_RUN)
    assert folder.path == tmp_path / "T"
