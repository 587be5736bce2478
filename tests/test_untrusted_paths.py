"""Names and paths from input files (issue 28 item 1): nothing procmod writes lands outside
the folder the user named, and a file an input file names is read only when it is a
readable file of the right kind — otherwise one line, exit 2, nothing written."""

import json
import re
import shutil
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pytest

from procmod.cli import main
from procmod.core.errors import ProcmodError
from procmod.core.paths import FileNames, UnsafePathError, contained_path, is_plain_name, named_file
from procmod.learn import examples_from_dict, preprocess
from procmod.learn.program import read_program, save_program
from procmod.learn.search import SearchOptions, load_checkpoint
from procmod.learn.structure import initial_program

CUBE = "\n".join(["v -0.5 -0.5 -0.5", "v 0.5 -0.5 -0.5", "v 0.5 0.5 -0.5", "v -0.5 0.5 -0.5",
                  "v -0.5 -0.5 0.5", "v 0.5 -0.5 0.5", "v 0.5 0.5 0.5", "v -0.5 0.5 0.5",
                  "f 1 3 2", "f 1 4 3", "f 5 6 7", "f 5 7 8", "f 1 2 6", "f 1 6 5",
                  "f 2 3 7", "f 2 7 6", "f 3 4 8", "f 3 8 7", "f 4 1 5", "f 4 5 8"]) + "\n"

# Part names an adversary (or a careless converter) might put in an examples file.
HOSTILE = ["../../../../ESCAPED", "..", ".", "a/b", "a\\b", "/abs/ABS", "C:\\x\\y", "NUL", "con.obj",
           "x" * 300, "nul\0byte", "wing", "Wing", "wing_left", "wing/left", " ", ".hidden", "trail."]


def _t(x, y, z, s=1.0):
    return [[s, 0, 0, x], [0, s, 0, y], [0, 0, s, z], [0, 0, 0, 1]]


def _examples(mesh_names, mesh="cube.obj", count=3):
    """An examples object: a box body with one child per mesh part (all the cube)."""
    parts = {"body": {"box": [2.0, 1.0, 2.0]}, **{n: {"mesh": mesh} for n in mesh_names}}
    examples = [{"part": "body", "transform": _t(0, 0, 0),
                 "children": [{"part": n, "transform": _t(0.1 * j, 1 + 0.1 * k, 0, 0.5), "children": []}
                              for j, n in enumerate(mesh_names)]} for k in range(count)]
    return {"format": "procmod-examples/1", "parts": parts, "examples": examples}


def _tree(root: Path) -> set:
    return {p.relative_to(root).as_posix() for p in root.rglob("*")}


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("procmod: error: ") and "\n" not in err, err
    assert "Traceback" not in err
    return err


# ---- the helper --------------------------------------------------------------------------------

def test_file_names_are_one_component_inside_the_folder_and_never_shared():
    names = FileNames(".obj", "examples.json", "part name")
    files = [names.name_for(n) for n in HOSTILE]
    assert len({f.casefold() for f in files}) == len(HOSTILE)  # distinct, also ignoring case
    for name, f in zip(HOSTILE, files):
        assert f.endswith(".obj") and "/" not in f and "\\" not in f and "\0" not in f and ":" not in f
        assert not f.startswith(".") and len(f.encode()) <= 80 and is_plain_name(f[:-4]), (name, f)
        assert Path(f).name == f
    assert names.name_for("wing") == "wing.obj"  # plain names stay readable (and stable)
    assert names.name_for("../../../../ESCAPED") == files[0]  # asking again: the same file
    assert FileNames(".obj").name_for("Wing") == "Wing.obj"  # only a collision maps a plain name
    assert files[HOSTILE.index("Wing")] != "Wing.obj"
    # the mapping depends on the name only, not on the process or machine
    assert FileNames(".obj").name_for("a/b") == files[HOSTILE.index("a/b")]


def test_named_file_and_contained_path(tmp_path):
    (tmp_path / "in").mkdir()
    (tmp_path / "in" / "sub").mkdir()
    (tmp_path / "in" / "m.obj").write_text(CUBE)
    (tmp_path / "shared.obj").write_text(CUBE)
    base = tmp_path / "in"
    assert named_file(base, "m.obj", "f: mesh") == base / "m.obj"
    assert named_file(base, "../shared.obj", "f: mesh") == base / ".." / "shared.obj"  # sharing is fine
    for bad, says in [("", "non-empty"), (".", "folder"), ("./", "folder"), ("../..", "folder"),
                      ("sub", "folder"), ("missing.obj", "does not exist"), (str(base / "m.obj"), "absolute"),
                      ("C:\\m.obj", "absolute"), ("m\0.obj", "NUL"), ("x" * 5000, "cannot use"), (3, "string")]:
        with pytest.raises(UnsafePathError, match=says) as info:
            named_file(base, bad, "f.json: parts.wing.mesh", kind="mesh")
        assert str(info.value).startswith("f.json: parts.wing.mesh") and "\n" not in str(info.value)
        assert len(str(info.value)) < 400
    with pytest.raises(UnsafePathError, match="expected a name ending in .pt"):
        named_file(base, "m.obj", "p: tensors", {".pt"}, "tensors")
    with pytest.raises(UnsafePathError, match="beside it"):
        named_file(base, "../shared.obj", "p: tensors", same_folder=True)
    assert contained_path(tmp_path, "parts/w.obj", "x") == tmp_path / "parts" / "w.obj"
    for bad in ("../w.obj", "parts/../../w.obj", "/w.obj", "", "."):
        with pytest.raises(UnsafePathError):
            contained_path(tmp_path, bad, "x")


# ---- writing: procmod learn --------------------------------------------------------------------

def test_save_program_keeps_every_part_file_inside_out(tmp_path):
    top = tmp_path / "a" / "b" / "c" / "d"
    (top / "in").mkdir(parents=True)
    (top / "in" / "cube.obj").write_text(CUBE)
    names = [n for n in HOSTILE if "\0" not in n]  # JSON files can hold NUL too; see the CLI test
    example_set = examples_from_dict(_examples(names), top / "in")
    data = preprocess(example_set)
    program = initial_program(data, np.random.default_rng(0))
    before = _tree(tmp_path)
    out = top / "out"
    save_program(program, out)
    new = _tree(tmp_path) - before
    assert all(p.startswith("a/b/c/d/out") for p in new), sorted(new)
    assert not (Path("/abs") / "ABS.obj").exists()
    files = sorted((out / "parts").iterdir())
    assert len(files) == len(names)  # one file per mesh part: none overwrote another
    again = read_program(out)
    for n in names:
        assert again.parts[n].kind == "mesh" and again.parts[n].vertices == example_set.parts[n].vertices


@dataclass
class _Quick(SearchOptions):
    init_iterations: int = 10
    split_iterations: int = 5
    warm_iterations: int = 2
    final_iterations: int = 10
    max_rounds: int = 3


def test_cli_learn_with_hostile_part_names_writes_only_inside_out(tmp_path, capsys, monkeypatch):
    import procmod.learn.search
    monkeypatch.setattr(procmod.learn.search, "SearchOptions", _Quick)
    top = tmp_path / "a" / "b" / "c" / "d"
    (top / "in").mkdir(parents=True)
    (top / "in" / "cube.obj").write_text(CUBE)
    absolute = str(tmp_path / "ABS")  # an absolute part name: today it writes tmp/ABS.obj
    names = ["../../../../ESCAPED", absolute, "a/b", "Wing", "wing", "nul\0byte"]
    (top / "in" / "examples.json").write_text(json.dumps(_examples(names)))
    before = _tree(tmp_path)
    out = top / "out"
    assert main(["learn", str(top / "in" / "examples.json"), "--out", str(out), "--particles", "1",
                 "--samples", "2", "--workers", "1"]) == 0
    new = _tree(tmp_path) - before
    assert all(p.startswith("a/b/c/d/out") for p in new), sorted(new)
    program = read_program(out)
    assert set(program.parts) == {"body", *names}
    assert len(list((out / "parts").iterdir())) == len(names)
    # the samples of the learned program still name the parts they place
    assert main(["sample", str(out), "-n", "1", "--out", str(tmp_path / "s.json"), "--format", "examples"]) == 0
    # render never writes over the program's files, which it reads only once the derivation
    # is read (a part's mesh was replaced by the whole sample)
    assert main(["sample", str(out), "-n", "1", "--size", "32", "--out", str(tmp_path / "samples")]) == 0
    derivation = tmp_path / "samples" / "sample_000.json"
    import procmod.core.paths
    for written in (sorted((out / "parts").iterdir())[0], out / "contact_sheet.png"):
        monkeypatch.setattr(procmod.core.paths, "_NAMED_FILES_READ", set())  # as in a new process
        kept = written.read_bytes()
        capsys.readouterr()
        assert main(["render", str(derivation), "--out", str(written)]) == 2
        assert "would overwrite the input" in capsys.readouterr().err and written.read_bytes() == kept
    # a derivation written on Windows names its program with backslashes
    data = json.loads(derivation.read_text())
    assert "/" in data["model"]
    data["model"] = data["model"].replace("/", "\\")
    (tmp_path / "samples" / "windows.json").write_text(json.dumps(data))
    assert main(["render", str(tmp_path / "samples" / "windows.json"), "--size", "32", "--out",
                 str(tmp_path / "w.png")]) == 0, capsys.readouterr().err


# ---- reading: the mesh of an examples file -----------------------------------------------------

@pytest.mark.parametrize("mesh, says", [
    ("", "non-empty"), (".", "folder"), ("../..", "folder"), ("sub", "folder"), ("missing.obj", "does not exist"),
    ("ABSOLUTE", "absolute"), ("notmesh.obj", "triangle mesh|no triangles"), ("notes.txt", "triangle mesh"),
    ("../../../../../../../../dev/null", "regular file|does not exist|folder"),
])
def test_cli_learn_refuses_a_mesh_that_is_not_a_readable_mesh_file(tmp_path, capsys, mesh, says):
    ins = tmp_path / "in"
    (ins / "sub").mkdir(parents=True)
    (ins / "cube.obj").write_text(CUBE)
    (ins / "notmesh.obj").write_text("this is not a mesh\n")
    (ins / "notes.txt").write_text("hello\n")
    if mesh == "ABSOLUTE":
        mesh = str(ins / "cube.obj")  # exists and is a mesh, but the rule is: relative to the file
    (ins / "examples.json").write_text(json.dumps(_examples(["wing"], mesh=mesh)))
    before = _tree(tmp_path)
    assert main(["learn", str(ins / "examples.json"), "--out", str(tmp_path / "out")]) == 2
    err = _one_line_error(capsys)
    assert "examples.json" in err and "parts.wing.mesh" in err, err
    assert re.search(says, err), err
    assert _tree(tmp_path) == before  # nothing written, not even --out


# ---- reading: the tensors of a program ---------------------------------------------------------

@pytest.fixture(scope="module")
def program_dir(tmp_path_factory):
    root = tmp_path_factory.mktemp("prog")
    (root / "in").mkdir()
    (root / "in" / "cube.obj").write_text(CUBE)
    data = preprocess(examples_from_dict(_examples(["wing"]), root / "in"))
    out = root / "p"
    save_program(initial_program(data, np.random.default_rng(0)), out)
    return out


@pytest.mark.parametrize("tensors, says", [
    ("", "non-empty"), (".", "folder"), ("../..", "beside it"), ("ABSOLUTE", "absolute"),
    ("../p/program.pt", "beside it"), ("sub", "ending in .pt"), ("sub.pt", "folder"),
    ("missing.pt", "does not exist"), ("program.json", "ending in .pt"), ("garbage.pt", "cannot read"),
    ("list.pt", "not a tensors file"), (7, "string"),
])
def test_programs_refuse_tensors_that_are_not_their_tensors_file(program_dir, tmp_path, capsys, tensors, says):
    import torch
    d = tmp_path / "p"
    shutil.copytree(program_dir, d)
    (d / "sub").mkdir()
    (d / "sub.pt").mkdir()
    (d / "garbage.pt").write_text("not a torch file\n")
    torch.save([1, 2, 3], d / "list.pt")
    if tensors == "ABSOLUTE":
        tensors = str(d / "program.pt")
    j = json.loads((d / "program.json").read_text())
    j["tensors"] = tensors
    (d / "program.json").write_text(json.dumps(j))
    with pytest.raises(ProcmodError, match=says) as info:
        read_program(d)
    assert "\n" not in str(info.value) and "program.json" in str(info.value) and "tensors" in str(info.value)
    before = _tree(tmp_path)
    assert main(["sample", str(d), "-n", "1", "--out", str(tmp_path / "s")]) == 2
    _one_line_error(capsys)
    assert _tree(tmp_path) == before


def test_a_checkpoint_refuses_tensors_outside_its_folder(tmp_path):
    import torch
    folder = tmp_path / "checkpoint"
    folder.mkdir()
    from procmod.learn.search import CHECKPOINT_FORMAT
    torch.save({}, tmp_path / "elsewhere.pt")  # today it is loaded as the checkpoint's tensors
    doc = {"format": CHECKPOINT_FORMAT, "programs": {}, "particles": []}
    for tensors in (str(tmp_path / "elsewhere.pt"), "../elsewhere.pt", "", "."):
        doc["tensors"] = tensors
        (folder / "state.json").write_text(json.dumps(doc))
        with pytest.raises(ProcmodError, match="cannot resume") as info:
            load_checkpoint(folder, {})
        assert "tensors" in str(info.value)


# ---- writing: a shapes file copies its meshes only into the new file's folder ------------------

def test_write_shapes_never_copies_a_mesh_outside_the_new_folder(tmp_path):
    from procmod.strings.shapes import read_shapes, write_shapes
    (tmp_path / "meshes").mkdir()
    (tmp_path / "meshes" / "cube.obj").write_text(CUBE)
    (tmp_path / "in" / "parts").mkdir(parents=True)
    (tmp_path / "in" / "parts" / "cube.obj").write_text(CUBE)
    shapes = {"format": "procmod-shapes/1", "parts": {"W": {"mesh": "../meshes/cube.obj"}},
              "shapes": [{"nodes": [{"part": "W", "transform": _t(0, 0, 0)}]}]}
    (tmp_path / "in" / "shapes.json").write_text(json.dumps(shapes))
    shape_set = read_shapes(tmp_path / "in" / "shapes.json")  # reading a shared mesh is fine
    out = tmp_path / "x" / "y" / "out"
    out.mkdir(parents=True)
    before = _tree(tmp_path)
    with pytest.raises(UnsafePathError, match="parts.W.mesh"):  # today: writes tmp/x/y/meshes/cube.obj
        write_shapes(shape_set, out / "shapes.json")
    assert _tree(tmp_path) == before
    shapes["parts"]["W"]["mesh"] = "parts/cube.obj"  # a mesh inside the folder is copied along
    (tmp_path / "in" / "shapes.json").write_text(json.dumps(shapes))
    write_shapes(read_shapes(tmp_path / "in" / "shapes.json"), out / "shapes.json")
    assert (out / "parts" / "cube.obj").read_text() == CUBE
    assert read_shapes(out / "shapes.json").library["W"].kind == "mesh"
