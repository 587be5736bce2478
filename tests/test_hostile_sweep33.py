"""Sweep 33: hostile and careless input files. A glTF part whose index buffer names
vertices the mesh lacks, and a glTF buffer whose name is one of the files a collection or
a string model folder holds: one line, exit 2, and no output that cannot be read back."""

import json
from pathlib import Path

import numpy as np
import pytest

from procmod.cli import main

CUBE_VERTICES = np.array([[x, y, z] for x in (-.5, .5) for y in (-.5, .5) for z in (-.5, .5)], np.float32)
CUBE_FACES = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1], [2, 3, 7], [2, 7, 6],
                       [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]], np.uint32)


def _t(x, y, z):
    return [[1, 0, 0, x], [0, 1, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


def _cube_gltf(folder: Path, buffer_name: str, faces=CUBE_FACES) -> None:
    """``folder/m.gltf``: a unit cube whose vertices and indices are in the file ``buffer_name``."""
    vertices, indices = CUBE_VERTICES.tobytes(), np.asarray(faces, np.uint32).tobytes()
    gltf = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "buffers": [{"uri": buffer_name, "byteLength": len(vertices) + len(indices)}],
            "bufferViews": [{"buffer": 0, "byteOffset": 0, "byteLength": len(vertices)},
                            {"buffer": 0, "byteOffset": len(vertices), "byteLength": len(indices)}],
            "accessors": [{"bufferView": 0, "componentType": 5126, "count": 8, "type": "VEC3",
                           "min": [-.5, -.5, -.5], "max": [.5, .5, .5]},
                          {"bufferView": 1, "componentType": 5125, "count": indices.__len__() // 4,
                           "type": "SCALAR"}]}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / "m.gltf").write_text(json.dumps(gltf))
    (folder / buffer_name).parent.mkdir(parents=True, exist_ok=True)
    (folder / buffer_name).write_bytes(vertices + indices)


def _shapes_file(folder: Path, fmt: str = "procmod-shapes/1") -> Path:
    """A shapes (or examples) file of a glTF cube beside a box."""
    parts = {"m": {"mesh": "m.gltf"}, "b": {"box": [1, 1, 1]}}
    if fmt == "procmod-examples/1":
        example = {"part": "b", "transform": _t(0, 0, 0),
                   "children": [{"part": "m", "transform": _t(0, 1, 0), "children": []}]}
        data = {"format": fmt, "parts": parts, "examples": [example] * 3}
    else:
        data = {"format": fmt, "parts": parts, "shapes": [{"nodes": [
            {"part": "m", "transform": _t(0, 0, .5)}, {"part": "b", "transform": _t(1, 0, .5)},
            {"part": "m", "transform": _t(2, 0, .5)}]}]}
    path = folder / ("shapes.json" if fmt == "procmod-shapes/1" else "examples.json")
    path.write_text(json.dumps(data))
    return path


def _one_line_error(capsys) -> str:
    err = capsys.readouterr().err.strip()
    assert err.startswith("procmod: error: ") and "\n" not in err and "Traceback" not in err, err
    return err


@pytest.mark.parametrize("command", [["strings", "graph"], ["learn", "--workers", "1", "--particles", "1"]])
def test_a_gltf_part_naming_a_vertex_it_lacks_is_one_line(tmp_path, capsys, command):
    faces = CUBE_FACES.copy()
    faces[1, 2] = 99  # 8 vertices: an IndexError traceback had come out of the part library
    _cube_gltf(tmp_path / "in", "m.bin", faces)
    path = _shapes_file(tmp_path / "in", "procmod-shapes/1" if command[0] == "strings" else "procmod-examples/1")
    assert main([*command, str(path), "--out", str(tmp_path / "out")]) == 2
    assert "a triangle refers to a vertex that does not exist (index 99, of 8 vertices)" in _one_line_error(capsys)
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("buffer", ["strings.txt", "growth.json", "graphs/shape_0000.json", "graphs"])
def test_augment_refuses_a_gltf_buffer_named_like_a_collection_file(tmp_path, capsys, buffer):
    # the copied buffer was replaced by the collection's own file: 'strings train' then failed to read the mesh
    _cube_gltf(tmp_path / "in", buffer)
    path = _shapes_file(tmp_path / "in")
    assert main(["strings", "augment", str(path), "--count", "1", "--out", str(tmp_path / "col")]) == 2
    err = _one_line_error(capsys)
    assert f"buffers {buffer!r}" in err and "rename it" in err
    assert not (tmp_path / "col").exists()


def test_train_refuses_a_gltf_buffer_named_like_a_model_file_and_a_plain_one_is_copied(tmp_path, capsys):
    _cube_gltf(tmp_path / "in", "vae.pt")  # a collection may hold it: only a model folder writes vae.pt
    assert main(["strings", "augment", str(_shapes_file(tmp_path / "in")), "--count", "1",
                 "--out", str(tmp_path / "col")]) == 0
    capsys.readouterr()
    assert (tmp_path / "col" / "vae.pt").is_file()
    assert main(["strings", "train", str(tmp_path / "col"), "--out", str(tmp_path / "model"), "--epochs", "1",
                 "--tagger-epochs", "1"]) == 2
    assert "buffers 'vae.pt'" in _one_line_error(capsys)
    assert not (tmp_path / "model").exists()
    # a buffer of another name is copied along, and the collection reads back
    _cube_gltf(tmp_path / "in2", "cube.bin")
    assert main(["strings", "augment", str(_shapes_file(tmp_path / "in2")), "--count", "1",
                 "--out", str(tmp_path / "col2")]) == 0
    from procmod.strings.pipeline import read_collection
    assert read_collection(tmp_path / "col2").library["m"].kind == "mesh"


def test_a_gltf_naming_a_texture_in_a_sibling_folder_is_copied_and_its_collection_recognised(tmp_path, capsys):
    # meshes/m.gltf naming ../textures/wood.png (an exporter's usual layout) had been refused as leaving its folder
    _cube_gltf(tmp_path / "in" / "meshes", "m.bin")
    gltf = json.loads((tmp_path / "in" / "meshes" / "m.gltf").read_text())
    gltf.update(images=[{"uri": "../textures/wood.png"}], textures=[{"source": 0}],
                materials=[{"pbrMetallicRoughness": {"baseColorTexture": {"index": 0}}}])
    gltf["meshes"][0]["primitives"][0]["material"] = 0
    (tmp_path / "in" / "meshes" / "m.gltf").write_text(json.dumps(gltf))
    (tmp_path / "in" / "textures").mkdir()
    from PIL import Image
    Image.new("RGB", (4, 4), (200, 100, 50)).save(tmp_path / "in" / "textures" / "wood.png")
    path = _shapes_file(tmp_path / "in")
    path.write_text(path.read_text().replace('"m.gltf"', '"meshes/m.gltf"'))
    col = tmp_path / "col"
    for _ in range(2):  # the second run replaces the first: the textures folder is the collection's own
        assert main(["strings", "augment", str(path), "--count", "1", "--out", str(col)]) == 0, capsys.readouterr().err
    assert (col / "textures" / "wood.png").is_file() and (col / "meshes" / "m.bin").is_file()
    from procmod.strings.pipeline import read_collection
    assert read_collection(col).library["m"].kind == "mesh"
    # a buffer that leaves the shapes file's folder is still refused, and nothing is written
    gltf["buffers"][0]["uri"] = "../../m.bin"
    (tmp_path / "in" / "meshes" / "m.gltf").write_text(json.dumps(gltf))
    (tmp_path / "m.bin").write_bytes((tmp_path / "in" / "meshes" / "m.bin").read_bytes())
    assert main(["strings", "augment", str(path), "--count", "1", "--out", str(tmp_path / "col2")]) == 2
    assert "leads out of its folder" in _one_line_error(capsys)
    assert not (tmp_path / "col2").exists()


@pytest.mark.skipif(not hasattr(__import__("os"), "mkfifo"), reason="named pipes are POSIX")
def test_a_target_picture_that_is_a_named_pipe_is_refused_not_waited_on(tmp_path):
    import os
    import subprocess
    import sys
    os.mkfifo(tmp_path / "target.png")  # Pillow's open had waited for a writer for ever
    run = subprocess.run([sys.executable, "-m", "procmod", "infer", "chain", "--target", str(tmp_path / "target.png"),
                          "--out", str(tmp_path / "run")], capture_output=True, text=True, timeout=120,
                         env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert run.returncode == 2, run.stderr
    assert run.stderr.strip() == f"procmod: error: {tmp_path / 'target.png'}: a pipe with no picture written to " \
                                 "it; give a picture file, or write one to the pipe as procmod reads it"
    assert not (tmp_path / "run").exists()


def test_a_target_picture_piped_in_is_read(tmp_path):
    """`cat a.png | procmod infer ... --target /dev/stdin`: a pipe with a picture in it is
    read as the picture (the refusal of named pipes had refused it, review h173)."""
    import os
    import subprocess
    import sys

    import numpy as np
    from PIL import Image

    square = np.full((64, 64), 255, dtype=np.uint8)
    square[20:44, 20:44] = 0
    Image.fromarray(square).save(tmp_path / "square.png")
    with open(tmp_path / "square.png", "rb") as picture:
        run = subprocess.run([sys.executable, "-m", "procmod", "infer", "chain", "--target", "/dev/stdin",
                              "--engine", "forward", "--particles", "4", "--size", "32",
                              "--out", str(tmp_path / "run")],
                             input=picture.read(), capture_output=True, timeout=120,
                             env={**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1])})
    assert run.returncode == 0, run.stderr
    assert (tmp_path / "run" / "best.json").exists()
