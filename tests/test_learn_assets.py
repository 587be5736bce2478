"""``procmod learn`` on asset files (glTF, GLB, URDF): one example per file, parts shared by
geometry, bad files as one-line errors (exit 2) that leave no output behind."""

import json
import math
from dataclasses import dataclass

import numpy as np
import pytest

from procmod.cli import main
from procmod.learn import preprocess
from procmod.learn.examples import read_example_inputs
from procmod.learn.search import SearchOptions

from asset_writers import (box_mesh, column_major, gltf_json, transformed, urdf, wedge_mesh, write_empty_gltf, write_glb,
                           write_huge_gltf, write_unreadable, write_zero_area_gltf)

MX = np.diag([-1.0, 1, 1, 1])


def T(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def ship_file(path, k: int, rng):
    """Ship k: a body (its length set by the node's scale), a mirrored wing pair (the left wing its own mesh 'wing.001', the
    mirrored vertex data of 'wing'), and in odd ships a gun on top; placement noise of a
    hand-made model (1e-3 of the ship's size) on every node."""
    noise = lambda m: T(*rng.normal(0, 3e-3, 3)) @ m  # noqa: E731
    length = 3 + 0.3 * k
    right = T(1.0, 0, 0.2 * k - 0.5)
    meshes = [("body", [box_mesh((2, 0.5, 3))]), ("wing", [wedge_mesh(1.5)]),
              ("wing.001", [transformed(wedge_mesh(1.5), MX)]), ("gun", [box_mesh((0.1, 0.1, 0.6))])]
    nodes = [{"name": "body", "mesh": 0, "scale": [1, 1, length / 3], "children": [1, 2] + ([3] if k % 2 else [])},
             {"name": "wing", "mesh": 1, "matrix": column_major(noise(right))},
             {"name": "wing.001", "mesh": 2, "matrix": column_major(noise(MX @ right @ MX))},
             {"name": "gun", "mesh": 3, "matrix": column_major(noise(T(0, 0.4, 0.3 * k)))}]
    data = gltf_json(meshes, nodes, [0])
    if path.suffix == ".glb":
        return write_glb(path, data)
    path.write_text(json.dumps(data))
    return path


def fleet(folder, n=6):
    folder.mkdir(parents=True, exist_ok=True)
    rng = np.random.default_rng(7)
    return [ship_file(folder / f"ship_{k}.{'glb' if k % 3 == 0 else 'gltf'}", k, rng) for k in range(n)]


@dataclass
class _QuickOptions(SearchOptions):
    init_iterations: int = 80
    split_iterations: int = 40
    warm_iterations: int = 10
    final_iterations: int = 80


def test_learn_a_folder_of_gltf_and_glb_files(tmp_path, monkeypatch, capsys):
    import procmod.learn.search
    monkeypatch.setattr(procmod.learn.search, "SearchOptions", _QuickOptions)
    files = fleet(tmp_path / "ships")
    # a flat mesh and a text file beside the scenes: the mesh is named as left out (it was
    # skipped without a word), the text file is nobody's business
    (tmp_path / "ships" / "ship_flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    (tmp_path / "ships" / "notes.txt").write_text("my ships\n")
    out = tmp_path / "run"
    assert main(["learn", str(tmp_path / "ships"), "--out", str(out), "--particles", "1", "--workers", "1",
                 "--samples", "2"]) == 0
    err = capsys.readouterr().err
    assert "note: left out ship_flat.obj, not read as examples (ship_flat.obj: an OBJ file keeps no part" in err, err
    assert "notes.txt" not in err
    # a URDF's meshes lie beside it: not named as left out
    from procmod.geometry.assets import left_out_note
    robot = tmp_path / "robot"
    robot.mkdir()
    (robot / "arm.urdf").write_text("<robot name='arm'/>")
    (robot / "arm.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n")
    assert left_out_note([robot]) is None and left_out_note([tmp_path / "ships"]) is not None
    program = json.loads((out / "program.json").read_text())
    assert sorted(program["parts"]) == ["body", "gun", "wing"]  # wing.001 is the mirrored wing
    # the wings of every ship, noisy and from two meshes, are one mirror pair of one part
    assert program["slots"]["body"].count("refl(wing)") == 1 and "wing" not in program["slots"]["body"]
    assert (out / "parts" / "wing.obj").exists()
    # several files given one by one are the same examples (same digest: the run resumes)
    _, by_folder = read_example_inputs([tmp_path / "ships"])
    _, by_files = read_example_inputs(sorted(files))
    assert by_folder == by_files
    capsys.readouterr()
    assert main(["learn", *map(str, sorted(files)), "--out", str(out), "--particles", "1", "--workers", "1",
                 "--samples", "2"]) == 0
    assert "holds a run with other examples" not in capsys.readouterr().err


def test_a_folder_of_asset_folders_is_read_and_subfolders_beside_files_are_named(tmp_path):
    """Assets kept one a folder (with their textures) were refused as "holds no .gltf"; a
    later batch in a subfolder beside the folder's own files was left out without a word,
    half the set (h128)."""
    from procmod.geometry.assets import asset_files, left_out_note
    rng = np.random.default_rng(7)
    nested = tmp_path / "nested"
    for k in range(4):
        (nested / f"ship_{k}").mkdir(parents=True)
        ship_file(nested / f"ship_{k}" / f"ship_{k}.glb", k, rng)
        (nested / f"ship_{k}" / "texture.png").write_bytes(b"")  # beside it, not 3D: nobody's business
    assert [f.name for f in asset_files([nested])] == [f"ship_{k}.glb" for k in range(4)]
    example_set, _ = read_example_inputs([nested])
    assert len(example_set.examples) == 4 and left_out_note([nested]) is None
    batches = tmp_path / "batches"
    fleet(batches, 2)
    (batches / "v2").mkdir()
    for k in (2, 3):
        ship_file(batches / "v2" / f"ship_{k}.glb", k, rng)
    example_set, _ = read_example_inputs([batches])
    assert len(example_set.examples) == 2  # the folder's own files, as before
    assert left_out_note([batches]) == (f"2 asset files in the subfolder v2/ were not read (a folder's own files are, "
                                        f"not its subfolders' beside them): give it too, e.g. {batches / 'v2'}")
    example_set, _ = read_example_inputs([batches, batches / "v2"])
    assert len(example_set.examples) == 4


def test_a_file_given_twice_is_one_example_and_said(tmp_path, monkeypatch):
    """``learn a.glb a.glb b.glb``, or a folder and a file in it, had counted the file as two
    examples without a word (h162)."""
    from procmod.geometry.assets import asset_files, left_out_note

    ships = fleet(tmp_path / "ships", 3)
    monkeypatch.chdir(tmp_path)
    given = [ships[0], ships[0], tmp_path / "ships", "ships/../ships/" + ships[2].name]
    assert [f.name for f in asset_files(given)] == [ships[0].name, ships[1].name, ships[2].name]
    assert len(read_example_inputs(given)[0].examples) == 3
    assert left_out_note(given) == f"{ships[0].name}, {ships[2].name} were given more than once and read once"
    assert left_out_note(ships) is None
    assert asset_files([ships[1], ships[0], ships[1]]) == [ships[1], ships[0]]  # in the order first given


def test_a_robots_meshes_and_a_link_back_up_are_no_examples(tmp_path):
    """A ROS robot folder (urdf/ beside meshes/ of .glb files) read one level down took its
    link meshes for examples; a URDF with its .glb meshes beside it had them named as
    subfolders to read too; a link back up to the folder named its own files again (h129)."""
    from procmod.geometry.assets import asset_files, left_out_note
    ros = tmp_path / "my_robot"
    (ros / "urdf").mkdir(parents=True)
    (ros / "meshes").mkdir()
    (ros / "urdf" / "robot.urdf").write_text("<robot name='r'/>")
    for name in ("arm.glb", "base.glb"):
        (ros / "meshes" / name).write_bytes(b"")
    assert asset_files([ros]) == [ros / "urdf" / "robot.urdf"] and left_out_note([ros]) is None
    beside = tmp_path / "beside"
    (beside / "meshes").mkdir(parents=True)
    (beside / "robot.urdf").write_text("<robot name='r'/>")
    (beside / "wheel.glb").write_bytes(b"")
    (beside / "meshes" / "arm.glb").write_bytes(b"")
    assert asset_files([beside]) == [beside / "robot.urdf"] and left_out_note([beside]) is None
    looped = tmp_path / "looped"
    looped.mkdir()
    ship_file(looped / "ship.gltf", 0, np.random.default_rng(0))
    (looped / "loop").symlink_to(looped)
    assert asset_files([looped]) == [looped / "ship.gltf"] and left_out_note([looped]) is None


def test_a_part_scaled_to_zero_is_refused_with_what_to_do(tmp_path):
    """A hidden helper scaled to zero (how some artists hide a mesh) was refused without a
    way out (h128)."""
    from procmod.learn.examples import ExamplesError
    nodes = [{"name": "Top", "mesh": 0, "children": [1]}, {"name": "Hidden", "mesh": 0, "scale": [0, 0, 0]}]
    write_glb(tmp_path / "table.glb", gltf_json([("top", [box_mesh((1, 0.1, 1))])], nodes, [0]))
    with pytest.raises(ExamplesError, match=r"node 'Hidden': its world transform is singular .*: delete the part "
                                            r"\(a hidden helper\) or give it and its parents non-zero scales"):
        read_example_inputs([tmp_path / "table.glb"])


def test_read_example_inputs_refuses_mixed_inputs(tmp_path, capsys):
    files = fleet(tmp_path / "ships", 2)
    ex = tmp_path / "examples.json"
    ex.write_text("{}")
    assert main(["learn", str(ex), str(files[0]), "--out", str(tmp_path / "out")]) == 2
    assert "not both" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def _two_roots(p):
    data = gltf_json([("body", [box_mesh((1, 1, 1))])], [{"name": "a", "mesh": 0}, {"name": "b", "mesh": 0}], [0, 1])
    p.write_text(json.dumps(data))


def _shear(p):
    # a rotated child under a non-uniformly scaled parent: its world transform shears
    c, s = math.cos(0.5), math.sin(0.5)
    rot = [c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    data = gltf_json([("body", [box_mesh((1, 1, 1))])],
                     [{"name": "a", "mesh": 0, "scale": [3, 1, 1], "children": [1]}, {"name": "b", "mesh": 0, "matrix": rot}],
                     [0])
    p.write_text(json.dumps(data))


def _shear_below(p):
    # the scale two levels up: the part in between has none of its own
    c, s = math.cos(0.5), math.sin(0.5)
    rot = [c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1]
    data = gltf_json([("body", [box_mesh((1, 1, 1))])],
                     [{"name": "a", "mesh": 0, "scale": [1, 2, 1], "children": [1]},
                      {"name": "b", "mesh": 0, "children": [2]}, {"name": "c", "mesh": 0, "matrix": rot}], [0])
    p.write_text(json.dumps(data))


def _empty_root(p):
    # Blender's usual grouping: an empty holding the parts, none of them their parent
    data = gltf_json([("body", [box_mesh((1, 1, 1))])],
                     [{"name": "Chair", "children": [1, 2]}, {"name": "a", "mesh": 0},
                      {"name": "b", "mesh": 0, "translation": [2, 0, 0]}], [0])
    p.write_text(json.dumps(data))


def _cycle(p):
    data = gltf_json([("body", [box_mesh((1, 1, 1))])],
                     [{"name": "a", "mesh": 0}, {"name": "b", "children": [2]}, {"name": "c", "children": [1]}], [0])
    p.write_text(json.dumps(data))


def _nan(p):
    v, f = box_mesh((1, 1, 1))
    v[2, 0] = np.nan
    p.write_text(json.dumps(gltf_json([("body", [(v, f)])], [{"name": "a", "mesh": 0}], [0])))


def _zero_area(p):
    write_zero_area_gltf(p, "body")


def _huge(p):
    write_huge_gltf(p, "body", box_mesh((1, 1, 1)))


_empty, _unreadable = write_empty_gltf, write_unreadable


def _urdf_two_parents(p):
    box = '<geometry><box size="1 1 1"/></geometry>'
    p.write_text(urdf({"a": [box], "b": [box], "c": [box]},
                      [("x", "a", "c", (0, 0, 0), (0, 0, 0)), ("y", "b", "c", (0, 0, 0), (0, 0, 0))]))


def _box_data(edit):
    data = gltf_json([("body", [box_mesh((1, 1, 1))])], [{"name": "a", "mesh": 0}], [0])
    edit(data)
    return data


def _no_uri(p):  # a GLB's JSON saved alone as .gltf: trimesh said KeyError: 'uri'
    p.write_text(json.dumps(_box_data(lambda d: d["buffers"][0].pop("uri"))))


def _meshopt_fallback(data, with_data: bool):
    data["extensionsUsed"] = ["EXT_meshopt_compression"]
    data["buffers"][0]["extensions"] = {"EXT_meshopt_compression": {"fallback": True}}
    if not with_data:
        data["buffers"][0].pop("uri")


def _meshopt_without_fallback_data(p):
    p.write_text(json.dumps(_box_data(lambda d: _meshopt_fallback(d, False))))


def test_a_meshopt_fallback_buffer_with_its_data_is_read(tmp_path):
    """gltfpack -cf writes the uncompressed data into a fallback buffer with a file of its
    own and uses the extension optionally: a loader without meshopt reads that (a review
    found it refused as compressed)."""
    from procmod.geometry.assets import read_assets

    (tmp_path / "x.gltf").write_text(json.dumps(_box_data(lambda d: _meshopt_fallback(d, True))))
    read = read_assets([tmp_path / "x.gltf"])
    assert sorted(read.parts) == ["body"]


def _view_past_buffer(p):  # trimesh said AssertionError with no text
    write_glb(p, _box_data(lambda d: d["bufferViews"][0].update(byteOffset=10 ** 12)))


def _accessor_past_view(p):  # trimesh said it cannot reshape an array into (10^12, 3)
    write_glb(p, _box_data(lambda d: d["accessors"][0].update(count=10 ** 12)))


@pytest.mark.parametrize("make, suffix, message", [
    (_no_uri, ".gltf", 'buffers[0] names no file ("uri")'),
    (_meshopt_without_fallback_data, ".gltf", "meshopt-compressed"),
    (_view_past_buffer, ".glb", "bufferViews[0] reaches byte 1,000,000,000,096 of buffer 0, which holds 240"),
    (_accessor_past_view, ".glb", "accessors[0] needs 12,000,000,000,000 bytes of bufferViews[0]"),
    (_unreadable, ".glb", "not a GLB file"),
    (_unreadable, ".gltf", "not a glTF file"),
    (_empty, ".gltf", "no mesh"),
    (_zero_area, ".gltf", "zero surface area"),
    (_nan, ".gltf", "non-finite vertex"),
    (_cycle, ".gltf", "cycle"),
    (_urdf_two_parents, ".urdf", "child of two joints"),
    (_huge, ".gltf", "more than procmod reads"),
    (_two_roots, ".gltf", "2 top-level parts"),
    (_empty_root, ".gltf", "2 top-level parts ('a', 'b'); they are under 'Chair', which draws no faces (an empty, "
                           "or a mesh without faces) and so is no part"),
])
def test_bad_asset_files_are_one_line_errors_and_write_nothing(tmp_path, capsys, make, suffix, message):
    folder = tmp_path / "in"
    fleet(folder, 2)  # good files beside the bad one: the bad one still stops the run
    make(folder / f"zz_bad{suffix}")
    out = tmp_path / "out"
    assert main(["learn", str(folder), "--out", str(out), "--particles", "1", "--workers", "1"]) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err and "zz_bad" in err, err
    assert err.startswith("procmod: error:")
    assert not out.exists()


def test_pybullet_quadrupeds_read_as_examples_with_mirrored_legs():
    """The robots the pybullet wheel ships (read from the installed package, not copied)."""
    pybullet_data = pytest.importorskip("pybullet_data")
    from pathlib import Path
    root = Path(pybullet_data.getDataPath())
    s, _ = read_example_inputs([root / "a1" / "a1.urdf", root / "laikago" / "laikago_toes.urdf"])
    assert [e.part for e in s.examples] == ["trunk", "chassis"]
    assert "thigh_mirror" not in s.parts  # a1's mirrored thigh mesh is its thigh (within 0.5%)
    d = preprocess(s)
    kinds = [n.type for n in d.nodes if n.kind != "part"]
    # left and right legs (hip with thigh and calf below) are mirror pairs on both robots
    assert kinds.count("refl(hip)") >= 1 and any(k.startswith("refl(") for k in kinds if "hip_motor" in k)


def test_a_urdf_robot_stands_up_the_y_axis_like_a_gltf_example(tmp_path):
    """URDF is z-up, procmod (and glTF) y-up: robots were learned lying on their side, and
    a set mixing a URDF robot with a glTF one disagreed about which way is up."""
    from procmod.geometry.part_library import world_bounds

    body = '<geometry><box size="0.6 0.3 0.1"/></geometry>'  # long in x, wide in y, flat in z
    leg = '<geometry><box size="0.05 0.05 0.4"/></geometry>'  # tall in z
    (tmp_path / "robot.urdf").write_text(urdf(
        {"body": [body], "leg_a": [leg], "leg_b": [leg]},
        [("a", "body", "leg_a", (0.25, 0.1, -0.25), (0, 0, 0)), ("b", "body", "leg_b", (-0.25, 0.1, -0.25), (0, 0, 0))]))
    examples, _ = read_example_inputs([tmp_path / "robot.urdf"])
    robot = examples.examples[0]
    boxes = [world_bounds(examples.parts[n.part], n.transform) for n in robot.walk()]
    lo, hi = np.min([b[0] for b in boxes], axis=0), np.max([b[1] for b in boxes], axis=0)
    extent = hi - lo
    assert np.allclose(extent, [0.6, 0.5, 0.3])  # height (0.05 + 0.45 leg reach) is now y
    legs = [n for n in robot.walk() if n.part != robot.part]
    assert all(n.transform[1][3] == pytest.approx(-0.25) for n in legs)  # the legs hang down y


def test_an_empty_is_named_only_when_the_parts_are_under_it(tmp_path):
    from procmod.learn.examples import ExamplesError
    data = gltf_json([("body", [box_mesh((1, 1, 1))])],
                     [{"name": "Group", "children": [1, 2]}, {"name": "a", "mesh": 0},
                      {"name": "b", "mesh": 0, "translation": [2, 0, 0]}, {"name": "loose", "mesh": 0}], [0, 3])
    (tmp_path / "x.gltf").write_text(json.dumps(data))
    with pytest.raises(ExamplesError, match="3 top-level parts") as info:
        read_example_inputs([tmp_path / "x.gltf"])
    assert "under the empty" not in str(info.value)


@pytest.mark.parametrize("make", [_shear, _shear_below])
def test_a_turned_part_under_a_scaled_parent_is_its_sheared_shape(tmp_path, make):
    """Its world transform shears, which a placement (rotation, scale, translation) cannot
    hold: the reader puts the shear into the part's geometry (it was refused, telling the
    user to apply a scale)."""
    from procmod.geometry.assets import read_assets
    from procmod.geometry.solid import part_triangles
    import trimesh

    make(tmp_path / "x.gltf")
    scene = trimesh.load(tmp_path / "x.gltf", force="scene")
    read = read_assets([tmp_path / "x.gltf"])
    nodes = {n.name: n for n in read.assets[0].nodes()}
    for name, node in nodes.items():  # every part where the file puts it, in the shape it has there
        mesh = scene.geometry[scene.graph[name][1]]
        want = np.sort(trimesh.transform_points(mesh.vertices, scene.graph[name][0]).round(9), axis=0)
        got = np.unique(part_triangles(read.parts[node.part].part(node.transform)).reshape(-1, 3).round(9), axis=0)
        assert np.allclose(np.sort(got, axis=0), want, atol=1e-7), name
        assert not np.linalg.det(np.asarray(node.transform)[:3, :3]) == 0
    example_set, _ = read_example_inputs([tmp_path / "x.gltf"])  # and it learns
    assert len(example_set.examples) == 1


def test_a_part_turned_by_eye_under_a_scaled_parent_stays_one_part(tmp_path):
    """A shear too small to change the shape (a half tabletop turned under 1 degree under
    its twin, scaled 1.3-1.7x along x for each table's width): one part, placed where the
    file puts it to within the geometry tolerance. The whole sheared map went into the
    geometry, so every table's half was a part type of its own (its size baked in too)."""
    from procmod.geometry.assets import GEOMETRY_TOLERANCE, read_assets
    from procmod.geometry.solid import part_triangles
    import trimesh

    rng = np.random.default_rng(5)
    paths = []
    for k in range(4):
        turn = math.radians(rng.uniform(-1.0, 1.0))
        c, s = math.cos(turn), math.sin(turn)
        rot = [c, s, 0, 0, -s, c, 0, 0, 0, 0, 1, 0, 0.6, 0, 0, 1]
        data = gltf_json([("top", [box_mesh((0.6, 0.05, 0.8))])],
                         [{"name": "left", "mesh": 0, "scale": [rng.uniform(1.3, 1.7), 1, 1], "children": [1]},
                          {"name": "right", "mesh": 0, "matrix": rot}], [0])
        paths.append(tmp_path / f"table_{k}.gltf")
        paths[-1].write_text(json.dumps(data))
    read = read_assets(paths)
    assert sorted(read.parts) == ["top"]
    for path, asset in zip(paths, read.assets):
        scene = trimesh.load(path, force="scene")
        for node in asset.nodes():
            mesh = scene.geometry[scene.graph[node.name][1]]
            want = trimesh.transform_points(mesh.vertices, scene.graph[node.name][0])
            got = part_triangles(read.parts[node.part].part(node.transform)).reshape(-1, 3)
            far = max(np.linalg.norm(got - w, axis=1).min() for w in want)
            assert far <= GEOMETRY_TOLERANCE * np.linalg.norm(np.ptp(want, axis=0)), (path.name, node.name)


def test_learn_overwrite_replaces_an_earlier_run_of_other_options(tmp_path, monkeypatch, capsys):
    """--overwrite refused an earlier learn run of another seed ("delete the checkpoint"),
    and deleting it left a folder that was no longer a learn run."""
    import procmod.learn.search
    monkeypatch.setattr(procmod.learn.search, "SearchOptions", _QuickOptions)
    fleet(tmp_path / "ships", 2)
    out = tmp_path / "run"
    argv = ["learn", str(tmp_path / "ships"), "--out", str(out), "--particles", "1", "--workers", "1", "--samples", "1"]
    assert main(argv) == 0
    capsys.readouterr()
    assert main(argv + ["--seed", "1"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "other examples or options; pass --overwrite to start afresh" in err
    assert main(argv + ["--seed", "1", "--overwrite"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["options"]["seed"] == 1 and report["resumed"] is False


def test_learn_takes_numpy_numbers(tmp_path, monkeypatch):
    """particles=np.int64(1) failed writing the checkpoint (an int64 is not JSON), leaving it half made."""
    import procmod.learn.search
    from procmod.learn.pipeline import learn
    monkeypatch.setattr(procmod.learn.search, "SearchOptions", _QuickOptions)
    fleet(tmp_path / "ships", 2)
    learn(tmp_path / "ships", tmp_path / "run", particles=np.int64(1), seed=np.int64(3), workers=1,
          samples=np.int64(1), options=_QuickOptions())
    options = json.loads((tmp_path / "run" / "report.json").read_text())["options"]
    assert options["particles"] == 1 and options["seed"] == 3 and (tmp_path / "run" / "program.json").is_file()
