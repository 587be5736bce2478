"""Mesh files as targets: face lines that name no vertex, meshes of any size, named pipes."""

import json
import os

import numpy as np
import pytest
import trimesh

from procmod.geometry.voxel import VoxelGrid
from procmod.targets.files import mesh_inside, read_mesh
from procmod.targets.image import TargetFileError

TRIANGLES = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\n"


@pytest.mark.parametrize("face, shown", [("f a b c", "'a'"), ("f 2 3 x", "'x'"), ("f 2 3 4.5", "'4.5'"),
                                         ("f 2/1 3 1e0", "'1e0'")])
def test_a_face_corner_that_is_no_number_names_its_line(tmp_path, face, shown):
    """numpy's parser inside trimesh had said "string or file could not be read to its end
    due to unmatched data", naming neither the line nor what a face line holds."""
    (tmp_path / "m.obj").write_text(TRIANGLES + face + "\n")
    with pytest.raises(TargetFileError) as caught:
        read_mesh(tmp_path / "m.obj")
    message = str(caught.value)
    assert "\n" not in message and "m.obj" in message
    assert f"line 8 ('{face}') has {shown} where a face names a vertex" in message
    assert "a face line is 'f' and three or more vertex numbers" in message


def test_line_numbers_count_the_file_s_lines_past_a_continuation(tmp_path):
    """A statement continued with a backslash had put every later line's number off by one."""
    (tmp_path / "m.obj").write_text("v 0 0 \\\n0\n" + TRIANGLES[8:] + "f a b c\n")
    with pytest.raises(TargetFileError, match=r"line 9 \('f a b c'\)"):  # 2 lines, 6, then it
        read_mesh(tmp_path / "m.obj")
    (tmp_path / "z.obj").write_text("v 0 0 \\\n0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n")
    with pytest.raises(TargetFileError, match=r"line 5 \('f 0 1 2'\) names vertex 0"):
        read_mesh(tmp_path / "z.obj")


def test_a_face_with_commas_is_refused_not_dropped(tmp_path):
    """``f 1,2,4`` had been dropped without a word (trimesh took it for one corner)."""
    (tmp_path / "m.obj").write_text(TRIANGLES + "f 2,3,4\n")
    with pytest.raises(TargetFileError, match=r"line 8 \('f 2,3,4'\) separates its vertex numbers with commas"):
        read_mesh(tmp_path / "m.obj")


@pytest.mark.parametrize("suffix", ["stl", "glb"])
def test_a_mesh_reads_the_same_at_any_scale(tmp_path, suffix):
    """Seams were merged to a fixed 1e-8: a torus of 10 nm collapsed into a few faces, and one
    of 1e12 into 33 vertices (trimesh's rounding overflowed int64); both read as in metres."""
    torus = trimesh.creation.torus(1.0, 0.35, major_sections=24, minor_sections=12)
    read = {}
    for scale in (1e-8, 1.0, 1e12):
        mesh = torus.copy()
        mesh.apply_scale(scale)
        mesh.export(tmp_path / f"t{scale:g}.{suffix}")
        read[scale] = read_mesh(tmp_path / f"t{scale:g}.{suffix}")
    for scale in (1e-8, 1e12):
        assert len(read[scale][0]) == len(read[1.0][0]) == len(torus.vertices)
        assert np.array_equal(read[scale][1], read[1.0][1])
        assert np.allclose(read[scale][0] / scale, read[1.0][0], atol=1e-6)
    # on the same grid scaled (a voxel centre on the surface may round either way)
    small = mesh_inside(*read[1e-8], VoxelGrid((-1.5e-8, -1.5e-8, -0.45e-8), 0.1e-8, (30, 30, 9)), "t")
    mid = mesh_inside(*read[1.0], VoxelGrid((-1.5, -1.5, -0.45), 0.1, (30, 30, 9)), "t")
    assert mid.sum() > 1000 and (small != mid).sum() <= 0.01 * mid.sum()


def test_a_mesh_at_1e30_is_no_point(tmp_path):
    """Coordinates of 1e30 overflowed the merge's int64 rounding: every vertex became one
    and the mesh was refused as of zero area."""
    trimesh.creation.box(bounds=[[-1e30] * 3, [1e30] * 3]).export(tmp_path / "big.obj")
    vertices, faces = read_mesh(tmp_path / "big.obj")
    assert (len(vertices), len(faces)) == (8, 12)
    assert np.allclose(np.abs(vertices), 1e30)


@pytest.mark.skipif(not hasattr(os, "mkfifo"), reason="no named pipes here")
def test_a_named_pipe_is_called_what_it_is(tmp_path):
    """A FIFO as the mesh had been called empty, as a glTF's buffer missing."""
    os.mkfifo(tmp_path / "pipe.obj")
    with pytest.raises(TargetFileError, match=r"pipe\.obj is a named pipe \(FIFO\), not a mesh file"):
        read_mesh(tmp_path / "pipe.obj")
    files = trimesh.Scene(trimesh.creation.box()).export(file_type="gltf")
    header = json.loads(files["model.gltf"])
    (tmp_path / "model.gltf").write_bytes(files["model.gltf"])
    os.mkfifo(tmp_path / header["buffers"][0]["uri"])
    with pytest.raises(TargetFileError, match=r"the buffer file '[^']+' it names is a named pipe \(FIFO\), not a file"):
        read_mesh(tmp_path / "model.gltf")
