"""Vertex positions trimesh reads wrongly from a glTF, decoded here before it reads them.

trimesh 4-5 reads an accessor's bytes as they lie, so two kinds of POSITION accessor that
real exporters write came out wrong:

* **Normalized integers** (``KHR_mesh_quantization``, as ``gltf-transform quantize`` and
  other web pipelines write): glTF 2.0 maps a normalized ``SHORT`` ``c`` to
  ``max(c / 32767, -1)``, ``UNSIGNED_SHORT`` to ``c / 65535``, ``BYTE`` to ``max(c / 127,
  -1)``, ``UNSIGNED_BYTE`` to ``c / 255``; trimesh took ``c`` itself, tens of thousands of
  times too large.
* **Sparse accessors**: the accessor's values (from its ``bufferView``, or zeros without
  one) with ``sparse.count`` of them replaced at ``sparse.indices``; trimesh ignored the
  replacements, and an accessor with no ``bufferView`` read as all zeros.

trimesh also reads a node drawn as **GPU instances** (``EXT_mesh_gpu_instancing``: Blender's
"GPU Instances" export, ``gltfpack -mi``; a forest of one tree mesh) as its mesh once, at the
node; the other copies vanished. Each instance becomes a node of its own under the
instancing node (:func:`expanded_instances`), placed by its ``TRANSLATION``, ``ROTATION``
and ``SCALE`` as the extension says (world = node's world x T x R x S), so that every
reader of the file sees the copies as separate placed parts.

And trimesh reads a mesh at rest, where viewers show it **morphed** (its morph targets at
their weights: Blender's shape keys as set) and **posed** (a skinned mesh by its joints).

:func:`decoded_gltf` rewrites each such accessor as plain ``FLOAT`` data in a buffer of
its own (a ``data:`` URI), gives a morphed or posed primitive the positions shown, and
each triangle fan as a triangle list (trimesh dropped fans), and returns the glTF JSON,
which trimesh then reads as usual (the file is left as it is). Everything else — other
buffers, images, the node tree — is as the file has it.
"""

from __future__ import annotations

import base64
import copy
import json
import struct
from pathlib import Path

import numpy as np

from ..core.limits import check_memory

# glTF 2.0 accessor.componentType -> little-endian numpy dtype
COMPONENT_TYPES = {5120: "<i1", 5121: "<u1", 5122: "<i2", 5123: "<u2", 5125: "<u4", 5126: "<f4"}
# what a normalized integer is divided by (signed ones are then clamped at -1)
NORMALIZED_DIVISOR = {5120: 127.0, 5121: 255.0, 5122: 32767.0, 5123: 65535.0}
COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}  # MAT4: float, column-major
SPARSE_INDEX_TYPES = (5121, 5123, 5125)


def _positions(header: dict) -> set[int]:
    """The accessors meshes use as POSITION (morph targets included)."""
    found = set()
    for mesh in header.get("meshes") or ():
        for primitive in (mesh.get("primitives") or ()) if isinstance(mesh, dict) else ():
            if not isinstance(primitive, dict):
                continue
            sets = [primitive.get("attributes") or {}] + list(primitive.get("targets") or ())
            for attributes in sets:
                index = attributes.get("POSITION") if isinstance(attributes, dict) else None
                if isinstance(index, int) and not isinstance(index, bool):
                    found.add(index)
    return found


def needs_decoding(header: dict) -> list[int]:
    """The POSITION accessors trimesh would misread: normalized integers, or sparse."""
    accessors = header.get("accessors") or []
    chosen = []
    for index in sorted(_positions(header)):
        if not 0 <= index < len(accessors) or not isinstance(accessors[index], dict):
            continue
        accessor = accessors[index]
        normalized = accessor.get("normalized") is True and accessor.get("componentType") in NORMALIZED_DIVISOR
        if normalized or "sparse" in accessor:
            chosen.append(index)
    return chosen


TRIANGLE_FAN = 6


def fan_primitives(header: dict) -> list[tuple[int, int]]:
    """``(mesh, primitive)`` of each TRIANGLE_FAN primitive (mode 6), which trimesh drops
    without a word (a pyramid drawn as fans was missing from its mesh)."""
    found = []
    for m, mesh in enumerate(header.get("meshes") or ()):
        for p, primitive in enumerate((mesh.get("primitives") or ()) if isinstance(mesh, dict) else ()):
            if isinstance(primitive, dict) and primitive.get("mode") == TRIANGLE_FAN:
                found.append((m, p))
    return found


def _fan_triangles(header: dict, buffers: list, primitive: dict, what: str) -> np.ndarray:
    """The triangle-list indices of a fan primitive: (v0, vk, vk+1) for each k."""
    if "indices" in primitive:
        index = primitive["indices"]
        if not isinstance(index, int) or not 0 <= index < len(header.get("accessors") or ()):
            raise ValueError(f"{what} names indices accessor {index!r}, which the file does not have")
        corners = accessor_values(header, buffers, index)[:, 0].astype(np.int64)
    else:
        position = (primitive.get("attributes") or {}).get("POSITION")
        accessors = header.get("accessors") or []
        if not isinstance(position, int) or not 0 <= position < len(accessors):
            raise ValueError(f"{what} has no POSITION accessor")
        corners = np.arange(int(accessors[position].get("count", 0)), dtype=np.int64)
    if len(corners) < 3:
        return np.zeros(0, dtype=np.uint32)
    k = np.arange(1, len(corners) - 1)
    return np.stack([np.full_like(k, corners[0]), corners[k], corners[k + 1]], axis=1).astype("<u4").ravel()


def _view_bytes(header: dict, buffers: list, view_index, what: str) -> tuple[bytes, int]:
    """The bytes of a bufferView (and its byteStride, 0 if tight)."""
    views = header.get("bufferViews") or []
    if not isinstance(view_index, int) or not 0 <= view_index < len(views) or not isinstance(views[view_index], dict):
        raise ValueError(f"{what} names bufferView {view_index!r}, which the file does not have")
    view = views[view_index]
    buffer_index, offset, length = view.get("buffer"), view.get("byteOffset", 0), view.get("byteLength")
    if not isinstance(buffer_index, int) or not 0 <= buffer_index < len(buffers):
        raise ValueError(f"bufferView {view_index} names buffer {buffer_index!r}, which the file does not have")
    data = buffers[buffer_index]
    if not (isinstance(offset, int) and isinstance(length, int) and 0 <= offset and offset + length <= len(data)):
        raise ValueError(f"bufferView {view_index} reaches past the end of buffer {buffer_index}")
    stride = view.get("byteStride", 0)
    return data[offset:offset + length], stride if isinstance(stride, int) and stride > 0 else 0


def _read_elements(data: bytes, offset, count: int, dtype: np.dtype, width: int, stride: int, what: str):
    """``count`` elements of ``width`` components from ``data``, ``stride`` bytes apart."""
    element = dtype.itemsize * width
    stride = stride or element
    if not isinstance(offset, int) or offset < 0 or (count and offset + (count - 1) * stride + element > len(data)):
        raise ValueError(f"{what} reaches past the end of its bufferView")
    if count == 0:
        return np.zeros((0, width), dtype)
    raw = np.frombuffer(data, np.uint8, count=(count - 1) * stride + element, offset=offset)
    rows = np.lib.stride_tricks.as_strided(raw, (count, element), (stride, 1))
    return np.ascontiguousarray(rows).view(dtype).reshape(count, width)


def accessor_values(header: dict, buffers: list, index: int) -> np.ndarray:
    """An accessor's values as float64, ``(count, components)``: normalized integers mapped
    as glTF says and sparse replacements applied."""
    accessor = header["accessors"][index]
    what = f"accessor {index}"
    kind, width = accessor.get("componentType"), COMPONENTS.get(accessor.get("type"))
    count = accessor.get("count")
    if kind not in COMPONENT_TYPES or width is None or not isinstance(count, int) or count < 0:
        raise ValueError(f"{what} has a componentType, type or count glTF 2.0 does not define")
    dtype = np.dtype(COMPONENT_TYPES[kind])
    if "bufferView" in accessor:
        data, stride = _view_bytes(header, buffers, accessor["bufferView"], what)
        values = _read_elements(data, accessor.get("byteOffset", 0), count, dtype, width, stride, what)
    else:
        # glTF: a sparse accessor without a bufferView starts at zero; its count is bounded
        # by no data in the file, only by memory
        check_memory(f"{what} of {count:,} elements", count * width * 8 * 3)
        values = np.zeros((count, width), dtype)
    values = values.copy()
    sparse = accessor.get("sparse")
    if sparse is not None:
        if not isinstance(sparse, dict) or not isinstance(sparse.get("indices"), dict) \
                or not isinstance(sparse.get("values"), dict):
            raise ValueError(f"{what}.sparse needs 'count', 'indices' and 'values'")
        replaced = sparse.get("count")
        indices = sparse["indices"]
        if not isinstance(replaced, int) or not 0 < replaced <= count \
                or indices.get("componentType") not in SPARSE_INDEX_TYPES:
            raise ValueError(f"{what}.sparse has a count or an index componentType glTF 2.0 does not allow")
        data, _ = _view_bytes(header, buffers, indices.get("bufferView"), f"{what}.sparse.indices")
        where = _read_elements(data, indices.get("byteOffset", 0), replaced,
                               np.dtype(COMPONENT_TYPES[indices["componentType"]]), 1, 0,
                               f"{what}.sparse.indices")[:, 0].astype(np.int64)
        if where.size and where.max() >= count:
            raise ValueError(f"{what}.sparse replaces element {int(where.max())}, past its count {count}")
        data, _ = _view_bytes(header, buffers, sparse["values"].get("bufferView"), f"{what}.sparse.values")
        values[where] = _read_elements(data, sparse["values"].get("byteOffset", 0), replaced, dtype, width, 0,
                                       f"{what}.sparse.values")
    out = values.astype(np.float64)
    if accessor.get("normalized") is True and kind in NORMALIZED_DIVISOR:
        out /= NORMALIZED_DIVISOR[kind]
        if dtype.kind == "i":
            np.maximum(out, -1.0, out=out)
    return out


# ---- GPU instances (EXT_mesh_gpu_instancing): one node per instance ---------------------------

INSTANCING = "EXT_mesh_gpu_instancing"
_INSTANCE_WIDTHS = {"TRANSLATION": 3, "ROTATION": 4, "SCALE": 3}
BYTES_PER_INSTANCE = 4096
"""Memory an expanded instance costs at least besides its mesh's copy: its node in the JSON and in
trimesh's scene graph, its transform (measured: ~3-5 KB a node in trimesh 4-5)."""


def _instancing(node) -> dict | None:
    """A node's ``EXT_mesh_gpu_instancing`` object (None without one)."""
    extensions = node.get("extensions") if isinstance(node, dict) else None
    spec = extensions.get(INSTANCING) if isinstance(extensions, dict) else None
    return spec if isinstance(spec, dict) else None


def instanced_nodes(header: dict) -> list[int]:
    """The nodes that draw their mesh as GPU instances (``EXT_mesh_gpu_instancing``)."""
    return [n for n, node in enumerate(header.get("nodes") or ())
            if _instancing(node) is not None and isinstance(node.get("mesh"), int)
            and not isinstance(node.get("mesh"), bool)]


def instance_count(header: dict, node: int) -> int:
    """The instances node ``node`` draws, as its accessors' ``count`` says (read without
    decoding; 1 for a node without the extension or whose count cannot be told): the
    largest, an upper bound for the limits checked with it (the first had been taken, and a
    custom ``_ID`` of 2 listed before a TRANSLATION of millions let those past them)."""
    spec = _instancing((header.get("nodes") or [])[node])
    attributes = spec.get("attributes") if spec is not None else None
    accessors = header.get("accessors") or []
    counts = []
    for index in (attributes.values() if isinstance(attributes, dict) else ()):
        if isinstance(index, int) and 0 <= index < len(accessors) and isinstance(accessors[index], dict):
            count = accessors[index].get("count")
            if isinstance(count, int) and not isinstance(count, bool) and count >= 0:
                counts.append(count)
    return max(counts) if counts else 1


def instance_matrices(header: dict, buffers: list, node: int) -> np.ndarray:
    """The ``(count, 4, 4)`` transforms of node ``node``'s GPU instances, each T x R x S of
    its ``TRANSLATION``, ``ROTATION`` (a quaternion x, y, z, w; floats, or normalized
    bytes or shorts as the extension allows) and ``SCALE``, each optional (identity, no
    turn, unit scale without it), in the node's frame. Raises ValueError for accessors that
    are missing, of another shape, of different counts or not finite."""
    from scipy.spatial.transform import Rotation

    attributes = _instancing(header["nodes"][node]).get("attributes")
    attributes = attributes if isinstance(attributes, dict) else {}
    accessors = header.get("accessors") or []
    what = f"node {node}'s {INSTANCING}"
    values = {}
    for name, width in _INSTANCE_WIDTHS.items():
        index = attributes.get(name)
        if index is None:
            continue
        if isinstance(index, bool) or not isinstance(index, int) or not 0 <= index < len(accessors) \
                or not isinstance(accessors[index], dict):
            raise ValueError(f"{what} {name} names accessor {index!r}, which the file does not have")
        read = accessor_values(header, buffers, index)
        if read.shape[1] != width:
            raise ValueError(f"{what} {name} is accessor {index} of {read.shape[1]} numbers an instance, not {width}")
        if not np.isfinite(read).all():
            raise ValueError(f"{what} {name} holds a number that is not finite (NaN or infinity)")
        values[name] = read
    counts = {len(v) for v in values.values()}
    if len(counts) > 1:
        raise ValueError(f"{what} accessors give different instance counts ({', '.join(map(str, sorted(counts)))})")
    count = counts.pop() if counts else instance_count(header, node)  # (only custom attributes: placed at the node)
    out = np.tile(np.eye(4), (count, 1, 1))
    if "ROTATION" in values:
        quaternions = values["ROTATION"]
        norms = np.linalg.norm(quaternions, axis=1)
        turned = norms > 0  # a zero quaternion (a padding row) turns nothing
        out[turned, :3, :3] = Rotation.from_quat(quaternions[turned] / norms[turned, None]).as_matrix()
    if "SCALE" in values:
        out[:, :3, :3] *= values["SCALE"][:, None, :]  # R x S: S scales R's columns
    if "TRANSLATION" in values:
        out[:, :3, 3] = values["TRANSLATION"]
    return out


def expanded_instances(header: dict, buffers: list, required: bool) -> dict:
    """``header`` with each GPU-instanced node (:func:`instanced_nodes`) made an empty whose
    children are its instances: a node each, drawing its mesh under the instance's
    transform (:func:`instance_matrices`) and named after it with the tool's numbering of
    copies (``Tree.001``, ``Tree.002``: an unnamed node's after its mesh). The extension is
    gone from the copy. Instances that cannot be read raise ValueError where the file
    requires the extension (``required``); otherwise the node draws its mesh once, as a
    reader without the extension does. Refuses instances past the machine's memory
    (:func:`~procmod.core.limits.check_memory`) before any is made."""
    chosen = instanced_nodes(header)
    total = sum(instance_count(header, n) for n in chosen)
    meshes = header.get("meshes") or []
    check_memory(f"expanding its {total:,} GPU instances ({INSTANCING})", total * BYTES_PER_INSTANCE,
                 "export it with fewer instances")
    out = copy.deepcopy(header)
    for name in ("extensionsUsed", "extensionsRequired"):
        if isinstance(out.get(name), list):
            out[name] = [e for e in out[name] if e != INSTANCING]
            if not out[name]:
                del out[name]
    nodes = out["nodes"]
    for n, node in enumerate(nodes):
        if _instancing(node) is not None:  # (on a node without a mesh it means nothing)
            del node["extensions"][INSTANCING]
    for n in chosen:
        try:
            matrices = instance_matrices(header, buffers, n)
        except ValueError as exc:
            if required:
                raise ValueError(f"its GPU instances ({INSTANCING}, which it requires) cannot be read: {exc}; export "
                                 "it again, or without GPU instances (Blender: glTF export > Data > Scene Graph > "
                                 "GPU Instances off; gltfpack without -mi)") from None
            continue  # drawn once, at the node, as a reader without the extension draws it
        node = nodes[n]
        mesh = node.pop("mesh")
        given = node.get("name")
        mesh_name = meshes[mesh].get("name") if 0 <= mesh < len(meshes) and isinstance(meshes[mesh], dict) else None
        base = given if isinstance(given, str) and given else mesh_name if isinstance(mesh_name, str) else ""
        shown = {key: node.pop(key) for key in ("weights", "skin") if key in node}  # the mesh's, drawn by the copies
        first = len(nodes)
        for k, m in enumerate(matrices):
            copy_ = {"mesh": mesh, "matrix": m.T.reshape(16).tolist(), **shown}  # glTF: column-major
            if base:
                copy_["name"] = f"{base}.{k + 1:03d}"
            nodes.append(copy_)
        children = node.get("children")
        node["children"] = list(range(first, len(nodes))) + (children if isinstance(children, list) else [])
    return out


# ---- morph targets and skins: the shape a viewer shows, not the mesh at rest -------------------

def _drawing_nodes(header: dict) -> dict:
    """mesh index -> the indices of the nodes that draw it."""
    out = {}
    for n, node in enumerate(header.get("nodes") or ()):
        mesh = node.get("mesh") if isinstance(node, dict) else None
        if isinstance(mesh, int) and not isinstance(mesh, bool):
            out.setdefault(mesh, []).append(n)
    return out


def _morph_weights(header: dict, m: int, drawers: list) -> list:
    """The weights mesh ``m``'s morph targets are shown at: what its nodes show when they
    agree (a node's ``weights``, else the mesh's), else the mesh's own (zero without them;
    :func:`morphs_split` gives nodes that disagree a copy of the mesh each first)."""
    mesh = header["meshes"][m]
    own = mesh.get("weights") if isinstance(mesh.get("weights"), list) else []
    shown = [node.get("weights") if isinstance(node.get("weights"), list) else own
             for node in (header["nodes"][n] for n in drawers) if isinstance(node, dict)]
    weights = shown[0] if shown and all(w == shown[0] for w in shown) else own
    return [float(w) for w in weights]


def morphs_split(header: dict) -> dict | None:
    """``header`` with a copy of a morphed mesh for each other set of weights its nodes show
    it at (the copy's own ``weights`` those, the nodes drawing it), or None when no nodes
    disagree. Four legs drawn by one mesh, one shown with its shape key at 1: all four were
    read at the mesh's weights, that leg at half its height, without a word."""
    drawing, out = _drawing_nodes(header), None
    for m, drawers in sorted(drawing.items()):
        meshes = header.get("meshes") or ()
        if not 0 <= m < len(meshes) or not isinstance(meshes[m], dict):
            continue
        own = meshes[m].get("weights") if isinstance(meshes[m].get("weights"), list) else []
        shown = {}
        for n in drawers:
            weights = header["nodes"][n].get("weights")
            shown.setdefault(json.dumps(weights if isinstance(weights, list) else own), []).append(n)
        if len(shown) < 2:
            continue
        out = out or copy.deepcopy(header)
        for key, nodes in list(shown.items())[1:]:  # the first keeps the mesh
            out["meshes"].append({**copy.deepcopy(out["meshes"][m]), "weights": json.loads(key)})
            for n in nodes:
                out["nodes"][n]["mesh"] = len(out["meshes"]) - 1
    return out


def morphed_primitives(header: dict) -> list[tuple[int, int, list]]:
    """``(mesh, primitive, weights)`` of each primitive shown morphed: morph targets with
    position offsets and a non-zero weight. trimesh reads a mesh's base shape, so a mesh
    exported with Blender's shape keys set (a cube pulled 4 m tall) was read at rest."""
    drawing, found = _drawing_nodes(header), []
    for m, mesh in enumerate(header.get("meshes") or ()):
        if not isinstance(mesh, dict):
            continue
        weights = _morph_weights(header, m, drawing.get(m, []))
        for p, primitive in enumerate(mesh.get("primitives") or ()):
            targets = primitive.get("targets") if isinstance(primitive, dict) else None
            if isinstance(targets, list) and any(w != 0.0 and isinstance(t, dict) and "POSITION" in t
                                                 for w, t in zip(weights, targets)):
                found.append((m, p, weights))
    return found


def skins_split(header: dict) -> dict | None:
    """``header`` with a copy of each mesh that a node with a skin draws and other nodes
    draw too, for each of those skinned nodes; None when there is none. Each skin poses
    its node's copy (:func:`skinned_meshes`): a wing mesh shared by two cloned
    characters' skeletons (three.js's SkeletonUtils.clone) had both wings read at rest,
    on top of each other, without a word (h144)."""
    out = None
    for m, drawers in sorted(_drawing_nodes(header).items()):
        meshes = header.get("meshes") or ()
        if len(drawers) < 2 or not 0 <= m < len(meshes) or not isinstance(meshes[m], dict):
            continue
        skinned = [n for n in drawers if isinstance(header["nodes"][n].get("skin"), int)]
        for n in skinned[1:] if skinned == drawers else skinned:  # the first keeps the mesh if all are skinned
            out = out or copy.deepcopy(header)
            out["meshes"].append(copy.deepcopy(out["meshes"][m]))
            out["nodes"][n]["mesh"] = len(out["meshes"]) - 1
    return out


def skinned_meshes(header: dict) -> list[tuple[int, int, int]]:
    """``(node, mesh, skin)`` of each node that draws a skinned mesh no other node draws
    (:func:`skins_split` gives each such node a copy first). trimesh reads a skinned
    mesh at its bind pose, placed by its node; glTF shows it posed by its joints."""
    drawing = _drawing_nodes(header)
    found = []
    for n, node in enumerate(header.get("nodes") or ()):
        if not isinstance(node, dict):
            continue
        mesh, skin = node.get("mesh"), node.get("skin")
        if isinstance(mesh, int) and isinstance(skin, int) and len(drawing.get(mesh, [])) == 1 \
                and 0 <= skin < len(header.get("skins") or ()) and 0 <= mesh < len(header.get("meshes") or ()):
            found.append((n, mesh, skin))
    return found


def _local_matrix(node: dict) -> np.ndarray:
    """A node's transform (its ``matrix``, column-major, or translation, rotation, scale)."""
    if isinstance(node.get("matrix"), list) and len(node["matrix"]) == 16:
        return np.asarray(node["matrix"], dtype=np.float64).reshape(4, 4).T
    from scipy.spatial.transform import Rotation

    quaternion = np.asarray(node.get("rotation", (0.0, 0.0, 0.0, 1.0)), dtype=np.float64)  # glTF's x, y, z, w
    usable = quaternion.shape == (4,) and np.isfinite(quaternion).all() and quaternion.any()
    rotation = Rotation.from_quat(quaternion).as_matrix() if usable else np.eye(3)  # (a broken one: unturned)
    m = np.eye(4)
    m[:3, :3] = rotation * np.asarray(node.get("scale", (1.0, 1.0, 1.0)), dtype=np.float64)
    m[:3, 3] = node.get("translation", (0.0, 0.0, 0.0))
    return m


def _global_matrices(header: dict) -> list:
    """Every node's world transform (its parents' times its own)."""
    nodes = header.get("nodes") or []
    parent = {}
    for n, node in enumerate(nodes):
        for child in (node.get("children") or ()) if isinstance(node, dict) else ():
            if isinstance(child, int) and 0 <= child < len(nodes):
                parent.setdefault(child, n)
    out = [None] * len(nodes)

    def world(n, depth=0):
        if out[n] is None:
            if depth > len(nodes):
                raise ValueError("the node hierarchy has a cycle")
            local = _local_matrix(nodes[n]) if isinstance(nodes[n], dict) else np.eye(4)
            out[n] = local if n not in parent else world(parent[n], depth + 1) @ local
        return out[n]

    return [world(n) for n in range(len(nodes))]


def _skinned(header: dict, buffers: list, node: int, skin: int, primitive: dict, positions: np.ndarray,
             worlds: list) -> np.ndarray:
    """``positions`` posed by the skin's joints (glTF: sum of weight x joint world x
    inverse bind matrix), in the node's own frame again (trimesh places them by it)."""
    spec = header["skins"][skin]
    joints = [int(j) for j in spec.get("joints", [])]
    if "inverseBindMatrices" in spec:
        inverse_bind = accessor_values(header, buffers, spec["inverseBindMatrices"]).reshape(-1, 4, 4)
        inverse_bind = np.transpose(inverse_bind, (0, 2, 1))  # column-major
    else:
        inverse_bind = np.tile(np.eye(4), (len(joints), 1, 1))
    if len(inverse_bind) < len(joints):
        raise ValueError(f"skin {skin} has fewer inverse bind matrices than joints")
    matrices = np.stack([worlds[j] @ inverse_bind[k] for k, j in enumerate(joints)])
    attributes = primitive.get("attributes") or {}
    homogeneous = np.hstack([positions, np.ones((len(positions), 1))])
    posed, total = np.zeros_like(homogeneous), np.zeros(len(positions))
    for s in range(8):  # JOINTS_0/WEIGHTS_0, JOINTS_1/WEIGHTS_1, ...
        if f"JOINTS_{s}" not in attributes or f"WEIGHTS_{s}" not in attributes:
            break
        which = accessor_values(header, buffers, attributes[f"JOINTS_{s}"]).astype(np.int64)
        weights = accessor_values(header, buffers, attributes[f"WEIGHTS_{s}"])
        if which.shape != (len(positions), 4) or weights.shape != (len(positions), 4):
            raise ValueError(f"skin {skin}: JOINTS_{s} or WEIGHTS_{s} is not one VEC4 a vertex")
        which = np.where(weights != 0.0, which, 0)  # an unused slot's index is padding (some exporters')
        if which.min(initial=0) < 0 or which.max(initial=0) >= len(joints):
            raise ValueError(f"skin {skin}: a vertex names a joint the skin does not have")
        for c in range(4):
            posed += weights[:, c, None] * np.einsum("vij,vj->vi", matrices[which[:, c]], homogeneous)
            total += weights[:, c]
    if not total.any():
        return positions  # no weights: at rest
    # weights should sum to 1 (glTF); a vertex with none keeps its place
    unweighted = total <= 0
    posed[~unweighted] /= total[~unweighted, None]
    posed[unweighted] = homogeneous[unweighted] @ worlds[node].T  # where its node puts it
    return (posed @ np.linalg.inv(worlds[node]).T)[:, :3]


def _binary_chunk(data: bytes) -> bytes | None:
    """A GLB's BIN chunk (None without one); its JSON chunk is read by
    :func:`procmod.geometry.mesh_files.gltf_header`."""
    at = 20 + struct.unpack_from("<I", data, 12)[0]
    while at + 8 <= len(data):
        chunk_length, chunk_kind = struct.unpack_from("<I4s", data, at)
        if chunk_kind == b"BIN\x00":
            return data[at + 8:at + 8 + chunk_length]
        at += 8 + chunk_length
    return None


def unplaced_roots(header: dict) -> list | None:
    """For a glTF with nodes but no scene (``scenes`` absent or empty: valid glTF, a
    library of objects), the nodes no node lists as a child, in order: the scene it is
    read as (viewers that show such a file show these; trimesh read nothing). None for a
    file with a scene."""
    nodes = header.get("nodes")
    if header.get("scenes") or not isinstance(nodes, list) or not nodes:
        return None
    children = {c for n in nodes if isinstance(n, dict) for c in (n.get("children") or ())
                if isinstance(c, int) and not isinstance(c, bool)}
    return [k for k in range(len(nodes)) if k not in children]


def camera_nodes_with_content(header: dict) -> list:
    """The nodes that are a camera and also hold a mesh or children (an object parented to
    the camera, as Blender and three.js write it): trimesh leaves a camera's node out of
    its scene, and with it everything under it (a traceback, 'No path from world->...')."""
    nodes = header.get("nodes")
    if not isinstance(nodes, list):
        return []
    return [n for n, node in enumerate(nodes) if isinstance(node, dict) and "camera" in node
            and ("mesh" in node or node.get("children"))]


def _glb_chunk(path: Path) -> bytes | None:
    """A GLB's binary chunk (whatever its suffix); None for a text glTF or a GLB without one."""
    data = path.read_bytes()
    return _binary_chunk(data) if data[:4] == b"glTF" else None


def _buffers(path: Path, header: dict, resolver, chunk: bytes | None = None) -> list:
    """The bytes of each of a glTF's buffers: a ``data:`` URI's, a file's (``resolver``), a
    GLB's binary chunk (``chunk``, read from ``path`` when not given)."""
    chunk = _glb_chunk(path) if chunk is None else chunk
    buffers = []
    for i, buffer in enumerate(header.get("buffers") or ()):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if isinstance(uri, str) and uri.startswith("data:") and "base64," in uri:
            buffers.append(base64.b64decode(uri[uri.index("base64,") + 7:]))
        elif isinstance(uri, str):
            buffers.append(resolver.get(uri))
        elif i == 0 and chunk is not None:
            buffers.append(chunk)
        else:
            raise ValueError(f"buffer {i} has no data (no uri, and not a GLB's binary chunk)")
    return buffers


def expanded_header(path: Path, header: dict, resolver) -> dict:
    """``header`` (a glTF's JSON) with its GPU instances expanded as :func:`decoded_gltf`
    expands them (:func:`expanded_instances`): the node list a reader of the decoded file
    sees; ``header`` itself for a file without them."""
    if not instanced_nodes(header):
        return header
    required = header.get("extensionsRequired")
    return expanded_instances(header, _buffers(Path(path), header, resolver),
                              isinstance(required, list) and INSTANCING in required)


def decoded_gltf(path: Path, header: dict, resolver) -> bytes | None:
    """The glTF (JSON, buffers as ``data:`` URIs or the files the original names) with its
    misread POSITION accessors (:func:`needs_decoding`) rewritten as ``FLOAT``; None when
    there are none. ``header`` is the file's JSON (``gltf_header``); ``resolver.get(uri)``
    gives a buffer file's bytes.

    A node drawn as GPU instances becomes a node per instance (:func:`expanded_instances`).
    Triangle-fan primitives become triangle lists (:func:`fan_primitives`); a camera's node
    that holds a mesh or children is read as a plain node (:func:`camera_nodes_with_content`).
    A mesh shown
    morphed (:func:`morphed_primitives`) or posed by a skin (:func:`skinned_meshes`) gets
    the positions it is shown at; nodes that show one mesh at other weights or under
    other skins get a copy each (:func:`morphs_split`, :func:`skins_split`).

    Raises ValueError for an accessor that reaches past its data."""
    path = Path(path)
    buffers = chunk = expanded = None
    if instanced_nodes(header):  # each instance a node first: the steps below see the copies as nodes
        chunk = _glb_chunk(path)
        buffers = _buffers(path, header, resolver, chunk)
        required = header.get("extensionsRequired")
        header = expanded = expanded_instances(header, buffers, isinstance(required, list) and INSTANCING in required)
    split = morphs_split(header)
    header = (header if split is None else split)
    posed = skins_split(header)
    if posed is not None:
        header = split = posed
    chosen = needs_decoding(header)
    fans = fan_primitives(header)
    morphs = morphed_primitives(header)
    skins = skinned_meshes(header)
    roots = unplaced_roots(header)
    cameras = camera_nodes_with_content(header)
    if not chosen and not fans and not morphs and not skins and roots is None and not cameras and split is None \
            and expanded is None:
        return None
    if buffers is None:
        chunk = _glb_chunk(path)
        buffers = _buffers(path, header, resolver, chunk)
    decoded = {index: accessor_values(header, buffers, index).astype("<f4") for index in chosen}
    out = copy.deepcopy(header)
    blob, views = b"", out.setdefault("bufferViews", [])
    for index, values in decoded.items():
        views.append({"buffer": len(buffers), "byteOffset": len(blob), "byteLength": values.nbytes})
        accessor = {key: value for key, value in out["accessors"][index].items()
                    if key not in ("bufferView", "byteOffset", "sparse", "normalized", "componentType", "min", "max")}
        accessor.update(bufferView=len(views) - 1, componentType=5126)
        if len(values):
            accessor.update(min=values.min(axis=0).tolist(), max=values.max(axis=0).tolist())
        out["accessors"][index] = accessor
        blob += values.tobytes()
    for m, p in fans:
        triangles = _fan_triangles(header, buffers, header["meshes"][m]["primitives"][p], f"mesh {m} primitive {p}")
        views.append({"buffer": len(buffers), "byteOffset": len(blob), "byteLength": triangles.nbytes})
        out.setdefault("accessors", []).append({"bufferView": len(views) - 1, "componentType": 5125,
                                                "count": len(triangles), "type": "SCALAR"})
        out["meshes"][m]["primitives"][p].update(mode=4, indices=len(out["accessors"]) - 1)
        blob += triangles.tobytes()
    # positions shown morphed and posed: each such primitive gets an accessor of its own (its
    # base accessor may be shared), in the node's frame, its morph targets and skin dropped
    shown = {}
    for m, p, weights in morphs:
        primitive = header["meshes"][m]["primitives"][p]
        positions = accessor_values(header, buffers, primitive["attributes"]["POSITION"])
        for w, target in zip(weights, primitive["targets"]):
            if w != 0.0 and isinstance(target, dict) and "POSITION" in target:
                positions = positions + w * accessor_values(header, buffers, target["POSITION"])
        shown[(m, p)] = positions
    worlds = _global_matrices(header) if skins else None
    for n, m, k in skins:
        if not abs(np.linalg.det(worlds[n][:3, :3])) > 1e-300:
            continue  # a node scaled to nothing: its mesh's place cannot be undone; read at rest
        for p, primitive in enumerate(header["meshes"][m].get("primitives") or ()):
            if not isinstance(primitive, dict) or "POSITION" not in (primitive.get("attributes") or {}):
                continue
            positions = shown.get((m, p))
            if positions is None:
                positions = accessor_values(header, buffers, primitive["attributes"]["POSITION"])
            shown[(m, p)] = _skinned(header, buffers, n, k, primitive, positions, worlds)
    for (m, p), positions in shown.items():
        values = positions.astype("<f4")
        views.append({"buffer": len(buffers), "byteOffset": len(blob), "byteLength": values.nbytes})
        accessor = {"bufferView": len(views) - 1, "componentType": 5126, "count": len(values), "type": "VEC3"}
        if len(values):
            accessor.update(min=values.min(axis=0).tolist(), max=values.max(axis=0).tolist())
        out["accessors"].append(accessor)
        target = out["meshes"][m]["primitives"][p]
        target["attributes"] = {**target["attributes"], "POSITION": len(out["accessors"]) - 1}
        target.pop("targets", None)
        blob += values.tobytes()
    for n, _, _ in skins:
        out["nodes"][n].pop("skin", None)
    for n in cameras:  # read as the plain node it also is: what it holds stays in the scene
        out["nodes"][n].pop("camera", None)
    if roots is not None:
        out["scenes"], out["scene"] = [{"nodes": roots}], 0
    out["buffers"] = [dict(b) for b in out.get("buffers") or ()]
    if chunk is not None and out["buffers"] and "uri" not in out["buffers"][0]:
        # read as a .gltf now: the binary chunk travels as a data URI
        out["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(chunk).decode()
    out["buffers"].append({"byteLength": len(blob),
                           "uri": "data:application/octet-stream;base64," + base64.b64encode(blob).decode()})
    return json.dumps(out).encode("utf-8")


__all__ = ["INSTANCING", "accessor_values", "camera_nodes_with_content", "decoded_gltf", "expanded_header",
           "expanded_instances", "fan_primitives", "instance_count", "instance_matrices", "instanced_nodes",
           "morphed_primitives", "needs_decoding", "skinned_meshes", "unplaced_roots"]
