"""3D files read and written (sweep 35): GPU-instanced glTF expanded into placed copies,
malformed Mesh parts refused as ProcmodErrors, GLB bufferView targets set."""

from __future__ import annotations

import json
import struct

import numpy as np
import pytest

from procmod.core.errors import ProcmodError
from procmod.geometry.assets import AssetError, read_assets
from procmod.geometry.mesh_export import export_mesh, glb_bytes
from procmod.geometry.mesh_files import load_mesh_file
from procmod.geometry.solid import Box, Mesh, MeshPartError, part_bounds, part_triangles, translation
from procmod.targets.image import TargetFileError
from procmod.targets.files import read_mesh
from procmod.viewer.layers import mesh_glb

from asset_writers import glb_container

INSTANCING = "EXT_mesh_gpu_instancing"
SIZE = (1.0, 2.0, 0.5)  # a post: no quarter turn maps it onto itself
QUARTER_Z = (0.0, 0.0, np.sqrt(0.5), np.sqrt(0.5))  # x, y, z, w: 90 degrees about +z


def _post():
    s = np.asarray(SIZE) / 2
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * s
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
         (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return v.astype("<f4"), np.array(f, "<u4")


def _glb(path, translations=None, rotations=None, scales=None, node=None, rotation_type=5126, required=True,
         bad_width=False):
    """A GLB (JSON + BIN, written by hand) of one post mesh drawn by one node as GPU instances."""
    v, f = _post()
    blob, views, accessors = b"", [], []

    def add(array, **accessor):
        nonlocal blob
        views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": array.nbytes})
        blob += array.tobytes() + b"\0" * (-array.nbytes % 4)
        accessors.append({"bufferView": len(views) - 1, "count": len(array), **accessor})
        return len(accessors) - 1

    position = add(v, componentType=5126, type="VEC3", min=v.min(0).tolist(), max=v.max(0).tolist())
    indices = add(f.ravel(), componentType=5125, type="SCALAR")
    attributes = {}
    if translations is not None:
        t = np.asarray(translations, "<f4")
        attributes["TRANSLATION"] = add(t[:, :2].copy() if bad_width else t, componentType=5126,
                                        type="VEC2" if bad_width else "VEC3")
    if rotations is not None:
        r = np.asarray(rotations, np.float64)
        if rotation_type == 5122:  # normalized short, as the extension allows
            attributes["ROTATION"] = add(np.round(r * 32767).astype("<i2"), componentType=5122, normalized=True,
                                         type="VEC4")
        else:
            attributes["ROTATION"] = add(r.astype("<f4"), componentType=5126, type="VEC4")
    if scales is not None:
        attributes["SCALE"] = add(np.asarray(scales, "<f4"), componentType=5126, type="VEC3")
    drawing = {"name": "Post", "mesh": 0, "extensions": {INSTANCING: {"attributes": attributes}}, **(node or {})}
    data = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [drawing],
            "meshes": [{"name": "Post", "primitives": [{"attributes": {"POSITION": position}, "indices": indices}]}],
            "accessors": accessors, "bufferViews": views, "buffers": [{"byteLength": len(blob)}],
            "extensionsUsed": [INSTANCING]}
    if required:
        data["extensionsRequired"] = [INSTANCING]
    path.write_bytes(glb_container(data, blob))
    return path


def _nodes(path):
    asset_set = read_assets(path)
    return asset_set, [n for root in asset_set.assets[0].roots for n in root.walk()]


def test_instances_under_a_node_matrix_are_placed_copies_everywhere_the_file_is_read(tmp_path):
    """A fence of instanced posts was refused ("does not expand"): each instance is now a copy
    placed by node world x T (the node's matrix: moved up 10, scaled 2)."""
    node = {"matrix": [2, 0, 0, 0, 0, 2, 0, 0, 0, 0, 2, 0, 0, 10, 0, 1]}  # column-major
    path = _glb(tmp_path / "fence.glb", [(0, 0, 0), (3, 0, 0), (6, 0, 0)], node=node)
    mesh = load_mesh_file(path, force="mesh", process=False)
    assert len(mesh.faces) == 36
    assert np.allclose(mesh.bounds, [[-1, 8, -0.5], [13, 12, 0.5]])
    vertices, faces = read_mesh(path)  # as a volume / silhouette target
    assert len(faces) == 36 and np.allclose([vertices.min(0), vertices.max(0)], [[-1, 8, -0.5], [13, 12, 0.5]])
    asset_set, nodes = _nodes(path)  # as a learn example: each instance a part node
    assert len(asset_set.parts) == 1 and [n.name for n in nodes] == ["Post.001", "Post.002", "Post.003"]
    assert len({n.part for n in nodes}) == 1
    centres = [tuple(np.round(n.transform[:3, 3], 6)) for n in nodes]
    assert centres == [(0, 10, 0), (6, 10, 0), (12, 10, 0)]


def test_a_rotated_scaled_instance_and_missing_optional_accessors(tmp_path):
    """ROTATION and SCALE apply in the instance's frame (T x R x S); a missing TRANSLATION
    places every instance at the node."""
    path = _glb(tmp_path / "turned.glb", [(0, 0, 0), (10, 0, 0)], rotations=[(0, 0, 0, 1), QUARTER_Z],
                scales=[(1, 1, 1), (2, 1, 1)])
    mesh = load_mesh_file(path, force="mesh", process=False)
    second = np.asarray(mesh.vertices)[np.asarray(mesh.vertices)[:, 0] > 5]
    # x scaled 2 (extent 2), then turned a quarter about z: extents (2, 2, 0.5) about (10, 0, 0)
    assert np.allclose(second.min(0), [9, -1, -0.25], atol=1e-6) and np.allclose(second.max(0), [11, 1, 0.25],
                                                                                  atol=1e-6)
    only_turns = _glb(tmp_path / "turns.glb", rotations=[(0, 0, 0, 1), QUARTER_Z])  # no TRANSLATION, no SCALE
    mesh = load_mesh_file(only_turns, force="mesh", process=False)
    assert len(mesh.faces) == 24
    assert np.allclose(mesh.bounds, [[-1, -1, -0.25], [1, 1, 0.25]], atol=1e-6)


def test_a_normalized_short_rotation_reads_as_its_float_one(tmp_path):
    turns = [(0, 0, 0, 1), QUARTER_Z, (np.sqrt(0.5), 0, 0, np.sqrt(0.5))]
    places = [(0, 0, 0), (5, 0, 0), (10, 0, 0)]
    floats = load_mesh_file(_glb(tmp_path / "f.glb", places, turns), force="mesh", process=False)
    shorts = load_mesh_file(_glb(tmp_path / "s.glb", places, turns, rotation_type=5122), force="mesh",
                            process=False)
    assert np.allclose(floats.vertices, shorts.vertices, atol=1e-4)
    assert np.allclose(shorts.bounds, [[-0.5, -1, -1], [10.5, 1, 1]], atol=1e-4)


def test_unreadable_instances_are_refused_when_required_and_drawn_once_when_not(tmp_path):
    path = _glb(tmp_path / "bad.glb", [(0, 0, 0), (3, 0, 0)], bad_width=True)
    with pytest.raises(ValueError, match=r"its GPU instances \(EXT_mesh_gpu_instancing, which it requires\) cannot "
                                         r"be read: .*TRANSLATION is accessor 2 of 2 numbers an instance, not 3"):
        load_mesh_file(path, force="mesh", process=False)
    with pytest.raises(TargetFileError, match="cannot be read"):
        read_mesh(path)
    with pytest.raises(AssetError, match="cannot be read"):
        read_assets(path)
    optional = _glb(tmp_path / "optional.glb", [(0, 0, 0), (3, 0, 0)], bad_width=True, required=False)
    assert len(load_mesh_file(optional, force="mesh", process=False).faces) == 12  # as a reader without it


def test_too_many_instances_are_refused_before_they_are_made(tmp_path, monkeypatch):
    path = _glb(tmp_path / "forest.glb", np.arange(3 * 10_001).reshape(-1, 3))
    with pytest.raises(AssetError, match=r"draws 10,001 GPU instances .*10,002 nodes once expanded, more than "
                                         r"procmod reads \(10000\)"):
        read_assets(path)
    monkeypatch.setattr("procmod.core.limits.physical_memory", lambda: 10 ** 6)
    with pytest.raises(ProcmodError, match=r"expanding its 10,001 GPU instances .* would need at least"):
        load_mesh_file(path, force="mesh", process=False)


@pytest.mark.parametrize("part, message", [
    (Mesh((), ()), r"a Mesh needs at least one face .* got 0 vertices and 0 faces"),
    (Mesh(((0, 0, 0), (1, 0, 0), (0, 1, 0)), ()), "got 3 vertices and 0 faces"),
    (Mesh(((0, 0, 0), (1, 0), (0, 1, 0)), ((0, 1, 2),)), r"a Mesh's vertices must be rows of three numbers"),
    (Mesh(((0, 0, 0), (1, 0, 0), (0, 1, 0)), ((0, 1, 2), (0, 1))), "a Mesh's faces must be rows of three"),
    (Mesh(((0, 0, 0), (1, 0, 0), (0, 1, 0)), ((0, 1, float("nan")),)), "must hold whole vertex numbers, got NaN"),
    (Mesh(((0, 0, 0), (1, 0, 0), (0, 1, 0)), ((0, 1, 9),)), "refers to vertex 9, but it has vertices 0 to 2"),
])
def test_malformed_mesh_parts_are_refused_as_procmod_errors(tmp_path, part, message):
    """Mesh((), ()) ended in numpy's words as a plain ValueError (a reduction over no faces,
    "inhomogeneous shape", "cannot convert float NaN to integer")."""
    for use in (part_triangles, part_bounds,
                lambda p: export_mesh([p], tmp_path / "x.glb", lambda tag: (1, 2, 3)),
                lambda p: export_mesh([p], tmp_path / "x.obj", lambda tag: (1, 2, 3))):
        with pytest.raises(MeshPartError, match=message) as caught:
            use(part)
        assert isinstance(caught.value, ProcmodError) and "\n" not in str(caught.value)
    assert not (tmp_path / "x.glb").exists() and not (tmp_path / "x.obj").exists()
    assert len(part_triangles(Mesh(((0, 0, 0), (1, 0, 0), (0, 1, 0)), ((0, 1, 2.0),)))) == 1  # 2.0 is vertex 2


def _json_chunk(data: bytes) -> dict:
    return json.loads(data[20:20 + struct.unpack_from("<I", data, 12)[0]])


def test_written_glbs_give_their_buffer_views_targets(tmp_path):
    """trimesh left bufferView.target unset (the Khronos validator's BUFFER_VIEW_TARGET_MISSING)."""
    parts = [Box((1, 2, 3), translation(0, 0, 0), "hull"), Box((1, 1, 1), translation(3, 0, 0), "wing")]
    export_mesh(parts, tmp_path / "x.glb", lambda tag: (200, 100, 50))
    layer = mesh_glb([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [(0, 1, 2)])  # a viewer layer's surface
    for tree in (_json_chunk((tmp_path / "x.glb").read_bytes()), _json_chunk(glb_bytes(parts, lambda t: (1, 2, 3))),
                 _json_chunk(layer)):
        want = {}
        for mesh in tree["meshes"]:
            for primitive in mesh["primitives"]:
                for index in primitive["attributes"].values():
                    want[tree["accessors"][index]["bufferView"]] = 34962
                want[tree["accessors"][primitive["indices"]]["bufferView"]] = 34963
        assert want and {k: tree["bufferViews"][k].get("target") for k in want} == want
    assert len(load_mesh_file(tmp_path / "x.glb", force="mesh", process=False).faces) == 24
