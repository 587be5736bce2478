"""Mesh files as targets (issue 25.1): meshes as modelling tools write them — split seams,
several overlapping components, inconsistent winding, small holes, non-manifold edges —
voxelized by their generalised winding number and checked against the solid they bound.

Boxes are placed with every face halfway between voxel centres (faces at multiples of the
voxel size from the grid's corner, which lies half a voxel further out), so the inside is
exact there: the tolerance for boxes is 0 voxels. Spheres are checked against the ball with
the tolerance their polygonal surface (and a hole's rim) needs, stated where it is used.
"""

import json
import struct
import math
from pathlib import Path

import numpy as np
import pytest
import trimesh

from procmod.cli import main
from procmod.geometry.inside import inside_voxels, orient_faces, winding_numbers
from procmod.geometry.voxel import VoxelGrid
from procmod.targets import Silhouette, Volume, load_target_file, load_volume_target, voxelize_mesh_file
from procmod.targets.image import TargetFileError

H = 0.1  # voxel size; voxelize_mesh_file's margin 0.1 puts the grid's centres at lo - 0.05 + 0.1 k


def _box(size, centre):
    box = trimesh.creation.box(size)
    box.apply_translation(centre)
    return box


def _in_boxes(grid, boxes):
    """The analytic solid: voxel centres inside any of the (size, centre) boxes."""
    c = grid.centres()
    inside = np.zeros(grid.shape, dtype=bool)
    for size, centre in boxes:
        inside |= np.all(np.abs(c - np.asarray(centre)) <= 0.5 * np.asarray(size), axis=-1)
    return inside


def _write_obj(path: Path, vertices, faces, split_seams: bool = False):
    """An OBJ as Maya writes one: positions once, and with ``split_seams`` every face with
    its own texture coordinates, so a reader splits every vertex at the seams between faces."""
    lines = [f"v {x:.9f} {y:.9f} {z:.9f}" for x, y, z in vertices]
    if split_seams:
        lines += [f"vt {u:.4f} {v:.4f}" for u, v in np.random.default_rng(0).uniform(size=(3 * len(faces), 2))]
        lines += [f"f {a + 1}/{3 * i + 1} {b + 1}/{3 * i + 2} {c + 1}/{3 * i + 3}" for i, (a, b, c) in enumerate(faces)]
    else:
        lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


def _voxelize(tmp_path, vertices, faces, name="m.obj", split_seams=False):
    _write_obj(tmp_path / name, vertices, faces, split_seams)
    return voxelize_mesh_file(tmp_path / name, H)


BOX = ((1.0, 0.6, 0.8), (0.0, 0.0, 0.0))
BOX2 = ((0.6, 1.0, 0.4), (0.4, 0.5, 0.3))  # overlaps BOX in [0.1, 0.5] x [0, 0.3] x [0.1, 0.4]


def test_split_seams_are_merged(tmp_path):
    box = _box(*BOX)
    path = tmp_path / "seams.obj"
    _write_obj(path, box.vertices, box.faces, split_seams=True)
    loaded = trimesh.load(path, force="mesh")
    assert len(loaded.vertices) > 8 and not loaded.is_watertight  # what a reader sees: seams split it
    grid, mask = voxelize_mesh_file(path, H)
    assert mask.sum() == 10 * 6 * 8 and np.array_equal(mask, _in_boxes(grid, [BOX]))


def test_overlapping_components_are_their_union(tmp_path):
    a, b = _box(*BOX), _box(*BOX2)
    union = trimesh.util.concatenate([a, b])
    grid, mask = _voxelize(tmp_path, union.vertices, union.faces)
    expected = _in_boxes(grid, [BOX, BOX2])
    # ray parity (the old rule) empties the overlap: 4 x 3 x 3 voxel centres lie in both boxes
    assert (_in_boxes(grid, [BOX]) & _in_boxes(grid, [BOX2])).sum() == 4 * 3 * 3
    assert np.array_equal(mask, expected)


@pytest.mark.parametrize("which", ["some", "all"])
def test_inconsistent_and_inverted_winding(tmp_path, which):
    box = _box(*BOX)
    faces = box.faces.copy()
    flip = np.array([0, 3, 4, 9]) if which == "some" else np.arange(len(faces))
    faces[flip] = faces[flip][:, ::-1]
    grid, mask = _voxelize(tmp_path, box.vertices, faces)
    assert np.array_equal(mask, _in_boxes(grid, [BOX]))


def test_winding_matters_without_orientation():
    # the orientation step is what makes flipped faces harmless: without it the winding
    # number near a flipped face drops below 1/2 (so the test above checks orient_faces)
    box = _box(*BOX)
    faces = box.faces.copy()
    faces[[0, 1]] = faces[[0, 1]][:, ::-1]
    grid = VoxelGrid.around(box.bounds[0], box.bounds[1], H, 0.1)
    assert not np.array_equal(inside_voxels(box.vertices, faces, grid), _in_boxes(grid, [BOX]))
    fixed, _ = orient_faces(box.vertices, faces)
    assert np.array_equal(inside_voxels(box.vertices, fixed, grid), _in_boxes(grid, [BOX]))


def test_a_cavity_stays_hollow_and_an_inverted_shell_is_turned(tmp_path):
    # a hollow box: outer shell facing out, inner shell facing in (a cavity); and the same
    # inner box on its own, inverted by mistake, which is turned over
    outer, inner = _box((1.0, 1.0, 1.0), (0, 0, 0)), _box((0.6, 0.4, 0.6), (0, 0, 0))
    inner.invert()
    hollow = trimesh.util.concatenate([outer, inner])
    grid, mask = _voxelize(tmp_path, hollow.vertices, hollow.faces, "hollow.obj")
    expected = _in_boxes(grid, [((1.0, 1.0, 1.0), (0, 0, 0))]) & ~_in_boxes(grid, [((0.6, 0.4, 0.6), (0, 0, 0))])
    assert np.array_equal(mask, expected)
    grid, mask = _voxelize(tmp_path, inner.vertices, inner.faces, "inverted.obj")
    assert np.array_equal(mask, _in_boxes(grid, [((0.6, 0.4, 0.6), (0, 0, 0))]))
    # the hollow box exported inside out (every normal flipped: outer shell facing in, the
    # cavity's wall facing out) read as filled; it is the hollow box
    inside_out = hollow.copy()
    inside_out.invert()
    grid, mask = _voxelize(tmp_path, inside_out.vertices, inside_out.faces, "inside_out.obj")
    assert np.array_equal(mask, expected)


@pytest.mark.parametrize("missing", [[0], [0, 1], [0, 5]])
def test_missing_faces(tmp_path, missing):
    # one triangle, one whole side (two triangles), two triangles of different sides: the
    # rim's cap subtends less than half the sphere from inside, so inside stays inside
    box = _box(*BOX)
    faces = np.delete(box.faces, missing, axis=0)
    grid, mask = _voxelize(tmp_path, box.vertices, faces)
    if missing == [0, 1]:
        # a whole side open: voxels right at the opening see w < 1/2 (20 of 480 here); they
        # lie in the one voxel layer next to it (at most 10 x 8 voxels), none outside the box
        expected = _in_boxes(grid, [BOX])
        assert (mask & ~expected).sum() == 0 and 0 < (expected & ~mask).sum() <= 80
        return
    assert np.array_equal(mask, _in_boxes(grid, [BOX]))


def test_non_manifold_edges(tmp_path):
    # two boxes sharing one edge (four faces on it) and a dangling fin triangle on another
    a = _box((0.6, 0.6, 0.6), (0.0, 0.0, 0.0))
    b = _box((0.6, 0.6, 0.6), (0.6, 0.6, 0.0))
    both = trimesh.util.concatenate([a, b])
    both.merge_vertices()
    edges = np.sort(both.edges, axis=1)
    _, counts = np.unique(edges, axis=0, return_counts=True)
    assert counts.max() == 4  # the shared edge is non-manifold
    corner = np.flatnonzero(np.all(np.isclose(a.vertices, [0.3, 0.3, 0.3]), axis=1))[0]
    other = np.flatnonzero(np.all(np.isclose(a.vertices, [0.3, 0.3, -0.3]), axis=1))[0]
    fin_v = np.vstack([a.vertices, [[0.9, -0.2, 0.0]]])
    fin_f = np.vstack([a.faces, [[corner, other, len(a.vertices)]]])
    grid, mask = _voxelize(tmp_path, both.vertices, both.faces, "edge.obj")
    assert np.array_equal(mask, _in_boxes(grid, [((0.6, 0.6, 0.6), (0, 0, 0)), ((0.6, 0.6, 0.6), (0.6, 0.6, 0))]))
    grid, mask = _voxelize(tmp_path, fin_v, fin_f, "fin.obj")
    assert np.array_equal(mask, _in_boxes(grid, [((0.6, 0.6, 0.6), (0, 0, 0))]))


def test_sphere_with_small_holes(tmp_path):
    sphere = trimesh.creation.icosphere(subdivisions=4, radius=1.0)  # faces ~0.08 across
    holes = [sphere.vertices[i] for i in (0, 100, 500)]
    keep = np.ones(len(sphere.faces), dtype=bool)
    for h in holes:  # each hole: the faces around a vertex, a rim of radius ~0.1
        keep &= np.linalg.norm(sphere.triangles_center - h, axis=1) > 0.08
    assert keep.sum() < len(sphere.faces) - 12
    grid, mask = _voxelize(tmp_path, sphere.vertices, sphere.faces[keep], "holes.obj")
    r = np.linalg.norm(grid.centres(), axis=-1)
    # Tolerance: the icosphere lies between its inradius and 1; a hole's cap (its rim's
    # triangulation) cuts at most rim_sag = 1 - sqrt(1 - 0.1^2) + that deeper, within 0.15
    # of the hole. Everything else must match the ball exactly.
    inradius = np.min(np.abs(np.einsum("ij,ij->i", sphere.face_normals, sphere.triangles_center)))
    band = (r > inradius - 1e-9) & (r <= 1.0)
    near_hole = np.min([np.linalg.norm(grid.centres() - h, axis=-1) for h in holes], axis=0) < 0.15
    ball = r <= 1.0
    assert np.array_equal(mask[~band & ~near_hole], ball[~band & ~near_hole])
    _write_obj(tmp_path / "closed.obj", sphere.vertices, sphere.faces)
    _, closed = voxelize_mesh_file(tmp_path / "closed.obj", H)
    # no voxel centre falls between a rim's cap and the faces removed from it: the holed
    # sphere voxelizes exactly as the closed one
    assert np.array_equal(mask, closed)


@pytest.mark.parametrize("suffix", [".obj", ".glb", ".ply", ".stl", ".off", ".dae"])
def test_every_format_gives_the_same_solid(tmp_path, suffix):
    # 1.74 + 2 x 0.1 across, off a whole number of voxels: float32 files (STL, GLB) get the same grid
    sphere = trimesh.creation.icosphere(subdivisions=3, radius=0.87)
    sphere.apply_translation((0.013, -0.021, 0.034))  # no voxel centre on a face
    _write_obj(tmp_path / "ref.obj", sphere.vertices, sphere.faces)
    grid_ref, ref = voxelize_mesh_file(tmp_path / "ref.obj", H)
    sphere.export(tmp_path / f"s{suffix}")
    grid, mask = voxelize_mesh_file(tmp_path / f"s{suffix}", H)
    # STL and GLB store float32 coordinates: the grid moves by ~1e-7, no centre changes side
    assert grid.shape == grid_ref.shape and np.allclose(grid.origin, grid_ref.origin, atol=1e-6)
    assert np.array_equal(mask, ref)
    assert 0.9 * (4 / 3) * math.pi * 0.87 ** 3 < mask.sum() * H ** 3 < 1.1 * (4 / 3) * math.pi * 0.87 ** 3


def test_collada_face_count_is_read_before_the_mesh(tmp_path, monkeypatch):
    from procmod.core.errors import ProcmodError
    from procmod.targets import files

    sphere = trimesh.creation.icosphere(subdivisions=2)
    sphere.export(tmp_path / "s.dae")
    assert files.declared_faces(tmp_path / "s.dae") == len(sphere.faces)
    monkeypatch.setattr(files, "MAX_MESH_FACES", len(sphere.faces) - 1)
    monkeypatch.setattr(trimesh, "load", lambda *a, **k: pytest.fail("the mesh was read"))
    with pytest.raises(ProcmodError, match="faces"):
        files.read_mesh(tmp_path / "s.dae")


def test_fast_winding_matches_direct_summation():
    # the crossing count + caps decomposition against summing every triangle's solid angle,
    # on a soup with every defect at once: components, holes, flipped faces, stray triangles
    rng = np.random.default_rng(3)
    parts = [_box((0.8, 0.5, 0.6), (0.05, 0.02, 0.01)), _box((0.5, 0.9, 0.3), (0.3, 0.4, 0.2)),
             trimesh.creation.icosphere(2, radius=0.4).apply_translation((-0.5, 0.3, 0.1))]
    v = np.vstack([p.vertices for p in parts])
    offsets = np.cumsum([0] + [len(p.vertices) for p in parts[:-1]])
    f = np.vstack([p.faces + o for p, o in zip(parts, offsets)])
    f = f[rng.uniform(size=len(f)) > 0.08]  # holes
    flip = rng.uniform(size=len(f)) < 0.2
    f[flip] = f[flip][:, ::-1]
    stray = len(v) + np.arange(30).reshape(-1, 3)
    v = np.vstack([v, rng.uniform(-0.8, 0.8, size=(30, 3))])
    f = np.vstack([f, stray])
    grid = VoxelGrid.around(v.min(0), v.max(0), 0.07, 0.1)
    fast = inside_voxels(v, f, grid)
    w = winding_numbers(v, f, grid.centres().reshape(-1, 3)).reshape(grid.shape)
    decided = np.abs(w - 0.5) > 1e-6  # exactly at w = 1/2 either answer is right
    assert decided.mean() > 0.99 and fast.sum() > 1000
    assert np.array_equal(fast[decided], (w >= 0.5)[decided])


def test_no_inside_is_one_line(tmp_path):
    # an open sheet: a single square has no inside at any voxel size
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], float)
    _write_obj(tmp_path / "sheet.obj", v, [[0, 1, 2], [0, 2, 3]])
    with pytest.raises(Exception, match="lies inside the mesh: an open sheet"):
        voxelize_mesh_file(tmp_path / "sheet.obj", H)


def test_volume_file_with_mesh_layers_on_one_grid(tmp_path):
    # two mesh layers (fill, avoid) share the grid fitted around both
    a, b = _box(*BOX), _box((0.4, 0.4, 0.4), (1.2, 0.0, 0.0))
    a.export(tmp_path / "fill.ply")
    b.export(tmp_path / "avoid.stl")
    spec = {"format": "procmod-volume/1", "voxel_size": H,
            "layers": [{"file": "fill.ply", "w_fill": 1.0, "w_avoid": 0.0},
                       {"file": "avoid.stl", "w_fill": -2.0, "w_avoid": 0.0}]}
    (tmp_path / "T.json").write_text(json.dumps(spec))
    target = load_volume_target(tmp_path / "T.json")
    assert isinstance(target, Volume)
    fill = _in_boxes(target.grid, [BOX])
    avoid = _in_boxes(target.grid, [((0.4, 0.4, 0.4), (1.2, 0.0, 0.0))])
    assert np.array_equal(target.combined, np.where(fill, 1.0, 0.0) + np.where(avoid, -2.0, 0.0))


def _seam_split_ship(folder: Path) -> Path:
    hull, wing = _box((1.0, 0.6, 3.0), (0.0, 0.0, 0.0)), _box((3.0, 0.2, 0.8), (0.0, 0.0, -0.5))
    ship = trimesh.util.concatenate([hull, wing])  # overlapping components too
    _write_obj(folder / "ship.obj", ship.vertices, ship.faces, split_seams=True)
    (folder / "T.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.25,
                                               "layers": [{"file": "ship.obj", "w_fill": 1, "w_avoid": -1}]}))
    return folder / "T.json"


def test_infer_on_a_seam_split_obj(tmp_path, capsys):
    target = _seam_split_ship(tmp_path)
    out = tmp_path / "run"
    code = main(["infer", "spaceship", "--target", str(target), "--engine", "ga", "--budget", "50evals",
                 "--seed", "1", "--out", str(out)])
    printed = capsys.readouterr()
    assert code == 0, printed.err
    assert (out / "report.html").is_file() and (out / "best.json").is_file()
    loaded = load_target_file(target)
    grid = loaded.grid
    expected = _in_boxes(grid, [((1.0, 0.6, 3.0), (0, 0, 0)), ((3.0, 0.2, 0.8), (0, 0, -0.5))])
    assert np.array_equal(loaded.combined > 0, expected)


def test_a_plan_view_without_up_looks_down_with_minus_z_at_the_top(tmp_path):
    """A camera straight above the scene with no "up" was refused quoting an up of
    [0, 1, 0] the file never gave; it now takes -z as the picture's top (+z looking up),
    as Blender's top and bottom views do, and draws the footprint."""
    box = _box((2.0, 1.0, 1.0), (0.0, 0.0, -0.5))  # 2 wide in x, 1 deep in z, all on the -z side
    _write_obj(tmp_path / "box.obj", box.vertices, box.faces)
    views = [{"mesh": "box.obj", "camera": {"eye": [0, y, 0], "look_at": [0, 0, 0], "projection": "orthographic",
                                            "fov": 4, "width": 40, "height": 40}} for y in (10, -10)]
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": views}))
    target = load_target_file(tmp_path / "S.json")
    assert target.cameras[0].up == (0.0, 0.0, -1.0) and target.cameras[1].up == (0.0, 0.0, 1.0)
    hit = [np.argwhere(w > 0) for w in target.weights]
    # 10 pixels a unit: x from -1 to 1 is columns 10..29 in both; z from -1 to 0 the top half
    # of the rows looking down (-z up), the bottom half looking up
    for rows in hit:
        assert rows[:, 1].min() == 10 and rows[:, 1].max() == 29
    assert hit[0][:, 0].min() == 10 and hit[0][:, 0].max() == 19
    assert hit[1][:, 0].min() == 20 and hit[1][:, 0].max() == 29
    views[1]["camera"]["eye"] = [0, -10, 1e-5]  # barely off vertical: y is an up for it, as before
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": views}))
    assert load_target_file(tmp_path / "S.json").cameras[1].up == (0.0, 1.0, 0.0)
    views[0]["camera"]["up"] = [0, 1, 0]  # given along the view: still refused, quoting what was given
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": views}))
    with pytest.raises(TargetFileError, match=r"views\[0\]\.camera\.up must be a non-zero vector not along"):
        load_target_file(tmp_path / "S.json")


def test_a_mesh_running_under_a_perspective_camera_is_cut_at_the_near_plane(tmp_path):
    """A long wall passing under the camera: its 12 big triangles each have a corner behind
    the camera and were all skipped (16 pixels to hit against 918 for the same solid
    subdivided); cut at the near plane, both meshes draw the same silhouette."""
    from procmod.geometry.camera import Camera, clip_to_near
    wall = _box((4.0, 1.0, 40.0), (0.0, 0.5, 10.0))  # z from -10 to 30; the camera at z = 20
    fine = wall.copy()
    for _ in range(5):
        fine = fine.subdivide()
    camera = {"eye": [0, 4, 20], "look_at": [0, 2, 0], "projection": "perspective", "fov": 60,
              "width": 64, "height": 64}
    hit = []
    for name, mesh in (("coarse", wall), ("fine", fine)):
        _write_obj(tmp_path / f"{name}.obj", mesh.vertices, mesh.faces)
        (tmp_path / f"{name}.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                           "views": [{"mesh": f"{name}.obj", "camera": camera}]}))
        hit.append(load_target_file(tmp_path / f"{name}.json").weights[0] > 0)
    assert hit[0].sum() > 800 and hit[0][-1].sum() > 40  # the wall reaches the bottom of the view
    assert (hit[0] != hit[1]).sum() <= 0.02 * hit[1].sum()  # the subdivided mesh's pixel centres differ at edges only
    # the cut keeps what lies in front: corners in front stay, the new ones lie on the plane
    cam = Camera(tuple(camera["eye"]), tuple(camera["look_at"]), projection="perspective")
    tris = np.asarray(wall.triangles)
    cut = clip_to_near(tris, cam)
    eye, _, _, forward = cam.basis()
    depth = (cut - eye) @ forward
    near = 1e-4 * np.linalg.norm(np.subtract(cam.look_at, cam.eye))
    assert depth.min() >= near - 1e-9
    in_front = (tris - eye) @ forward >= near
    assert len(cut) >= in_front.any(axis=1).sum()  # each triangle with a corner in front leaves one or two


def test_an_orthographic_camera_does_not_see_behind_its_eye():
    """An orthographic camera looking away from the model scored exactly what one facing it
    did, while the placement note said the model lay behind the camera."""
    from procmod.geometry.camera import Camera, Silhouettes
    from procmod.geometry.solid import Box, translation
    away = Camera((0.0, 0.0, 5.0), (0.0, 0.0, 10.0), projection="orthographic", fov=4.0, width=32, height=32)
    facing = Camera((0.0, 0.0, 5.0), (0.0, 0.0, 0.0), projection="orthographic", fov=4.0, width=32, height=32)
    box = Box((1.0, 1.0, 1.0), translation(0.0, 0.0, 0.0))
    seen = {}
    for name, camera in (("away", away), ("facing", facing)):
        out = Silhouettes([camera])
        out.add(box)
        seen[name] = out.image(0).sum()
    assert seen["facing"] > 50 and seen["away"] == 0
    # a part across the eye's plane shows its half in front
    out = Silhouettes([away])
    out.add(Box((1.0, 1.0, 4.0), translation(0.0, 0.0, 5.0)))
    assert out.image(0).sum() == seen["facing"]


def test_silhouette_view_of_a_mesh(tmp_path, capsys):
    box = _box((2.0, 1.0, 1.0), (0.0, 0.0, 0.0))
    _write_obj(tmp_path / "box.obj", box.vertices, box.faces, split_seams=True)
    view = {"mesh": "box.obj", "hit": 1.0, "avoid": -0.5,
            "camera": {"eye": [0, 0, 10], "look_at": [0, 0, 0], "projection": "orthographic", "fov": 4,
                       "width": 40, "height": 40}}
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [view]}))
    target = load_target_file(tmp_path / "S.json")
    assert isinstance(target, Silhouette)
    w = target.weights[0]
    # 10 pixels per world unit, centred: the box covers columns 10..29 and rows 15..24
    expected = np.full((40, 40), -0.5)
    expected[15:25, 10:30] = 1.0
    assert np.array_equal(w, expected)
    code = main(["infer", "spaceship", "--target", str(tmp_path / "S.json"), "--engine", "ga", "--budget", "50evals",
                 "--out", str(tmp_path / "run")])
    assert code == 0, capsys.readouterr().err


def test_read_mesh_reports_what_it_cleaned(tmp_path):
    from procmod.targets import read_mesh
    box = _box(*BOX)
    _write_obj(tmp_path / "b.obj", box.vertices, np.vstack([box.faces, [[0, 0, 1]]]), split_seams=True)
    vertices, faces = read_mesh(tmp_path / "b.obj")
    assert len(vertices) == 8 and len(faces) == 12  # seams merged, the degenerate face dropped


@pytest.mark.slow
def test_a_million_faces_loads_in_seconds(tmp_path):
    import time
    sphere = trimesh.creation.icosphere(subdivisions=8, radius=1.0)  # 1,310,720 faces
    keep = np.linalg.norm(sphere.triangles_center - sphere.vertices[0], axis=1) > 0.05
    trimesh.Trimesh(sphere.vertices, sphere.faces[keep]).export(tmp_path / "big.ply")
    start = time.perf_counter()
    grid, mask = voxelize_mesh_file(tmp_path / "big.ply", 2.2 / 128)
    seconds = time.perf_counter() - start
    assert abs(mask.sum() * grid.size ** 3 - 4 / 3 * math.pi) < 0.02 * 4 / 3 * math.pi
    assert seconds < 60, seconds  # about 5 s on an idle 2-core machine


def test_obj_relative_indices_and_tab_spacing_are_read_as_written(tmp_path):
    """trimesh resolves ``f -4 -3 -2`` against the whole file and drops a tab-separated
    ``v\\t...``: the first of two objects vanished (procmod.geometry.mesh_files)."""
    from procmod.geometry.mesh_files import load_mesh_file

    tetra = "f -4 -2 -3\nf -4 -3 -1\nf -4 -1 -2\nf -3 -2 -1\n"
    text = ("o A\nv 0 0 0\nv 1 0 0\nv 0 1 0\nv\t0 0 1\n" + tetra
            + "o B\n  v 5 0 0\nv 6 0 0\nv 5 1 0\nv 5 0 1\n" + tetra)
    (tmp_path / "two.obj").write_text(text)
    mesh = load_mesh_file(tmp_path / "two.obj", force="mesh", process=False)
    assert len(mesh.vertices) == 8 and len(mesh.faces) == 8
    used = np.unique(np.asarray(mesh.faces))
    assert used.tolist() == list(range(8))  # each object's faces use its own four vertices
    assert np.allclose(mesh.vertices[mesh.faces[:4]].min(axis=(0, 1)), 0.0)


def test_a_flipped_piece_overlapping_another_in_part_is_a_solid_not_a_cavity(tmp_path):
    """One probe face decided before: with B's first face inside A, the flipped box B was
    taken for a cavity and carved out of A; by face order, 960 or 1152 voxels."""
    def box(lo, hi):
        mesh = trimesh.creation.box(extents=np.subtract(hi, lo))
        mesh.apply_translation(np.add(lo, hi) / 2)
        return mesh

    a, b = box([-2, -1, -1], [2, 1, 1]), box([1, -0.5, -0.5], [4, 0.5, 0.5])
    b.invert()
    hollow_outer, hollow_inner = box([-2, -2, -2], [2, 2, 2]), box([-1, -1, -1], [1, 1, 1])
    hollow_inner.invert()  # a real cavity stays one
    meshes = {f"order{k}": trimesh.util.concatenate([a, trimesh.Trimesh(b.vertices, b.faces[order], process=False)])
              for k, order in enumerate([np.argsort(b.triangles_center[:, 0]), np.argsort(-b.triangles_center[:, 0])])}
    meshes["hollow"] = trimesh.util.concatenate([hollow_outer, hollow_inner])
    inside = {}
    for name, mesh in meshes.items():
        mesh.export(tmp_path / f"{name}.obj")
        (tmp_path / f"{name}.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.25,
                                                           "layers": [{"file": f"{name}.obj"}]}))
        inside[name] = int((load_volume_target(tmp_path / f"{name}.json").combined > 0).sum())
    assert inside["order0"] == inside["order1"] == 16 * 8 * 8 + 8 * 4 * 4  # A, and B's part outside A
    assert inside["hollow"] == 16 ** 3 - 8 ** 3


def _volume_file(folder: Path, mesh: str, **fields) -> Path:
    spec = {"format": "procmod-volume/1", "voxel_size": 0.25,
            "layers": [{"file": mesh, "w_fill": 1, "w_avoid": -1}], **fields}
    (folder / "T.json").write_text(json.dumps(spec))
    return folder / "T.json"


def test_mesh_scale_and_offset_put_a_mesh_in_the_models_frame(tmp_path):
    """A mesh exported in centimetres, away from the origin, reads as the same mesh in metres
    at the origin once "mesh_scale" and "mesh_offset" say so (voxel_size in the model's units)."""
    box = _box((2.0, 1.0, 3.0), (0.0, 0.5, 0.0))
    _write_obj(tmp_path / "m.obj", box.vertices, box.faces)
    _write_obj(tmp_path / "cm.obj", box.vertices * 100 + [700.0, 0.0, -300.0], box.faces, split_seams=True)
    metres = load_volume_target(_volume_file(tmp_path, "m.obj"))
    placed = load_volume_target(_volume_file(tmp_path, "cm.obj", mesh_scale=0.01, mesh_offset=[-7, 0, 3]))
    assert placed.grid.shape == metres.grid.shape
    assert np.allclose(placed.grid.origin, metres.grid.origin)
    assert np.array_equal(placed.combined, metres.combined)
    view = {"mesh": "cm.obj", "camera": {"eye": [0, 0, 10], "look_at": [0, 0, 0], "projection": "orthographic",
                                         "fov": 4, "width": 40, "height": 40}}
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [view],
                                                 "mesh_scale": 0.01, "mesh_offset": [-7, 0, 3]}))
    (tmp_path / "S0.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                  "views": [{**view, "mesh": "m.obj"}]}))
    assert np.array_equal(load_target_file(tmp_path / "S.json").weights[0],
                          load_target_file(tmp_path / "S0.json").weights[0])


@pytest.mark.parametrize("fields, message", [
    ({"mesh_scale": 0}, "mesh_scale must be positive"),
    ({"mesh_scale": -0.01}, "mesh_scale must be positive"),
    ({"mesh_offset": [1, 2]}, "mesh_offset"),
    ({"mesh_scale": 1e-300}, "mesh_scale must lie in 1e-12..1e12"),
])
def test_a_bad_mesh_placement_is_one_line(tmp_path, capsys, fields, message):
    box = _box(*BOX)
    _write_obj(tmp_path / "m.obj", box.vertices, box.faces)
    target = _volume_file(tmp_path, "m.obj", **fields)
    assert main(["infer", "spaceship", "--target", str(target), "--engine", "forward", "--budget", "5evals",
                 "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert message in err and err.count("\n") == 1 and not (tmp_path / "run").exists()


def test_mesh_placement_in_a_file_without_meshes_is_refused(tmp_path):
    from procmod.targets.image import TargetFileError
    np.save(tmp_path / "a.npy", np.ones((3, 3, 3)))
    (tmp_path / "T.json").write_text(json.dumps({
        "format": "procmod-volume/1", "mesh_scale": 0.01, "layers": [{"file": "a.npy"}],
        "grid": {"origin": [0, 0, 0], "voxel_size": 1}}))
    with pytest.raises(TargetFileError, match="mesh_scale places mesh layers and this file has none"):
        load_volume_target(tmp_path / "T.json")


def test_a_units_note_followed_to_the_letter_places_the_target_and_a_stray_piece_is_named(tmp_path):
    """A mesh in centimetres with a voxel size picked in its own units: the note gives the
    voxel size in the model's units too (with the mesh_scale alone the mesh fell within
    two voxels, and that refusal pointed back to mesh_scale); the refusal names a voxel
    size to give. A small piece left far off is named, not taken for other units."""
    from procmod.cli import _model
    from procmod.targets.placement import placement_note

    ship = trimesh.util.concatenate([_box((1.0, 0.6, 3.0), (0, 0, 0)), _box((3.0, 0.2, 0.8), (0, 0, -0.5))])
    _write_obj(tmp_path / "cm.obj", ship.vertices * 100, ship.faces)
    model = _model("spaceship")

    def note(mesh, **fields):
        return placement_note(model, load_volume_target(_volume_file(tmp_path, mesh, **fields)),
                              np.random.default_rng(0))

    advice = note("cm.obj", voxel_size=25)
    fields = json.loads("{" + advice[advice.index("give ") + 5:advice.index(" in the target file")]
                        .replace(" and ", ", ") + "}")
    assert fields == {"mesh_scale": 0.01, "voxel_size": 0.25}
    assert note("cm.obj", **fields) is None  # followed to the letter: placed
    with pytest.raises(TargetFileError, match=r"under two voxels of 25.*give a voxel_size in them, such as 0\.09"):
        load_volume_target(_volume_file(tmp_path, "cm.obj", voxel_size=25, mesh_scale=0.01))
    # with a "grid" given (in the model's units), the grid is the file's: no voxel_size advice
    (tmp_path / "G.json").write_text(json.dumps({"format": "procmod-volume/1", "layers": [{"file": "cm.obj"}],
                                                 "grid": {"origin": [-160, -40, -160], "voxel_size": 10,
                                                          "shape": [32, 8, 32]}}))
    advice = placement_note(model, load_volume_target(tmp_path / "G.json"), np.random.default_rng(0))
    assert "\"mesh_scale\": 0.01 in the target file" in advice and "voxel_size" not in advice, advice
    # a stray beside a piece itself in other units: the units from the piece, and the stray named
    far = trimesh.util.concatenate([_box((100.0, 60.0, 300.0), (0, 0, 0)), _box((30.0, 30.0, 30.0), (40000.0, 0, 0))])
    _write_obj(tmp_path / "far.obj", far.vertices, far.faces)
    text = note("far.obj", voxel_size=10)
    assert "26.5x the size" in text and "\"mesh_scale\": 0.1 in" in text, text  # not 0.0001, as for the whole box
    assert "27 voxels of the target's fill lie far from the rest (near (4" in text, text
    stray = trimesh.util.concatenate([ship, _box((0.3, 0.3, 0.3), (300.0, 0.0, 0.0))])
    _write_obj(tmp_path / "stray.obj", stray.vertices, stray.faces)
    text = note("stray.obj")
    assert "1 voxel of the target's fill lies far from the rest (near (300, " in text and "mesh_scale" not in text, text
    assert "while the rest spans 3 x 0.75 x 3" in text, text  # the voxels of the ship


def test_a_target_in_other_units_or_elsewhere_gets_a_note_saying_how_to_place_it(tmp_path, capsys):
    """A spaceship target exported in centimetres (Maya's default) or left 500 units from the
    origin scored 0 with no word why; the note names the field and the value that fix it,
    and the same target in the model's frame gets none."""
    from procmod.cli import _model
    from procmod.targets.placement import placement_note

    ship = trimesh.util.concatenate([_box((1.0, 0.6, 3.0), (0, 0, 0)), _box((3.0, 0.2, 0.8), (0, 0, -0.5))])
    _write_obj(tmp_path / "cm.obj", ship.vertices * 100, ship.faces)
    _write_obj(tmp_path / "far.obj", ship.vertices + [500.0, 0.0, 40.0], ship.faces)
    model = _model("spaceship")

    def note(mesh, **fields):
        return placement_note(model, load_volume_target(_volume_file(tmp_path, mesh, **fields)),
                              np.random.default_rng(0))

    def given(text, field):
        at = text.index(f"\"{field}\": ") + len(field) + 4
        return json.loads(text[at:text.index(" in the target file", at)].split(" and ")[0])

    assert given(note("cm.obj", voxel_size=25), "mesh_scale") == 0.01
    assert note("cm.obj", mesh_scale=0.01) is None
    # advice is the value to give, from what the file gives now
    assert given(note("cm.obj", mesh_scale=10, voxel_size=250), "mesh_scale") == 0.01
    far = note("far.obj")
    offset = given(far, "mesh_offset")
    assert offset[0] == pytest.approx(-500, abs=1) and note("far.obj", mesh_offset=offset) is None
    halfway = note("far.obj", mesh_offset=[-250, 0, 0])
    assert note("far.obj", mesh_offset=given(halfway, "mesh_offset")) is None
    # .npy layers lie on the file's grid: the advice moves the grid, which the file can take
    np.save(tmp_path / "ship.npy", load_volume_target(_volume_file(tmp_path, "far.obj")).combined > 0)
    far_grid = load_volume_target(_volume_file(tmp_path, "far.obj")).grid
    (tmp_path / "G.json").write_text(json.dumps({"format": "procmod-volume/1", "layers": [{"file": "ship.npy"}],
                                                 "grid": {"origin": list(far_grid.origin),
                                                          "voxel_size": far_grid.size}}))
    advice = placement_note(model, load_volume_target(tmp_path / "G.json"), np.random.default_rng(0))
    assert "give grid.origin [" in advice and "mesh_offset" not in advice
    # the CLI prints it on stderr and still runs
    code = main(["infer", "spaceship", "--target", str(_volume_file(tmp_path, "cm.obj", voxel_size=25)),
                 "--engine", "smc", "--particles", "20", "--out", str(tmp_path / "run")])
    printed = capsys.readouterr()
    assert code == 0 and printed.err.startswith("note: the target's fill spans") and "mesh_scale" in printed.err
    # a view of the centimetre mesh framed for centimetres: the model is a speck in it
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [
        {"mesh": "cm.obj", "camera": {"eye": [0, 300, 2000], "look_at": [0, 0, 0]}}]}))
    assert "views[0]: the shape to hit spans" in placement_note(model, load_target_file(tmp_path / "S.json"),
                                                                 np.random.default_rng(0))
    # a camera looking away from the model: all of it behind the camera
    (tmp_path / "B.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [
        {"mesh": "far.obj", "camera": {"eye": [495, 0, 40], "look_at": [505, 0, 40]}}]}))
    assert "behind the camera" in placement_note(model, load_target_file(tmp_path / "B.json"),
                                                 np.random.default_rng(0))


@pytest.mark.parametrize("copies", ["reversed", "same", "both"])
def test_a_closed_mesh_exported_double_sided_is_its_solid(tmp_path, copies):
    """Each face also present reversed (SketchUp, 'double-sided' game assets) cancelled
    in the winding number: no inside at all. Repeated faces are now resolved first."""
    box = _box(*BOX)
    extra = {"reversed": [box.faces[:, ::-1]], "same": [box.faces], "both": [box.faces[:, ::-1], box.faces]}[copies]
    grid, mask = _voxelize(tmp_path, box.vertices, np.vstack([box.faces, *extra]), f"{copies}.obj")
    assert np.array_equal(mask, _in_boxes(grid, [BOX]))


def test_the_shared_wall_of_two_touching_solids_and_a_double_sided_fin_stay_out(tmp_path):
    """A face with its reverse that does not close up (two boxes' common wall, a fin
    modelled double-sided) is taken out, which leaves the winding number as it was."""
    from procmod.geometry.inside import single_sided

    a = _box((0.6, 0.6, 0.6), (0, 0, 0))
    b = trimesh.Trimesh(a.vertices * [-1, 1, 1] + [0.6, 0, 0], a.faces[:, ::-1])  # a's mirror image in its +x wall
    both = trimesh.util.concatenate([a, b])
    both.merge_vertices()
    faces = np.asarray(both.faces)
    assert len(single_sided(faces)) == len(faces) - 4  # the wall's two triangles, both ways
    grid, mask = _voxelize(tmp_path, both.vertices, faces, "touching.obj")
    assert np.array_equal(mask, _in_boxes(grid, [((0.6, 0.6, 0.6), (0, 0, 0)), ((0.6, 0.6, 0.6), (0.6, 0, 0))]))
    fin_v = np.vstack([a.vertices, [[0.9, 0.0, 0.0], [0.9, 0.2, 0.0]]])
    n = len(a.vertices)
    corner = np.flatnonzero(np.all(np.isclose(a.vertices, [0.3, 0.3, 0.3]), axis=1))[0]
    fin = [[corner, n, n + 1], [corner, n + 1, n]]
    grid, mask = _voxelize(tmp_path, fin_v, np.vstack([a.faces, fin]), "fin2.obj")
    assert np.array_equal(mask, _in_boxes(grid, [((0.6, 0.6, 0.6), (0, 0, 0))]))


def _obj_text(mesh, relative=False):
    n = len(mesh.vertices)
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in mesh.vertices]
    lines += [f"f {a - n if relative else a + 1} {b - n if relative else b + 1} {c - n if relative else c + 1}"
              for a, b, c in mesh.faces]
    return lines


@pytest.mark.parametrize("variant", ["bom", "bom_relative", "end_comments", "cr_only"])
def test_obj_quirks_of_other_tools_read_the_same_solid(tmp_path, variant):
    """A UTF-8 byte-order mark lost the first vertex (silently a wrong shape with
    relative indices); ``f 1 2 3 # note`` and lone-CR line ends were refused."""
    box = _box(*BOX)
    lines = _obj_text(box, relative=variant == "bom_relative")
    if variant == "end_comments":
        lines = [line + "  # from a tool" for line in lines]
    data = ("\r" if variant == "cr_only" else "\n").join(lines).encode() + b"\n"
    if variant.startswith("bom"):
        data = b"\xef\xbb\xbf" + data
    (tmp_path / "m.obj").write_bytes(data)
    grid, mask = voxelize_mesh_file(tmp_path / "m.obj", H)
    assert np.array_equal(mask, _in_boxes(grid, [BOX]))


def test_binary_stl_counts_that_disagree_with_the_size(tmp_path):
    """Bytes after the last triangle, or a count of zero, are read by the size; a file cut
    off inside its triangles is refused saying so; an ASCII STL without endsolid is read."""
    box = _box(*BOX)
    good = trimesh.exchange.stl.export_stl(box)
    cases = {"padded": good + b"\0" * 16, "no_count": good[:80] + b"\0\0\0\0" + good[84:],
             "ascii": trimesh.exchange.stl.export_stl_ascii(box).rsplit("endsolid", 1)[0].encode(),
             # a solid's name thousands of characters long was read as a binary header
             "long_name": trimesh.exchange.stl.export_stl_ascii(box).replace("solid", "solid " + "n" * 5000).encode()}
    for name, data in cases.items():
        (tmp_path / f"{name}.stl").write_bytes(data)
        grid, mask = voxelize_mesh_file(tmp_path / f"{name}.stl", H)
        assert np.array_equal(mask, _in_boxes(grid, [BOX])), name
    (tmp_path / "cut.stl").write_bytes(good[:-70])
    (tmp_path / "v.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": H,
                                                 "layers": [{"file": "cut.stl", "w_fill": 1}]}))
    with pytest.raises(TargetFileError, match=r"cannot read the mesh \(a cut-off binary STL: its header says 12 "
                                              "triangles but the file holds 10"):
        load_volume_target(tmp_path / "v.json")


def test_ascii_stl_as_tools_write_it_and_files_named_for_another_format(tmp_path):
    """ASCII STL with a byte-order mark, without its solid line, or with tabs is read (it
    was taken for a binary STL of 10^8-10^9 triangles: "decimate it first"); a binary glTF
    named .gltf is read as the GLB it is; OBJ text named .stl is refused naming OBJ."""
    from procmod.targets.files import declared_faces
    box = _box(*BOX)
    text = trimesh.exchange.stl.export_stl_ascii(box)
    cases = {"bom": b"\xef\xbb\xbf" + text.encode(),
             "no_solid": text.split("\n", 1)[1].rsplit("endsolid", 1)[0].encode(),
             "tabs": text.replace("  ", "\t").replace(" ", "\t").encode()}
    for name, data in cases.items():
        (tmp_path / f"{name}.stl").write_bytes(data)
        assert declared_faces(tmp_path / f"{name}.stl") == 12, name
        grid, mask = voxelize_mesh_file(tmp_path / f"{name}.stl", H)
        assert np.array_equal(mask, _in_boxes(grid, [BOX])), name
    # and what read before still reads: NUL bytes in ASCII (padding, a C string's end), a
    # solid's name past 64 KiB, a binary STL whose free-text header starts 'ply', padded
    cases = {"nul_padded": text.encode() + b"\0" * 300, "nul_name": text.replace("\n", "\0\n", 1).encode(),
             "long_name": text.replace("solid", "solid " + "n" * 70_000, 1).encode()}
    binary = trimesh.exchange.stl.export_stl(box)
    cases["ply_header"] = b"plywood shelf".ljust(80, b" ") + binary[80:] + b"\0" * 7
    for name, data in cases.items():
        (tmp_path / f"{name}.stl").write_bytes(data)
        assert declared_faces(tmp_path / f"{name}.stl") == 12, name
        grid, mask = voxelize_mesh_file(tmp_path / f"{name}.stl", H)
        assert np.array_equal(mask, _in_boxes(grid, [BOX])), name
    (tmp_path / "named.gltf").write_bytes(box.export(file_type="glb"))
    assert declared_faces(tmp_path / "named.gltf") == 12
    grid, mask = voxelize_mesh_file(tmp_path / "named.gltf", H)
    assert np.array_equal(mask, _in_boxes(grid, [BOX]))
    (tmp_path / "obj.stl").write_text(box.export(file_type="obj"))
    (tmp_path / "v.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": H,
                                                 "layers": [{"file": "obj.stl", "w_fill": 1}]}))
    with pytest.raises(TargetFileError, match=r"cannot read the mesh \(it holds OBJ text, not STL; rename it"):
        load_volume_target(tmp_path / "v.json")


def _gltf_box(folder: Path, normalized=False, uri="box.bin", cut=0):
    box = _box(*BOX)
    if normalized:
        positions = np.round(box.vertices / np.abs(box.vertices).max() * 32767).astype("<i2")
        positions = np.hstack([positions, np.zeros((len(positions), 1), "<i2")])  # 4-byte aligned rows
    else:
        positions = box.vertices.astype("<f4")
    blob = positions.tobytes() + np.asarray(box.faces, "<u4").tobytes()
    position = {"bufferView": 0, "componentType": 5122 if normalized else 5126, "count": len(box.vertices),
                "type": "VEC3", "min": positions[:, :3].min(0).tolist(), "max": positions[:, :3].max(0).tolist()}
    if normalized:
        position["normalized"] = True
    spec = {"asset": {"version": "2.0"}, "scene": 0, "scenes": [{"nodes": [0]}], "nodes": [{"mesh": 0}],
            "meshes": [{"primitives": [{"attributes": {"POSITION": 0}, "indices": 1}]}],
            "accessors": [position, {"bufferView": 1, "componentType": 5125, "count": box.faces.size,
                                     "type": "SCALAR"}],
            "bufferViews": [{"buffer": 0, "byteLength": positions.nbytes, **({"byteStride": 8} if normalized else {})},
                            {"buffer": 0, "byteOffset": positions.nbytes, "byteLength": box.faces.size * 4}],
            "buffers": [{"byteLength": len(blob), "uri": uri}]}
    (folder / "box.gltf").write_text(json.dumps(spec))
    if uri == "box.bin":
        (folder / "box.bin").write_bytes(blob[:len(blob) - cut])
    (folder / "v.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": H,
                                               "layers": [{"file": "box.gltf", "w_fill": 1}]}))
    return folder / "v.json"


def test_a_gltf_without_its_buffer_file_is_refused_saying_why(tmp_path):
    assert load_volume_target(_gltf_box(tmp_path)).combined.any()  # the plain file reads
    for kwargs, message in (({"uri": "gone.bin"}, "the buffer file 'gone.bin' it names is missing .looked for beside box.gltf.; copy it along"),
                            ({"cut": 40}, "its buffer file 'box.bin' is 200 bytes but the glTF says 240")):
        with pytest.raises(TargetFileError, match=message):
            load_volume_target(_gltf_box(tmp_path, **kwargs))


def _quantized(spec: dict, blob: bytes, scale: float) -> tuple[dict, bytes]:
    """The same box with its positions as normalized SHORTs (KHR_mesh_quantization, as
    gltf-transform quantize writes them), the node scaling them back; and the plain file's
    bytes with the positions those SHORTs stand for (a power-of-two scale keeps them exact)."""
    count = spec["accessors"][0]["count"]
    vertices = np.frombuffer(blob, "<f4", count=count * 3).reshape(-1, 3)
    shorts = np.round(vertices / scale * 32767).astype("<i2")
    meant = (shorts / 32767).astype("<f4") * np.float32(scale)
    rows = np.hstack([shorts, np.zeros((len(shorts), 1), "<i2")]).tobytes()  # rows padded to 4 bytes
    spec = json.loads(json.dumps(spec))
    spec["accessors"][0].update(componentType=5122, normalized=True, min=shorts.min(0).tolist(),
                                max=shorts.max(0).tolist())
    spec["bufferViews"][0].update(byteLength=len(rows), byteStride=8)
    spec["bufferViews"][1]["byteOffset"] = len(rows)
    spec["nodes"][0]["scale"] = [scale] * 3
    spec["extensionsUsed"] = spec["extensionsRequired"] = ["KHR_mesh_quantization"]
    data = rows + blob[count * 12:]
    spec["buffers"][0]["byteLength"] = len(data)
    return spec, data, meant.tobytes() + blob[count * 12:]


def _sparse(spec: dict, blob: bytes) -> tuple[dict, bytes]:
    """The same box with its positions in a sparse accessor: no bufferView (all zeros) and
    every vertex given as a replacement, in a shuffled order."""
    count = spec["accessors"][0]["count"]
    order = np.random.default_rng(0).permutation(count)
    vertices = np.frombuffer(blob, "<f4", count=count * 3).reshape(-1, 3)
    indices, values = order.astype("<u2").tobytes(), vertices[order].astype("<f4").tobytes()
    faces = blob[count * 12:]
    spec = json.loads(json.dumps(spec))
    data = faces + indices + b"\0" * (-len(indices) % 4) + values
    spec["bufferViews"] = [{"buffer": 0, "byteLength": len(faces)},
                           {"buffer": 0, "byteOffset": len(faces), "byteLength": len(indices)},
                           {"buffer": 0, "byteOffset": len(faces) + len(indices) + (-len(indices) % 4),
                            "byteLength": len(values)}]
    position = {k: v for k, v in spec["accessors"][0].items() if k != "bufferView"}
    position["sparse"] = {"count": count, "indices": {"bufferView": 1, "componentType": 5123},
                          "values": {"bufferView": 2}}
    spec["accessors"] = [position, {**spec["accessors"][1], "bufferView": 0}]
    spec["buffers"][0]["byteLength"] = len(data)
    return spec, data


def _glb(spec: dict, data: bytes) -> bytes:
    spec = json.loads(json.dumps(spec))
    spec["buffers"] = [{"byteLength": len(data)}]
    text = json.dumps(spec).encode()
    text += b" " * (-len(text) % 4)
    data += b"\0" * (-len(data) % 4)
    return (struct.pack("<4sII", b"glTF", 2, 28 + len(text) + len(data)) + struct.pack("<I4s", len(text), b"JSON")
            + text + struct.pack("<I4s", len(data), b"BIN\0") + data)


def test_quantized_and_sparse_gltf_positions_read_as_the_plain_file(tmp_path):
    """trimesh read normalized SHORT positions as the integers themselves (32767 times too
    large: the file was refused) and a sparse accessor as zeros (refused as no area)."""
    plain = load_volume_target(_gltf_box(tmp_path)).combined
    spec, blob = json.loads((tmp_path / "box.gltf").read_text()), (tmp_path / "box.bin").read_bytes()
    quantized, data, meant = _quantized(spec, blob, 4.0)
    (tmp_path / "box.bin").write_bytes(meant)
    rounded = load_volume_target(tmp_path / "v.json").combined  # the box the SHORTs stand for
    assert rounded.sum() == plain.sum()
    (tmp_path / "box.bin").write_bytes(blob)
    for name, (variant, data), expected in (("quantized", (quantized, data), rounded),
                                            ("sparse", _sparse(spec, blob), plain)):
        for kind in ("gltf", "glb"):
            folder = tmp_path / f"{name}-{kind}"
            folder.mkdir()
            if kind == "gltf":
                (folder / "box.bin").write_bytes(data)
                (folder / "box.gltf").write_text(json.dumps(variant))
            else:
                (folder / "box.glb").write_bytes(_glb(variant, data))
            (folder / "v.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": H,
                                                       "layers": [{"file": f"box.{kind}", "w_fill": 1}]}))
            read = load_volume_target(folder / "v.json").combined
            assert read.shape == expected.shape and np.array_equal(read, expected), (name, kind)


def test_a_meshopt_compressed_gltf_is_refused_saying_what_to_do(tmp_path):
    _gltf_box(tmp_path)
    spec = json.loads((tmp_path / "box.gltf").read_text())
    spec["extensionsUsed"] = spec["extensionsRequired"] = ["EXT_meshopt_compression"]
    (tmp_path / "box.gltf").write_text(json.dumps(spec))
    with pytest.raises(TargetFileError, match="meshopt-compressed .EXT_meshopt_compression.*without compression"):
        load_volume_target(tmp_path / "v.json")


def test_a_cut_off_glb_is_refused_saying_so(tmp_path):
    data = _box(*BOX).export(file_type="glb")
    (tmp_path / "box.glb").write_bytes(data[:-40])
    (tmp_path / "v.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": H,
                                                 "layers": [{"file": "box.glb", "w_fill": 1}]}))
    with pytest.raises(TargetFileError, match=f"a cut-off GLB file: its header says {len(data):,} bytes but the "
                                              f"file holds {len(data) - 40:,}"):
        load_volume_target(tmp_path / "v.json")


def test_a_terrain_read_as_a_volume_gets_a_note_and_a_closed_mesh_none(tmp_path, capsys):
    """A heightfield given as a volume layer ran without a word and filled a scattered skin
    under it; now the run says the mesh is mostly an open sheet."""
    x, z = np.meshgrid(np.linspace(-3, 3, 30), np.linspace(-3, 3, 30))
    y = np.sin(x) * np.cos(z)
    vertices = np.stack([x, y, z], axis=-1).reshape(-1, 3)
    k = np.arange(29 * 29).reshape(29, 29) + np.arange(29)[:, None]
    faces = np.concatenate([np.stack([k.ravel(), k.ravel() + 30, k.ravel() + 1], axis=1),
                            np.stack([k.ravel() + 1, k.ravel() + 30, k.ravel() + 31], axis=1)])
    _write_obj(tmp_path / "terrain.obj", vertices, faces)
    box = _box(*BOX)
    _write_obj(tmp_path / "box.obj", box.vertices, box.faces)
    # a closed box over a ground plane: the plane changes no voxel, so the inside is the box's
    # and no guess (h79: "mostly an open sheet ... close it", of the plane)
    ground = np.array([[-30, -2, -30], [30, -2, -30], [30, -2, 30], [-30, -2, 30]], dtype=float)
    _write_obj(tmp_path / "grounded.obj", np.concatenate([box.vertices, ground]),
               np.concatenate([box.faces, np.array([[0, 2, 1], [0, 3, 2]]) + len(box.vertices)]))
    for name, noted in (("terrain", True), ("box", False), ("grounded", False)):
        (tmp_path / f"{name}.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.25,
                                                           "layers": [{"file": f"{name}.obj", "w_fill": 1}]}))
        code = main(["infer", "spaceship", "--target", str(tmp_path / f"{name}.json"), "--engine", "smc",
                     "--particles", "2", "--out", str(tmp_path / f"out_{name}")])
        err = capsys.readouterr().err
        assert code == 0 and ("mostly an open sheet" in err) == noted, err


def test_meshes_in_other_units_or_far_away_are_told_how_to_fix_it(tmp_path, capsys):
    """Advice a technical artist could follow: the suggested mesh_offset of a scan
    123,456.7 from the origin was written 1.235e+05 (43 units off, and the note then
    repeated the value given); a centimetre mesh's grid was refused as memory with
    "use a larger voxel_size", a tiny one as "no inside" with "use a smaller voxel_size",
    a grid beside the mesh as "an open sheet"; a view the mesh overfills scored
    11054 with no word; a mesh given as --target was "not an image Pillow can read"."""
    from procmod.cli import _model
    from procmod.targets.placement import placement_note

    ship = trimesh.util.concatenate([_box((1.0, 0.6, 3.0), (0, 0, 0)), _box((3.0, 0.2, 0.8), (0, 0, -0.5))])
    _write_obj(tmp_path / "far.obj", ship.vertices + [123456.7, 0.0, 0.0], ship.faces)
    model = _model("spaceship")
    note = placement_note(model, load_volume_target(_volume_file(tmp_path, "far.obj")), np.random.default_rng(0))
    at = note.index("\"mesh_offset\": ") + len("\"mesh_offset\": ")
    offset = json.loads(note[at:note.index(" in the target file", at)])
    assert offset[0] == pytest.approx(-123456.7, abs=1)  # was 43 off: 1.235e+05
    assert placement_note(model, load_volume_target(_volume_file(tmp_path, "far.obj", mesh_offset=offset)),
                          np.random.default_rng(0)) is None
    # a mesh 21,000 units across at voxel size 0.5: memory, but said with its span and the units
    from procmod.core import ProcmodError
    _write_obj(tmp_path / "cm.obj", ship.vertices * 7000, ship.faces)
    with pytest.raises(ProcmodError, match=r"the mesh spans 2.1e\+04 x 4.2e\+03 x 2.1e\+04: use a larger voxel_size, "
                                           r"or, if the mesh was made in other units .*\"mesh_scale\""):
        load_volume_target(_volume_file(tmp_path, "cm.obj", voxel_size=0.5))
    # a stray triangle far from a ship of the right size: the grid is refused for it, and
    # the message names it (it blamed the units and suggested a mesh_scale of 0.01)
    stray = np.concatenate([ship.vertices, [[1000, 1000, 1000], [1000.1, 1000, 1000], [1000, 1000.1, 1000]]])
    _write_obj(tmp_path / "stray.obj", stray, np.concatenate([ship.faces, [[len(ship.vertices) + k for k in range(3)]]]))
    with pytest.raises(ProcmodError, match=r"memory.*; 1 face of the mesh lies far from the rest \(near \(1000, 1000, "
                                           r"1000\), while the rest spans 3 x 0.6 x 3\): delete that stray piece") as error:
        load_volume_target(_volume_file(tmp_path, "stray.obj", voxel_size=0.05))
    assert "mesh_scale" not in str(error.value)
    # a mesh smaller than a voxel
    _write_obj(tmp_path / "mm.obj", ship.vertices * 0.001, ship.faces)
    with pytest.raises(TargetFileError, match=r"the mesh spans only .* under two voxels of 0.5.*\"mesh_scale\""):
        load_volume_target(_volume_file(tmp_path, "mm.obj", voxel_size=0.5))
    # a grid given in the file, beside the mesh
    _write_obj(tmp_path / "m.obj", ship.vertices, ship.faces)
    (tmp_path / "G.json").write_text(json.dumps({"format": "procmod-volume/1", "layers": [{"file": "m.obj"}],
                                                 "grid": {"origin": [100, 100, 100], "voxel_size": 0.5,
                                                          "shape": [4, 4, 4]}}))
    with pytest.raises(TargetFileError, match=r"does not cover the mesh, which spans .*: the grid belongs where .*\"mesh_offset\""):
        load_volume_target(tmp_path / "G.json")
    # a silhouette the mesh overfills: no outline to match
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [
        {"mesh": "cm.obj", "camera": {"eye": [0, 20, 0.01], "look_at": [0, 0, 0], "width": 64, "height": 64}}]}))
    assert "covers 100% of the view, so it has no outline" in placement_note(
        model, load_target_file(tmp_path / "S.json"), np.random.default_rng(0))
    # the same for a painted mask (Blender's panel, all black): no mesh, so no units to give
    np.save(tmp_path / "black.npy", np.ones((64, 64)))
    (tmp_path / "M.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [
        {"weights": "black.npy", "camera": {"eye": [0, 20, 0.01], "look_at": [0, 0, 0]}}]}))
    note = placement_note(model, load_target_file(tmp_path / "M.json"), np.random.default_rng(0))
    assert "covers 100% of the view, so it has no outline" in note and "mesh_scale" not in note
    # a close-up that fills 98% of the view but keeps an edge of its outline in it: no such note
    near = load_target_file(tmp_path / "S.json")
    near.weights[0][:, 0] = -1.0
    assert (near.weights[0] > 0).mean() > 0.95
    assert "no outline" not in (placement_note(model, near, np.random.default_rng(0)) or "")
    # a mesh file as --target
    assert main(["infer", "spaceship", "--target", str(tmp_path / "m.obj"), "--out", str(tmp_path / "run")]) == 2
    assert "a mesh is a target through a target file" in capsys.readouterr().err
    # a voxel grid likewise (it was "not an image Pillow can read")
    np.save(tmp_path / "grid.npy", np.ones((4, 4, 4)))
    assert main(["infer", "spaceship", "--target", str(tmp_path / "grid.npy"), "--out", str(tmp_path / "run")]) == 2
    assert "an .npy array is a target through a target file" in capsys.readouterr().err
    # a tool's own scene, named by a target file or given as --target: what to export instead
    (tmp_path / "ship.fbx").write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00")
    (tmp_path / "F.json").write_text(json.dumps({"format": "procmod-volume/1", "layers": [{"file": "ship.fbx"}]}))
    with pytest.raises(TargetFileError, match=r'layers\[0\].file: "ship.fbx" is not a voxel grid .*; an Autodesk FBX '
                                              r"file is not read by procmod; export glTF 2.0 \(.glb\) or OBJ from "
                                              r"its tool"):
        load_target_file(tmp_path / "F.json")
    assert main(["infer", "spaceship", "--target", str(tmp_path / "ship.fbx"), "--out", str(tmp_path / "run")]) == 2
    err = capsys.readouterr().err
    assert "a mesh is a target through a target file" in err and "Autodesk FBX file is not read" in err
    assert len(err.strip().splitlines()) == 1 and not (tmp_path / "run").exists()


def test_a_small_cad_part_gets_a_margin_of_its_size_and_a_margin_heavy_grid_is_named(tmp_path, capsys):
    """A 20 x 10 x 5 mm bracket from a CAD tool, in millimetres, for a model in metres at
    0.2 mm voxels: 100 x 50 x 25 voxels, but the default margin of 0.1 on each side made
    the grid 1100 x 1050 x 1025, refused as too fine a voxel size or the wrong units."""
    trimesh.creation.box([20, 10, 5]).export(tmp_path / "bracket_mm.stl")
    spec = {"format": "procmod-volume/1", "mesh_scale": 0.001, "voxel_size": 0.0002,
            "layers": [{"file": "bracket_mm.stl"}]}
    (tmp_path / "t.json").write_text(json.dumps(spec))
    target = load_target_file(tmp_path / "t.json")
    assert target.grid.shape == (150, 100, 75)  # a quarter of the 20 mm on each side
    assert (target.combined > 0).sum() == 100 * 50 * 25
    # a mesh of 0.4 units or more, or voxels of 0.05 or more: the margin stays 0.1
    big = _box((1.0, 0.6, 0.8), (0.0, 0.0, 0.0))
    big.export(tmp_path / "big.stl")
    (tmp_path / "big.json").write_text(json.dumps(dict(spec, mesh_scale=1, voxel_size=0.05,
                                                       layers=[{"file": "big.stl"}])))
    assert load_target_file(tmp_path / "big.json").grid.origin == pytest.approx((-0.6, -0.4, -0.5))
    # an explicit margin too wide for memory: the refusal says the margin, not the units
    (tmp_path / "wide.json").write_text(json.dumps(dict(spec, voxel_size=0.00002, margin=0.1)))
    assert main(["infer", "spaceship", "--target", str(tmp_path / "wide.json"), "--engine", "forward",
                     "--out", str(tmp_path / "out")]) == 2
    said = capsys.readouterr().err
    assert "the grid is mostly its margin of 0.1 on each side: give a smaller \"margin\"" in said, said
    assert "mesh_scale" not in said and not (tmp_path / "out").exists()


def test_a_mesh_from_a_z_up_tool_stands_up_with_mesh_up(tmp_path):
    """procmod's models are y-up; an OBJ or STL from 3ds Max or a CAD tool is z-up and lay
    on its side with no way to turn it. "mesh_up": "z" turns it as Blender's glTF exporter
    does, (x, y, z) -> (x, z, -y), before mesh_scale and mesh_offset."""
    box = _box((1.0, 3.0, 0.6), (0.5, 1.0, 0.3))  # y-up: 3 tall
    _write_obj(tmp_path / "y.obj", box.vertices, box.faces)
    zup = box.vertices[:, [0, 2, 1]] * [1, -1, 1]  # the same box as a z-up tool writes it: (x, -z, y)
    _write_obj(tmp_path / "z.obj", zup * 100, box.faces)
    want = load_volume_target(_volume_file(tmp_path, "y.obj"))
    got = load_volume_target(_volume_file(tmp_path, "z.obj", mesh_up="z", mesh_scale=0.01))
    assert got.grid.shape == want.grid.shape and np.allclose(got.grid.origin, want.grid.origin)
    assert np.array_equal(got.combined, want.combined)
    lying = load_volume_target(_volume_file(tmp_path, "z.obj", mesh_scale=0.01))
    assert lying.grid.shape != want.grid.shape  # without it, on its side
    with pytest.raises(TargetFileError, match=r"mesh_up is the mesh's up axis, one of 'y', 'z'"):
        load_volume_target(_volume_file(tmp_path, "z.obj", mesh_up="up"))
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "mesh_up": "z", "mesh_scale": 0.01,
                                                 "views": [{"mesh": "z.obj", "camera": {"eye": [0, 1, 8], "look_at": [0.5, 1, 0]}}]}))
    (tmp_path / "R.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                 "views": [{"mesh": "y.obj", "camera": {"eye": [0, 1, 8], "look_at": [0.5, 1, 0]}}]}))
    assert np.array_equal(load_target_file(tmp_path / "S.json").weights[0],
                          load_target_file(tmp_path / "R.json").weights[0])


def test_a_target_lying_on_its_side_is_told_mesh_up(tmp_path):
    """A z-up tool's mesh of the model's shape read y-up lies on its side (it scored 32 of
    336 with no word); the note names "mesh_up", and is silent once it is given or when the
    mesh stands as the model does."""
    from procmod.cli import _model
    from procmod.targets.placement import model_box, placement_note

    model = _model("spaceship")
    lo, hi = model_box(model, np.random.default_rng(0))
    size, centre = hi - lo, 0.5 * (lo + hi)
    standing = _box(tuple(size), tuple(centre))
    _write_obj(tmp_path / "y.obj", standing.vertices, standing.faces)
    _write_obj(tmp_path / "z.obj", standing.vertices[:, [0, 2, 1]] * [1, -1, 1], standing.faces)  # as z-up

    def note(mesh, **fields):
        return placement_note(model, load_volume_target(_volume_file(tmp_path, mesh, voxel_size=0.1, **fields)),
                              np.random.default_rng(0))

    assert note("y.obj") is None
    lying = note("z.obj")
    assert lying is not None and "give \"mesh_up\": \"z\" in the target file" in lying, lying
    assert note("z.obj", mesh_up="z") is None
    # whatever its size (its proportions are what lie): 1.7x the samples' box
    _write_obj(tmp_path / "z17.obj", standing.vertices[:, [0, 2, 1]] * [1.7, -1.7, 1.7], standing.faces)
    assert "\"mesh_up\": \"z\"" in note("z17.obj")
    # a file that moves its mesh with mesh_offset gets the offset that goes with the turn
    _write_obj(tmp_path / "zfar.obj", standing.vertices[:, [0, 2, 1]] * [1, -1, 1] + [0, 40, 0], standing.faces)
    moved = note("zfar.obj", mesh_offset=[0, -40, 0])
    at = moved.index("\"mesh_offset\": ") + len("\"mesh_offset\": ")
    offset = json.loads(moved[at:moved.index(" in the target file", at)])
    assert note("zfar.obj", mesh_up="z", mesh_offset=offset) is None
    # a file without one whose mesh, stood up, would not meet the model gets it too (h79: a
    # centimetre z-up mesh far from the origin took a run for each piece of advice)
    alone = note("zfar.obj")
    assert "give \"mesh_up\": \"z\" and \"mesh_offset\": " in alone, alone
    at = alone.index("\"mesh_offset\": ") + len("\"mesh_offset\": ")
    assert note("zfar.obj", mesh_up="z", mesh_offset=json.loads(alone[at:alone.index(" in the target file", at)])) \
        is None
    # a y-up mesh given "mesh_up": "z" lies on its side: the note says the turn did it
    turned = note("y.obj", mesh_up="z")
    assert turned is not None and "\"mesh_up\": \"z\" turned it over; leave \"mesh_up\" out" in turned, turned
    # a narrow ship with tall fins stands as it is: no turn suggested
    _write_obj(tmp_path / "fins.obj", _box((2.5, 7.0, 10.5), (0, 0, 0)).vertices, _box((2.5, 7.0, 10.5), (0, 0, 0)).faces)
    assert "mesh_up" not in (note("fins.obj") or "")


def test_a_white_on_black_mask_gets_a_note_and_a_camera_far_out_is_no_coincidence(tmp_path):
    """A white object on black (a mask or alpha pass) was read inverted without a word: the
    whole border to hit, the object to avoid. And a camera 30 units from its look_at, a
    million units out, was refused as coinciding with it (allclose's tolerance grows with
    the coordinates)."""
    from PIL import Image

    from procmod.models import get_model
    from procmod.targets.placement import placement_note

    mask = np.zeros((64, 64), np.uint8)
    mask[20:44, 24:40] = 255  # the object, white
    Image.fromarray(mask).save(tmp_path / "mask.png")
    camera = {"eye": [0, 2, 30], "look_at": [0, 2, 0], "projection": "orthographic", "fov": 16}
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                 "views": [{"image": "mask.png", "camera": camera}]}))
    note = placement_note(get_model("spaceship"), load_target_file(tmp_path / "S.json"), np.random.default_rng(0))
    assert note is not None and "surrounds the rest of the view" in note and "invert the picture" in note
    Image.fromarray(255 - mask).save(tmp_path / "mask.png")  # black on white, as documented: no such note
    note = placement_note(get_model("spaceship"), load_target_file(tmp_path / "S.json"), np.random.default_rng(0))
    assert "invert" not in (note or "")
    far = {"eye": [1e6, 5e5, -2999970.0], "look_at": [1e6, 5e5, -3e6], "projection": "orthographic", "fov": 16}
    (tmp_path / "F.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                 "views": [{"image": "mask.png", "camera": far}]}))
    assert isinstance(load_target_file(tmp_path / "F.json"), Silhouette)
    (tmp_path / "F.json").write_text(json.dumps({"format": "procmod-silhouette/1", "views": [
        {"image": "mask.png", "camera": dict(far, eye=far["look_at"])}]}))
    with pytest.raises(TargetFileError, match="the camera's eye and look_at coincide"):
        load_target_file(tmp_path / "F.json")


def test_a_collada_file_that_declares_its_up_axis_is_not_turned_twice(tmp_path):
    """COLLADA says which axis is up, and procmod reads it standing by that; the README's
    advice for a z-up tool ("mesh_up": "z") turned Blender's z-up export a second time,
    and the ship stood on its tail without a word. A file that says Y_UP (trimesh writes it
    into every file) is read unturned, so "mesh_up" may still stand it up."""
    box = _box((1.0, 3.0, 0.6), (0.5, 1.0, 0.3))
    box.export(tmp_path / "y.dae")
    text = (tmp_path / "y.dae").read_text()
    assert "<up_axis>Y_UP</up_axis>" in text
    (tmp_path / "z.dae").write_text(text.replace("<up_axis>Y_UP</up_axis>", "<up_axis>Z_UP</up_axis>"))
    with pytest.raises(TargetFileError, match=r"declares its up axis \(<up_axis>Z_UP</up_axis>\).*leave out "
                                              r"\"mesh_up\""):
        load_volume_target(_volume_file(tmp_path, "z.dae", mesh_up="z"))
    as_read = load_volume_target(_volume_file(tmp_path, "y.dae")).grid.shape
    assert load_volume_target(_volume_file(tmp_path, "y.dae", mesh_up="z")).grid.shape != as_read  # turned
    # the up axis as the reader reads it: not one in a comment, and one after a long asset block
    (tmp_path / "comment.dae").write_text(text.replace("<up_axis>Y_UP</up_axis>",
                                                       "<!-- was <up_axis>Z_UP</up_axis> -->"))
    assert load_volume_target(_volume_file(tmp_path, "comment.dae", mesh_up="z")).grid.shape != as_read
    long = "<contributor><comments>" + "x" * 70_000 + "</comments></contributor>"
    (tmp_path / "long.dae").write_text(text.replace("<up_axis>Y_UP</up_axis>", long + "<up_axis>Z_UP</up_axis>"))
    with pytest.raises(TargetFileError, match="Z_UP"):
        load_volume_target(_volume_file(tmp_path, "long.dae", mesh_up="z"))


@pytest.mark.parametrize("key, meant", [("up_axis", "mesh_up"), ("upAxis", "mesh_up"), ("mesh_up_axis", "mesh_up"),
                                        ("units", "mesh_scale"), ("mesh_units", "mesh_scale"), ("scale", "mesh_scale"),
                                        ("translation", "mesh_offset"), ("offset", "mesh_offset"),
                                        ("resolution", "voxel_size"), ("self_weight", "w_self"),
                                        ("rotation", "turns a mesh only by"), ("mesh_rotate", "turns a mesh only by"),
                                        ("mesh_translate", "mesh_offset"), ("z_up", "mesh_up")])
def test_a_placement_said_in_other_words_is_refused(tmp_path, key, meant):
    """These keys were read without a word and changed nothing: a z-up OBJ given
    "mesh_up_axis": "z" was read y-up, and the note then advised what the user believed
    they had written."""
    box = _box((1.0, 3.0, 0.6), (0.5, 1.0, 0.3))
    _write_obj(tmp_path / "m.obj", box.vertices, box.faces)
    with pytest.raises(TargetFileError, match=meant):
        load_volume_target(_volume_file(tmp_path, "m.obj", **{key: "z"}))
    load_volume_target(_volume_file(tmp_path, "m.obj", mesh_source="maya", meshes=["m.obj"]))  # a tool's own: read
    # a file with no mesh to place keeps a tool's own "scale" (it places nothing of procmod's)
    np.save(tmp_path / "grid.npy", np.ones((4, 4, 4), dtype=np.float32))
    (tmp_path / "G.json").write_text(json.dumps({"format": "procmod-volume/1", key: "z", "layers": [
        {"file": "grid.npy", "w_fill": 1}], "grid": {"origin": [0, 0, 0], "voxel_size": 0.25}}))
    load_volume_target(tmp_path / "G.json")


def test_a_gltf_mesh_drawn_by_many_nodes_is_counted_once_per_node_before_reading(tmp_path, monkeypatch):
    """A 1.5 MB glTF whose one mesh 1000 nodes draw filled 10 GB before it was refused: its
    faces were counted once. Strips and fans count too."""
    from procmod.core.errors import ProcmodError
    from procmod.targets import files

    ball = trimesh.creation.icosphere(subdivisions=2)  # 320 faces
    ball.export(tmp_path / "one.gltf")
    spec = json.loads((tmp_path / "one.gltf").read_text())
    mesh = next(i for i, n in enumerate(spec["nodes"]) if "mesh" in n)
    spec["nodes"] = [{"children": list(range(1, 51))}] + [{"mesh": spec["nodes"][mesh]["mesh"],
                                                         "translation": [3.0 * k, 0, 0]} for k in range(50)]
    spec["scenes"] = [{"nodes": [0]}]
    spec["scene"] = 0
    (tmp_path / "many.gltf").write_text(json.dumps(spec))
    assert files.declared_faces(tmp_path / "many.gltf") == 50 * 320
    assert len(trimesh.load(tmp_path / "many.gltf", force="mesh").faces) == 50 * 320  # what reading makes of it
    unscened = {key: value for key, value in spec.items() if key not in ("scenes", "scene")}
    (tmp_path / "unscened.gltf").write_text(json.dumps(unscened))  # no scene draws it: each mesh once, not 50x
    assert files.declared_faces(tmp_path / "unscened.gltf") == 320
    monkeypatch.setattr(files, "MAX_MESH_FACES", 320 * 10)
    monkeypatch.setattr(trimesh, "load", lambda *a, **k: pytest.fail("the mesh was read"))
    with pytest.raises(ProcmodError, match="faces"):
        files.read_mesh(tmp_path / "many.gltf")


def test_obj_faces_after_a_tab_or_indent_and_uppercase_stl_facets_are_counted(tmp_path):
    from procmod.targets import files

    box = _box((1.0, 1.0, 1.0), (0, 0, 0))
    lines = [f"v {x} {y} {z}" for x, y, z in box.vertices]
    lines += [("f\t" if i % 3 == 0 else "  f " if i % 3 == 1 else "f ") + " ".join(str(v + 1) for v in f)
              for i, f in enumerate(box.faces)]
    (tmp_path / "t.obj").write_text("\n".join(lines))  # no newline at the end
    assert files.declared_faces(tmp_path / "t.obj") == len(box.faces) == len(files.read_mesh(tmp_path / "t.obj")[1])
    stl = trimesh.exchange.stl.export_stl_ascii(box).upper()
    (tmp_path / "u.stl").write_text(stl)
    assert files.declared_faces(tmp_path / "u.stl") == len(box.faces)


def test_a_textured_mesh_target_decodes_no_texture(tmp_path, monkeypatch):
    """A target needs the geometry only: with materials, trimesh decoded every texture and
    packed them into one atlas (a GLB of 12 textures of 2048 x 2048: 20 s and 3.3 GB, the
    same without textures 2 s)."""
    from PIL import Image

    ball = trimesh.creation.icosphere(subdivisions=2)
    ball.visual = trimesh.visual.TextureVisuals(uv=np.random.default_rng(0).random((len(ball.vertices), 2)),
                                                image=Image.new("RGB", (64, 64), (200, 30, 30)))
    ball.export(tmp_path / "tex.glb")
    opened = []
    real_open = Image.open
    monkeypatch.setattr(Image, "open", lambda *a, **k: opened.append(a) or real_open(*a, **k))
    load_volume_target(_volume_file(tmp_path, "tex.glb"))
    assert not opened, "a texture was decoded"


def _with_arrays(spec: dict, arrays: list) -> list:
    """Append float32 / uint8 arrays to a glTF's (data-URI) buffer 0; their accessor indices."""
    import base64

    uri = spec["buffers"][0]["uri"]
    blob = base64.b64decode(uri.split(",", 1)[1])
    found = []
    for values, kind, component in arrays:
        blob += b"\0" * (-len(blob) % 4)
        spec["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": values.nbytes})
        blob += values.tobytes()
        spec["accessors"].append({"bufferView": len(spec["bufferViews"]) - 1, "componentType": component,
                                  "count": len(values), "type": kind})
        found.append(len(spec["accessors"]) - 1)
    spec["buffers"][0] = {"byteLength": len(blob),
                          "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}
    return found


def test_a_gltf_mesh_is_read_as_its_morph_targets_and_skin_show_it(tmp_path):
    """trimesh reads a mesh at rest: a cube pulled 4 m tall by a shape key Blender exported
    set (a morph target of weight 1) was read as the cube, and a bar bent by a posed joint
    (Blender's export with "Use Rest Position Armature" off) standing, while glTF viewers
    and the tool's own OBJ export show them pulled and posed."""
    from asset_writers import box_mesh, gltf_json

    from procmod.targets.files import read_mesh

    v, f = box_mesh((1.0, 1.0, 1.0), (0.0, 0.5, 0.0))
    spec = gltf_json([("cube", [(v, f)])], [{"name": "cube", "mesh": 0}], (0,))
    pulled = np.where(v[:, 1:2] > 0.5, [0.0, 4.0, 0.0], 0.0).astype(np.float32)
    (delta,) = _with_arrays(spec, [(pulled, "VEC3", 5126)])
    spec["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": delta}]
    spec["meshes"][0]["weights"] = [1.0]
    (tmp_path / "pulled.gltf").write_text(json.dumps(spec))
    assert read_mesh(tmp_path / "pulled.gltf")[0][:, 1].max() == pytest.approx(5.0, abs=1e-6)
    spec["nodes"][0]["weights"] = [0.5]  # a node's weights are what it shows
    (tmp_path / "half.gltf").write_text(json.dumps(spec))
    assert read_mesh(tmp_path / "half.gltf")[0][:, 1].max() == pytest.approx(3.0, abs=1e-6)

    v, f = box_mesh((0.2, 3.0, 0.2), (0.0, 1.5, 0.0))  # a bar up y, bound to one joint at the origin
    spec = gltf_json([("bar", [(v, f)])], [{"name": "bar", "mesh": 0, "skin": 0, "children": []},
                                           {"name": "bone", "rotation": [math.sin(math.pi / 4), 0, 0,
                                                                         math.cos(math.pi / 4)]}], (0, 1))
    joints, weights = _with_arrays(spec, [(np.zeros((len(v), 4), np.uint8), "VEC4", 5121),
                                          (np.tile(np.float32([1, 0, 0, 0]), (len(v), 1)), "VEC4", 5126)])
    spec["meshes"][0]["primitives"][0]["attributes"].update(JOINTS_0=joints, WEIGHTS_0=weights)
    spec["skins"] = [{"joints": [1]}]
    (tmp_path / "bent.gltf").write_text(json.dumps(spec))
    vertices = read_mesh(tmp_path / "bent.gltf")[0]
    assert np.allclose(vertices.min(0), [-0.1, -0.1, 0.0], atol=1e-5) and \
        np.allclose(vertices.max(0), [0.1, 0.1, 3.0], atol=1e-5), (vertices.min(0), vertices.max(0))  # bent along z


def test_face_lines_are_counted_across_blocks_and_a_file_without_newlines_in_little_memory(tmp_path, monkeypatch):
    """The scan kept an unfinished line whole: a file with no newline (CR line ends) was
    held in memory entire and joined again with every block (800 MB: 1.6 GB, 13 s)."""
    from procmod.geometry import mesh_files

    monkeypatch.setattr(mesh_files, "_SCAN_BLOCK", 7)  # lines and face prefixes split between blocks
    lines = ["v 0 0 0", "v 1 0 0", "v 0 1 0", "f 1 2 3", "  f 1 3 2", "f\t1 2 3", "# f 1 2 3", "vf 1", "f" + " 1" * 40]
    (tmp_path / "m.obj").write_text("\n".join(lines) + "\n")
    assert mesh_files.declared_faces(tmp_path / "m.obj") == 4
    (tmp_path / "cr.obj").write_bytes("\r".join(lines[3:] + lines[:3]).encode() * 2000)  # one "line", from "f 1 2 3"
    seen = []
    real = mesh_files._scan_lines

    def watched(file, pattern):
        import tracemalloc
        tracemalloc.start()
        try:
            return real(file, pattern)
        finally:
            seen.append(tracemalloc.get_traced_memory()[1])
            tracemalloc.stop()

    monkeypatch.setattr(mesh_files, "_scan_lines", watched)
    assert mesh_files.declared_faces(tmp_path / "cr.obj") == 1  # a lower bound: one line, a face line
    assert seen[0] < 20_000, seen  # bytes: a line's start and a block, not the file (260 KB)


def test_a_round_primitive_along_its_axes_keeps_them_and_a_turned_plane_is_left_quietly(tmp_path, recwarn):
    """A 32-gon's least box lies half a facet off its axes: the unturned table's round top
    had taken a turn of 16.9 degrees (and the others 16.9 more than theirs). Turned planes
    had made trimesh warn of a division by zero."""
    def round_table(path, k, turn):
        top = trimesh.creation.cylinder(radius=0.5 + 0.2 * k, height=0.05, sections=32)
        top.apply_transform(trimesh.transformations.rotation_matrix(math.pi / 2, [1, 0, 0]))  # its axis up y
        top.apply_transform(trimesh.transformations.rotation_matrix(turn, [0, 1, 0]))
        write_glb(path, gltf_json([("Top", [(top.vertices, top.faces)])], [{"name": "Top", "mesh": 0}], (0,)))
        return path

    from asset_writers import gltf_json, write_glb

    from procmod.geometry.assets import read_assets
    from scipy.spatial.transform import Rotation

    read = read_assets([round_table(tmp_path / f"r{k}.glb", k, turn) for k, turn in enumerate((0.0, 0.4, 1.0))])
    assert sorted(read.parts) == ["Top"]
    for asset, turn in zip(read.assets, (0.0, 0.4, 1.0)):
        m = np.asarray(asset.nodes()[0].transform)[:3, :3]
        angle = Rotation.from_matrix(m / np.linalg.norm(m, axis=0)).magnitude()
        assert angle == pytest.approx(turn, abs=1e-6), (asset.path.name, angle)
    planes = []
    for k in range(3):
        plane = trimesh.creation.box((1.0 + 0.5 * k, 0.0, 0.6))
        plane.apply_transform(trimesh.transformations.rotation_matrix(0.3 + 0.2 * k, [1, 0.2, 0]))
        planes.append(write_glb(tmp_path / f"p{k}.glb", gltf_json([("Panel", [(plane.vertices, plane.faces)])],
                                                                 [{"name": "Panel", "mesh": 0}], (0,))))
    read_assets(planes)
    assert not [w for w in recwarn if issubclass(w.category, RuntimeWarning)], [str(w.message) for w in recwarn]


def test_odd_but_readable_skins_and_shared_morphed_meshes_read_as_viewers_show_them(tmp_path):
    """Review cases: a joint index past the skin's joints in a slot of weight zero (some
    exporters' padding) had refused the file; a skinned node scaled to nothing raised a
    numpy error; a mesh two nodes draw, one with weights of its own, was morphed under both."""
    from asset_writers import box_mesh, gltf_json

    from procmod.targets.files import read_mesh

    v, f = box_mesh((0.2, 3.0, 0.2), (0.0, 1.5, 0.0))
    nodes = [{"name": "bar", "mesh": 0, "skin": 0},
             {"name": "bone", "rotation": [math.sin(math.pi / 4), 0, 0, math.cos(math.pi / 4)]}]
    spec = gltf_json([("bar", [(v, f)])], nodes, (0, 1))
    padded = np.tile(np.uint8([0, 7, 7, 7]), (len(v), 1))
    joints, weights = _with_arrays(spec, [(padded, "VEC4", 5121),
                                          (np.tile(np.float32([1, 0, 0, 0]), (len(v), 1)), "VEC4", 5126)])
    spec["meshes"][0]["primitives"][0]["attributes"].update(JOINTS_0=joints, WEIGHTS_0=weights)
    spec["skins"] = [{"joints": [1]}]
    (tmp_path / "padded.gltf").write_text(json.dumps(spec))
    assert read_mesh(tmp_path / "padded.gltf")[0][:, 2].max() == pytest.approx(3.0, abs=1e-5)  # posed
    spec["nodes"][0]["scale"] = [0, 0, 0]
    (tmp_path / "flat.gltf").write_text(json.dumps(spec))
    with pytest.raises(TargetFileError, match="zero area"):  # at rest, placed by a node of no size: said in words
        read_mesh(tmp_path / "flat.gltf")

    v, f = box_mesh((1.0, 1.0, 1.0), (0.0, 0.5, 0.0))
    spec = gltf_json([("cube", [(v, f)])], [{"name": "root", "children": [1, 2]}, {"name": "a", "mesh": 0, "weights": [1.0]},
                                            {"name": "b", "mesh": 0, "translation": [3, 0, 0]}], (0,))
    (delta,) = _with_arrays(spec, [(np.where(v[:, 1:2] > 0.5, [0.0, 4.0, 0.0], 0.0).astype(np.float32), "VEC3", 5126)])
    spec["meshes"][0]["primitives"][0]["targets"] = [{"POSITION": delta}]
    spec["meshes"][0]["weights"] = [0.0]
    (tmp_path / "two.gltf").write_text(json.dumps(spec))
    vertices = read_mesh(tmp_path / "two.gltf")[0]
    assert vertices[vertices[:, 0] > 2, 1].max() == pytest.approx(1.0, abs=1e-6)  # b shows the mesh's weights
    # and a its own (h73: it was read at the mesh's too, its shape key dropped without a word)
    assert vertices[vertices[:, 0] < 2, 1].max() == pytest.approx(5.0, abs=1e-6)

    # one skinned mesh drawn by two nodes under two skins (cloned characters sharing the
    # geometry): each is posed by its own skin's joints, not both read at rest (h144)
    v, f = box_mesh((2.0, 0.2, 1.0), (1.0, 0.0, 0.0))  # a wing from x 0 to 2, bound to one joint
    nodes = [{"name": "root", "children": [1, 2, 3, 4]}, {"name": "bone.L", "translation": [2, 0, 0]},
             {"name": "bone.R", "translation": [-4, 0, 0]}, {"name": "wing.L", "mesh": 0, "skin": 0},
             {"name": "wing.R", "mesh": 0, "skin": 1}]
    spec = gltf_json([("wing", [(v, f)])], nodes, (0,))
    joints, weights = _with_arrays(spec, [(np.zeros((len(v), 4), np.uint8), "VEC4", 5121),
                                          (np.tile(np.float32([1, 0, 0, 0]), (len(v), 1)), "VEC4", 5126)])
    spec["meshes"][0]["primitives"][0]["attributes"].update(JOINTS_0=joints, WEIGHTS_0=weights)
    spec["skins"] = [{"joints": [1]}, {"joints": [2]}]
    (tmp_path / "clones.gltf").write_text(json.dumps(spec))
    vertices = read_mesh(tmp_path / "clones.gltf")[0]
    assert sorted(np.unique(np.round(vertices[:, 0], 5))) == [-4.0, -2.0, 2.0, 4.0]


def test_a_collada_up_axis_written_with_spaces_or_in_lower_case_is_read_as_checked(tmp_path):
    """pycollada takes only the exact words: "\\n  Z_UP\\n" was read as Y_UP (a z-up mesh lay
    down) while the target file's check read Z_UP and refused the "mesh_up" that would
    have stood it up."""
    from procmod.targets.files import read_mesh

    box = _box((1.0, 1.0, 4.0), (0.0, 0.0, 2.0))  # tall along z: a z-up tool's standing box
    box.export(tmp_path / "b.dae")
    text = (tmp_path / "b.dae").read_text()
    for k, said in enumerate(("\n  Z_UP\n", "z_up")):
        (tmp_path / f"z{k}.dae").write_text(text.replace("<up_axis>Y_UP</up_axis>", f"<up_axis>{said}</up_axis>"))
        assert np.ptp(read_mesh(tmp_path / f"z{k}.dae")[0], axis=0) == pytest.approx([1.0, 4.0, 1.0], abs=1e-6)


def test_a_top_level_up_in_a_silhouette_of_pictures_is_a_cameras(tmp_path):
    from PIL import Image

    Image.new("L", (20, 20), 255).save(tmp_path / "a.png")
    camera = {"eye": [0, 0, 10], "look_at": [0, 0, 0]}
    (tmp_path / "S.json").write_text(json.dumps({"format": "procmod-silhouette/1", "up": [0, 1, 0],
                                                 "views": [{"image": "a.png", "camera": camera}]}))
    with pytest.raises(TargetFileError, match="a view's camera \"up\""):
        load_target_file(tmp_path / "S.json")


def test_a_text_gltf_named_glb_and_a_gltf_without_a_scene_are_read(tmp_path):
    """A text glTF saved under a .glb name is read as the text it is (it was refused with
    "incorrect header on GLB file"), as a GLB named .gltf already was, and a byte-order
    mark before a text glTF's JSON is passed over (it was "model.gltf" not found); a glTF
    whose meshes hang in no scene (valid glTF: a library of objects) is read as its top
    nodes (it was "holds no triangle faces")."""
    from procmod.geometry.assets import read_assets
    from procmod.targets.files import declared_faces
    from asset_writers import box_mesh, gltf_json, write_glb
    box = _box(*BOX)
    text = box.export(file_type="gltf", embed_buffers=True)["model.gltf"]
    (tmp_path / "text.glb").write_bytes(text)
    (tmp_path / "marked.glb").write_bytes(b"\xef\xbb\xbf\n " + text)
    (tmp_path / "marked.gltf").write_bytes(b"\xef\xbb\xbf" + text)
    for name in ("text.glb", "marked.glb", "marked.gltf"):
        assert declared_faces(tmp_path / name) == 12
        grid, mask = voxelize_mesh_file(tmp_path / name, H)
        assert np.array_equal(mask, _in_boxes(grid, [BOX]))
    v, f = box_mesh(BOX[0], BOX[1])
    library = gltf_json([("box", [(v, f)])], [{"name": "Box", "mesh": 0}], roots=(0,))
    del library["scenes"], library["scene"]
    for path in (tmp_path / "library.gltf", tmp_path / "library.glb"):
        if path.suffix == ".gltf":
            path.write_text(json.dumps(library))
        else:
            write_glb(path, library)
        grid, mask = voxelize_mesh_file(path, H)
        assert np.array_equal(mask, _in_boxes(grid, [BOX])), path.name
        (node,) = read_assets(path).assets[0].roots
        assert node.name == "Box"


def test_leaf_cards_around_a_closed_trunk_are_left_out_of_the_volume(tmp_path, capsys):
    """A tree as games and SpeedTree export it: a closed trunk and hundreds of single-quad
    leaf cards facing every way. The cards enclose nothing, but each one's capped rim made
    its winding number +-1/2 on both sides, so the crown filled voxels by the way each
    card happened to face (216 voxels, 235 with the cards turned over, 56 in both, on a
    user's tree). They are left out, with a note; an open piece that is not flat (a bowl)
    is kept."""
    from procmod.targets import load_volume_target
    rng = np.random.default_rng(0)
    trunk = _box((0.4, 2.0, 0.4), (0.0, 1.0, 0.0))
    vertices, faces = [trunk.vertices], [trunk.faces]
    offset = len(trunk.vertices)
    for _ in range(300):
        centre = rng.normal([0, 2.3, 0], 0.6)
        u, v = (np.linalg.qr(rng.normal(size=(3, 3)))[0][:, :2] * 0.15).T
        vertices.append(np.array([centre - u - v, centre + u - v, centre + u + v, centre - u + v]))
        faces.append(np.array([[0, 1, 2], [0, 2, 3]]) + offset)
        offset += 4
    vertices, faces = np.concatenate(vertices), np.concatenate(faces)
    cards = len(trunk.vertices) <= faces.min(axis=1)
    flipped = faces.copy()
    flipped[cards] = flipped[cards][:, ::-1]
    masks = {}
    for name, f in (("tree", faces), ("turned", flipped), ("trunk", trunk.faces)):
        _write_obj(tmp_path / f"{name}.obj", vertices, f)
        (tmp_path / f"{name}.json").write_text(json.dumps({
            "format": "procmod-volume/1", "grid": {"origin": [-2, -1, -2], "voxel_size": 0.2, "shape": [20, 30, 20]},
            "layers": [{"file": f"{name}.obj", "w_fill": 1}]}))
        target = load_volume_target(tmp_path / f"{name}.json")
        masks[name] = target.combined > 0
        assert any("600 faces of open flat pieces" in note for note in target.file_notes) == (name != "trunk")
    assert np.array_equal(masks["tree"], masks["trunk"]) and np.array_equal(masks["turned"], masks["trunk"])
    # a bowl (an open hemisphere) beside the trunk is no flat piece: its inside is read as before
    bowl = trimesh.creation.icosphere(subdivisions=3)
    bowl.update_faces(bowl.triangles_center[:, 1] < 0)
    bowl.remove_unreferenced_vertices()
    bowl.apply_translation([1.2, 0.5, 0.0])
    joined = trimesh.util.concatenate([trunk, bowl])
    _write_obj(tmp_path / "bowl.obj", joined.vertices, joined.faces)
    (tmp_path / "bowl.json").write_text(json.dumps({
        "format": "procmod-volume/1", "grid": {"origin": [-2, -1, -2], "voxel_size": 0.2, "shape": [20, 30, 20]},
        "layers": [{"file": "bowl.obj", "w_fill": 1}]}))
    assert not load_volume_target(tmp_path / "bowl.json").file_notes
    # flat pieces that close a room together stay: six wall planes overlapping at the corners
    # (no shared vertex) beside a closed cube; left out, the room had lost its inside (a review)
    walls = []
    for axis in range(3):
        for side in (-1, 1):
            c, u, v = np.zeros(3), np.zeros(3), np.zeros(3)
            c[axis], u[(axis + 1) % 3], v[(axis + 2) % 3] = side, 1.02, 1.02
            quad = trimesh.Trimesh([c - u - v, c + u - v, c + u + v, c - u + v], [[0, 1, 2], [0, 2, 3]], process=False)
            walls.append(quad if side > 0 else trimesh.Trimesh(quad.vertices, quad.faces[:, ::-1], process=False))
    cube = _box((0.3, 0.3, 0.3), (2.5, 0.0, 0.0))
    room = trimesh.util.concatenate(walls + [cube])
    _write_obj(tmp_path / "room.obj", room.vertices, room.faces)
    (tmp_path / "room.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.1,
                                                    "layers": [{"file": "room.obj", "w_fill": 1}]}))
    target = load_volume_target(tmp_path / "room.json")
    assert (target.combined > 0).sum() == 8000 + 27 and not target.file_notes


def _silhouette_of_picture(tmp_path, name: str, picture) -> Path:
    picture.save(tmp_path / f"{name}.png")
    camera = {"eye": [0, 0, 10], "look_at": [0, 0, 0], "projection": "orthographic", "fov": 4}
    path = tmp_path / f"{name}.json"
    path.write_text(json.dumps({"format": "procmod-silhouette/1", "views": [{"image": f"{name}.png",
                                                                             "camera": camera}]}))
    return path


def test_a_light_cut_out_is_read_from_its_alpha_channel_and_a_shaded_photo_gets_a_note(tmp_path):
    """h79: a light-grey object on a transparent ground (a product cut-out), or a mask drawn
    only in the alpha channel of a white picture, was refused as having no dark pixel; a
    photo shaded from grey 170 to 40 had its lit half read as "either" without a word."""
    from PIL import Image

    from procmod.targets.files import load_target_file

    inside = np.zeros((60, 80), dtype=bool)
    inside[15:45, 20:60] = True
    rgba = np.zeros((60, 80, 4), dtype=np.uint8)
    rgba[..., :3], rgba[..., 3] = 210, np.where(inside, 255, 0)
    for name, picture in (("cutout", Image.fromarray(rgba, "RGBA")),
                          ("alpha_mask", Image.fromarray(np.dstack([np.full((60, 80, 3), 255, np.uint8),
                                                                    np.where(inside, 255, 0).astype(np.uint8)]),
                                                         "RGBA"))):
        target = load_target_file(_silhouette_of_picture(tmp_path, name, picture))
        weights = target.weights[0]
        assert ((weights > 0) == inside).all(), name
        assert any("read from the picture's alpha channel" in n for n in target.file_notes)
    # the cut-out with a dark logo printed on it: the logo alone had been the shape to hit
    logo = rgba.copy()
    logo[25:35, 35:45, :3] = 20
    target = load_target_file(_silhouette_of_picture(tmp_path, "logo", Image.fromarray(logo, "RGBA")))
    assert ((target.weights[0] > 0) == inside).all()
    assert any("mostly light (to avoid, by its grey levels) with 8% of it dark" in n for n in target.file_notes), \
        target.file_notes
    # a red or yellow object photographed on white: no dark pixel, read by its colour (refused before)
    for name, colour in (("red", (220, 30, 30)), ("yellow", (250, 220, 40))):
        photo = np.full((60, 80, 3), 255, dtype=np.uint8)
        photo[inside] = colour
        target = load_target_file(_silhouette_of_picture(tmp_path, name, Image.fromarray(photo, "RGB")))
        assert ((target.weights[0] > 0) == inside).all(), name
        assert any("read from the picture's colours" in n for n in target.file_notes), target.file_notes
    # ... but not when what is read is most of the picture, or its border: an object filling the
    # frame (it had been read inverted, h87); nor a grey picture with a coloured dot
    photo = np.full((60, 80, 3), (250, 220, 40), dtype=np.uint8)
    photo[:3], photo[-3:] = 255, 255
    dotted = np.full((60, 80, 3), 200, dtype=np.uint8)
    dotted[inside] = 120
    dotted[30, 40] = (255, 0, 255)
    for name, picture in (("filling", photo), ("dotted", dotted)):
        with pytest.raises(TargetFileError, match="no pixel is dark enough to hit"):
            load_target_file(_silhouette_of_picture(tmp_path, name, Image.fromarray(picture, "RGB")))
    # a silhouette in greys on an opaque page with a transparent pixel or margin keeps its grey
    # levels (its light page had been read as the shape to hit, h87)
    page = np.zeros((60, 80, 4), dtype=np.uint8)
    page[..., :3], page[..., 3] = 255, 255
    page[inside, :3] = 0
    page[0, 0, 3] = 0
    target = load_target_file(_silhouette_of_picture(tmp_path, "page", Image.fromarray(page, "RGBA")))
    assert ((target.weights[0] > 0) == inside).all() and target.file_notes == []
    # a shape drawn dark on a transparent ground keeps its grey levels (a light rim is no cut-out)
    drawn = rgba.copy()
    drawn[..., :3] = 0
    drawn[15:45, 20:24, :3] = 230
    target = load_target_file(_silhouette_of_picture(tmp_path, "drawn_rgba", Image.fromarray(drawn, "RGBA")))
    assert (target.weights[0][15:45, 24:60] > 0).all() and (target.weights[0][15:45, 20:24] < 0).all()
    assert target.file_notes == []
    shaded = np.full((60, 80), 255, dtype=np.uint8)
    shaded[15:45, 20:60] = np.linspace(170, 40, 30).astype(np.uint8)[:, None]  # lit from above
    target = load_target_file(_silhouette_of_picture(tmp_path, "shaded", Image.fromarray(shaded, "L")))
    assert any("of the shape's pixels are mid-grey" in n for n in target.file_notes), target.file_notes
    # one grey painted on is "either" meant (scenes/city_skyline's ground)
    painted = np.full((60, 80), 255, dtype=np.uint8)
    painted[15:30, 20:60], painted[30:45, 20:60] = 0, 128
    target = load_target_file(_silhouette_of_picture(tmp_path, "painted", Image.fromarray(painted, "L")))
    assert target.file_notes == []
    # a black shape with smoothed edges, thin or not, is no shaded photo
    for width in (3, 30):
        drawn = np.full((60, 80), 255, dtype=np.uint8)
        drawn[15:15 + width, 20:60] = 0
        drawn[14, 20:60] = drawn[15 + width, 20:60] = 128  # a smoothed edge each side
        target = load_target_file(_silhouette_of_picture(tmp_path, f"drawn{width}", Image.fromarray(drawn, "L")))
        assert target.file_notes == [], (width, target.file_notes)


def test_a_floor_exported_with_the_model_is_named(tmp_path):
    """h79: a solid slab under a ship was 92% of the volume to fill, and a ground plane
    filled a silhouette view (the note blamed the mesh's units), without saying what it
    was. A closed slab is named in a volume; an open plane, left out of a volume, only in
    a view; the ship alone in neither."""
    from procmod.targets.files import load_target_file

    ship = trimesh.util.concatenate([_box((1.0, 0.6, 3.0), (0, 0, 0)), _box((3.0, 0.2, 0.8), (0, 0, -0.5))])
    slab = _box((60.0, 0.1, 60.0), (0, -0.8, 0))
    plane = trimesh.Trimesh([[-30, -0.8, -30], [30, -0.8, -30], [30, -0.8, 30], [-30, -0.8, 30]],
                            [[0, 2, 1], [0, 3, 2]], process=False)
    camera = {"eye": [0, 6, 8], "look_at": [0, 0, 0], "width": 40, "height": 30}
    for name, mesh, in_volume in (("slab", trimesh.util.concatenate([ship, slab]), True),
                                  ("plane", trimesh.util.concatenate([ship, plane]), False),
                                  ("ship", ship, False)):
        _write_obj(tmp_path / f"{name}.obj", mesh.vertices, mesh.faces)
        (tmp_path / f"{name}_v.json").write_text(json.dumps({"format": "procmod-volume/1", "voxel_size": 0.5,
                                                             "layers": [{"file": f"{name}.obj", "w_fill": 1}]}))
        (tmp_path / f"{name}_s.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                             "views": [{"mesh": f"{name}.obj", "camera": camera}]}))
        said = [any("a separate flat piece 60 x 60 wide" in n for n in load_target_file(tmp_path / f"{name}_{k}.json")
                    .file_notes) for k in ("v", "s")]
        assert said == [in_volume, name != "ship"], (name, said)
    # the model's own flat top over a short column is no floor (h80); and a single flat piece
    # with a sliver, whose vertices no kept face uses, is read (h80: a ValueError traceback)
    from procmod.targets.files import ground_piece_note

    table = trimesh.util.concatenate([_box((1.4, 0.04, 1.4), (0, 0.42, 0)), _box((0.1, 0.38, 0.1), (0, 0.2, 0))])
    assert ground_piece_note(table.vertices, table.faces, "table") is None
    plate = _box((2.0, 0.05, 2.0), (0, 0, 0))
    vertices = np.concatenate([plate.vertices, [[5, 5, 5], [6, 6, 6], [7, 7, 7]]])  # a sliver's, its face dropped
    assert ground_piece_note(vertices, plate.faces, "plate") is None
    _write_obj(tmp_path / "sliver.obj", vertices, np.concatenate([plate.faces, [[8, 9, 10]]]))
    (tmp_path / "sliver.json").write_text(json.dumps({"format": "procmod-silhouette/1",
                                                      "views": [{"mesh": "sliver.obj", "camera": camera}]}))
    load_target_file(tmp_path / "sliver.json")


def test_a_z_up_mesh_in_a_silhouette_view_is_said_to_lie_on_its_side(tmp_path):
    """h79: a z-up STL seen from the side was a vertical bar the model could not match, with
    no word, where the same mesh as a volume got the "mesh_up": "z" note."""
    from procmod.cli import _model
    from procmod.targets.files import load_target_file
    from procmod.targets.placement import placement_note

    ship = trimesh.util.concatenate([_box((7.0, 3.0, 9.0), (0, 1.5, 0)), _box((9.0, 0.5, 2.0), (0, 1.0, -1.0))])
    lying = ship.vertices @ np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]).T  # (x, y, z) -> (x, -z, y): z up
    _write_obj(tmp_path / "z.obj", lying, ship.faces)
    _write_obj(tmp_path / "y.obj", ship.vertices, ship.faces)
    camera = {"eye": [30, 2, 0], "look_at": [0, 2, 0], "width": 40, "height": 30}
    model = _model("spaceship")

    def note(mesh, **fields):
        path = tmp_path / f"{mesh}_{len(fields)}.json"
        path.write_text(json.dumps({"format": "procmod-silhouette/1", **fields,
                                    "views": [{"mesh": f"{mesh}.obj", "camera": camera}]}))
        return placement_note(model, load_target_file(path), np.random.default_rng(0)) or ""

    assert "laid on their side" in note("z") and "\"mesh_up\": \"z\"" in note("z")
    assert "laid on their side" not in note("z", mesh_up="z")
    assert "laid on their side" not in note("y")
    assert "turned it over" in note("y", mesh_up="z")
    # in centimetres: the units first, as for a volume (h81: "mesh_up" alone, then nothing)
    _write_obj(tmp_path / "zcm.obj", lying * 100, ship.faces)
    assert "give \"mesh_scale\": 0.01" in note("zcm")
    assert "\"mesh_up\": \"z\"" in note("zcm", mesh_scale=0.01)
    # a backdrop behind a y-up ship: named, and no "mesh_up" from the box it stretches (h81)
    backdrop = _box((40.0, 40.0, 0.3), (0, 0, -10))
    _write_obj(tmp_path / "backed.obj", np.concatenate([ship.vertices, backdrop.vertices]),
               np.concatenate([ship.faces, backdrop.faces + len(ship.vertices)]))
    backed = note("backed")
    assert "a separate flat piece" in backed and "mesh_up" not in backed, backed


def test_a_silhouette_picture_that_shows_nothing_is_refused_and_frames_are_noted(tmp_path):
    """h90: a fully transparent picture (black, alpha 0) was read black, the whole view to
    hit; so was a float picture of NaNs; an animated GIF's other frames went unmentioned,
    where a picture target says so."""
    from PIL import Image

    clear = Image.fromarray(np.zeros((20, 20, 4), dtype=np.uint8), "RGBA")
    with pytest.raises(TargetFileError, match="the picture is fully transparent"):
        load_target_file(_silhouette_of_picture(tmp_path, "clear", clear))
    # a 16-bit grey with a transparent value none of its pixels has: Pillow's RGBA of it is
    # clear everywhere, and it had been refused as fully transparent (h92)
    grey16 = np.full((20, 20), 40000, dtype=np.uint16)
    grey16[5:15, 5:15] = 1000
    Image.fromarray(grey16).save(tmp_path / "grey16.png", transparency=65535)
    spec16 = json.loads(_silhouette_of_picture(tmp_path, "x16", clear).read_text())
    spec16["views"][0]["image"] = "grey16.png"
    (tmp_path / "grey16.json").write_text(json.dumps(spec16))
    assert (load_target_file(tmp_path / "grey16.json").weights[0] > 0).sum() == 100
    nans = Image.fromarray(np.full((20, 20), np.nan, dtype=np.float32), "F")
    nans.save(tmp_path / "nans.tiff")
    spec = json.loads(_silhouette_of_picture(tmp_path, "x", clear).read_text())
    spec["views"][0]["image"] = "nans.tiff"
    (tmp_path / "nans.json").write_text(json.dumps(spec))
    with pytest.raises(TargetFileError, match="pixels are all NaN or infinite"):
        load_target_file(tmp_path / "nans.json")
    shape = np.full((20, 20), 255, dtype=np.uint8)
    shape[5:15, 5:15] = 0
    frames = [Image.fromarray(shape, "L"), Image.fromarray(255 - shape, "L")]
    frames[0].save(tmp_path / "anim.gif", save_all=True, append_images=frames[1:])
    spec["views"][0]["image"] = "anim.gif"
    (tmp_path / "anim.json").write_text(json.dumps(spec))
    assert any("holds 2 frames or pages and procmod read the first" in n
               for n in load_target_file(tmp_path / "anim.json").file_notes)
