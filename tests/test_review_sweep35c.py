"""Review of the GPU-instancing reader (sweep 35): a .gltf drawn as GPU instances whose buffer
file is missing or cut off is refused as every other .gltf is, naming the file and the fix,
when read as learn / strings examples too (the instances' accessors were read first, before
the checks: "cannot read X.gltf (X.bin)", and a buffer file that is a named pipe hung)."""

from __future__ import annotations

import json
import os
import threading

import numpy as np
import pytest

from procmod.geometry.assets import AssetError, read_assets
from procmod.geometry.gltf_accessors import instance_count
from procmod.geometry.mesh_files import declared_faces, gltf_header
from procmod.targets.files import read_mesh
from procmod.targets.image import TargetFileError

from asset_writers import glb_container

INSTANCING = "EXT_mesh_gpu_instancing"


def _instanced_gltf(folder, bin_name="posts.bin", keep=None):
    """A .gltf of one box drawn three times as GPU instances; its buffer in ``bin_name``
    (the first ``keep`` bytes of it; all without)."""
    v = np.array([[x, y, z] for x in (-0.5, 0.5) for y in (-1, 1) for z in (-0.25, 0.25)], "<f4")
    f = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                  (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)], "<u4").ravel()
    t = np.array([(0, 0, 0), (3, 0, 0), (6, 0, 0)], "<f4")
    blob, views = b"", []
    for array in (v, f, t):
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes})
        blob += array.tobytes()
    accessors = [{"bufferView": 0, "count": 8, "componentType": 5126, "type": "VEC3",
                  "min": v.min(0).tolist(), "max": v.max(0).tolist()},
                 {"bufferView": 1, "count": len(f), "componentType": 5125, "type": "SCALAR"},
                 {"bufferView": 2, "count": 3, "componentType": 5126, "type": "VEC3"}]
    data = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"name": "Post", "mesh": 0, "extensions": {INSTANCING: {"attributes": {"TRANSLATION": 2}}}}],
            "meshes": [{"name": "Post", "primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob), "uri": bin_name}],
            "extensionsUsed": [INSTANCING], "extensionsRequired": [INSTANCING]}
    (folder / bin_name).write_bytes(blob if keep is None else blob[:keep])
    path = folder / "posts.gltf"
    path.write_text(json.dumps(data))
    return path


def test_the_instanced_gltf_reads_with_its_buffer_file(tmp_path):
    asset_set = read_assets(_instanced_gltf(tmp_path))
    assert [n.name for n in asset_set.assets[0].nodes()] == ["Post.001", "Post.002", "Post.003"]


def test_an_instanced_gltf_whose_buffer_file_is_missing_names_it_as_examples_too(tmp_path):
    path = _instanced_gltf(tmp_path)
    (tmp_path / "posts.bin").unlink()
    with pytest.raises(TargetFileError, match="'posts.bin' it names is missing .*copy it along"):
        read_mesh(path)  # (said so already)
    with pytest.raises(AssetError) as caught:
        read_assets(path)
    said = str(caught.value)
    assert "'posts.bin' it names is missing" in said and "copy it along" in said and "\n" not in said


def test_an_instanced_gltf_whose_buffer_file_is_cut_off_says_so_as_examples_too(tmp_path):
    path = _instanced_gltf(tmp_path, keep=100)
    with pytest.raises(AssetError, match="'posts.bin' is 100 bytes but the glTF says .*cut off"):
        read_assets(path)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="named pipes are POSIX")
def test_an_instanced_gltf_whose_buffer_file_is_a_named_pipe_is_refused_not_waited_on(tmp_path):
    """Reading the instances' accessors opened the pipe and waited for a writer for ever."""
    path = _instanced_gltf(tmp_path)
    (tmp_path / "posts.bin").unlink()
    os.mkfifo(tmp_path / "posts.bin")
    outcome = []

    def read():
        try:
            read_assets(path)
            outcome.append("read")
        except AssetError as exc:
            outcome.append(str(exc))

    reader = threading.Thread(target=read, daemon=True)
    reader.start()
    reader.join(timeout=5)
    if reader.is_alive():  # waiting on the pipe: give it an end of file, so that the thread ends
        os.close(os.open(tmp_path / "posts.bin", os.O_WRONLY | os.O_NONBLOCK))
        reader.join(timeout=5)
    assert outcome and "is a named pipe (FIFO), not a file" in outcome[0]


def _glb_with_custom_attribute_first(path, instances):
    """A GLB of one box drawn as ``instances`` GPU instances, a custom ``_ID`` attribute of
    two values listed before TRANSLATION (a count the extension says all must share)."""
    v = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], "<f4")
    f = np.array([(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
                  (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)], "<u4").ravel()
    t = np.zeros((instances, 3), "<f4")
    t[:, 0] = 2 * np.arange(instances)
    ids = np.arange(2, dtype="<f4")
    blob, views = b"", []
    for array in (v, f, ids, t):
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes})
        blob += array.tobytes()
    accessors = [{"bufferView": 0, "count": 8, "componentType": 5126, "type": "VEC3", "min": [0, 0, 0],
                  "max": [1, 1, 1]},
                 {"bufferView": 1, "count": len(f), "componentType": 5125, "type": "SCALAR"},
                 {"bufferView": 2, "count": 2, "componentType": 5126, "type": "SCALAR"},
                 {"bufferView": 3, "count": instances, "componentType": 5126, "type": "VEC3"}]
    data = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}],
            "nodes": [{"name": "Post", "mesh": 0,
                       "extensions": {INSTANCING: {"attributes": {"_ID": 2, "TRANSLATION": 3}}}}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob)}],
            "extensionsUsed": [INSTANCING]}
    path.write_bytes(glb_container(data, blob))
    return path


def test_the_limits_count_every_instance_whichever_attribute_comes_first(tmp_path):
    """The faces a file draws and the instances to expand were counted from the first
    attribute (2 here): a file of millions of instances passed the face and memory limits
    unchecked and was expanded, trimesh placing each (about 0.5 ms and 6 KB a copy)."""
    path = _glb_with_custom_attribute_first(tmp_path / "ids_first.glb", 20_000)
    assert instance_count(gltf_header(path), 0) == 20_000
    assert declared_faces(path) == 12 * 20_000
    with pytest.raises(AssetError, match="draws 20,000 GPU instances"):  # refused before any is made
        read_assets(path)
