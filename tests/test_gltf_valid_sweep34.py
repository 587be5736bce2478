"""The GLB files procmod writes are valid glTF 2.0: what the Khronos glTF-Validator checks,
checked here in plain Python (GLB framing, strict JSON, accessor bounds equal to the data,
alignment, index types), and the validator itself when it is installed (slow).

The Khronos validator had found two kinds of broken file: a part with coordinates beyond
32-bit floats (glTF's) written as ``Infinity`` in the JSON (INVALID_JSON: no reader opens
it; a NaN part was dropped without a word, or failed in trimesh with an AssertionError),
and an empty viewer layer written with a zero-length BIN chunk (GLB_EMPTY_BIN_CHUNK).
Looking at far-out parts, a part past ~9.2e10 from the origin collapsed as trimesh merged
its vertices (an int64 overflow), in OBJ files and merged GLBs.
"""

from __future__ import annotations

import json
import os
import shutil
import struct
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from procmod.core.errors import ProcmodError
from procmod.geometry.export import colour_of
from procmod.geometry.mesh_export import MAX_PART_NODES, export_mesh, glb_bytes, parts_to_trimesh
from procmod.geometry.solid import Box, Cylinder, Mesh, compose, rotation, scaling, translation
from procmod.viewer.layers import mesh_glb

COMPONENTS = {5120: np.int8, 5121: np.uint8, 5122: np.int16, 5123: np.uint16, 5125: np.uint32, 5126: np.float32}
WIDTH = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def _strict_constant(name):
    raise ValueError(f"{name} is not JSON")


def read_glb(data: bytes) -> tuple[dict, bytes | None]:
    """A GLB's JSON and BIN chunk, checking its framing as the glTF 2.0 spec states it."""
    magic, version, length = struct.unpack_from("<III", data, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(data))
    chunks, at = [], 12
    while at < len(data):
        size, kind = struct.unpack_from("<II", data, at)
        assert size % 4 == 0 and at + 8 + size <= len(data), "chunks are padded to 4 bytes and lie in the file"
        chunks.append((kind, data[at + 8:at + 8 + size]))
        at += 8 + size
    assert chunks[0][0] == 0x4E4F534A, "the JSON chunk comes first"
    # NaN / Infinity are Python's JSON, not JSON's
    header = json.loads(chunks[0][1].decode("utf-8"), parse_constant=_strict_constant)
    assert len(chunks) <= 2 and all(kind == 0x004E4942 for kind, _ in chunks[1:])
    binary = chunks[1][1] if len(chunks) == 2 else None
    assert binary is None or len(binary) > 0, "a GLB holds no zero-length BIN chunk"
    return header, binary


def accessor_data(header: dict, binary: bytes, index: int) -> np.ndarray:
    """An accessor's elements (count x width), checking that they lie, aligned, in their buffer view."""
    accessor = header["accessors"][index]
    view = header["bufferViews"][accessor["bufferView"]]
    dtype = np.dtype(COMPONENTS[accessor["componentType"]])
    width = WIDTH[accessor["type"]]
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    assert start % dtype.itemsize == 0, "an accessor starts aligned to its component size"
    stride = view.get("byteStride", dtype.itemsize * width)
    assert stride % 4 == 0 or accessor["type"] == "SCALAR"
    end = start + stride * (accessor["count"] - 1) + dtype.itemsize * width
    assert end <= view.get("byteOffset", 0) + view["byteLength"] <= len(binary)
    rows = np.lib.stride_tricks.as_strided(np.frombuffer(binary, dtype=np.uint8, offset=start),
                                           (accessor["count"], dtype.itemsize * width), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(accessor["count"], width)


def check_glb(data: bytes) -> dict:
    """Check a GLB as the validator does where viewers trip: accessor min/max equal to the
    data, finite positions, index types that hold every index, indices within the vertices."""
    header, binary = read_glb(data)
    assert header["asset"]["version"] == "2.0"
    assert (binary is None) == (not header.get("buffers")), "a buffer for the BIN chunk, and only then"
    if binary is not None:
        assert header["buffers"][0]["byteLength"] <= len(binary) < header["buffers"][0]["byteLength"] + 4
    for view in header.get("bufferViews", []):
        assert view.get("byteOffset", 0) % 4 == 0
    for k, accessor in enumerate(header.get("accessors", [])):
        values = accessor_data(header, binary, k)
        if "min" in accessor or "max" in accessor:
            dtype = COMPONENTS[accessor["componentType"]]
            assert np.array_equal(np.asarray(accessor["min"], dtype=dtype), values.min(0)), f"accessor {k} min"
            assert np.array_equal(np.asarray(accessor["max"], dtype=dtype), values.max(0)), f"accessor {k} max"
    for mesh in header.get("meshes", []):
        for primitive in mesh["primitives"]:
            position = header["accessors"][primitive["attributes"]["POSITION"]]
            assert "min" in position and "max" in position, "POSITION needs min and max"
            points = accessor_data(header, binary, primitive["attributes"]["POSITION"])
            assert np.isfinite(points).all()
            if "indices" in primitive:
                indices = accessor_data(header, binary, primitive["indices"])
                assert header["accessors"][primitive["indices"]]["componentType"] in (5121, 5123, 5125)
                assert indices.max() < position["count"] <= np.iinfo(indices.dtype).max + 1
    return header


def _grid_mesh(n: int) -> Mesh:
    """One flat mesh of n x n vertices (numpy arrays: fast)."""
    grid = np.stack(np.meshgrid(np.arange(n), np.arange(n), indexing="ij"), -1).reshape(-1, 2)
    quad = (np.arange(n - 1)[:, None] * n + np.arange(n - 1)[None, :]).reshape(-1)
    faces = np.r_[np.c_[quad, quad + n, quad + 1], np.c_[quad + 1, quad + n, quad + n + 1]]
    return Mesh(np.c_[grid, np.zeros(len(grid))].astype(float), faces, tag="ground")


CASES = {
    "one box": [Box((1, 2, 3))],
    "zero-size box and cone": [Box((0, 0, 0)), Cylinder(0.5, 2.0, translation(2, 0, 0), top_radius=0.0)],
    "placements": [Box((1, 2, 3), scaling(-1, 1, 1)),
                   Box((1, 1, 1), (1, 0.5, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1)),  # sheared
                   Box((1, 1, 1), compose(translation(1e12, 2, 3), rotation("z", 0.3), scaling(2, 3, 4))),
                   Cylinder(1.0, -2.0, scaling(0, 1, 1))],
    "names": [Box((1, 1, 1), tag='tür"m\'\\ 塔 🚀'), Box((1, 1, 1), translation(2, 0, 0), tag=""),
              Box((1, 1, 1), translation(4, 0, 0), tag="world"), Box((1, 1, 1), translation(6, 0, 0), tag="world")],
    "many parts": [Box((1, 1, 1), translation(i, 0, 0), tag=f"t{i % 3}") for i in range(MAX_PART_NODES + 1)],
    "over 65535 vertices": [_grid_mesh(260)],
}


@pytest.mark.parametrize("name", list(CASES))
def test_written_glbs_are_valid_gltf(tmp_path, name):
    parts = CASES[name]
    export_mesh(parts, tmp_path / "x.glb", colour_of)
    header = check_glb((tmp_path / "x.glb").read_bytes())
    assert len(header["nodes"]) == (len(parts) if len(parts) <= MAX_PART_NODES else len({p.tag for p in parts}))
    check_glb(glb_bytes(parts, colour_of))


def test_viewer_layers_are_valid_gltf():
    mesh = _grid_mesh(260)
    check_glb(mesh_glb(mesh.vertices, mesh.faces))
    check_glb(mesh_glb([[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 1, 2]]))


def test_an_empty_viewer_layer_holds_no_empty_bin_chunk():
    header, binary = read_glb(mesh_glb(np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)))
    assert binary is None and not header.get("buffers") and not header.get("meshes")
    assert read_glb(glb_bytes([], colour_of))[1] is None


@pytest.mark.parametrize("part", [Box((1e39, 1.0, 1.0)), Box((1.0, float("nan"), 1.0)),
                                  Box((1.0, 1.0, 1.0), translation(4e38, 0, 0)),
                                  Cylinder(1.0, 1.0, translation(float("inf"), 0, 0))])
@pytest.mark.parametrize("suffix", [".glb", ".obj"])
def test_coordinates_a_mesh_file_cannot_hold_are_refused(tmp_path, part, suffix):
    path = tmp_path / f"x{suffix}"
    with pytest.raises(ProcmodError, match="which a mesh file cannot hold") as caught:
        export_mesh([Box((1, 1, 1), tag="fine"), part], path, colour_of)
    message = str(caught.value)
    assert "\n" not in message and type(part).__name__ in message
    assert list(tmp_path.iterdir()) == [], "no file, not a half-written one"
    with pytest.raises(ProcmodError, match="which a mesh file cannot hold"):
        glb_bytes([part], colour_of)


def test_a_viewer_layer_beyond_float32_is_refused():
    with pytest.raises(ProcmodError, match="which a mesh file cannot hold"):
        mesh_glb([[0, 0, 0], [1e39, 0, 0], [0, 1, 0]], [[0, 1, 2]])


@pytest.mark.parametrize("x", [1e11, -1e12])
def test_a_far_part_keeps_its_shape(tmp_path, x):
    """trimesh's vertex merge had overflowed int64 past ~9.2e10: the box came out 4 vertices, 0 wide."""
    part = Box((1, 2, 3), translation(x, 0, 0))
    mesh = parts_to_trimesh([part], colour_of)
    assert len(mesh.vertices) == 8 and np.allclose(mesh.extents, (1, 2, 3))
    export_mesh([part], tmp_path / "x.obj", colour_of)
    assert sum(line.startswith("v ") for line in (tmp_path / "x.obj").read_text().splitlines()) == 8


def _validator() -> Path | None:
    """The gltf-validator npm package named by $GLTF_VALIDATOR, when it and node are there."""
    folder = os.environ.get("GLTF_VALIDATOR")
    if not folder or not Path(folder, "package.json").is_file() or shutil.which("node") is None:
        return None
    return Path(folder)


@pytest.mark.slow
def test_khronos_validator_finds_no_error_or_warning(tmp_path):
    """Runs bench/validate_gltf.py (the edge cases and sample outputs; no infer runs)."""
    validator = _validator()
    if validator is None:
        pytest.skip("set GLTF_VALIDATOR to the folder of `npm install gltf-validator` (needs node)")
    bench = Path(__file__).resolve().parents[1] / "bench" / "validate_gltf.py"
    done = subprocess.run([sys.executable, str(bench), "--validator", str(validator), "--quick"],
                          capture_output=True, text=True, timeout=600)
    assert done.returncode == 0, done.stdout[-4000:] + done.stderr[-2000:]
