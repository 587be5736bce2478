"""Mesh files with polygon faces and glTF primitives as exporters write them: concave
n-gons (OBJ, PLY, OFF), binary PLY with faces of mixed corner counts, OFF n-gons, glTF
triangle fans and loose-edge primitives, and glTF extensions procmod cannot honour."""

import json
import math
import re

import numpy as np
import pytest

from asset_writers import box_mesh, gltf_json, write_gltf
from procmod.geometry.assets import AssetError, read_assets
from procmod.geometry.mesh_files import load_mesh_file, normalised_obj
from procmod.geometry.polygons import polygon_triangles, triangulate_faces

# An L-shaped prism, 1 high: its top and bottom are one concave six-cornered face each
# (as Blender's OBJ and PLY exporters keep them). Area 22, volume 5. A fan from the first
# corner of each L covers the inner corner too (area 26).
L_VERTICES = [(3, 0, 0), (3, 1, 0), (1, 1, 0), (1, 3, 0), (0, 3, 0), (0, 0, 0),
              (3, 0, 1), (3, 1, 1), (1, 1, 1), (1, 3, 1), (0, 3, 1), (0, 0, 1)]
L_FACES = [(6, 7, 8, 9, 10, 11), (5, 4, 3, 2, 1, 0), (0, 1, 7, 6), (1, 2, 8, 7), (2, 3, 9, 8), (3, 4, 10, 9),
           (4, 5, 11, 10), (5, 0, 6, 11)]


def _measures(mesh):
    return round(float(mesh.area), 9), round(float(mesh.volume), 9)


def _star(rng, k):
    """A random star-shaped (mostly concave) polygon of k corners in a random plane."""
    angles = (np.arange(k) + rng.uniform(0.1, 0.9, k)) * 2 * np.pi / k  # gaps under pi: the centre sees it all
    radii = rng.uniform(0.2, 1.0, k)
    flat = np.stack([radii * np.cos(angles), radii * np.sin(angles)], axis=1)
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    return flat @ q[:2] + rng.normal(size=3), flat


def test_ear_clipping_covers_a_concave_polygon_exactly_and_keeps_its_winding():
    rng = np.random.default_rng(0)
    fanned_wrong = 0
    for _ in range(200):
        k = int(rng.integers(4, 12))
        points, flat = _star(rng, k)
        x, y = flat[:, 0], flat[:, 1]
        area = 0.5 * abs(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))
        triangles = polygon_triangles(points)
        assert triangles.shape == (k - 2, 3)
        a, b, c = (points[triangles[:, j]] for j in range(3))
        crosses = np.cross(b - a, c - a)
        normal = np.cross(points, np.roll(points, -1, axis=0)).sum(0)
        assert (crosses @ normal > -1e-12).all()  # every triangle wound as the polygon
        assert 0.5 * np.linalg.norm(crosses, axis=1).sum() == pytest.approx(area, rel=1e-9)
        fan = np.array([[0, i, i + 1] for i in range(1, k - 1)])
        fan_area = 0.5 * np.linalg.norm(np.cross(points[fan[:, 1]] - points[fan[:, 0]],
                                                 points[fan[:, 2]] - points[fan[:, 0]]), axis=1).sum()
        fanned_wrong += not np.isclose(fan_area, area, rtol=1e-9)
    assert fanned_wrong > 50  # the case is one where a fan would be wrong


def test_convex_faces_keep_the_fan_and_bad_indices_are_named():
    square = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0.0]])
    assert triangulate_faces(square, [[0, 1, 2, 3]]).tolist() == [[0, 1, 2], [0, 2, 3]]
    with pytest.raises(ValueError, match=r"a face refers to vertex 7 \(counting from 0\), but the file has 4"):
        triangulate_faces(square, [[0, 1, 7]])


def _obj_text(vertices, faces, form="{}"):
    lines = [f"v {x} {y} {z}" for x, y, z in vertices]
    lines += ["f " + " ".join(form.format(i + 1) for i in face) for face in faces]
    return "\n".join(lines) + "\n"


@pytest.mark.parametrize("form", ["{}", "{0}/{0}/{0}", "{0}//{0}"])
def test_an_obj_with_concave_ngons_reads_as_its_shape(tmp_path, form):
    """An L-shaped prism's six-cornered faces were fanned: area 26, not 22."""
    (tmp_path / "l.obj").write_text(_obj_text(L_VERTICES, L_FACES, form)
                                    + "vt 0 0\nvn 0 0 1\n" * len(L_VERTICES))
    mesh = load_mesh_file(tmp_path / "l.obj", force="mesh", process=False)
    assert _measures(mesh) == (22.0, 5.0) and mesh.is_watertight
    # a file of convex faces only is read by trimesh as it is
    assert normalised_obj(_obj_text(*box_mesh((1, 1, 1)))) is None
    quads = "v 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nf 1 2 3 4\n"
    assert normalised_obj(quads) is None


def _ply_bytes(vertices, faces, fmt):
    """A PLY of float vertices and uchar-counted int faces (``fmt``: ascii or a binary order)."""
    header = (f"ply\nformat {fmt} 1.0\nelement vertex {len(vertices)}\nproperty float x\nproperty float y\n"
              f"property float z\nelement face {len(faces)}\nproperty list uchar int vertex_indices\nend_header\n")
    if fmt == "ascii":
        body = "".join(f"{x} {y} {z}\n" for x, y, z in vertices)
        body += "".join(f"{len(f)} " + " ".join(map(str, f)) + "\n" for f in faces)
        return (header + body).encode()
    order = "<" if fmt == "binary_little_endian" else ">"
    body = np.asarray(vertices, dtype=order + "f4").tobytes()
    for f in faces:
        body += np.uint8(len(f)).tobytes() + np.asarray(f, dtype=order + "i4").tobytes()
    return header.encode() + body


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian", "binary_big_endian"])
def test_ply_with_mixed_and_concave_faces_reads_as_its_shape(tmp_path, fmt):
    """A binary PLY whose faces were not all one size was refused ('PLY is unexpected
    length'), an ASCII one's concave faces were fanned."""
    (tmp_path / "l.ply").write_bytes(_ply_bytes(L_VERTICES, L_FACES, fmt))
    assert _measures(load_mesh_file(tmp_path / "l.ply", force="mesh", process=False)) == (22.0, 5.0)
    v, f = box_mesh((1, 2, 3))
    mixed = [tuple(t) for t in f[:2]] + [(4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    (tmp_path / "box.ply").write_bytes(_ply_bytes(v, mixed, fmt))
    assert _measures(load_mesh_file(tmp_path / "box.ply", force="mesh", process=False)) == (22.0, 6.0)
    (tmp_path / "tri.ply").write_bytes(_ply_bytes(v, f, fmt))  # triangles only: the fast path
    assert _measures(load_mesh_file(tmp_path / "tri.ply", force="mesh", process=False)) == (22.0, 6.0)


def test_off_with_ngons_reads_and_bad_off_is_told(tmp_path):
    """An OFF face of five or more corners failed inside numpy."""
    lines = ["OFF", "# an L prism", f"{len(L_VERTICES)} {len(L_FACES)} 0"]
    lines += [f"{x} {y} {z}" for x, y, z in L_VERTICES]
    lines += [f"{len(f)} " + " ".join(map(str, f)) + " 0.5 0.5 0.5" for f in L_FACES]  # colours after the corners
    (tmp_path / "l.off").write_text("\n".join(lines) + "\n")
    assert _measures(load_mesh_file(tmp_path / "l.off", force="mesh", process=False)) == (22.0, 5.0)
    # ModelNet's files run the vertex count on to the keyword ("OFF8 6 0"); they were refused (h63)
    (tmp_path / "modelnet.off").write_text("\n".join([f"OFF{lines[2]}"] + lines[3:]) + "\n")
    assert _measures(load_mesh_file(tmp_path / "modelnet.off", force="mesh", process=False)) == (22.0, 5.0)
    (tmp_path / "short.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n")
    with pytest.raises(ValueError, match="declares 3 vertices and 1 faces but holds 2 lines"):
        load_mesh_file(tmp_path / "short.off", force="mesh", process=False)
    (tmp_path / "bad.off").write_text("OFF\n3 1 0\n0 0 0\n1 0 0\n0 1 0\n4 0 1 2\n")
    with pytest.raises(ValueError, match="face 0 of the OFF file names 4 corners but lists 3"):
        load_mesh_file(tmp_path / "bad.off", force="mesh", process=False)


def _pyramid_fan_gltf(path, with_box: bool, lines: bool = False):
    """A mesh whose pyramid is drawn as two triangle fans (mode 6): apex fan + base fan;
    with a box as a triangle list beside it, and optionally a lines primitive."""
    box_v, box_f = box_mesh((1, 1, 1), centre=(3, 0.5, 0.5))
    data = gltf_json([("thing", [(box_v, box_f)] * (1 if with_box else 0) + [(np.zeros((3, 3)), [0, 1, 2])] * 2)],
                     [{"name": "Thing", "mesh": 0}], (0,))
    apex = [(0.5, 1, 0.5), (0, 0, 0), (0, 0, 1), (1, 0, 1), (1, 0, 0), (0, 0, 0)]  # apex, then the base ring
    base = [(0, 0, 0), (1, 0, 0), (1, 0, 1), (0, 0, 1)]
    import base64
    blob = base64.b64decode(data["buffers"][0]["uri"].split(",", 1)[1])
    prims = data["meshes"][0]["primitives"]
    for prim, fan_points in zip(prims[-2:], (apex, base)):
        v = np.asarray(fan_points, dtype=np.float32)
        data["bufferViews"].append({"buffer": 0, "byteOffset": len(blob), "byteLength": v.nbytes})
        blob += v.tobytes()
        data["accessors"].append({"bufferView": len(data["bufferViews"]) - 1, "componentType": 5126,
                                  "count": len(v), "type": "VEC3", "min": v.min(0).tolist(), "max": v.max(0).tolist()})
        prim.clear()
        prim.update(attributes={"POSITION": len(data["accessors"]) - 1}, mode=6)  # non-indexed fan
    if lines:
        prims.append({"attributes": {"POSITION": prims[0]["attributes"]["POSITION"]}, "mode": 1})
    data["buffers"][0] = {"byteLength": len(blob),
                          "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}
    path.write_text(json.dumps(data))
    return path


def test_gltf_triangle_fans_are_read(tmp_path):
    """trimesh dropped TRIANGLE_FAN primitives: a pyramid of fans was missing from its mesh."""
    mesh = load_mesh_file(_pyramid_fan_gltf(tmp_path / "pyr.gltf", with_box=False), force="mesh", process=False)
    assert len(mesh.faces) == 6 and mesh.volume == pytest.approx(1 / 3)
    both = load_mesh_file(_pyramid_fan_gltf(tmp_path / "both.gltf", with_box=True), force="mesh", process=False)
    assert len(both.faces) == 18 and both.volume == pytest.approx(1 + 1 / 3)
    parts = read_assets(tmp_path / "both.gltf").parts
    assert len(parts["thing"].faces) == 18


def test_a_mesh_with_a_lines_primitive_is_a_part(tmp_path):
    """learn refused a mesh whose triangles came with a loose-edges (lines) primitive:
    'holds no mesh'."""
    path = _pyramid_fan_gltf(tmp_path / "edges.gltf", with_box=True, lines=True)
    asset_set = read_assets(path)
    assert len(asset_set.parts["thing"].faces) == 18 and asset_set.assets[0].roots[0].name == "Thing"


@pytest.mark.parametrize("extension, used_only, message", [
    # (EXT_mesh_gpu_instancing is read now, its instances expanded: tests/test_3d_sweep35.py)
    ("ACME_mesh_warp", False, "requires the glTF extension ACME_mesh_warp, which procmod does not read"),
])
def test_gltf_extensions_procmod_cannot_honour_are_refused(tmp_path, extension, used_only, message):
    """A required extension that changes geometry was ignored."""
    data = gltf_json([("box", [box_mesh((1, 1, 1))])], [{"name": "Box", "mesh": 0}], (0,))
    data["extensionsUsed"] = [extension]
    if not used_only:
        data["extensionsRequired"] = [extension]
    (tmp_path / "x.gltf").write_text(json.dumps(data))
    with pytest.raises(ValueError, match=message):
        load_mesh_file(tmp_path / "x.gltf", force="mesh", process=False)
    with pytest.raises(AssetError, match=message):
        read_assets(tmp_path / "x.gltf")
    # extensions for materials, textures or metadata change no geometry: read as before
    data["extensionsUsed"] = data["extensionsRequired"] = ["KHR_materials_unlit", "MSFT_texture_dds",
                                                           "EXT_mesh_features"]
    write = tmp_path / "unlit.gltf"
    write.write_text(json.dumps(data))
    assert len(load_mesh_file(write, force="mesh", process=False).faces) == 12


def test_write_gltf_helper_unchanged(tmp_path):
    """The writer the other asset tests use still writes a plain triangle list."""
    path = write_gltf(tmp_path / "b.gltf", [("box", [box_mesh((1, 1, 1))])], [{"name": "Box", "mesh": 0}])
    assert len(load_mesh_file(path, force="mesh", process=False).faces) == 12


def test_obj_mistakes_are_said_plainly(tmp_path):
    """trimesh said "index 98 is out of bounds for axis 0 with size 12" and "string or
    file could not be read to its end due to unmatched data"."""
    (tmp_path / "ref.obj").write_text(_obj_text(L_VERTICES, L_FACES + [(0, 1, 98)]))
    with pytest.raises(ValueError, match="line 21 names vertex 99, but the file has 12 vertices"):
        load_mesh_file(tmp_path / "ref.obj", force="mesh", process=False)
    (tmp_path / "comma.obj").write_text("v 0,0 0,0 0,5\nv 1,0 0,0 0,0\nv 0,0 1,0 0,0\nf 1 2 3\n")
    with pytest.raises(ValueError, match=r"line 1 \('v 0,0 0,0 0,5'\) writes numbers with decimal commas"):
        load_mesh_file(tmp_path / "comma.obj", force="mesh", process=False)


def test_an_obj_vertex_of_two_numbers_is_refused_and_whole_float_indices_are_read(tmp_path):
    """One stray "v 5 5" line made trimesh read every vertex of the file as two numbers,
    and reading the mesh failed with numpy's "axis 1 is out of bounds" (exit 1); faces
    indexed "1.0 2.0 3.0" (a script's exporter) were refused in trimesh's words (h112)."""
    box = _obj_text(*box_mesh((1, 1, 1)))
    (tmp_path / "two.obj").write_text(box + "v 5 5\n")
    with pytest.raises(ValueError, match=r"line 21 \('v 5 5'\) gives a vertex 2 coordinates, but an OBJ vertex "
                                         r"takes three \(x y z\)"):
        load_mesh_file(tmp_path / "two.obj", force="mesh", process=False)
    whole = "\n".join(re.sub(r"(?<=[ /])(\d+)(?=[ /]|$)", r"\1.0", line) if line.startswith("f ") else line
                      for line in box.splitlines()) + "\n"
    assert "f 1.0 " in whole
    (tmp_path / "whole.obj").write_text(whole)
    mesh = load_mesh_file(tmp_path / "whole.obj", force="mesh", process=False)
    assert len(mesh.faces) == 12 and mesh.volume == pytest.approx(1.0)
    # counted from 0 in floats: refused as counted from 0 (the float check had let "0.0" through, h117)
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0.0 1.0 2.0\n")
    with pytest.raises(ValueError, match=r"line 4 .* names vertex 0, but OBJ numbers vertices from 1"):
        load_mesh_file(tmp_path / "zero.obj", force="mesh", process=False)
    (tmp_path / "commas.obj").write_text("v 0,0,0\nv 1,0,0\nv 0,1,0\nf 1 2 3\n")
    with pytest.raises(ValueError, match=r"line 1 \('v 0,0,0'\) separates its numbers with commas"):
        load_mesh_file(tmp_path / "commas.obj", force="mesh", process=False)


@pytest.mark.parametrize("face", ["f 0 1 2", "f 00/1 1/2 2/3", "f -0 1 2"])
def test_an_obj_counted_from_0_is_refused_not_read_with_its_0_as_the_last_vertex(tmp_path, face):
    """A script's own exporter writes OBJ faces counted from 0; trimesh read each 0 as
    the last vertex without a word, and a target voxelised to 37% of its volume (h63)."""
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvt 1 0\nvt 0 1\n"
                                       "f 1 2 4\n" + face + "\n")
    with pytest.raises(ValueError, match="line 9 .* names vertex 0, but OBJ numbers vertices from 1 .*counts from 0"):
        load_mesh_file(tmp_path / "zero.obj", force="mesh", process=False)


def test_an_obj_whose_0_is_no_part_of_its_faces_geometry_is_read(tmp_path):
    """A texture coordinate or normal 0 (in a file with none), or a line to vertex 0, is
    no part of the geometry read: such files read right before the refusal of faces
    counted from 0, and still do (h65)."""
    (tmp_path / "zero.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1/0/0 2/0/0 3/0/0\n"
                                       "f 1//0 2//0 4//0\nl 0 1\n")
    assert len(load_mesh_file(tmp_path / "zero.obj", force="mesh", process=False).faces) == 2


def test_review_cases_repeated_corners_lines_and_a_byte_order_mark(tmp_path):
    """A face closed with its first corner again fell back to the fan; an OBJ whose loose
    line named a missing vertex was refused (trimesh ignores lines); an OFF file with a
    UTF-8 byte-order mark was refused; comma-separated numbers were called decimal commas."""
    closed = [tuple(f) + (f[0],) if len(f) == 6 else f for f in L_FACES]  # the L's faces end where they began
    (tmp_path / "closed.obj").write_text(_obj_text(L_VERTICES, closed) + "l 1 99\n")
    assert _measures(load_mesh_file(tmp_path / "closed.obj", force="mesh", process=False)) == (22.0, 5.0)
    lines = ["OFF", f"{len(L_VERTICES)} {len(L_FACES)} 0"] + [f"{x} {y} {z}" for x, y, z in L_VERTICES]
    lines += [f"{len(f)} " + " ".join(map(str, f)) for f in L_FACES]
    (tmp_path / "bom.off").write_bytes(b"\xef\xbb\xbf" + "\n".join(lines).encode())
    assert _measures(load_mesh_file(tmp_path / "bom.off", force="mesh", process=False)) == (22.0, 5.0)
    (tmp_path / "sep.obj").write_text("v 0.0, 0.0, 0.0\nv 1.0, 0.0, 0.0\nv 0.0, 1.0, 0.0\nf 1 2 3\n")
    with pytest.raises(ValueError, match="separates its numbers with commas"):
        load_mesh_file(tmp_path / "sep.obj", force="mesh", process=False)


def test_a_notch_of_short_edges_in_a_long_face_is_concave(tmp_path):
    """Corners were judged against the face's longest edge: a letter's inner curve (7.5
    degrees a corner on short edges) or a V notch in a long strip read as convex, and the
    fan covered the notch (a silhouette of an arch had its notch filled)."""
    notch = [(0, 0, 0), (10, 0, 0), (10, 1, 0), (5.1, 1, 0), (5, 0.8, 0), (4.9, 1, 0), (0, 1, 0)]
    (tmp_path / "v.obj").write_text(_obj_text(notch, [range(7)]))
    assert load_mesh_file(tmp_path / "v.obj", force="mesh", process=False).area == pytest.approx(9.98)
    arch = [(-2, 0, 0), (-1, 0, 0)] + [(-math.cos(a), math.sin(a), 0) for a in np.linspace(0, math.pi, 25)[1:-1]] \
        + [(1, 0, 0), (2, 0, 0), (2, 2, 0), (-2, 2, 0)]
    (tmp_path / "arch.obj").write_text(_obj_text(arch, [range(len(arch))]))
    area = load_mesh_file(tmp_path / "arch.obj", force="mesh", process=False).area
    segment = 0.5 * 24 * math.sin(math.pi / 24)  # the notch: a half 48-gon of radius 1
    assert area == pytest.approx(8 - segment)


def _collada(unit: float, up: str, matrix: str = "") -> str:
    """The L prism as one COLLADA polylist of six- and four-cornered polygons."""
    points = " ".join(f"{x} {y} {z}" for x, y, z in L_VERTICES)
    corners = " ".join(str(i) for f in L_FACES for i in f)
    return f"""<?xml version="1.0" encoding="utf-8"?>
<COLLADA xmlns="http://www.collada.org/2005/11/COLLADASchema" version="1.4.1">
<asset><unit name="u" meter="{unit}"/><up_axis>{up}</up_axis></asset>
<library_geometries><geometry id="g" name="L"><mesh>
<source id="p"><float_array id="pa" count="{3 * len(L_VERTICES)}">{points}</float_array>
<technique_common><accessor source="#pa" count="{len(L_VERTICES)}" stride="3"><param name="X" type="float"/>
<param name="Y" type="float"/><param name="Z" type="float"/></accessor></technique_common></source>
<vertices id="v"><input semantic="POSITION" source="#p"/></vertices>
<polylist count="{len(L_FACES)}"><input semantic="VERTEX" source="#v" offset="0"/>
<vcount>{" ".join(str(len(f)) for f in L_FACES)}</vcount><p>{corners}</p></polylist>
</mesh></geometry></library_geometries>
<library_visual_scenes><visual_scene id="s"><node id="n" name="n">{matrix}<instance_geometry url="#g"/></node>
</visual_scene></library_visual_scenes><scene><instance_visual_scene url="#s"/></scene></COLLADA>
"""


def test_collada_polygons_units_and_up_axis_are_honoured(tmp_path):
    """pycollada's fan (through trimesh) covered the L's inner corner, and a file's <unit>
    and <up_axis> were ignored: Blender's export (z up) lay on its back beside its glTF."""
    (tmp_path / "y.dae").write_text(_collada(1.0, "Y_UP"))
    mesh = load_mesh_file(tmp_path / "y.dae", force="mesh", process=False)
    assert _measures(mesh) == (22.0, 5.0) and np.allclose(mesh.bounds, [[0, 0, 0], [3, 3, 1]])
    (tmp_path / "z.dae").write_text(_collada(0.01, "Z_UP"))  # centimetres, z up
    mesh = load_mesh_file(tmp_path / "z.dae", force="mesh", process=False)
    assert np.allclose(mesh.bounds, [[0, 0, -0.03], [0.03, 0.01, 0]])  # (x, y, z) -> (x, z, -y), in metres
    robot = load_mesh_file(tmp_path / "z.dae", up="z", force="mesh", process=False)  # a URDF's links are z up
    assert np.allclose(robot.bounds, [[0, 0, 0], [0.03, 0.03, 0.01]])
    # a node mirrored by a negative scale came in inside out (signed volume -5)
    (tmp_path / "m.dae").write_text(_collada(1.0, "Y_UP", "<matrix>-1 0 0 0 0 1 0 0 0 0 1 0 0 0 0 1</matrix>"))
    assert load_mesh_file(tmp_path / "m.dae", force="mesh", process=False).volume == pytest.approx(5.0)


def test_second_review_cases(tmp_path):
    """A concave face whose reflex corner is written twice was fanned (the turn across
    the repeat was never measured); a spike that earcut leaves out (a zero-area triangle)
    made the face fall back to the fan; an OBJ of faces and no vertices said nothing."""
    ell = np.array([(2, 0, 0), (2, 1, 0), (1, 1, 0), (1, 2, 0), (0, 2, 0), (0, 0, 0)], dtype=float)

    def covered(points, triangles):
        a, b, c = (points[triangles[:, j]] for j in range(3))
        return 0.5 * np.linalg.norm(np.cross(b - a, c - a), axis=1).sum()
    twice = np.insert(ell, 3, ell[2], axis=0)  # the reflex corner (1, 1) twice
    assert covered(twice, triangulate_faces(twice, [np.arange(7)])) == pytest.approx(3.0)
    (tmp_path / "unwelded.obj").write_text("v 0 0 0\nv 2 0 0\nv 2 1 0\nv 1 1 0\nv 1 2 0\nv 0 2 0\nv 1 1 0\n"
                                           "f 2 3 4 7 5 6 1\n")  # 4 and 7 at one place
    assert load_mesh_file(tmp_path / "unwelded.obj", force="mesh", process=False).area == pytest.approx(3.0)
    spike = np.insert(ell, 3, [(1.5, 1.5, 0), (1, 1, 0)], axis=0)  # out into the notch and back
    triangles = triangulate_faces(spike, [np.arange(8)])
    assert covered(spike, triangles) == pytest.approx(3.0)
    (tmp_path / "faces.obj").write_text("f 1 2 3 4\n")
    with pytest.raises(ValueError, match="line 1 names vertex 4, but the file has 0 vertices"):
        load_mesh_file(tmp_path / "faces.obj", force="mesh", process=False)


@pytest.mark.parametrize("fmt", ["ascii", "binary_little_endian"])
def test_a_ply_of_triangle_strips_reads_as_its_shape(tmp_path, fmt):
    """The Stanford scanning repository's older models and range-scan tools write faces as
    a `tristrips` element (strips separated by -1, every other triangle turned the other
    way); trimesh reads none, and procmod refused such a file as holding no triangle
    faces. A unit cube in two strips, with a stitch between them, reads as a closed cube
    facing out."""
    from plyfile import PlyData, PlyElement

    corners = np.array([(x, y, z) for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float32)
    # the four sides round the cube, then the top and the bottom: two strips in one row
    sides = [0, 4, 1, 5, 3, 7, 2, 6, 0, 4]
    ends = [4, 6, 5, 7, -1, 0, 1, 2, 3]
    vertex = np.array([tuple(c) for c in corners], dtype=[("x", "f4"), ("y", "f4"), ("z", "f4")])
    strips = np.array([(np.array(sides + [-1] + ends, dtype=np.int32),)], dtype=[("vertex_indices", "O")])
    PlyData([PlyElement.describe(vertex, "vertex"), PlyElement.describe(strips, "tristrips",
                                                                        val_types={"vertex_indices": "i4"})],
            text=(fmt == "ascii"), byte_order="<").write(str(tmp_path / "cube.ply"))
    mesh = load_mesh_file(tmp_path / "cube.ply")
    assert len(mesh.faces) == 12 and mesh.is_watertight and mesh.is_winding_consistent
    assert mesh.volume == pytest.approx(1.0) and mesh.area == pytest.approx(6.0)  # facing out, every side once
