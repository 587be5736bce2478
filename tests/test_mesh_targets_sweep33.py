"""Mesh files as volume targets: a sweep with meshes written as modelling tools write them."""

import json

import numpy as np
import pytest
import trimesh

from procmod.geometry.inside import closed_winding
from procmod.geometry.voxel import VoxelGrid
from procmod.targets.files import load_volume_target, read_mesh
from procmod.targets.image import TargetFileError


def test_column_on_a_triangles_bound_is_not_skipped(tmp_path):
    """A voxel column whose centre lies exactly on a triangle's bounding box (x = -2.0 on a
    grid from -2.7 at 0.2, where (-2.0 + 2.7) / 0.2 - 0.5 rounds to 3.000000000000001) had
    been left out of the triangles to its right: the column missed a crossing and a torus
    written as OBJ (its tube's top and bottom rings at x = -2 exactly) lost the voxels of that
    column inside its tube."""
    torus = trimesh.creation.torus(major_radius=2.0, minor_radius=0.6, major_sections=64, minor_sections=32)
    torus.export(tmp_path / "torus.obj")
    (tmp_path / "t.json").write_text(json.dumps({
        "format": "procmod-volume/1", "layers": [{"file": "torus.obj"}],
        "grid": {"origin": [-2.7, -2.7, -0.7], "voxel_size": 0.2, "shape": [27, 27, 7]}}))
    target = load_volume_target(tmp_path / "t.json")
    mask = target.combined > 0
    centres = target.grid.centres()
    ring = np.hypot(centres[..., 0], centres[..., 1]) - 2.0
    distance = np.hypot(ring, centres[..., 2]) - 0.6
    far = np.abs(distance) > target.grid.size  # clear of the surface (its facets and ties)
    assert np.array_equal(mask[far], (distance < 0)[far])
    assert mask[3, 13, 1:6].all()  # the column at x = -2, y = 0 through the tube


def test_crossing_on_a_column_at_a_rounded_bound():
    """A box whose left side lies on a column centre computed as the grid computes it: the line
    there, perturbed to the right, runs through the box as its neighbour does."""
    grid = VoxelGrid((-2.7, -0.3, -1.0), 0.2, (8, 3, 10))
    x = -2.7 + 3.5 * 0.2  # -2.0: the centre of column 3, where the index rounds up
    box = trimesh.creation.box(bounds=[[x, -0.25, -0.45], [x + 0.8, 0.25, 0.45]])
    w = closed_winding(box.vertices[box.faces], np.ones(len(box.faces), dtype=np.int64), grid).reshape(grid.shape)
    # the line perturbed off x = -2.0 to its right runs inside the box: column 3 is as full as column 4
    assert np.array_equal(w[3], w[4])
    assert w[4, 1].sum() == 4  # z = -0.3 .. 0.3


def test_a_far_stray_face_leaves_the_model_s_faces(tmp_path):
    """Zero area is judged by each face's own size: against the whole mesh's extent, one
    stray triangle 1e7 units away made every face of a sphere of radius 2 (faces about 0.05
    wide) "zero area", and the mesh was refused as having none (1e6 away: as lying off the
    grid, which spanned the sphere)."""
    sphere = trimesh.creation.icosphere(subdivisions=5, radius=2.0)
    stray = trimesh.Trimesh([[1e7, 0, 0], [1e7 + 1, 0, 0], [1e7, 1, 0]], [[0, 1, 2]])
    trimesh.util.concatenate([sphere, stray]).export(tmp_path / "ship.obj")
    vertices, faces = read_mesh(tmp_path / "ship.obj")
    assert len(faces) == len(sphere.faces) + 1
    (tmp_path / "t.json").write_text(json.dumps({
        "format": "procmod-volume/1", "layers": [{"file": "ship.obj"}],
        "grid": {"origin": [-2.5, -2.5, -2.5], "voxel_size": 0.2, "shape": [25, 25, 25]}}))
    mask = load_volume_target(tmp_path / "t.json").combined > 0
    assert mask[12, 12, 12] and 4000 < mask.sum() < 4300  # the sphere: 4,139 voxel centres within radius 2


def test_huge_coordinates_print_no_warning(tmp_path, capsys):
    """A face on coordinates near 1e300 overflowed in the area test and numpy printed a
    RuntimeWarning (two lines) before procmod's one-line refusal."""
    import warnings

    (tmp_path / "huge.obj").write_text("v -1e300 -1 -1\nv 1e300 -1 -1\nv 0 1 -1\nv 0 0 1\n"
                                       "f 1 3 2\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        with pytest.raises(TargetFileError):
            read_mesh(tmp_path / "huge.obj")


def test_floor_and_roof_planes_over_folded_walls_close_the_room(tmp_path):
    """A room as modelled: four walls folded into one open piece (a tube), and a floor and a
    roof as separate planes a little wider than it (an overhang). The planes alone enclose
    nothing, so they were left out "as leaf cards" and the room's inside was the open tube's
    guess (7,432 of its 8,000 voxels, 64 of the lost ones more than a voxel from any wall)."""
    corners = [(-1, -1), (1, -1), (1, 1), (-1, 1)]
    vertices = [(x, -1, z) for x, z in corners] + [(x, 1, z) for x, z in corners]
    faces = []
    for i in range(4):
        j = (i + 1) % 4
        faces += [[i, j, 4 + j], [i, 4 + j, 4 + i]]
    for y, order in ((-1, [[0, 1, 2], [0, 2, 3]]), (1, [[0, 2, 1], [0, 3, 2]])):
        base = len(vertices)
        vertices += [(-1.1, y, -1.1), (1.1, y, -1.1), (1.1, y, 1.1), (-1.1, y, 1.1)]
        faces += [[base + a for a in face] for face in order]
    trimesh.Trimesh(vertices, faces, process=False).export(tmp_path / "room.obj")
    (tmp_path / "t.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.1,
                                                 "layers": [{"file": "room.obj"}]}))
    target = load_volume_target(tmp_path / "t.json")
    assert (target.combined > 0).sum() == 8000
    assert not any("open flat pieces" in note for note in target.file_notes)


def test_a_relative_index_before_the_first_vertex_is_refused(tmp_path):
    """``f -1 -2 -9`` after four vertices: rewritten as vertex -4, which trimesh counted
    back from the end of the file again, a face on another vertex without a word."""
    (tmp_path / "cut.obj").write_text("v -1 -1 -1\nv 1 -1 -1\nv 0 1 -1\nv 0 0 1\n"
                                      "f -1 -2 -9\nf 1 2 4\nf 2 3 4\nf 3 1 4\n")
    with pytest.raises(TargetFileError, match=r"line 5 .*names vertex -9, 9 back, but only 4 vertices"):
        read_mesh(tmp_path / "cut.obj")


FAR_STRAY = """
import sys
import numpy as np
import trimesh
from procmod.geometry.inside import closed_winding
from procmod.geometry.voxel import VoxelGrid
grid = VoxelGrid((-1.0, -1.0, -1.0), 0.2, (10, 10, 10))
box = trimesh.creation.box(extents=[1, 1, 1])
x = float(sys.argv[1])
stray = np.array([[[x, 0, 0], [x + 1, 0, 0], [x, 1, 0]]])
for tris in (box.vertices[box.faces], np.concatenate([box.vertices[box.faces], stray])):
    print((closed_winding(tris, np.ones(len(tris), dtype=np.int64), grid) > 0.5).sum())
"""


@pytest.mark.parametrize("x", ["1e19", "3.4e38", "-1e19", "inf"])
def test_a_stray_face_beyond_2_to_the_63_voxels_leaves_the_box_and_ends(x):
    """A stray face at 1e19 (or FLT_MAX, an exporter's "unset"): its column index passed
    2^63, numba's int() of it is -2^63, and the column loop counted up from there for ever,
    deaf to Ctrl-C. It crosses no column: the box alone is the inside."""
    import subprocess
    import sys

    try:
        done = subprocess.run([sys.executable, "-c", FAR_STRAY, x], capture_output=True, text=True, timeout=120)
    except subprocess.TimeoutExpired:
        pytest.fail("closed_winding did not end within 120 s")
    assert done.returncode == 0, done.stderr
    alone, with_stray = done.stdout.split()
    assert alone == with_stray and int(alone) > 0
