"""Small glTF and URDF files for the asset tests, written the way tools write them.

``write_gltf`` writes glTF 2.0 JSON with one embedded (base64) buffer: float32 positions
(with the min / max the spec requires) and uint32 indices per primitive, nodes with a
name, a mesh, children and a matrix or TRS. Malformed files (a cycle, a declared
triangle count no buffer holds) are written by editing the returned JSON.
"""

from __future__ import annotations

import base64
import json

import numpy as np


def gltf_json(meshes, nodes, roots) -> dict:
    """``meshes``: [(name, [(vertices, faces), ...primitives])]; ``nodes``: glTF node dicts."""
    blob, views, accessors, out_meshes = b"", [], [], []
    for name, primitives in meshes:
        prims = []
        for vertices, faces in primitives:
            v = np.asarray(vertices, dtype=np.float32).reshape(-1, 3)
            f = np.asarray(faces, dtype=np.uint32).reshape(-1)
            for data, acc in ((v, {"componentType": 5126, "count": len(v), "type": "VEC3",
                                   "min": np.nan_to_num(v.min(0)).tolist(), "max": np.nan_to_num(v.max(0)).tolist()}),
                              (f, {"componentType": 5125, "count": len(f), "type": "SCALAR"})):
                views.append({"buffer": 0, "byteOffset": len(blob), "byteLength": data.nbytes})
                blob += data.tobytes()
                blob += b"\0" * (-len(blob) % 4)
                accessors.append({"bufferView": len(views) - 1, **acc})
            prims.append({"attributes": {"POSITION": len(accessors) - 2}, "indices": len(accessors) - 1})
        out_meshes.append({"name": name, "primitives": prims})
    return {"asset": {"version": "2.0", "generator": "procmod tests"}, "scene": 0, "scenes": [{"nodes": list(roots)}],
            "nodes": nodes, "meshes": out_meshes, "bufferViews": views, "accessors": accessors,
            "buffers": [{"byteLength": len(blob),
                         "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()}]}


def write_gltf(path, meshes, nodes, roots=(0,)):
    path.write_text(json.dumps(gltf_json(meshes, nodes, roots)))
    return path


def write_glb(path, data: dict):
    """``data`` (from :func:`gltf_json`) as a GLB container: its buffer in the BIN chunk."""
    data = json.loads(json.dumps(data))
    uri = data["buffers"][0].pop("uri")
    blob = base64.b64decode(uri.split(",", 1)[1])
    path.write_bytes(glb_container(data, blob))
    return path


def glb_container(data: dict, blob: bytes) -> bytes:
    """A GLB file of glTF JSON ``data`` and its binary buffer ``blob`` (both chunks padded)."""
    import struct
    text = json.dumps(data).encode()
    text += b" " * (-len(text) % 4)
    blob += b"\0" * (-len(blob) % 4)
    body = struct.pack("<I4s", len(text), b"JSON") + text + struct.pack("<I4s", len(blob), b"BIN\0") + blob
    return struct.pack("<4sII", b"glTF", 2, 12 + len(body)) + body


def box_mesh(size, centre=(0, 0, 0)):
    """Vertices and faces of a box (outward winding)."""
    s = np.asarray(size, dtype=np.float64) / 2
    v = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)]) * s + centre
    f = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1),
         (2, 3, 7), (2, 7, 6), (0, 2, 6), (0, 6, 4), (1, 5, 7), (1, 7, 3)]
    return v, np.array(f)


def wedge_mesh(length=1.0):
    """A mesh with no symmetry a rigid motion could confuse with its mirror image: a box
    with one corner cut off, longer along x."""
    v = np.array([[0, 0, 0], [length, 0, 0], [0, 0.4, 0], [length * 0.6, 0.4, 0],
                  [0, 0, 0.2], [length, 0, 0.2], [0, 0.4, 0.2], [length * 0.6, 0.4, 0.1]], dtype=np.float64)
    f = [(0, 2, 1), (1, 2, 3), (4, 5, 6), (5, 7, 6), (0, 1, 4), (1, 5, 4),
         (2, 6, 3), (3, 6, 7), (0, 4, 2), (2, 4, 6), (1, 3, 5), (3, 7, 5)]
    return v, np.array(f)


def transformed(mesh, m):
    v, f = mesh
    m = np.asarray(m, dtype=np.float64)
    w = v @ m[:3, :3].T + m[:3, 3]
    if np.linalg.det(m[:3, :3]) < 0:  # keep the winding outward
        f = f[:, ::-1]
    return w, f


def column_major(m) -> list:
    return np.asarray(m, dtype=np.float64).T.reshape(-1).tolist()


def urdf(links, joints, name="robot") -> str:
    """``links``: {name: [visual xml, ...]}; ``joints``: [(name, parent, child, xyz, rpy)]."""
    out = [f'<?xml version="1.0" ?>\n<robot name="{name}">']
    for link, visuals in links.items():
        out.append(f'  <link name="{link}">' + "".join(f"<visual>{v}</visual>" for v in visuals) + "</link>")
    for jname, parent, child, xyz, rpy in joints:
        out.append(f'  <joint name="{jname}" type="revolute"><parent link="{parent}"/><child link="{child}"/>'
                   f'<origin xyz="{" ".join(map(str, xyz))}" rpy="{" ".join(map(str, rpy))}"/>'
                   '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>')
    out.append("</robot>")
    return "\n".join(out) + "\n"


def write_obj(path, mesh):
    v, f = mesh
    path.write_text("\n".join([f"v {x!r} {y!r} {z!r}" for x, y, z in np.asarray(v, dtype=float).tolist()] +
                              [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in np.asarray(f)]) + "\n")
    return path


# ---- bad assets, shared by the learn and strings tests -------------------------------------

def write_zero_area_gltf(p, name: str) -> None:
    """A glTF whose only mesh ``name`` is one degenerate triangle."""
    p.write_text(json.dumps(gltf_json([(name, [(np.zeros((3, 3)), [[0, 1, 2]])])], [{"name": "a", "mesh": 0}], [0])))


def write_huge_gltf(p, name: str, mesh) -> None:
    """A glTF whose mesh ``name`` declares 10^7 triangles (its data holds ``mesh``)."""
    data = gltf_json([(name, [mesh])], [{"name": "a", "mesh": 0}], [0])
    data["accessors"][1]["count"] = 3 * 10 ** 7
    p.write_text(json.dumps(data))


def write_empty_gltf(p) -> None:
    """A glTF scene with no nodes."""
    p.write_text(json.dumps({"asset": {"version": "2.0"}, "scenes": [{"nodes": []}], "scene": 0}))


def write_unreadable(p) -> None:
    """Bytes that are no scene at all."""
    p.write_bytes(b"\x89PNG\r\n not a scene at all")
