"""procmod.geometry.assets: glTF / GLB / URDF hierarchies, one part per distinct geometry,
and every kind of bad asset file as a one-line AssetError."""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest
import trimesh
from scipy.spatial.transform import Rotation

from procmod.geometry import assets
from procmod.geometry.assets import GEOMETRY_TOLERANCE, AssetError, read_assets
from procmod.geometry.solid import part_triangles

from asset_writers import (box_mesh, column_major, gltf_json, transformed, urdf, wedge_mesh, write_glb,
                           write_gltf, write_obj)


def T(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def R(rotvec):
    m = np.eye(4)
    m[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    return m


MX = np.diag([-1.0, 1, 1, 1])


def world_triangles(s, node):
    return part_triangles(s.parts[node.part].part(node.transform))


def same_surface(a, b, tol):
    """Every vertex of triangles ``a`` is within ``tol`` of one of ``b`` and back."""
    pa, pb = a.reshape(-1, 3), b.reshape(-1, 3)
    d = np.linalg.norm(pa[:, None] - pb[None], axis=-1)
    return max(d.min(1).max(), d.min(0).max()) <= tol


def ship_gltf(path, twist=np.eye(4)):
    """A body with two wings: node 'wing' uses mesh 'wing'; node 'wing.001' (the mirror
    side) uses its own mesh 'wing.001', the wing's vertices mirrored and moved by
    ``twist`` (Blender's unlinked duplicate after 'apply transform'), its node placing it
    as the wing's mirror image; an empty 'Empty' holds the body; a 'gun' mesh has two
    primitives."""
    wing = wedge_mesh(1.5)
    right = T(1.0, 0, 0)
    data = twist @ MX  # wing.001's vertices: data(wing)
    left = MX @ right @ np.linalg.inv(data)  # so that left(data(wing)) = MX right (wing)
    meshes = [("body", [box_mesh((2, 0.5, 3))]), ("wing", [wing]), ("wing.001", [transformed(wing, data)]),
              ("gun", [box_mesh((0.1, 0.1, 0.5)), box_mesh((0.2, 0.2, 0.1), (0, 0, 0.3))])]
    nodes = [{"name": "Empty", "children": [1]},
             {"name": "body", "mesh": 0, "children": [2, 3, 4]},
             {"name": "wing", "mesh": 1, "matrix": column_major(right)},
             {"name": "wing.001", "mesh": 2, "matrix": column_major(left)},
             {"name": "gun", "mesh": 3, "translation": [0, 0.4, 1.0]}]
    return write_gltf(path, meshes, nodes), wing, right


def test_gltf_hierarchy_and_one_part_per_distinct_geometry(tmp_path):
    twist = T(0.3, -0.2, 0.5) @ R([0.4, -0.9, 0.2])
    path, wing, right = ship_gltf(tmp_path / "ship.gltf", twist)
    s = read_assets(path)
    assert sorted(s.parts) == ["body", "gun", "wing"]  # 'wing.001' is the wing; the gun's primitives one part
    (root,) = s.assets[0].roots  # the empty passed its child on
    assert (root.name, root.part) == ("body", "body")
    kids = {c.name: c for c in root.children}
    assert sorted(kids) == ["gun", "wing", "wing.001"]
    assert kids["wing.001"].part == "wing" and kids["gun"].part == "gun"
    assert len(s.parts["gun"].faces) == 24
    # the mirrored copy is placed with a negative determinant, and reproduces its geometry
    assert np.linalg.det(kids["wing.001"].transform[:3, :3]) < 0
    want = transformed(wing, MX @ right)
    got = world_triangles(s, kids["wing.001"])
    assert same_surface(got, want[0][want[1]], 2 * GEOMETRY_TOLERANCE * 1.6)
    # float32 file coordinates: the plain wing is placed as written
    assert np.allclose(kids["wing"].transform, right, atol=1e-6)


def test_mirror_images_are_separate_parts_with_mirror_false(tmp_path):
    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    assert sorted(read_assets(path, mirror=False).parts) == ["body", "gun", "wing", "wing.001"]


def test_geometry_beyond_the_tolerance_is_its_own_part_and_names_stay_distinct(tmp_path):
    a, _, _ = ship_gltf(tmp_path / "a.gltf")
    # b: the same names, but its wing's cut corner 3% further out (no scaling of a's wing:
    # a wing only longer is a's wing at another size, _bake_scales) and its body a rigid
    # motion of a's body
    vertices, faces = wedge_mesh(1.5)
    vertices = vertices.copy()
    vertices[3, 0] += 0.03 * 1.5
    wing = (vertices, faces)
    meshes = [("body", [transformed(box_mesh((2, 0.5, 3)), R([0, 0, math.pi / 2]))]), ("wing", [wing])]
    nodes = [{"name": "body", "mesh": 0, "children": [1]}, {"name": "wing", "mesh": 1, "translation": [1, 0, 0]}]
    b = write_gltf(tmp_path / "b.gltf", meshes, nodes)
    s = read_assets([a, b])
    assert sorted(s.parts) == ["body", "gun", "wing", "wing_2"]
    rb = s.assets[1].roots[0]
    assert rb.part == "body" and rb.children[0].part == "wing_2"
    # a wing 2% longer in another file is a's wing at another size, whose mirrored twin in
    # a (wing.001) stays a's wing
    b = write_gltf(tmp_path / "b.gltf", [meshes[0], ("wing", [wedge_mesh(1.5 * 1.02)])], nodes)
    s = read_assets([a, b])
    assert sorted(s.parts) == ["body", "gun", "wing"]
    assert sorted(n.part for n in s.assets[0].nodes()) == ["body", "gun", "wing", "wing"]


def test_a_folder_reads_its_asset_files_in_name_order_and_glb_reads_like_gltf(tmp_path):
    path, _, _ = ship_gltf(tmp_path / "b_ship.gltf")
    write_glb(tmp_path / "a_ship.glb", json.loads(path.read_text()))
    (tmp_path / "notes.txt").write_text("not an asset")
    s = read_assets(tmp_path)
    assert [a.path.name for a in s.assets] == ["a_ship.glb", "b_ship.gltf"]
    for asset in s.assets:
        assert sorted(c.part for c in asset.roots[0].children) == ["gun", "wing", "wing"]
    # reading is deterministic: same names, same transforms
    again = read_assets(tmp_path)
    assert list(again.parts) == list(s.parts)
    for x, y in zip(again.assets[1].nodes(), s.assets[1].nodes()):
        assert x.part == y.part and np.array_equal(x.transform, y.transform)


ROBOT_LINKS = {
    "base": [],  # a link without visuals: its children attach to the trunk's parent (none)
    "trunk": ['<origin xyz="0 0 0.1"/><geometry><box size="0.6 0.3 0.2"/></geometry>'],
    "hip_l": ['<geometry><box size="0.1 0.2 0.3"/></geometry>'],
    "hip_r": ['<geometry><box size="0.3 0.1 0.2"/></geometry>'],  # a quarter turn of the left hip
    "leg_l": ['<origin xyz="0 0 -0.2" rpy="0.3 0 0"/><geometry><mesh filename="package://bot/meshes/leg.obj" '
              'scale="2 2 2"/></geometry>',
              '<origin xyz="0 0 -0.45"/><geometry><sphere radius="0.05"/></geometry>'],
    "leg_r": ['<origin xyz="0 0 -0.2" rpy="0.3 0 0"/><geometry><mesh filename="meshes/leg_mirror.obj" '
              'scale="2 2 2"/></geometry>'],
}
ROBOT_JOINTS = [("j0", "base", "trunk", (0, 0, 0.5), (0, 0, 0)),
                ("jl", "trunk", "hip_l", (0.2, 0.2, 0), (0, 0, 0.1)),
                ("jr", "trunk", "hip_r", (0.2, -0.2, 0), (0, 0, -0.1)),
                ("kl", "hip_l", "leg_l", (0, 0.05, -0.1), (0, 0.2, 0)),
                ("kr", "hip_r", "leg_r", (0, -0.05, -0.1), (0, 0.2, 0))]


def robot(tmp_path, links=ROBOT_LINKS, joints=ROBOT_JOINTS):
    (tmp_path / "meshes").mkdir(exist_ok=True)
    leg = wedge_mesh(0.2)
    write_obj(tmp_path / "meshes" / "leg.obj", leg)
    write_obj(tmp_path / "meshes" / "leg_mirror.obj", transformed(leg, np.diag([1.0, -1, 1, 1])))  # mirrored
    path = tmp_path / "bot.urdf"
    path.write_text(urdf(links, joints))
    return path


def rpy(r, p, y):
    m = np.eye(4)
    m[:3, :3] = Rotation.from_euler("xyz", [r, p, y]).as_matrix()
    return m


def test_urdf_links_joints_visuals_and_shared_geometry(tmp_path):
    s = read_assets(robot(tmp_path))
    (trunk,) = s.assets[0].roots
    assert (trunk.name, trunk.part) == ("trunk", "trunk")
    assert np.allclose(trunk.transform, T(0, 0, 0.6))  # joint origin, then the visual's
    hips = {c.name: c for c in trunk.children}
    assert sorted(hips) == ["hip_l", "hip_r"]
    assert hips["hip_r"].part == "hip_l"  # the same box up to a quarter turn
    for name in hips:  # both place a box of the right's shape where the file says
        want = T(0.2, 0.2 if name == "hip_l" else -0.2, 0.5) @ rpy(0, 0, 0.1 if name == "hip_l" else -0.1)
        size = (0.1, 0.2, 0.3) if name == "hip_l" else (0.3, 0.1, 0.2)
        box = part_triangles(s.parts["hip_l"].part(hips[name].transform))
        want_box = transformed(box_mesh(size), want)
        assert same_surface(box, want_box[0][want_box[1]], 1e-9)
    leg_l = hips["hip_l"].children[0]
    leg_r = hips["hip_r"].children[0]
    assert leg_l.part == leg_r.part == "leg"  # the mirror file is the mirrored leg (at the same scale)
    assert np.linalg.det(leg_l.transform[:3, :3]) > 0 > np.linalg.det(leg_r.transform[:3, :3])
    world_l = T(0.2, 0.2, 0.5) @ rpy(0, 0, 0.1) @ T(0, 0.05, -0.1) @ rpy(0, 0.2, 0) @ T(0, 0, -0.2) @ rpy(0.3, 0, 0)
    want = transformed(wedge_mesh(0.2), world_l @ np.diag([2.0, 2, 2, 1]))
    assert same_surface(world_triangles(s, leg_l), want[0][want[1]], 1e-9)
    (toe,) = leg_l.children  # a link's second visual is a child of its first
    assert toe.name == "leg_l#1" and toe.part == "leg_l"  # a sphere, named after its link
    assert s.parts["leg_l"].kind == "mesh" and s.parts["trunk"].kind == "box"


# ---- bad asset files: one line each ------------------------------------------------------------

def one_line(exc_info):
    message = str(exc_info.value)
    assert "\n" not in message and len(message) < 400
    return message


def ship(tmp_path):
    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    return json.loads(path.read_text())


def edit_gltf(tmp_path, edit, name="bad.gltf"):
    data = ship(tmp_path)
    edit(data)
    path = tmp_path / name
    path.write_text(json.dumps(data))
    return path


def nan_wing(data):
    mesh = gltf_json([("wing", [(np.array([[0, 0, 0], [np.nan, 0, 0], [0, 1, 0]]), [[0, 1, 2]])])], [], [0])
    data["buffers"], data["bufferViews"], data["accessors"] = mesh["buffers"], mesh["bufferViews"], mesh["accessors"]
    data["meshes"] = [{"name": n, "primitives": mesh["meshes"][0]["primitives"]} for n in ("body", "wing", "w2", "gun")]


def _deepen(data, levels):
    """A chain of ``levels`` empty nodes under the last node."""
    first = len(data["nodes"])
    data["nodes"][-1]["children"] = data["nodes"][-1].get("children", []) + [first]
    data["nodes"] += [{"name": f"n{i}", "children": [first + i + 1]} for i in range(levels - 1)]
    data["nodes"].append({"name": "last"})


def flat_mesh(data):
    mesh = gltf_json([("flat", [(np.array([[0, 0, 0], [1, 1, 1], [2, 2, 2]]), [[0, 1, 2]])])], [], [0])
    data["buffers"], data["bufferViews"], data["accessors"] = mesh["buffers"], mesh["bufferViews"], mesh["accessors"]
    data["meshes"] = [{"name": n, "primitives": mesh["meshes"][0]["primitives"]} for n in ("body", "wing", "w2", "gun")]


@pytest.mark.parametrize("edit, message", [
    (lambda d: d["nodes"][2].update(children=[1]), "two parents"),  # body under the empty and the wing
    (lambda d: d["nodes"][2].update(children=[2]), "node 2 .* lists itself among its children"),  # "two parents"
    (lambda d: d["nodes"].extend([{"name": "a", "children": [6]}, {"name": "b", "children": [5]}]), "cycle"),
    (lambda d: d["nodes"][3].update(children=[4]), "two parents"),  # gun under body and wing.001
    # one parent listing a child twice was said as "two parents" (h128)
    (lambda d: next(n for n in d["nodes"] if n.get("children"))["children"].append(
        next(n for n in d["nodes"] if n.get("children"))["children"][0]), "is listed twice among the children of node"),
    (lambda d: d.update(meshes=[], nodes=[{"name": "empty"}]), "no mesh"),
    (lambda d: d["accessors"][1].update(count=3 * 10 ** 7), "has 10000\\d+ triangles"),
    (nan_wing, "non-finite vertex"),
    (flat_mesh, "zero surface area"),
    (lambda d: d["nodes"][2].update(matrix=[float("nan")] * 16), "non-finite or malformed transform"),
    (lambda d: d["nodes"][2].update(children=[99]), "does not exist"),
    # trimesh's "No path from world->a!" traceback before
    (lambda d: d["nodes"][2].update(mesh=5), "refers to mesh 5, which the file does not have"),
    # refused after minutes of trimesh building the scene graph before
    (lambda d: _deepen(d, 300), "deeper than 256 levels"),
])
def test_bad_gltf_files_are_one_line_errors(tmp_path, edit, message):
    with pytest.raises(AssetError) as exc:
        read_assets(edit_gltf(tmp_path, edit))
    assert __import__("re").search(message, one_line(exc)), str(exc.value)
    assert "bad.gltf" in str(exc.value)


def test_ten_million_triangles_are_refused_before_any_buffer_is_read(tmp_path, monkeypatch):
    # the file declares 10^7 triangles and has a buffer of a few bytes: decoding it would
    # fail or take the memory of the real thing; the declared count is checked first
    import trimesh
    calls = []
    monkeypatch.setattr(trimesh, "load", lambda *a, **k: calls.append(a))
    path = edit_gltf(tmp_path, lambda d: d["accessors"][1].update(count=3 * 10 ** 7))
    with pytest.raises(AssetError, match="more than procmod reads"):
        read_assets(path)
    assert calls == []


@pytest.mark.parametrize("content, message", [
    (b"\x00\x01 not a glb" * 10, "not a GLB file"),
    (b"glTF\x02\x00\x00\x00\xff\x00\x00\x00\x10\x00\x00\x00JSON{", "damaged GLB"),
    (b"", "not a GLB file"),
])
def test_unreadable_glb(tmp_path, content, message):
    path = tmp_path / "bad.glb"
    path.write_bytes(content)
    with pytest.raises(AssetError, match=message) as exc:
        read_assets(path)
    one_line(exc)


@pytest.mark.parametrize("text, message", [("{not json", "does not parse"), ("[1, 2]", "not an object"),
                                           ("", "does not parse"),
                                           # Python's own message had been cut mid-word (h131)
                                           ('{"x": ' + "[" * 100_000 + "]" * 100_000 + "}",
                                            r"its JSON nests more deeply than Python can read; a glTF file nests "
                                            r"a few levels\)$")])
def test_unreadable_gltf(tmp_path, text, message):
    path = tmp_path / "bad.gltf"
    path.write_text(text)
    with pytest.raises(AssetError, match=message) as exc:
        read_assets(path)
    one_line(exc)


def urdf_edit(tmp_path, links=None, joints=None):
    return robot(tmp_path, links if links is not None else ROBOT_LINKS, joints if joints is not None else ROBOT_JOINTS)


@pytest.mark.parametrize("make, message", [
    (lambda p: urdf_edit(p, joints=ROBOT_JOINTS + [("loop", "leg_l", "trunk", (0, 0, 0), (0, 0, 0))]),
     "child of two joints"),
    (lambda p: urdf_edit(p, links={"a": ROBOT_LINKS["trunk"], "b": ROBOT_LINKS["hip_l"]},
                         joints=[("x", "a", "b", (0, 0, 0), (0, 0, 0)), ("y", "b", "a", (0, 0, 0), (0, 0, 0))]),
     "cycle"),
    (lambda p: urdf_edit(p, joints=ROBOT_JOINTS + [("z", "trunk", "nowhere", (0, 0, 0), (0, 0, 0))]),
     "does not exist"),
    (lambda p: urdf_edit(p, links={**ROBOT_LINKS, "leg_r": ['<geometry><mesh filename="meshes/missing.obj"/></geometry>']}),
     "does not exist"),
    (lambda p: urdf_edit(p, links={"a": []}, joints=[]), "holds no visual or collision geometry"),
    (lambda p: urdf_edit(p, links={**ROBOT_LINKS, "hip_l": ['<geometry><box size="0.1 -1 0.3"/></geometry>']}),
     "box size"),
])
def test_bad_urdf_files_are_one_line_errors(tmp_path, make, message):
    with pytest.raises(AssetError, match=message) as exc:
        read_assets(make(tmp_path))
    assert "bot.urdf" in one_line(exc)


def test_broken_xml_is_refused_not_half_read(tmp_path):
    path = robot(tmp_path)
    text = path.read_text()
    path.write_text(text[: len(text) // 2])  # yourdfpy alone would recover the first links
    with pytest.raises(AssetError, match="not well-formed XML") as exc:
        read_assets(path)
    one_line(exc)


def test_urdf_mesh_files_are_checked(tmp_path, monkeypatch):
    path = robot(tmp_path)
    v, f = wedge_mesh(0.2)
    v = v.copy()
    v[3, 1] = np.nan
    write_obj(tmp_path / "meshes" / "leg.obj", (v, f))
    with pytest.raises(AssetError, match="non-finite") as exc:
        read_assets(path)
    one_line(exc)
    robot(tmp_path)
    monkeypatch.setattr(assets, "MAX_FACES", 11)  # the wedge has 12
    with pytest.raises(AssetError, match="more than procmod reads") as exc:
        read_assets(path)
    one_line(exc)
    monkeypatch.undo()
    (tmp_path / "meshes" / "leg.obj").write_text("this is no mesh\n")
    with pytest.raises(AssetError, match="leg.obj") as exc:
        read_assets(path)
    one_line(exc)


def test_file_lists(tmp_path):
    with pytest.raises(AssetError, match="holds no .gltf"):
        read_assets(tmp_path)
    (tmp_path / "x.obj").write_text("v 0 0 0\n")
    with pytest.raises(AssetError, match="not an asset file"):
        read_assets(tmp_path / "x.obj")
    with pytest.raises(AssetError, match="does not exist"):
        read_assets(tmp_path / "missing.glb")


def test_other_tools_files_are_refused_with_the_way_to_convert_them(tmp_path):
    """An FBX or Maya scene (what a Maya user has) is not read; the message says what to export."""
    (tmp_path / "castle.fbx").write_bytes(b"Kaydara FBX Binary  \x00\x1a\x00")
    with pytest.raises(AssetError, match=r"castle.fbx: not an asset file .*Autodesk FBX file is not read by procmod; "
                                         r"export glTF 2.0 \(.glb\) from its tool, or import it into Blender"):
        read_assets(tmp_path / "castle.fbx")
    with pytest.raises(AssetError, match=r"holds no .gltf, .glb, .urdf file, nor do its subfolders \(castle.fbx: an "
                                         r"Autodesk FBX file"):
        read_assets(tmp_path)
    (tmp_path / "castle.obj").write_text("v 0 0 0\n")
    with pytest.raises(AssetError, match="an OBJ file keeps no part hierarchy; export the parts as glTF 2.0"):
        read_assets(tmp_path / "castle.obj")
    (tmp_path / "castle.mb").write_bytes(b"FOR4")
    # Maya exports glTF only through a plug-in: its route is FBX, then Blender
    with pytest.raises(AssetError, match=r"a Maya scene is not read by procmod; export it as FBX, import that into "
                                         r"Blender \(File > Import > FBX\) and export glTF 2.0 \(.glb\)$"):
        read_assets(tmp_path / "castle.mb")
    # a file no 3D tool writes gets no advice
    (tmp_path / "notes.txt").write_text("castle")
    with pytest.raises(AssetError, match=r"notes.txt: not an asset file \(expected a name ending in .gltf, .glb, "
                                         r"\.urdf\)$"):
        read_assets(tmp_path / "notes.txt")


def ros_package(tmp_path, link: str, mesh_file: str, uri_name: str) -> Path:
    """A ROS workspace's package ``my_robot`` holding ``meshes/mesh_file`` and
    ``urdf/robot.urdf``, whose link ``link`` names it ``package://my_robot/meshes/uri_name``."""
    package = tmp_path / "ws" / "src" / "my_robot"
    (package / "meshes").mkdir(parents=True)
    write_obj(package / "meshes" / mesh_file, wedge_mesh(0.2))
    (package / "urdf").mkdir()
    links = {link: [f'<geometry><mesh filename="package://my_robot/meshes/{uri_name}"/></geometry>']}
    (package / "urdf" / "robot.urdf").write_text(urdf(links, []))
    return package


def test_a_package_mesh_resolves_the_same_from_the_urdfs_own_folder(tmp_path, monkeypatch):
    """``package://`` meshes are looked for in the URDF folder's ancestors: given as a bare
    ``robot.urdf`` from its own folder, the path has no ancestors until resolved."""
    package = ros_package(tmp_path, "leg", "leg.obj", "leg.obj")
    monkeypatch.chdir(package / "urdf")
    s = read_assets("robot.urdf")
    assert s.parts["leg"].kind == "mesh"
    # not found: the URI and where it was sought, not the last place tried (the root folder)
    (package / "meshes" / "leg.obj").unlink()
    with pytest.raises(AssetError, match=r"'package://my_robot/meshes/leg.obj' is neither 'meshes/leg.obj' nor "
                                         r"'my_robot/meshes/leg.obj' under the URDF's folder"):
        read_assets("robot.urdf")


def test_a_package_mesh_is_read_from_its_own_package_not_another_holding_the_same_name(tmp_path):
    """Many ROS packages hold a ``meshes/base_link.stl``: a cart's URDF naming its own and
    an arm package's read the cart's file for both (the first ancestor holding the bare
    name won, h144). The package's own folder comes first now, found by its folder's name
    or its package.xml (a commented-out name in it left aside); meshes copied beside a
    URDF in a package of the user's own are still read (h146)."""
    src = tmp_path / "ws" / "src"
    for name, size in (("cart", 0.5), ("arm_description", 0.1)):
        (src / name / "meshes").mkdir(parents=True)
        write_obj(src / name / "meshes" / "base_link.obj", wedge_mesh(size))
    (src / "cart" / "package.xml").write_text("<package format='2'><name> cart </name></package>")
    (src / "arm_description" / "package.xml").write_text("<package><name>arm_description</name></package>")
    (src / "cart" / "urdf").mkdir()
    links = {"base": ['<geometry><mesh filename="package://cart/meshes/base_link.obj"/></geometry>'],
             "arm": ['<geometry><mesh filename="package://arm_description/meshes/base_link.obj"/></geometry>']}
    robot = src / "cart" / "urdf" / "robot.urdf"
    robot.write_text(urdf(links, [("mount", "base", "arm", (0, 0, 0.1), (0, 0, 0))]))
    expected = sorted(tuple(np.round(np.ptp(wedge_mesh(size)[0], axis=0), 6)) for size in (0.5, 0.1))

    def extents(path):
        s = read_assets(path)
        return sorted(tuple(np.round(np.ptp(np.asarray(p.vertices), axis=0), 6)) for p in s.parts.values())

    assert extents(robot) == expected
    (src / "arm_description" / "package.xml").write_text("<package><name>arm_v2</name></package>")
    assert extents(robot) == expected  # by its folder's name (a package renamed since)
    # a URDF inside a package whose folder has another name (a download's "-main") is in
    # it by its package.xml, whose commented-out template name is left aside
    repo = tmp_path / "robot_description-main"
    (repo / "meshes").mkdir(parents=True)
    (repo / "urdf").mkdir()
    (repo / "package.xml").write_text("<package><!-- <name>my_package</name> --><name>robot_description</name>"
                                      "</package>")
    write_obj(repo / "meshes" / "base_link.obj", wedge_mesh(0.2))
    (repo / "urdf" / "robot.urdf").write_text(urdf(
        {"base": ['<geometry><mesh filename="package://robot_description/meshes/base_link.obj"/></geometry>']}, []))
    assert extents(repo / "urdf" / "robot.urdf") == [tuple(np.round(np.ptp(wedge_mesh(0.2)[0], axis=0), 6))]
    # a robot's URDF and meshes copied into the user's own package
    own = tmp_path / "my_sim"
    (own / "meshes").mkdir(parents=True)
    (own / "package.xml").write_text("<package><name>my_sim</name></package>")
    write_obj(own / "meshes" / "base_link.obj", wedge_mesh(0.3))
    (own / "robot.urdf").write_text(urdf({"arm": links["arm"]}, []))
    assert extents(own / "robot.urdf") == [tuple(np.round(np.ptp(wedge_mesh(0.3)[0], axis=0), 6))]
    # a package.xml that is no regular file (a FIFO) is passed over, not read (it had blocked)
    import os

    os.mkfifo(tmp_path / "package.xml")
    assert extents(own / "robot.urdf") == [tuple(np.round(np.ptp(wedge_mesh(0.3)[0], axis=0), 6))]
    (own / "bare.urdf").write_text(urdf({"arm": ['<geometry><mesh filename="package://my_sim"/></geometry>']}, []))
    with pytest.raises(AssetError, match=r"'package://my_sim' names a package but no file in it"):
        read_assets(own / "bare.urdf")


def test_a_package_mesh_named_percent_encoded_is_found_and_a_xacro_left_is_named(tmp_path):
    """A URI-escaping exporter writes a space as %20 in a package:// URI, as ROS decodes it;
    a URDF saved from its .xacro without running xacro failed on "${pi/2}" as a float, or
    on the xacro: prefix, with no word of xacro."""
    package = ros_package(tmp_path, "base", "base link.obj", "base%20link.obj")
    assert read_assets(package / "urdf" / "robot.urdf").parts["base link"].kind == "mesh"
    plain = urdf({"base": ['<geometry><box size="1 1 1"/></geometry>']}, [])
    for left, said in ((plain.replace('<geometry>', '<origin rpy="0 0 ${pi/2}"/><geometry>'), "${pi/2"),
                       (plain.replace('<link ', '<xacro:property name="r" value="1"/><link ', 1), "<xacro:property"),
                       (plain.replace('size="1 1 1"', 'size="$(arg size) 1 1"'), "$(arg size")):
        (tmp_path / "left.urdf").write_text(left)
        expected = (f"still holds xacro macros ({said!r}...); expand them into a plain URDF first (ROS: xacro "
                    "robot.urdf.xacro > robot.urdf)")
        with pytest.raises(AssetError, match=re.escape(expected)):
            read_assets(tmp_path / "left.urdf")
    # xacro's own output keeps its namespace declaration and a comment naming the source
    out = plain.replace("<robot ", '<!-- generated by xacro from ${file} -->'
                                   '<robot xmlns:xacro="http://www.ros.org/wiki/xacro" ', 1)
    (tmp_path / "expanded.urdf").write_text(out)
    assert len(read_assets(tmp_path / "expanded.urdf").assets) == 1
    (tmp_path / "robot.urdf.xacro").write_text(out)
    with pytest.raises(AssetError, match=r"a xacro file \(a URDF written with macros\) is not read by procmod; expand "
                                         r"its macros into a URDF first"):
        read_assets(tmp_path / "robot.urdf.xacro")


def test_a_gltf_buffer_named_percent_encoded_or_up_a_folder_is_found(tmp_path):
    """The glTF spec writes a space in a URI as %20; example sets may share buffers (..)."""
    import base64

    path, _, _ = ship_gltf(tmp_path / "inline.gltf")
    data = json.loads(path.read_text())
    blob = base64.b64decode(data["buffers"][0]["uri"].split(",", 1)[1])
    (tmp_path / "buffers").mkdir()
    (tmp_path / "buffers" / "my ship.bin").write_bytes(blob)
    (tmp_path / "models").mkdir()
    data["buffers"][0]["uri"] = "../buffers/my%20ship.bin"
    (tmp_path / "models" / "my ship.gltf").write_text(json.dumps(data))
    data["buffers"][0]["uri"] = "..\\buffers\\my%20ship.bin"  # a Windows tool's separators (h63: "missing")
    (tmp_path / "models" / "windows.gltf").write_text(json.dumps(data))
    inline = read_assets(path)
    for name in ("my ship.gltf", "windows.gltf"):
        external = read_assets(tmp_path / "models" / name)
        assert list(inline.parts) == list(external.parts)
        for x, y in zip(inline.assets[0].nodes(), external.assets[0].nodes()):
            assert x.part == y.part and np.allclose(x.transform, y.transform)
    data["buffers"][0]["uri"] = str(tmp_path / "buffers" / "my ship.bin")  # absolute: refused
    (tmp_path / "models" / "absolute.gltf").write_text(json.dumps(data))
    with pytest.raises(AssetError, match="absolute path"):
        read_assets(tmp_path / "models" / "absolute.gltf")


def test_a_draco_compressed_gltf_is_refused_with_what_to_do(tmp_path):
    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    data = json.loads(path.read_text())
    data["extensionsUsed"] = data["extensionsRequired"] = ["KHR_draco_mesh_compression"]
    path.write_text(json.dumps(data))
    with pytest.raises(AssetError, match="Draco-compressed.*export it without mesh compression"):
        read_assets(path)


def test_a_draco_file_with_plain_data_beside_is_read_and_one_without_is_refused(tmp_path):
    """A file that uses Draco without requiring it keeps plain accessors for readers
    without Draco (gltf-pipeline's uncompressed fallback), and was refused all the same (h63)."""
    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    data = json.loads(path.read_text())
    data["extensionsUsed"] = ["KHR_draco_mesh_compression"]
    for primitive in data["meshes"][0]["primitives"]:
        primitive["extensions"] = {"KHR_draco_mesh_compression": {"bufferView": 0, "attributes": {"POSITION": 0}}}
    (tmp_path / "fallback.gltf").write_text(json.dumps(data))
    plain, fallback = read_assets(path), read_assets(tmp_path / "fallback.gltf")
    assert [(n.name, n.part) for n in fallback.assets[0].nodes()] == [(n.name, n.part) for n in plain.assets[0].nodes()]
    position = data["meshes"][0]["primitives"][0]["attributes"]["POSITION"]
    del data["accessors"][position]["bufferView"]  # compressed only: trimesh read placeholder zeros
    (tmp_path / "compressed.gltf").write_text(json.dumps(data))
    with pytest.raises(AssetError, match="Draco-compressed"):
        read_assets(tmp_path / "compressed.gltf")


@pytest.mark.parametrize("edit", ["version", "objects by id", "binary"])
def test_a_gltf_1_file_is_refused_with_how_to_upgrade_it(tmp_path, edit):
    """glTF 1.0 keeps its objects by id: learn and strings said "'nodes' is not a list of
    node objects" (h63)."""
    import struct

    from procmod.geometry.mesh_files import load_mesh_file

    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    data = json.loads(path.read_text())
    if edit == "version":
        data["asset"]["version"] = "1.0"
    elif edit == "objects by id":
        del data["asset"]
        data["nodes"] = {f"node_{i}": node for i, node in enumerate(data["nodes"])}
    path.write_text(json.dumps(data))
    if edit == "binary":  # a glTF 1.0 binary (KHR_binary_glTF): version 1 in the GLB header
        text = json.dumps(data).encode()
        path = tmp_path / "ship.glb"
        path.write_bytes(struct.pack("<4sIIII", b"glTF", 1, 20 + len(text), len(text), 0) + text)
    with pytest.raises(AssetError, match=r"is glTF 1.0, which procmod does not read .*gltf-pipeline"):
        read_assets(path)
    with pytest.raises(ValueError, match=r"is glTF 1.0, which procmod does not read"):
        load_mesh_file(path, force="scene")


def test_a_urdf_mesh_over_the_face_limit_is_refused_from_its_header(tmp_path, monkeypatch):
    """Read whole before: 12 s and 4.5 GB for a 10^7-face STL before the limit said no."""
    import struct

    monkeypatch.setattr(assets, "MAX_FACES", 1000)
    (tmp_path / "meshes").mkdir()
    # a binary STL's header claims 5000 faces; the records are never read
    (tmp_path / "meshes" / "big.stl").write_bytes(b"\0" * 80 + struct.pack("<I", 5000) + b"\0" * 50 * 10)
    links = {"base": ['<geometry><mesh filename="meshes/big.stl"/></geometry>']}
    (tmp_path / "big.urdf").write_text(urdf(links, []))
    with pytest.raises(AssetError, match="declares 5,000 triangles"):
        read_assets(tmp_path / "big.urdf")


def test_alignment_ranks_every_start_on_a_subset_and_refines_only_the_best(tmp_path, monkeypatch):
    """Distinct look-alikes (noisy spheres: every start is tried, none fits) cost a few
    full-sample ICPs a pair, not one per start (96 here); a rotated, noisy copy of a rock
    still matches its original."""
    import trimesh

    full = []
    icp = assets._icp
    monkeypatch.setattr(assets, "_icp", lambda a, b, m, improper, plane, steps, points=None: (
        full.append(points is None), icp(a, b, m, improper, plane, steps, points))[1])
    sphere = trimesh.creation.icosphere(subdivisions=2)
    rng = np.random.default_rng(0)
    rock = trimesh.convex.convex_hull(rng.normal(size=(40, 3)) * [1.0, 0.8, 0.6])
    turned = rock.vertices @ Rotation.from_rotvec([0.4, -1.1, 0.7]).as_matrix().T
    turned = turned + rng.normal(0, 1e-3 * rock.scale, turned.shape)
    meshes = [(f"ball{k}", [(sphere.vertices + rng.normal(0, 0.02, sphere.vertices.shape), sphere.faces)])
              for k in range(2)] + [("rock", [(rock.vertices, rock.faces)]), ("copy", [(turned, rock.faces)])]
    nodes = [{"name": name, "mesh": k, "translation": [3.0 * k, 0, 0]} for k, (name, _) in enumerate(meshes)]
    s = read_assets(write_gltf(tmp_path / "look_alikes.gltf", meshes, nodes, roots=range(4)))
    assert sorted(s.parts) == ["ball0", "ball1", "copy"]  # the shorter name of the two rocks
    starts = full.count(False)
    assert starts >= 96  # both handednesses of the spheres' 48 starts were ranked
    # two pairs reach ICP (the balls; the rocks), each handedness at most the kept starts + 2 fine
    assert full.count(True) <= 2 * 2 * (assets._KEPT_STARTS + 2)


def test_a_camera_or_light_beside_the_model_is_passed_over(tmp_path):
    """Blender and Maya export the scene's camera as a node of its own; trimesh leaves
    a childless camera node out of its scene, which refused the whole file."""
    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    data = json.loads(path.read_text())
    data["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]
    data["nodes"] += [{"name": "Camera", "camera": 0, "translation": [5, 5, 5]}, {"name": "Light"}]
    data["scenes"][0]["nodes"] += [5, 6]
    (tmp_path / "with_camera.gltf").write_text(json.dumps(data))
    plain, with_camera = read_assets(path), read_assets(tmp_path / "with_camera.gltf")
    assert [n.name for n in with_camera.assets[0].nodes()] == [n.name for n in plain.assets[0].nodes()]


def test_a_model_parented_to_a_camera_is_read_where_the_camera_puts_it(tmp_path):
    """Blender and three.js write an object parented to the camera as the camera node's
    child; trimesh left the camera's node out of its scene and everything under it with it:
    learn and strings ended in a traceback ('No path from world->Camera!') and a target
    was refused (h63)."""
    from procmod.geometry.mesh_files import load_mesh_file

    path, _, _ = ship_gltf(tmp_path / "ship.gltf")
    data = json.loads(path.read_text())
    data["cameras"] = [{"type": "perspective", "perspective": {"yfov": 0.8, "znear": 0.1}}]
    data["nodes"].append({"name": "Camera", "camera": 0, "translation": [0, 2, 10], "children": [0]})
    data["scenes"][0]["nodes"] = [5]
    (tmp_path / "on_camera.gltf").write_text(json.dumps(data))
    plain, on_camera = read_assets(path), read_assets(tmp_path / "on_camera.gltf")
    moved = {n.name: n.transform for n in on_camera.assets[0].nodes()}
    for node in plain.assets[0].nodes():
        assert np.allclose(moved[node.name], T(0, 2, 10) @ node.transform, atol=1e-6), node.name
    bounds = load_mesh_file(tmp_path / "on_camera.gltf", force="mesh").bounds
    assert np.allclose(bounds, load_mesh_file(path, force="mesh").bounds + [0, 2, 10], atol=1e-5)


def test_copies_of_a_coarse_round_part_turned_by_apply_rotation_are_one_part(tmp_path):
    """An icosphere of 80 faces (equal moments: its principal axes say nothing) copied
    with a random rotation baked into each copy's vertices: ICP's basin on a nearly round
    surface is a few degrees wide, and 16 copies were 14 parts; starts from pairs of
    vertices (same distances, same number of edges) find the copies' own map."""
    import trimesh

    ball = trimesh.creation.icosphere(subdivisions=1, radius=0.2)
    meshes, nodes = [("base", [box_mesh((2, 0.2, 1))])], [{"name": "base", "mesh": 0, "children": []}]
    for k in range(6):
        turned = ball.vertices @ Rotation.random(random_state=k).as_matrix().T
        meshes.append((f"knob.{k:03d}", [(turned, ball.faces)]))
        nodes[0]["children"].append(len(nodes))
        nodes.append({"name": f"k{k}", "mesh": k + 1, "translation": [-0.75 + 0.3 * k, 0.25, 0]})
    s = read_assets(write_gltf(tmp_path / "knobs.gltf", meshes, nodes))
    assert sorted(s.parts) == ["base", "knob.000"]
    for node in s.assets[0].nodes()[1:]:  # each copy placed where its own vertices were
        k = int(node.name[1:])
        want = meshes[k + 1][1][0][0] + [-0.75 + 0.3 * k, 0.25, 0]
        got = world_triangles(s, node).reshape(-1, 3)
        assert same_surface(got, want[ball.faces], 1e-5)


def test_an_unnamed_mesh_is_named_after_its_node(tmp_path):
    """trimesh names an unnamed glTF mesh "GLTF", "GLTF_1", ...: parts were named so."""
    meshes = [("", [box_mesh((1, 1, 1))]), ("", [wedge_mesh(0.5)])]
    nodes = [{"name": "body", "mesh": 0, "children": [1]}, {"name": "fin", "mesh": 1, "translation": [1, 0, 0]}]
    data = gltf_json(meshes, nodes, (0,))
    for mesh in data["meshes"]:
        mesh.pop("name", None)
    (tmp_path / "unnamed.gltf").write_text(json.dumps(data))
    assert sorted(read_assets(tmp_path / "unnamed.gltf").parts) == ["body", "fin"]


def _chair(path, baked: bool, turned: float = 0.0):
    """A seat (a flat square box mesh) and a leg under it; ``baked``: every transform applied
    in the tool (world coordinates in the meshes, identity nodes); ``turned``: the seat's
    mesh modelled turned about the vertical by that many degrees and its node turned back."""
    seat, leg = box_mesh((0.45, 0.04, 0.45)), box_mesh((0.04, 0.45, 0.04))
    at_seat, at_leg = np.eye(4), np.eye(4)
    at_seat[:3, 3], at_leg[:3, 3] = (0, 0.45, 0), (0.2, -0.225, 0.2)
    if baked:
        meshes = [("Seat.baked", [transformed(seat, at_seat)]), ("Leg.baked", [transformed(leg, at_seat @ at_leg)])]
        nodes = [{"name": "Seat", "mesh": 0, "children": [1]}, {"name": "Leg", "mesh": 1}]
    else:
        turn = np.eye(4)
        turn[:3, :3] = Rotation.from_euler("y", turned, degrees=True).as_matrix()
        meshes = [("Seat", [transformed(seat, turn)]), ("Leg", [leg])]
        nodes = [{"name": "Seat", "mesh": 0, "children": [1], "matrix": column_major(at_seat @ np.linalg.inv(turn))},
                 {"name": "Leg", "mesh": 1, "matrix": column_major(turn @ at_leg)}]
    write_glb(path, gltf_json(meshes, nodes, (0,)))
    return path


def test_a_symmetric_part_is_placed_unturned_when_its_geometry_allows_it(tmp_path):
    """A seat whose transforms were applied in Blender (or a table top modelled turned and
    turned back) matched the other examples' seat by a half turn as well as by none; the
    half turn was kept, and the learned program sampled chairs tipped over."""
    files = [_chair(tmp_path / "a.glb", False), _chair(tmp_path / "b.glb", True),
             _chair(tmp_path / "c.glb", False, turned=90.0)]
    read = read_assets(files)
    assert len(read.parts) == 2  # one seat, one leg
    for asset in read.assets:
        for node in asset.nodes():
            assert np.allclose(np.asarray(node.transform)[:3, :3], np.eye(3), atol=1e-6), (asset.path, node.name)


def test_a_mesh_whose_transforms_were_applied_gets_a_frame_at_its_middle(tmp_path):
    """Geometry exported with its transforms applied lies in world coordinates about the
    world's origin: a leg's part frame was 0.75 m from the leg, its placements encoded that
    offset, and learned tables' legs strayed 0.3 m outside the top. A pivot on the geometry
    (the unbaked chair's) stays where the artist put it."""
    read = read_assets([_chair(tmp_path / "b.glb", True)])
    leg = np.asarray(read.parts["Leg.baked"].vertices)
    assert np.allclose((leg.min(0) + leg.max(0)) / 2, 0, atol=1e-6)  # the frame at the leg's middle
    nodes = {node.name: node for node in read.assets[0].nodes()}
    assert np.allclose(np.asarray(nodes["Leg"].transform)[:3, 3], (0.2, 0.225, 0.2), atol=1e-6)
    want = transformed(box_mesh((0.04, 0.45, 0.04)), T(0.2, 0.225, 0.2))
    assert same_surface(world_triangles(read, nodes["Leg"]).reshape(-1, 3), want[0][want[1]].reshape(-1, 3), 1e-6)
    unbaked = read_assets([_chair(tmp_path / "a.glb", False)])
    assert np.allclose(np.asarray(unbaked.parts["Leg"].vertices), box_mesh((0.04, 0.45, 0.04))[0])


def _turned_baked_table(path, k: int, mesh_names=("Top", "Leg")):
    """Table ``k`` of four: a top and four legs of its own sizes, the whole table turned
    (about the vertical, and tipped a little) and every transform applied, as Blender's
    Apply All Transforms leaves them: the meshes in world coordinates, the nodes identity."""
    height, width, depth = 0.45 + 0.1 * k, 1.0 + 0.2 * k, 0.6 + 0.1 * k
    turn = R([0.05 * k, (0.3, 1.1, -0.7, 2.0)[k], 0.0]) @ T(3.0 * k, 0, 0)
    meshes = [(mesh_names[0], [transformed(box_mesh((width, 0.05, depth), (0, height + 0.025, 0)), turn)])]
    nodes = [{"name": "Top", "mesh": 0, "children": [1, 2, 3, 4]}]
    for j, (sx, sz) in enumerate(((1, 1), (1, -1), (-1, 1), (-1, -1))):
        at = (sx * (width / 2 - 0.05), height / 2, sz * (depth / 2 - 0.05))
        meshes.append((mesh_names[1] + (f".{j + 1:03d}" if mesh_names[1] == "Cube" else f".{j:03d}" if j else ""),
                       [transformed(box_mesh((0.05, height, 0.05), at), turn)]))
        nodes.append({"name": "Leg" + (f".{j:03d}" if j else ""), "mesh": j + 1})
    write_glb(path, gltf_json(meshes, nodes, (0,)))
    return path, meshes


def test_copies_turned_and_scaled_with_their_transforms_applied_are_one_part(tmp_path):
    """Four tables of different sizes, each turned and baked: a leg's shape along its own
    axes differs from table to table, and the scale grouping had made each table's top
    and legs part types of their own (8 for 2), so the learned program could not mix them.
    Each node must still place its part where the file's vertices were."""
    files = [_turned_baked_table(tmp_path / f"t{k}.glb", k) for k in range(4)]
    read = read_assets([path for path, _ in files])
    assert sorted(read.parts) == ["Leg", "Top"]
    for asset, (_, meshes) in zip(read.assets, files):
        for node, (_, [(vertices, faces)]) in zip(asset.nodes(), meshes):
            assert same_surface(world_triangles(read, node).reshape(-1, 3), vertices[faces].reshape(-1, 3), 1e-5)
    # meshes as Blender names its cubes ("Cube", "Cube.001"): the objects' names tell top from leg
    files = [_turned_baked_table(tmp_path / f"c{k}.glb", k, ("Cube", "Cube")) for k in range(4)]
    assert sorted(read_assets([path for path, _ in files]).parts) == ["Leg", "Top"]
    # the parts are upright boxes in their own frames (a leg: 0.05 x about 0.6 x 0.05)
    leg = np.ptp(np.asarray(read.parts["Leg"].vertices), axis=0)
    assert np.allclose(leg[[0, 2]], 0.05, atol=1e-4) and 0.45 - 1e-4 < leg[1] < 0.75, leg


def test_parts_of_unnamed_nodes_take_their_meshes_tool_names(tmp_path):
    """Nodes without names (a converter's export) placing meshes a tool named "Cube" and
    "Cube.001": the parts had been named after trimesh's node indices ("1", "2"), which mean
    nothing; they take the meshes' names, as named nodes give theirs."""
    meshes = [("Cube.001", [box_mesh((0.2, 1.0, 0.2))]), ("Cube", [box_mesh((1.0, 0.1, 0.1))])]
    nodes = [{"name": "Fence", "children": [1, 2, 3]}, {"mesh": 0, "translation": [0, 0.5, 0]},
             {"mesh": 1, "translation": [0.6, 0.7, 0]}, {"mesh": 0, "translation": [1.2, 0.5, 0]}]
    assert sorted(read_assets(write_gltf(tmp_path / "fence.gltf", meshes, nodes)).parts) == ["Cube", "Cube_2"]
    for node in nodes[1:]:  # named nodes: their names, as before
        node["name"] = "Post" if node["mesh"] == 0 else "Rail"
    assert sorted(read_assets(write_gltf(tmp_path / "named.gltf", meshes, nodes)).parts) == ["Post", "Rail"]


def test_a_child_named_after_a_mesh_of_several_primitives_is_not_merged_into_it(tmp_path):
    """trimesh places a mesh of several primitives (Blender: an object with two material
    slots) as frames NODE_<id> under its node's; the node's own children named NODE_...
    (a child "gun_sight" of "gun", trimesh's "gun_1" for a second "gun") had been merged
    into its mesh as well as read as their own parts (h144)."""
    gun = [box_mesh((0.1, 0.1, 0.5)), box_mesh((0.2, 0.2, 0.1), (0, 0, 0.3))]
    meshes = [("gun", gun), ("sight", [box_mesh((0.05, 0.05, 0.05))]), ("stock", [box_mesh((0.3, 0.1, 0.1))])]
    nodes = [{"name": "gun", "mesh": 0, "children": [1, 2]},
             {"name": "gun_sight", "mesh": 1, "translation": [0, 0.2, 0]},
             {"name": "gun", "mesh": 2, "translation": [0, 0, -0.4]}]  # trimesh names it "gun_1"
    s = read_assets(write_gltf(tmp_path / "gun.gltf", meshes, nodes))
    assert sorted(s.parts) == ["gun", "sight", "stock"]
    assert len(s.parts["gun"].faces) == 24 and len(s.parts["sight"].faces) == 12


def test_a_primitives_kinds_are_told_by_size_not_by_the_names_of_its_objects(tmp_path):
    """A review's sets: a version that took object names for kinds split tables named per
    file (Table01_Top, Table02_Top) into 12 part types for 2, legs named one way here and
    another there, and books named by colour into one type each. Kinds of a tool's
    primitive are told by size (SCALE_GROUP) and geometry, as before."""
    def table(path, k, names):
        height = 0.45 + 0.08 * k
        top = {"name": names[0], "mesh": 0, "scale": [0.6 + 0.1 * k, 0.025, 0.4], "translation": [0, height, 0]}
        legs = [{"name": name, "mesh": 0, "scale": [0.025, height / 2, 0.025],
                 "translation": [x * 0.5, height / 2, z * 0.3]}
                for name, (x, z) in zip(names[1:], ((1, 1), (1, -1), (-1, 1), (-1, -1)))]
        return write_gltf(path, [("Cube", [box_mesh((2.0, 2.0, 2.0))])],
                          [{"name": "Table", "children": [1, 2, 3, 4, 5]}, top, *legs])

    prefixed = [table(tmp_path / f"p{k}.gltf", k, [f"Table0{k}_Top"] + [f"Table0{k}_Leg" + (f".00{j}" if j else "")
                                                                       for j in range(4)]) for k in range(4)]
    mixed = [table(tmp_path / f"m{k}.gltf", k, ["Top"] + (["Leg", "Leg.001", "Leg.002", "Leg.003"] if k % 2 else
                                                           ["Leg_FL", "Leg_FR", "Leg_BL", "Leg_BR"])) for k in range(4)]
    for files in (prefixed, mixed):
        assert len(read_assets(files).parts) == 2, sorted(read_assets(files).parts)


def test_cubes_the_user_named_torso_head_and_forearm_are_three_parts(tmp_path):
    """h98's robots: a torso, a head and two forearms (under the upper arms), each a
    Blender cube with its scale applied (meshes Cube, Cube.001, Cube.002), within 3x of
    each other on every axis, were one part type: the learned program's robots drew 2-5
    of them anywhere (55 of 200 samples). Their objects' names, where they hang in
    different places and sizes keep them apart, make them three. Parts hanging side by
    side, however named (books by colour or title), and roots named per file stay one."""
    rng = np.random.default_rng(2)

    def robot(path, k):
        torso = (0.36 + 0.02 * k, 0.5, 0.25)
        meshes = [("Cube", [box_mesh(torso)]), ("Cube.001", [box_mesh((0.22 + 0.01 * k,) * 3)]),
                  ("Cube.002", [box_mesh((0.1, 0.3 + 0.01 * k, 0.1))]), ("Arm", [wedge_mesh(0.25)])]
        nodes = [{"name": "Torso", "mesh": 0, "children": [1, 2, 3]},
                 {"name": "Head", "mesh": 1, "translation": [0, 0.4, 0]},
                 {"name": "UpperArm", "mesh": 3, "translation": [0.3, 0.1, 0], "children": [4]},
                 {"name": "UpperArm.001", "mesh": 3, "translation": [-0.3, 0.1, 0], "children": [5]},
                 {"name": "Forearm", "mesh": 2, "translation": [0, -0.3, 0]},
                 {"name": "Forearm.001", "mesh": 2, "translation": [0, -0.3, 0]}]
        return write_gltf(path, meshes, nodes)

    read = read_assets([robot(tmp_path / f"r{k}.gltf", k) for k in range(4)])
    assert sorted(read.parts) == ["Arm", "Forearm", "Head", "Torso"]

    # h110: the head on a neck and the forearms on upper arms, necks and arms scaled from
    # one cylinder: where each hangs is read before any mesh is baked (the split had turned
    # on the order of the root's children), and by its parent's name too
    def necked(path, k, stand_first):
        cylinder, cube = box_mesh((1, 1, 1)), box_mesh((1, 1, 1))
        meshes = [("Cube", [cube]), ("Cylinder", [cylinder])]
        nodes = [{"name": "Robot", "children": [2, 1] if stand_first else [1, 2]},
                 {"name": "Torso", "mesh": 0, "scale": [0.36 + 0.02 * k, 0.5, 0.25], "children": [3, 4, 5]},
                 {"name": "Stand", "mesh": 1, "scale": [0.6, 0.05, 0.6], "translation": [0, -1, 0]},
                 {"name": "Neck", "mesh": 1, "scale": [0.3, 0.1, 0.4], "translation": [0, 0.6, 0], "children": [6]},
                 {"name": "UpperArm", "mesh": 1, "scale": [0.25, 0.6, 0.4], "translation": [0.8, 0, 0],
                  "children": [7]},
                 {"name": "UpperArm.001", "mesh": 1, "scale": [0.25, 0.6, 0.4], "translation": [-0.8, 0, 0],
                  "children": [8]},
                 {"name": "Head", "mesh": 0, "scale": [2.2 + 0.1 * k, 2.2, 1.8], "translation": [0, 3, 0]},
                 {"name": "Forearm", "mesh": 0, "scale": [1.2, 0.6 + 0.01 * k, 0.9], "translation": [0, -1.2, 0]},
                 {"name": "Forearm.001", "mesh": 0, "scale": [1.2, 0.6 + 0.01 * k, 0.9], "translation": [0, -1.2, 0]}]
        return write_gltf(path, meshes, nodes)

    for stand_first in (False, True):
        read = read_assets([necked(tmp_path / f"n{k}{stand_first}.gltf", k, stand_first) for k in range(4)])
        kinds = {asset.path.name: sorted({n.part for n in asset.nodes() if n.name.startswith(("Head", "Forearm"))})
                 for asset in read.assets}
        assert all(len(parts) == 2 for parts in kinds.values()), (stand_first, kinds)

    def shelf(path):
        books = [{"name": colour, "mesh": 1, "translation": [0.1 * j - 0.2, 0.15, 0],
                  "scale": [rng.uniform(0.02, 0.05), rng.uniform(0.18, 0.26), rng.uniform(0.12, 0.16)]}
                 for j, colour in enumerate(("Red", "Blue", "Green", "Red.001", "Blue.001"))]
        return write_gltf(path, [("Plank", [box_mesh((0.6, 0.02, 0.2))]), ("Cube", [box_mesh((1, 1, 1))])],
                          [{"name": "Shelf", "mesh": 0, "children": [1, 2, 3, 4, 5]}, *books])

    read = read_assets([shelf(tmp_path / f"s{k}.gltf") for k in range(4)])
    assert len(read.parts) == 2, sorted(read.parts)

    # h106: names alone split parts that hang side by side (books by title, one node each,
    # each title apart in size from the next) and roots named per file (tops by wood)
    def titled(path, k):
        titles = [("Dune", "Emma", "Ulysses"), ("Hamlet", "Walden", "Beloved")][k]
        books = [{"name": title, "mesh": 1, "translation": [0.1 * j - 0.1, 0.15, 0],
                  "scale": [0.02 + 0.012 * j, 0.2 + 0.03 * j, 0.14]} for j, title in enumerate(titles)]
        return write_gltf(path, [("Plank", [box_mesh((0.6, 0.02, 0.2))]), ("Cube", [box_mesh((1, 1, 1))])],
                          [{"name": "Shelf", "mesh": 0, "children": [1, 2, 3]}, *books])

    assert len(read_assets([titled(tmp_path / f"t{k}.gltf", k) for k in range(2)]).parts) == 2

    def wooden(path, k):
        wood = ("Oak", "Walnut", "Pine", "Birch")[k]
        legs = [{"name": f"{wood}_Leg" + (f".{j:03d}" if j else ""), "mesh": 1, "translation": [x, -0.35, z]}
                for j, (x, z) in enumerate(((0.4, 0.3), (-0.4, 0.3), (0.4, -0.3), (-0.4, -0.3)))]
        return write_gltf(path, [("Cube", [box_mesh((1, 1, 1))]), ("Cylinder", [box_mesh((0.05, 0.7, 0.05))])],
                          [{"name": f"{wood}_Top", "mesh": 0, "scale": [1.0 + 0.1 * k, 0.04, 0.7],
                            "translation": [0, 0.72, 0], "children": [1, 2, 3, 4]}, *legs])

    read = read_assets([wooden(tmp_path / f"w{k}.gltf", k) for k in range(4)])
    assert len(read.parts) == 2, sorted(read.parts)

    # h108, h109: names given per file, under a parent of its own in each (a car's wheels
    # called Wheel, Tyre and Tire under three bodies; Wheel by one author, Tire by another,
    # whose wheels are bigger): each file's, or each author's, wheels had been a part type
    def car(path, k, words=("Wheel", "Tyre", "Tire")):
        word = words[k]
        wheels = [{"name": f"{word}_{corner}", "mesh": 1, "translation": [x, -0.3, z],
                   "scale": [0.3 + 0.04 * k, 0.3 + 0.04 * k, 0.2]}
                  for corner, (x, z) in zip(("FL", "FR", "RL", "RR"), ((1, 0.8), (1, -0.8), (-1, 0.8), (-1, -0.8)))]
        return write_gltf(path, [(f"Body{k}", [box_mesh((3.0 + 0.5 * k, 1.0 + 0.3 * k, 1.6))]),
                                 ("Cylinder", [box_mesh((1, 1, 1))])],
                          [{"name": "Body", "mesh": 0, "children": [1, 2, 3, 4]}, *wheels])

    read = read_assets([car(tmp_path / f"c{k}.gltf", k) for k in range(3)])
    assert len(read.parts) == 2, sorted(read.parts)  # a body, a wheel
    read = read_assets([car(tmp_path / f"a{k}.gltf", k, ("Wheel", "Wheel", "Tire", "Tire")) for k in range(4)])
    assert len(read.parts) == 2, sorted(read.parts)


def _cube_chair(path, height: float, baked_legs: bool = False):
    """A chair as Blender users make one: the default cube scaled into a seat, a back and
    four legs, the scales left unapplied (``baked_legs``: the legs' scale applied, so their
    mesh is a leg at its size under an unscaled node)."""
    cube = box_mesh((1, 1, 1))
    leg_size = (0.04, height, 0.04)
    meshes = [("Cube", [cube]), ("Cube.001", [transformed(cube, np.diag([*leg_size, 1.0]))])]
    nodes = [{"name": "Seat", "mesh": 0, "translation": [0, height, 0], "scale": [0.45, 0.04, 0.45],
              "children": [1]},
             {"name": "Back", "mesh": 0, "translation": [0, 0.22 / 0.04, -0.21 / 0.45],
              "scale": [1.0, 0.4 / 0.04, 0.03 / 0.45]}]
    for i, (x, z) in enumerate([(0.2, 0.2), (-0.2, 0.2), (0.2, -0.2), (-0.2, -0.2)]):
        leg = {"name": f"Leg.{i:03d}", "mesh": 1 if baked_legs else 0, "translation": [x, height / 2, z]}
        if not baked_legs:
            leg["scale"] = list(leg_size)
        nodes.append(leg)
    write_glb(path, gltf_json(meshes, nodes, [0] + list(range(2, 6))))
    return path


def test_a_primitive_scaled_into_several_parts_is_several_parts(tmp_path):
    """Six scaled cubes were one part type, "Cube", six times over (the learned program
    sampled chairs of 1, 2 or 10 boxes), and a leg whose scale was applied was another part
    than its twin whose scale was not."""
    files = [_cube_chair(tmp_path / f"c{k}.glb", 0.45 + 0.03 * k, baked_legs=(k == 3)) for k in range(4)]
    read = read_assets(files)
    for asset in read.assets:
        counts = {}
        for node in asset.nodes():
            counts[node.part] = counts.get(node.part, 0) + 1
        assert counts == {"Seat": 1, "Back": 1, "Leg": 4}, (asset.path.name, counts)
    # every part where the file puts it: the leg of chair 2 is 0.51 tall and 0.04 wide
    leg = next(n for n in read.assets[2].nodes() if n.part == "Leg")
    corners = part_triangles(read.parts["Leg"].part(leg.transform)).reshape(-1, 3)
    assert np.allclose(np.ptp(corners, axis=0), (0.04, 0.51, 0.04), atol=1e-6)


def test_a_primitive_added_at_other_sizes_is_one_part_whose_size_varies(tmp_path):
    """A pole added at five depths (or scaled with the scale applied, in every example)
    was five part types, Pole to Pole_5, and a sample drew none or two of them; a table top
    whose location was applied (its mesh moved off its origin) in some files was a part of
    its own, and their samples floated or sank."""
    cylinder = trimesh.creation.cylinder(radius=0.06, height=1.0, sections=12)
    turn = np.array([[1, 0, 0, 0], [0, 0, 1, 0], [0, -1, 0, 0], [0, 0, 0, 1.0]])  # its axis up (y)
    files = []
    for k, height in enumerate((4.0, 4.5, 3.8, 5.0, 4.2)):
        pole = transformed((cylinder.vertices, cylinder.faces), turn @ np.diag([1, 1, height, 1.0]))
        base = box_mesh((0.5, 0.3, 0.5))
        pole_node = {"name": "Pole", "mesh": 1, "translation": [0, 0.15 + height / 2, 0]}
        base_node = {"name": "Base", "mesh": 0, "translation": [0, 0.15, 0], "children": [1]}
        if k < 2:  # "Apply Location" on the pole: its mesh sits where the node was, the node at the parent
            pole = transformed(pole, np.array([[1, 0, 0, 0], [0, 1, 0, 0.15 + height / 2], [0, 0, 1, 0],
                                               [0, 0, 0, 1.0]]))
            pole_node.pop("translation")
        files.append(write_glb(tmp_path / f"p{k}.glb",
                               gltf_json([("Base", [base]), (f"Cylinder.{k:03d}", [pole])], [base_node, pole_node],
                                         [0])))
    read = read_assets(files)
    assert sorted(read.parts) == ["Base", "Pole"]
    for asset, height in zip(read.assets, (4.0, 4.5, 3.8, 5.0, 4.2)):  # each where and as long as its file has it
        pole = next(n for n in asset.nodes() if n.part == "Pole")
        corners = part_triangles(read.parts["Pole"].part(pole.transform)).reshape(-1, 3)
        assert np.allclose(np.ptp(corners, axis=0)[1], height, atol=1e-6)
        assert np.isclose(corners[:, 1].min(), 0.3, atol=1e-6)  # on the base


def test_a_round_primitive_applied_at_other_widths_in_float32_is_one_part(tmp_path):
    """Candelabra plates (a 24-sided cylinder, Ctrl+A applied at radii 0.16-0.21) were
    five part types for eight examples: their unit shapes, rounded to 9 digits, differed by
    the float32 rounding of a scale across the axis (1.7e-8), and each sample copied one
    example's layout."""
    cylinder = trimesh.creation.cylinder(radius=1.0, height=1.0, sections=24)
    files = []
    radii = (0.16, 0.18, 0.19, 0.2, 0.21)
    for k, radius in enumerate(radii):
        plate = transformed((cylinder.vertices, cylinder.faces), np.diag([radius, radius, 0.02, 1.0]))
        nodes = [{"name": "Base", "mesh": 0, "children": [1]},
                 {"name": f"Plate.{k:03d}", "mesh": 1, "translation": [0, 0.3, 0]}]
        files.append(write_glb(tmp_path / f"c{k}.glb", gltf_json([("Base", [box_mesh((0.2, 0.2, 0.2))]),
                                                                  (f"Cylinder.{k:03d}", [plate])], nodes, [0])))
    read = read_assets(files)
    assert sorted(read.parts) == ["Base", "Plate"]
    for asset, radius in zip(read.assets, radii):  # each as wide as its file has it
        plate = next(n for n in asset.nodes() if n.part == "Plate")
        corners = part_triangles(read.parts["Plate"].part(plate.transform)).reshape(-1, 3)
        assert np.allclose(sorted(np.ptp(corners, axis=0)), sorted((2 * radius, 2 * radius, 0.02)), atol=1e-5)


def test_planes_scaled_into_panels_are_parts_of_their_own(tmp_path):
    """A flat primitive (Blender's plane) has no extent across it: it is grouped by its other
    two axes' scales like any other."""
    plane = (np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], dtype=float), np.array([[0, 2, 1], [0, 3, 2]]))
    nodes = [{"name": "Floor", "mesh": 0, "scale": [2.0, 1, 2.0], "children": [1]},
             {"name": "Strip", "mesh": 0, "translation": [0, 0.5, 0], "scale": [0.05, 1, 0.5]}]
    write_glb(tmp_path / "a.glb", gltf_json([("Plane", [plane])], nodes, [0]))
    read = read_assets([tmp_path / "a.glb"])
    assert sorted(n.part for n in read.assets[0].nodes()) == ["Floor", "Strip"]


def test_meshes_the_user_named_apart_stay_apart_whatever_their_shape(tmp_path):
    """A column (a box 1x1x3) and a wall (a box 3x1x2), cubes with their scales applied
    under names of their own, were grouped as one cube at several sizes: one part type
    named "wall", and strings named the column "wall" and the wall "wall_2"."""
    nodes, meshes = [], []
    for k, (name, size) in enumerate((("column", (1.0, 3.0, 1.0)), ("wall", (3.0, 2.0, 1.0)))):
        meshes.append((name, [box_mesh(size)]))
    for k in range(4):
        nodes.append({"name": f"piece{k}", "mesh": k % 2, "translation": [2.0 * k, 1.0, 0]})
    write_glb(tmp_path / "row.glb", gltf_json(meshes, nodes, list(range(4))))
    read = read_assets([tmp_path / "row.glb"])
    assert sorted(read.parts) == ["column", "wall"]
    for node in read.assets[0].nodes():  # each at its own size
        corners = part_triangles(read.parts[node.part].part(node.transform)).reshape(-1, 3)
        assert np.allclose(np.ptp(corners, axis=0), (1, 3, 1) if node.part == "column" else (3, 2, 1), atol=1e-6)
    from procmod.strings.assets import shapes_from_assets
    assert sorted(shapes_from_assets([tmp_path / "row.glb"]).library) == ["column", "wall"]


def test_copies_each_with_mesh_data_of_their_own_are_matched_triangle_for_triangle(tmp_path, monkeypatch):
    """A scene of copies whose mesh data are their own (a tool's plain duplicates, their
    transforms applied: moved, turned, a quarter turn) is one part, found vertex for
    vertex without the surface alignment (~40 ms a pair: a 5,000-part scene took
    minutes); each node still places the part where its triangles were. A copy with other
    triangles, or bent beyond the tolerance, is still told apart by the alignment."""
    aligned = []
    align = assets._align
    monkeypatch.setattr(assets, "_align", lambda *a: (aligned.append(1), align(*a))[1])
    rng = np.random.default_rng(3)
    wedge = wedge_mesh()
    turns = [np.eye(4), R([0, 0, math.pi / 2])] + [R(rng.normal(size=3)) for _ in range(10)]
    meshes = [(f"piece{k}", [transformed(wedge, T(*rng.normal(size=3) * 5) @ turn)]) for k, turn in enumerate(turns)]
    nodes = [{"name": name, "mesh": k} for k, (name, _) in enumerate(meshes)]
    read = read_assets(write_gltf(tmp_path / "copies.gltf", meshes, nodes, roots=range(len(nodes))))
    assert list(read.parts) == ["piece0"] and not aligned
    for node, (_, [(vertices, faces)]) in zip(read.assets[0].nodes(), meshes):
        assert same_surface(world_triangles(read, node).reshape(-1, 3), vertices[faces].reshape(-1, 3), 1e-5)
    # the quarter-turned copy is placed by an exact quarter turn (float32 coordinates aside)
    quarter = read.assets[0].nodes()[1].transform[:3, :3]
    assert np.abs(quarter - np.round(quarter)).max() < 1e-6
    bent_v, bent_f = transformed(wedge, R([0.3, 0.2, 0.1]))
    bent_v = bent_v.copy()
    bent_v[0] += 0.05  # a corner pulled out by 5% of the diagonal: another part
    meshes.append(("bent", [(bent_v, bent_f)]))
    nodes.append({"name": "bent", "mesh": len(nodes)})
    aligned.clear()
    read = read_assets(write_gltf(tmp_path / "bent.gltf", meshes, nodes, roots=range(len(nodes))))
    assert sorted(read.parts) == ["bent", "piece0"] and aligned


def test_scale_groups_are_single_linkage_components_in_order_of_first_member():
    """The k-d tree grouping gives the groups a pairwise union gives, on rows with many
    copies and chains of steps just within and just beyond the limit."""
    rng = np.random.default_rng(0)
    limit = math.log(assets.SCALE_GROUP)
    rows = np.concatenate([rng.normal(0, 2, size=(40, 3)), np.repeat(rng.normal(0, 2, size=(5, 3)), 8, axis=0),
                           np.cumsum(np.full((6, 3), [0.999 * limit, 0, 0]), axis=0) + 20,
                           np.cumsum(np.full((3, 3), [1.001 * limit, 0, 0]), axis=0) - 20])
    rows = rows[rng.permutation(len(rows))]
    group = list(range(len(rows)))

    def root(i):
        while group[i] != i:
            i = group[i]
        return i

    for i in range(len(rows)):
        for j in range(i + 1, len(rows)):
            if np.abs(rows[i] - rows[j]).max() <= limit:
                group[root(j)] = root(i)
    want = {}
    for i in range(len(rows)):
        want.setdefault(root(i), []).append(i)
    assert assets._scale_groups(rows) == list(want.values())


def _fin_robot(folder, mesh_uri: str, robot_attrs: str = "") -> Path:
    """A box base with one mesh link on top, named by ``mesh_uri``."""
    return _write(folder / "r.urdf", f"""<?xml version="1.0"?>
<robot name="r"{robot_attrs}><link name="base"><visual><geometry><box size="0.4 0.2 0.05"/></geometry></visual></link>
<joint name="j" type="fixed"><parent link="base"/><child link="fin"/><origin xyz="0 0 0.025"/></joint>
<link name="fin"><visual><geometry><mesh filename="{mesh_uri}"/></geometry></visual></link></robot>
""")


def _write(path, text):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def _fin_box(asset_set) -> tuple:
    (base,) = asset_set.assets[0].roots
    (fin,) = base.children
    corners = world_triangles(asset_set, fin).reshape(-1, 3)
    return tuple(np.round(corners.min(0), 6)), tuple(np.round(corners.max(0), 6))


@pytest.mark.parametrize("up_axis", ["<up_axis>Y_UP</up_axis>", "<up_axis>Z_UP</up_axis>", ""])
def test_a_urdfs_collada_mesh_keeps_its_axes_whatever_its_up_axis_says(tmp_path, up_axis):
    """RViz and MoveIt take a URDF's COLLADA vertices in the link's frame as they are, and
    ROS packages are drawn so; procmod turned a Y_UP or unmarked one (the COLLADA default)
    on its side, unlike the same part as an STL. Its <unit> still counts."""
    fin = trimesh.creation.box([0.4, 0.02, 0.2])
    fin.apply_translation([0, 0, 0.1])  # upright on the base, z up
    text = trimesh.exchange.dae.export_collada(fin).decode()
    assert "<up_axis>Y_UP</up_axis>" in text
    _write(tmp_path / "meshes" / "fin.dae", text.replace("<up_axis>Y_UP</up_axis>", up_axis))
    fin.export(tmp_path / "meshes" / "fin.stl")
    want = _fin_box(read_assets(_fin_robot(tmp_path / "stl", "../meshes/fin.stl")))
    assert np.allclose(want, ((-0.2, -0.01, 0.025), (0.2, 0.01, 0.225)))
    assert _fin_box(read_assets(_fin_robot(tmp_path / "dae", "../meshes/fin.dae"))) == want
    unit = '<unit meter="0.01" name="centimeter"/>'
    _write(tmp_path / "meshes" / "fin_cm.dae", text.replace("<up_axis>Y_UP</up_axis>", unit + up_axis))
    low, high = _fin_box(read_assets(_fin_robot(tmp_path / "cm", "../meshes/fin_cm.dae")))
    assert np.allclose(np.subtract(high, low), [0.004, 0.0002, 0.002])


def test_a_urdf_mesh_named_by_an_absolute_file_uri_is_read(tmp_path):
    """xacro's file://$(find pkg)/meshes/... expands to file:///abs/path: it was refused as
    an absolute path; %-encoded spaces too."""
    from urllib.parse import quote

    (tmp_path / "my meshes").mkdir()
    write_obj(tmp_path / "my meshes" / "leg 2.obj", wedge_mesh(0.2))
    uri = "file://" + quote(str((tmp_path / "my meshes" / "leg 2.obj").resolve()))
    assert "%20" in uri
    for given in (uri, uri.replace("file://", "file://localhost")):
        s = read_assets(_fin_robot(tmp_path / "urdf", given))
        assert sorted(p.kind for p in s.parts.values()) == ["box", "mesh"]
    with pytest.raises(AssetError, match="does not exist"):
        read_assets(_fin_robot(tmp_path / "urdf", uri.replace("leg%202", "leg%203")))


def test_a_urdf_in_a_default_xml_namespace_is_read(tmp_path):
    """<robot xmlns="...">: ROS reads it; procmod said it held no link."""
    write_obj(tmp_path / "fin.obj", wedge_mesh(0.2))
    plain = read_assets(_fin_robot(tmp_path / "a", "../fin.obj"))
    spaced = read_assets(_fin_robot(tmp_path / "b", "../fin.obj", ' xmlns="http://www.ros.org"'))
    assert _fin_box(spaced) == _fin_box(plain)
    commented = _fin_robot(tmp_path / "c", "../fin.obj", ' xmlns="http://www.ros.org"')
    commented.write_text(commented.read_text().replace("<robot", '<!-- <robot xmlns="old"> --><robot', 1))
    assert _fin_box(read_assets(commented)) == _fin_box(plain)  # (h76: a regex took the comment's)


def test_a_robot_drawn_only_by_collision_geometry_is_read_from_it(tmp_path, monkeypatch):
    """Simulators' URDFs (pybullet's, MuJoCo exports) may have only <collision> elements:
    refused as holding no visual geometry. Its collision shapes are its parts now; a robot
    with visuals is read from them alone, as RViz shows it."""
    path = _write(tmp_path / "r.urdf", """<?xml version="1.0"?>
<robot name="r"><link name="base"><collision><geometry><box size="0.4 0.2 0.05"/></geometry></collision></link>
<joint name="j" type="fixed"><parent link="base"/><child link="pole"/><origin xyz="0 0 0.3"/></joint>
<link name="pole"><collision><geometry><cylinder radius="0.02" length="0.5"/></geometry></collision></link></robot>
""")
    s = read_assets(path)
    (base,) = s.assets[0].roots
    assert (base.part, [c.name for c in base.children]) == ("base", ["pole"])
    assert np.allclose(base.children[0].transform[:3, 3], [0, 0, 0.3])
    path.write_text(path.read_text().replace('<link name="pole">', '<link name="pole"><visual><geometry>'
                                             '<sphere radius="0.1"/></geometry></visual>'))
    (pole,) = read_assets(path).assets[0].roots  # visuals present: the collision-only base passes it on
    assert pole.name == "pole" and read_assets(path).parts[pole.part].kind == "mesh"
    path.write_text(path.read_text().replace("<collision>", "<!--").replace("</collision>", "-->")
                    .replace("<visual>", "<!--").replace("</visual>", "-->"))
    with pytest.raises(AssetError, match="holds no visual or collision geometry"):
        read_assets(path)
    # collision elements count against the node limit only when they are read (h78: a robot
    # of 2 visuals and a convex decomposition of 10,000 boxes had been refused)
    monkeypatch.setattr(assets, "MAX_NODES", 6)
    boxes = "".join('<collision><geometry><box size="0.1 0.1 0.1"/></geometry></collision>' for _ in range(8))
    path.write_text(f"""<?xml version="1.0"?>
<robot name="r"><link name="base"><visual><geometry><box size="0.4 0.2 0.05"/></geometry></visual>{boxes}</link></robot>
""")
    assert [n.name for n in read_assets(path).assets[0].nodes()] == ["base"]
    path.write_text(path.read_text().replace('<visual><geometry><box size="0.4 0.2 0.05"/></geometry></visual>', ""))
    with pytest.raises(AssetError, match="no visual geometry and more than 6 links and collision elements"):
        read_assets(path)


@pytest.mark.parametrize("kind, offset", [("revolute", 0.5), ("prismatic", 0.03), ("revolute", 0.0)])
def test_a_mimic_joints_offset_places_its_link_as_robot_state_publisher_does(tmp_path, kind, offset):
    """A joint that mimics another is at multiplier x the other's value + offset (the URDF
    specification): at the zero configuration, its offset. A gripper's second finger that
    mimics the first with an offset had stood at zero (h73)."""
    path = _write(tmp_path / "g.urdf", f"""<?xml version="1.0"?>
<robot name="g"><link name="palm"><visual><geometry><box size="0.1 0.1 0.02"/></geometry></visual></link>
<joint name="f1" type="{kind}"><parent link="palm"/><child link="finger1"/><origin xyz="0.03 0 0.05"/>
  <axis xyz="0 0 2"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<link name="finger1"><visual><geometry><box size="0.01 0.02 0.08"/></geometry></visual></link>
<joint name="f2" type="{kind}"><parent link="palm"/><child link="finger2"/><origin xyz="-0.03 0 0.05"/>
  <axis xyz="0 0 2"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
  <mimic joint="f1" multiplier="-1" offset="{offset}"/></joint>
<link name="finger2"><visual><geometry><box size="0.01 0.02 0.08"/></geometry></visual></link></robot>
""")
    (palm,) = read_assets(path).assets[0].roots
    fingers = {c.name: c.transform for c in palm.children}
    assert np.allclose(fingers["finger1"], T(0.03, 0, 0.05))  # not mimicking: at its zero
    motion = rpy(0, 0, offset) if kind == "revolute" else T(0, 0, offset)  # about / along the (unit) axis
    assert np.allclose(fingers["finger2"], T(-0.03, 0, 0.05) @ motion)
    # a mimic of a mimic: multiplier x the other's value (its own offset) + offset (h87)
    path.write_text(path.read_text().replace("</robot>", f"""<joint name="f3" type="{kind}"><parent link="palm"/>
  <child link="finger3"/><axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>
  <mimic joint="f2" multiplier="2" offset="0.1"/></joint>
<link name="finger3"><visual><geometry><box size="0.01 0.02 0.08"/></geometry></visual></link></robot>"""))
    (palm,) = read_assets(path).assets[0].roots
    third = {c.name: c.transform for c in palm.children}["finger3"]
    assert np.allclose(third, rpy(0, 0, 2 * offset + 0.1) if kind == "revolute" else T(0, 0, 2 * offset + 0.1))
    path.write_text(path.read_text().replace('<mimic joint="f1"', '<mimic joint="f3"'))  # f2 -> f3 -> f2
    with pytest.raises(AssetError, match="joints 'f2', 'f3' mimic one another in a cycle"):
        read_assets(path)


def test_a_long_mimic_chain_a_deep_link_chain_and_a_huge_axis(tmp_path):
    """h90: 600 joints on one base, each mimicking the one before, exceeded Python's
    recursion (a traceback); so did a chain of 500 links without mimics, now refused like a
    glTF hierarchy deeper than MAX_DEPTH; an axis of 1e300s overflowed its length, and its
    mimic offset was dropped with numpy's warnings."""
    links = "".join(f'<link name="l{i}"><visual><geometry><box size="0.01 0.01 0.01"/></geometry></visual></link>'
                    for i in range(601))
    joints = "".join(f'<joint name="j{i}" type="revolute"><parent link="l0"/><child link="l{i}"/><axis xyz="0 0 1"/>'
                     f'<limit lower="-1" upper="1" effort="1" velocity="1"/>'
                     + (f'<mimic joint="j{i - 1}" multiplier="1" offset="0.001"/>' if i > 1 else "") + "</joint>"
                     for i in range(1, 601))
    path = _write(tmp_path / "long.urdf", f'<?xml version="1.0"?><robot name="r">{links}{joints}</robot>')
    (base,) = read_assets(path).assets[0].roots
    last = {c.name: c.transform for c in base.children}["l600"]
    assert np.allclose(last, rpy(0, 0, 0.599))  # 599 mimics of 0.001 each
    deep = "".join(f'<joint name="j{i}" type="fixed"><parent link="l{i - 1}"/><child link="l{i}"/></joint>'
                   for i in range(1, 601))
    with pytest.raises(AssetError, match="the link hierarchy is deeper than 256 levels"):
        read_assets(_write(tmp_path / "deep.urdf", f'<?xml version="1.0"?><robot name="r">{links}{deep}</robot>'))
    huge = _write(tmp_path / "huge.urdf", """<?xml version="1.0"?><robot name="r">
<link name="a"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
<link name="b"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
<link name="c"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
<joint name="j1" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>
  <limit lower="-1" upper="1" effort="1" velocity="1"/></joint>
<joint name="j2" type="revolute"><parent link="a"/><child link="c"/><axis xyz="0 1e300 1e300"/>
  <limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="j1" offset="0.5"/></joint></robot>""")
    import warnings
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy's overflow warning is an error here
        (a,) = read_assets(huge).assets[0].roots
    c = {n.name: n.transform for n in a.children}["c"]
    axis = np.array([0.0, 1.0, 1.0]) / math.sqrt(2.0)
    assert np.allclose(c[:3, :3], Rotation.from_rotvec(0.5 * axis).as_matrix())


def test_two_joints_of_one_name_are_refused_where_joints_mimic(tmp_path):
    """A mimic names the joint it follows, and its value was kept by name: with two joints
    of one name the second took the first's (h93). Such a file is refused where joints
    mimic (ROS's parser refuses it always); without mimics it reads as before."""
    text = """<?xml version="1.0"?><robot name="r">
<link name="a"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
<link name="b"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
<link name="c"><visual><geometry><box size="0.1 0.1 0.1"/></geometry></visual></link>
<joint name="j" type="fixed"><parent link="a"/><child link="b"/></joint>
<joint name="j" type="fixed"><parent link="a"/><child link="c"/></joint></robot>"""
    assert len(read_assets(_write(tmp_path / "plain.urdf", text)).assets[0].roots[0].children) == 2
    mimic = text.replace('<joint name="j" type="fixed"><parent link="a"/><child link="c"/></joint>',
                         '<joint name="j" type="revolute"><parent link="a"/><child link="c"/><axis xyz="0 0 1"/>'
                         '<limit lower="-1" upper="1" effort="1" velocity="1"/><mimic joint="x" offset="0.3"/></joint>')
    with pytest.raises(AssetError, match="two joints are named 'j', and joints mimic others by name"):
        read_assets(_write(tmp_path / "mimic.urdf", mimic))
