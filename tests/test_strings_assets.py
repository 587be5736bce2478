"""``procmod strings graph|augment`` on asset files (glTF, GLB): one shape per file, one part
per distinct mesh (named after its mesh data), y-up scenes turned z-up, scaled placements
made rigid, bad files as one-line errors (exit 2) that leave no output behind."""

import json
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

from procmod.cli import main
from procmod.strings.assets import Y_UP_TO_Z_UP, read_shape_inputs, shapes_from_assets
from procmod.strings.contacts import part_points, shape_graph
from procmod.strings.shapes import ShapesFormatError, read_shapes, shapes_from_dict

from asset_writers import (box_mesh, column_major, gltf_json, transformed, wedge_mesh, write_empty_gltf, write_glb,
                           write_huge_gltf, write_unreadable, write_zero_area_gltf)

Z_TO_Y = np.linalg.inv(Y_UP_TO_Z_UP)


SETS = Path(__file__).resolve().parents[1] / "examples_sets" / "strings"


def prism_mesh(sides=12, radius=0.25, height=2.0):
    """A closed prism standing along y (as glTF meshes are modelled), ``sides`` faces round."""
    angles = np.pi / sides + 2 * np.pi * np.arange(sides) / sides
    ring = np.stack([radius * np.cos(angles), np.zeros(sides), -radius * np.sin(angles)], 1)
    v = np.concatenate([ring + [0, -height / 2, 0], ring + [0, height / 2, 0]])
    f = []
    for k in range(sides):
        n = (k + 1) % sides
        f += [(k, n, sides + n), (k, sides + n, sides + k)]
    for k in range(1, sides - 1):
        f += [(0, k + 1, k), (sides, sides + k, sides + k + 1)]
    return v, np.array(f)


def yaw(x, y, z, angle):
    c, s = np.cos(angle), np.sin(angle)
    return np.array([[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1.0]])


def fence(cells, angle, offset, spacing=2.0):
    """Posts at grid cells, rails between 4-neighbours, the whole turned by ``angle`` about
    the vertical: (part, z-up world placement of the part's z-up frame) pairs."""
    turn = yaw(*offset, angle)
    out = [("post", turn @ yaw(spacing * i, spacing * j, 1.0, 0.0)) for i, j in cells]
    cs = set(cells)
    for i, j in sorted(cs):
        for di, dj in ((1, 0), (0, 1)):
            if (i + di, j + dj) in cs:
                out.append(("rail", turn @ yaw(spacing * (i + di / 2), spacing * (j + dj / 2), 1.0,
                                               0.0 if dj == 0 else np.pi / 2)))
    return out


RING = [(i, j) for i in range(3) for j in range(3) if (i, j) != (1, 1)]
TAIL = [(0, 0), (1, 0), (2, 0), (0, 1), (2, 1), (0, 2), (1, 2), (2, 2), (3, 2), (4, 2)]
# a rail modelled along x in z-up terms: 1.6 long, 0.2 wide, 0.3 high, as y-up mesh data
RAIL = transformed(box_mesh((1.6, 0.2, 0.3)), Z_TO_Y)


def fence_file(path, placements, scale_rails=1.0, second_rail_mesh=False):
    """A y-up glTF (GLB by suffix) of a fence: an empty root with the parts as children.
    ``second_rail_mesh``: every other rail uses 'rail.001', the rail's vertex data turned a
    quarter turn (a copy a modeller made): the same part up to a rigid motion."""
    quarter = yaw(0, 0, 0, np.pi / 2)
    meshes = [("post", [prism_mesh()]), ("rail", [RAIL]), ("rail.001", [transformed(RAIL, Z_TO_Y @ quarter @ Y_UP_TO_Z_UP)])]
    nodes = [{"name": "fence", "children": list(range(1, len(placements) + 1))}]
    k = 0
    for part, m in placements:
        mesh = 0 if part == "post" else 1
        node_m = m @ np.diag([1.0, scale_rails, 1.0, 1.0]) if part == "rail" else m
        if part == "rail" and second_rail_mesh and k % 2:
            mesh, node_m = 2, node_m @ np.linalg.inv(quarter)  # rail.001 placed to look the same
        k += part == "rail"
        nodes.append({"name": f"{part}{len(nodes)}", "mesh": mesh,
                      "matrix": column_major(Z_TO_Y @ node_m @ Y_UP_TO_Z_UP)})
    data = gltf_json(meshes, nodes, [0])
    if path.suffix == ".glb":
        return write_glb(path, data)
    path.write_text(json.dumps(data))
    return path


def fence_folder(folder):
    folder.mkdir(parents=True, exist_ok=True)
    fence_file(folder / "a_ring.glb", fence(RING, np.radians(17), (0.3, 0.1, 0.0)), second_rail_mesh=True)
    fence_file(folder / "b_tail.gltf", fence(TAIL, np.radians(-52), (20.0, 5.0, 0.0)))
    return folder


def test_gltf_scenes_read_as_shapes_one_per_file(tmp_path):
    folder = fence_folder(tmp_path / "fences")
    ss = read_shape_inputs([folder])
    assert sorted(ss.library) == ["post", "rail"]  # rail.001 is the rail turned: one part
    assert ss.letters == {"post": "P", "rail": "R"}
    assert [len(s) for s in ss.shapes] == [8 + 8, 10 + 10]
    # the same fences written as a shapes file with box parts, z-up: the same contact graphs
    ref = shapes_from_dict({"format": "procmod-shapes/1",
                            "parts": {"post": {"box": [0.4, 0.4, 2.0]}, "rail": {"box": [1.6, 0.2, 0.3]}},
                            "shapes": [{"nodes": [{"part": p, "transform": m.tolist()} for p, m in fence(cells, a, o)]}
                                       for cells, a, o in ((RING, np.radians(17), (0.3, 0.1, 0.0)),
                                                           (TAIL, np.radians(-52), (20.0, 5.0, 0.0)))]}, tmp_path)
    same = nx.algorithms.isomorphism.categorical_node_match("type", None)
    for shape, other in zip(ss.shapes, ref.shapes):
        g, h = shape_graph(ss, shape), shape_graph(ref, other)
        assert sorted(g.edges) == sorted(h.edges) and nx.is_isomorphic(g, h, node_match=same)
        assert nx.cycle_basis(g)
        for part, t in zip(shape.parts, shape.transforms):
            assert np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-9)  # rigid placements
            p = part_points(ss.library, part, t)
            if part == "post":  # stands along z (the y-up scene was turned)
                assert np.ptp(p[:, 2]) == pytest.approx(2.0, abs=1e-5)
    # the files one by one read the same as their folder
    by_files = read_shape_inputs(sorted(folder.iterdir()))
    assert all(np.allclose(a, b) for s, t in zip(ss.shapes, by_files.shapes) for a, b in zip(s.transforms, t.transforms))


def test_a_mesh_placed_at_two_scales_is_two_parts(tmp_path):
    fence_file(tmp_path / "a.gltf", fence(RING, 0.3, (0, 0, 0)))
    fence_file(tmp_path / "b.gltf", fence(RING, 0.3, (0, 0, 0)), scale_rails=1.5)  # rails 1.5 times as wide
    ss = shapes_from_assets([tmp_path / "a.gltf", tmp_path / "b.gltf"])
    assert sorted(ss.library) == ["post", "rail", "rail_2"]
    assert set(ss.shapes[1].parts) == {"post", "rail_2"}
    wide = part_points(ss.library, "rail_2", np.eye(4))
    assert sorted(np.round(np.ptp(wide, axis=0), 6).tolist()) == [0.3, 0.3, 1.6]  # the scale is in the part
    assert all(np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-9) for t in ss.shapes[1].transforms)


def test_a_shapes_files_scaled_placements_are_made_rigid_as_assets_are(tmp_path, capsys):
    """A shapes file of unit parts scaled per placement (a fence of unit boxes; a prism
    mesh at two heights) is read as asset inputs are: the scale goes into the part, one
    part per size. Kept in the transforms, the fence's edge categories had been 32 for 4."""
    from procmod.strings.categories import EdgeCategories

    def at(x, y, z, sx, sy, sz):
        return [[sx, 0, 0, x], [0, sy, 0, y], [0, 0, sz, z], [0, 0, 0, 1]]

    v, f = prism_mesh()
    (tmp_path / "prism.obj").write_text("".join(f"v {a} {b} {c}\n" for a, b, c in v)
                                        + "".join(f"f {a + 1} {b + 1} {c + 1}\n" for a, b, c in f))
    shapes = []
    for n in (3, 4):
        nodes = []
        for i in range(n):
            nodes.append({"part": "unit", "transform": at(i, 0, 0.5, 0.2, 0.2, 1.0)})  # a post
            if i < n - 1:
                nodes.append({"part": "unit", "transform": at(i + 0.5, 0, 0.9, 0.8, 0.1, 0.1)})  # a rail
        # a 12-sided prism lying along y on post 0 (its flat side down), half or whole length
        lamp = at(0, 0, 1 + 0.25 * np.cos(np.pi / 12), 1, 0.5 if n == 3 else 1.0, 1)
        nodes.append({"part": "lamp", "transform": lamp})
        shapes.append({"nodes": nodes})
    parts = {"unit": {"box": [1, 1, 1]}, "lamp": {"mesh": "prism.obj"}}
    (tmp_path / "set.json").write_text(json.dumps({"format": "procmod-shapes/1", "shapes": shapes, "parts": parts}))
    ss = read_shape_inputs(tmp_path / "set.json")
    assert sorted(ss.library) == ["lamp", "lamp_2", "unit", "unit_2"]
    assert {ss.library[k].size for k in ("unit", "unit_2")} == {(0.2, 0.2, 1.0), (0.8, 0.1, 0.1)}
    assert all(np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-12) for s in ss.shapes for t in s.transforms)
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    assert len(EdgeCategories.fit(ss, ss.shapes, graphs).names) - 1 <= 4
    # a collection grown from it holds the scaled prism as a mesh of its own, and reads back
    assert main(["strings", "augment", str(tmp_path / "set.json"), "--count", "3", "--rounds", "4",
                 "--out", str(tmp_path / "coll")]) == 0
    back = read_shapes(tmp_path / "coll" / "shapes.json")
    assert sorted(back.library) == sorted(ss.library)
    assert np.allclose(part_points(back.library, "lamp", np.eye(4)), part_points(ss.library, "lamp", np.eye(4)))
    # a file whose placements are rigid is read as it is, its meshes where the file says
    rigid = read_shape_inputs(SETS / "castle.json")
    assert rigid.base_dir is not None and rigid.library == read_shapes(SETS / "castle.json").library


def test_graph_and_augment_take_asset_folders(tmp_path, capsys):
    folder = fence_folder(tmp_path / "fences")
    assert main(["strings", "graph", str(folder), "--out", str(tmp_path / "graphs")]) == 0
    out = capsys.readouterr().out
    assert "shape 0: 16 parts, 16 contacts, 1 independent cycles" in out and "post=P, rail=R" in out
    assert sorted(p.name for p in (tmp_path / "graphs").iterdir()) == ["shape_000.json", "shape_001.json"]
    coll = tmp_path / "coll"
    assert main(["strings", "augment", str(folder / "a_ring.glb"), str(folder / "b_tail.gltf"), "--count", "5",
                 "--rounds", "8", "--out", str(coll)]) == 0
    capsys.readouterr()
    # the collection's shapes file names mesh files written beside it, which read back exactly
    data = json.loads((coll / "shapes.json").read_text())
    assert data["parts"]["post"] == {"mesh": "parts/post.obj"} and data["parts"]["rail"] == {"mesh": "parts/rail.obj"}
    back = read_shapes(coll / "shapes.json")
    ss = read_shape_inputs([folder])
    assert np.array_equal(np.asarray(back.library["post"].vertices), np.asarray(ss.library["post"].vertices))
    assert np.array_equal(np.asarray(back.library["post"].faces), np.asarray(ss.library["post"].faces))
    assert len(back.shapes) == 5
    assert json.loads((coll / "growth.json").read_text())["settings"]["shapes"] == [
        str(folder / "a_ring.glb"), str(folder / "b_tail.gltf")]


def _cycle(p):
    data = gltf_json([("post", [prism_mesh()])],
                     [{"name": "a", "mesh": 0}, {"name": "b", "children": [2]}, {"name": "c", "children": [1]}], [0])
    p.write_text(json.dumps(data))


def _nan(p):
    v, f = prism_mesh()
    v[2, 0] = np.nan
    p.write_text(json.dumps(gltf_json([("post", [(v, f)])], [{"name": "a", "mesh": 0}], [0])))


def _zero_area(p):
    write_zero_area_gltf(p, "post")


def _huge(p):
    write_huge_gltf(p, "post", prism_mesh())


_empty, _unreadable = write_empty_gltf, write_unreadable


def _flat(p):
    data = gltf_json([("post", [prism_mesh()])], [{"name": "a", "mesh": 0, "scale": [1, 0, 1]}], [0])
    p.write_text(json.dumps(data))


@pytest.mark.parametrize("make, suffix, message", [
    (_unreadable, ".glb", "not a GLB file"),
    (_unreadable, ".gltf", "not a glTF file"),
    (_empty, ".gltf", "no mesh"),
    (_zero_area, ".gltf", "zero surface area"),
    (_nan, ".gltf", "non-finite vertex"),
    (_cycle, ".gltf", "cycle"),
    (_huge, ".gltf", "more than procmod reads"),
    (_flat, ".gltf", "scale of zero"),
])
@pytest.mark.parametrize("command", ["graph", "augment"])
def test_bad_asset_files_are_one_line_errors_and_write_nothing(tmp_path, capsys, make, suffix, message, command):
    folder = fence_folder(tmp_path / "in")  # good files beside the bad one: the bad one still stops the run
    make(folder / f"zz_bad{suffix}")
    out = tmp_path / "out"
    argv = ["strings", command, str(folder), "--out", str(out)] + (["--count", "4"] if command == "augment" else [])
    assert main(argv) == 2
    err = capsys.readouterr().err.strip()
    assert err.count("\n") == 0 and message in err and "zz_bad" in err, err
    assert err.startswith("procmod: error:")
    assert not out.exists()


def test_json_and_asset_files_are_not_mixed(tmp_path, capsys):
    folder = fence_folder(tmp_path / "in")
    shapes = tmp_path / "shapes.json"
    shapes.write_text("{}")
    with pytest.raises(ShapesFormatError, match="not both"):
        read_shape_inputs([shapes, folder / "a_ring.glb"])
    assert main(["strings", "graph", str(shapes), str(folder), "--out", str(tmp_path / "out")]) == 2
    assert "not both" in capsys.readouterr().err and not (tmp_path / "out").exists()


def test_augment_translations_only_is_recorded(tmp_path, capsys):
    folder = fence_folder(tmp_path / "fences")
    for flag, rotate in (([], True), (["--translations-only"], False)):
        out = tmp_path / f"coll{int(rotate)}"
        assert main(["strings", "augment", str(folder), "--count", "3", "--rounds", "2", "--out", str(out), *flag]) == 0
        assert json.loads((out / "growth.json").read_text())["settings"]["rotate"] is rotate
    capsys.readouterr()


def test_mesh_names_become_safe_part_file_names(tmp_path):
    # a 240-character mesh name crashed augment (file name too long); CON, AUX, nul were
    # written as-is (device names on Windows)
    from procmod.core.paths import is_plain_name
    fence_file(tmp_path / "a.gltf", fence(RING, 0.3, (0, 0, 0)))
    spec = json.loads((tmp_path / "a.gltf").read_text())
    spec["meshes"][0]["name"], spec["meshes"][1]["name"] = "CON", "L" * 240
    (tmp_path / "a.gltf").write_text(json.dumps(spec))
    ss = shapes_from_assets([tmp_path / "a.gltf"])
    sources = [shape.source for shape in ss.library.values()]
    assert len(sources) == 2 and all(s.startswith("parts/") and s.endswith(".obj") for s in sources)
    assert all(is_plain_name(s[len("parts/"):-len(".obj")]) for s in sources), sources
    assert "parts/CON.obj" not in sources


def _row_of_blocks(path, mesh, scales):
    """A y-up GLB of one mesh ``blk`` placed in a row along x, node k with x-scale
    ``scales[k]`` (-1: the mesh mirrored)."""
    nodes = [{"name": "row", "children": list(range(1, len(scales) + 1))}]
    for k, sx in enumerate(scales):
        nodes.append({"name": f"b{k}", "mesh": 0, "matrix": column_major(
            np.diag([sx, 1.0, 1.0, 1.0]) + np.array([[0, 0, 0, 1.2 * k]] + [[0] * 4] * 3))})
    return write_glb(path, gltf_json([("blk", [mesh])], nodes, [0]))


@pytest.mark.parametrize("mesh, parts", [
    (box_mesh((1.0, 0.5, 0.3), centre=(0.2, 0.1, 0.0)), ["blk"]),  # a box's mirror image is the box, turned
    (transformed(wedge_mesh(1.0), np.eye(4)), ["blk", "blk_2"]),    # a wedge's is not (left and right)
])
def test_a_mirrored_copy_is_another_part_only_when_no_turn_makes_it(tmp_path, mesh, parts):
    # a cube placed with x-scale -1 was a second part type ('blk_2') though turned it is the cube
    path = _row_of_blocks(tmp_path / "row.glb", mesh, [1.0, -1.0, 1.0, -1.0])
    ss = shapes_from_assets([path])
    assert sorted(ss.library) == parts
    shape = ss.shapes[0]
    if len(parts) == 2:
        assert list(shape.parts) == ["blk", "blk_2", "blk", "blk_2"]
    for k, (part, t) in enumerate(zip(shape.parts, shape.transforms)):
        assert np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=1e-9) and np.linalg.det(t[:3, :3]) > 0
        # each placed part covers the box the file's node covers (within the parts' tolerance)
        node = Y_UP_TO_Z_UP @ np.diag([(1.0, -1.0)[k % 2], 1.0, 1.0, 1.0])
        node[:3, 3] = Y_UP_TO_Z_UP[:3, :3] @ [1.2 * k, 0, 0]
        want, got = transformed(mesh, node)[0], part_points(ss.library, part, t)
        assert np.allclose(got.min(0), want.min(0), atol=5e-3) and np.allclose(got.max(0), want.max(0), atol=5e-3)


def test_augment_keeps_variants_as_large_as_the_inputs(tmp_path, capsys):
    """Variants over a fixed 120 parts were dropped without a word: a 301-part fence grew
    into fragments of 28-112 parts. The limit is now twice the largest input (at least
    120; --max-parts sets it) and is recorded."""
    cells = [(i, j) for i in range(25) for j in range(2)]
    fence_file(tmp_path / "long.glb", fence(cells, 0.0, (0.0, 0.0, 0.0)))
    out = tmp_path / "grown"
    assert main(["strings", "augment", str(tmp_path / "long.glb"), "--count", "4", "--rounds", "6",
                 "--out", str(out)]) == 0
    shapes = json.loads((out / "shapes.json").read_text())["shapes"]
    assert len(shapes[0]["nodes"]) == 123 and len(shapes) == 4
    assert max(len(s["nodes"]) for s in shapes[1:]) > 120
    assert json.loads((out / "growth.json").read_text())["settings"]["max_parts"] == 246
    assert main(["strings", "augment", str(tmp_path / "long.glb"), "--count", "2", "--rounds", "3", "--max-parts",
                 "130", "--out", str(tmp_path / "capped")]) == 0
    capped = json.loads((tmp_path / "capped" / "shapes.json").read_text())["shapes"]
    assert all(len(s["nodes"]) <= 130 for s in capped[1:])


def test_augment_refuses_at_once_a_shape_no_string_can_write(tmp_path, capsys, monkeypatch):
    """A 3D lattice of hubs and struts cannot be written as a string (more than 99 rings
    open at once): augment ran for minutes on a user's 2,651-part station, then failed
    writing its collection. It is refused before the first round, naming the shape."""
    from procmod.strings import sampling
    n = 7  # hubs a side: a 7 x 7 x 7 lattice of 1,225 parts, the smallest cube here that no string writes
    turns = [np.eye(3), np.array([[0, -1, 0], [1, 0, 0], [0, 0, 1.0]]), np.array([[0, 0, -1], [0, 1, 0], [1, 0, 0.0]])]
    nodes = []
    for corner in np.ndindex(n, n, n):
        at = 2.0 * np.array(corner)
        nodes.append({"part": "hub", "transform": yaw(*at, 0.0).tolist()})
        for axis in range(3):
            if corner[axis] < n - 1:  # a strut (along x in its own frame) to the next hub along the axis
                m = yaw(*(at + np.eye(3)[axis]), 0.0)
                m[:3, :3] = turns[axis]
                nodes.append({"part": "strut", "transform": m.tolist()})
    (tmp_path / "grid.json").write_text(json.dumps({
        "format": "procmod-shapes/1", "parts": {"hub": {"box": [0.6, 0.6, 0.6]}, "strut": {"box": [1.4, 0.2, 0.2]}},
        "shapes": [{"nodes": nodes}]}))
    rounds = []
    real = sampling.augment
    monkeypatch.setattr(sampling, "augment", lambda *a, **k: rounds.append(1) or real(*a, **k))
    code = main(["strings", "augment", str(tmp_path / "grid.json"), "--count", "3", "--out", str(tmp_path / "o")])
    err = capsys.readouterr().err
    assert code == 2 and not rounds and "cannot be written as a string" in err and err.count("\n") == 1, err


def test_pieces_of_several_parts_are_not_said_to_touch_nothing(tmp_path, capsys):
    """Rails nudged a few millimetres off their posts split a fence into pieces of several
    parts, and the note said 105 parts 'touch no other part': they touch each other, only
    not the largest piece. graph's note also offers --tolerance."""
    placements = fence([(i, 0) for i in range(6)], 0.0, (0.0, 0.0, 0.0))
    # the third rail lifted off its posts: two pieces of 5 parts and the rail alone
    rails = [k for k, (part, _) in enumerate(placements) if part == "rail"]
    lifted = placements[rails[2]][1].copy()
    lifted[2, 3] += 5.0
    placements[rails[2]] = ("rail", lifted)
    fence_file(tmp_path / "gap.glb", placements)
    assert main(["strings", "graph", str(tmp_path / "gap.glb"), "--out", str(tmp_path / "g")]) == 0
    err = capsys.readouterr().err
    assert "is in 3 pieces of 5, 5, 1 parts" in err and "touch nothing of the largest piece" in err, err
    assert "give --tolerance" in err


def test_part_names_with_line_breaks_print_on_one_line(tmp_path, capsys):
    """A mesh named "a\nb" in a glTF split the "types:" line of 'strings graph' in two
    (error messages escaped it; h113)."""
    shapes = {"format": "procmod-shapes/1",
              "parts": {"po\nst": {"box": [0.4, 0.4, 2.0]}, "rail\x1b[31m": {"box": [1.6, 0.2, 0.3]}},
              "shapes": [{"nodes": [{"part": {"post": "po\nst", "rail": "rail\x1b[31m"}[p], "transform": m.tolist()}
                                    for p, m in fence(RING, 0.0, (0.0, 0.0, 0.0))]}]}
    (tmp_path / "named.json").write_text(json.dumps(shapes))
    assert main(["strings", "graph", str(tmp_path / "named.json"), "--out", str(tmp_path / "graphs")]) == 0
    out = capsys.readouterr().out
    types = [line for line in out.splitlines() if line.startswith("types: ")]
    assert len(types) == 1 and "po\\nst=" in types[0] and "rail\\x1b[31m=" in types[0], out
    assert "\x1b" not in out and not any(line.startswith("st=") for line in out.splitlines())


def test_a_very_long_part_name_is_cut_on_the_types_line(tmp_path, capsys):
    """A 5,000-character mesh name printed in full, twice over the screen (h131)."""
    long_name = "post" + "x" * 5000
    shapes = {"format": "procmod-shapes/1",
              "parts": {long_name: {"box": [0.4, 0.4, 2.0]}, "rail": {"box": [1.6, 0.2, 0.3]}},
              "shapes": [{"nodes": [{"part": {"post": long_name, "rail": "rail"}[p], "transform": m.tolist()}
                                    for p, m in fence(RING, 0.0, (0.0, 0.0, 0.0))]}]}
    (tmp_path / "named.json").write_text(json.dumps(shapes))
    assert main(["strings", "graph", str(tmp_path / "named.json"), "--out", str(tmp_path / "graphs")]) == 0
    (types,) = [line for line in capsys.readouterr().out.splitlines() if line.startswith("types: ")]
    assert "postxxx" in types and "rail=" in types and len(types) < 200, types
