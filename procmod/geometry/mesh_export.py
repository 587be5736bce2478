"""Mesh export of 3D parts: OBJ and GLB (through trimesh), with one colour per part tag.

Colours: procmod's palette is sRGB (the PNG pictures' colours). An OBJ's vertex colours
are sRGB by custom (Blender's OBJ importer and exporter treat them so); a glTF's
``COLOR_0`` is linear by its specification, so a GLB gets the palette converted
(:func:`srgb_bytes_to_linear`). Written as sRGB, every GLB had shown washed out in
Blender's glTF importer and three.js next to ``best.png`` and the OBJ.

Parts: a GLB written to a file (:func:`export_mesh`) holds one node and one mesh per part,
both named after the part's tag, as a modelling tool's scene does, so that the file is
one part per object in Blender and reads back as its parts in ``procmod strings graph``
(which takes a glTF's meshes for parts; merged into one mesh, a strings instantiation
of 26 parts had read back as one part). ``procmod learn`` needs a hierarchy, which the
flat file does not hold: ``procmod sample --format examples`` writes one. A part's node
holds its placement and its mesh the part in its own frame, shared by the parts alike
(linked data), so that an artist gets each part as an object with its own origin and
axes (written in world coordinates, every object had sat at the world origin, unturned,
a mesh of its own); a placement that shears, which a glTF node's matrix may not (it must
decompose into translation, rotation and scale), is written into the mesh under an
identity node instead. Above :data:`MAX_PART_NODES` parts, the file holds one node per
tag instead: Blender's importer takes time growing with the square of the objects (1,000
parts 5.6 s, 2,000 29 s, 5,000 over 170 s; merged, 0.6 s). The report's viewer keeps one merged
mesh (:func:`glb_bytes`): one draw call, whatever the part count. An OBJ file holds one
object (``o``) per part named so too, each in world coordinates (OBJ has no placements),
or one per tag above :data:`MAX_PART_NODES` parts: merged into one mesh, an artist's
importer had made the whole result one object.
"""

from __future__ import annotations

import io
import json
import os
import re
import struct
from pathlib import Path

import numpy as np
import trimesh

from ..core.errors import InvalidArgumentError, cut_text, shown_value
from ..core.io import write_bytes_atomic
from .solid import IDENTITY, matrix, part_triangles


def srgb_bytes_to_linear(rgb) -> np.ndarray:
    """sRGB colour bytes -> linear-light colour bytes (the sRGB transfer function's
    inverse, IEC 61966-2-1), as uint8."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(linear * 255.0).astype(np.uint8)


FLOAT32_MAX = float(np.finfo(np.float32).max)
"""The largest coordinate a glTF file holds: its positions are 32-bit floats."""


def check_storable(points, what: str) -> None:
    """Refuse coordinates a mesh file cannot hold: NaN, infinities, or beyond +-:data:`FLOAT32_MAX`
    (glTF's 32-bit floats; most OBJ readers read 32-bit floats too). trimesh wrote them as they
    were: a part beyond became ``Infinity`` in the GLB's JSON (no reader opens the file), and a
    NaN part was dropped without a word (an empty node), or failed with trimesh's AssertionError."""
    points = np.asarray(points, dtype=np.float64)
    fits = np.abs(points) <= FLOAT32_MAX  # NaN compares False: it does not fit either
    if not fits.all():
        bad = points[~fits]
        raise InvalidArgumentError(f"{what} has a coordinate of {shown_value(float(bad.flat[0]))}, which a mesh file "
                                   f"cannot hold (finite numbers within +-{FLOAT32_MAX:.3g}); check its size and "
                                   "transform")


MERGE_DIGITS = 8
"""trimesh merges vertices on a grid of ``10 ** -MERGE_DIGITS`` (its ``tol.merge``, 1e-8)."""


def merge_digits(points) -> int:
    """The digits of the grid on which to merge the vertices of ``points`` (finite): trimesh's
    :data:`MERGE_DIGITS`, coarser where a coordinate times ``10 ** digits`` would pass int64.
    trimesh rounds ``coordinate * 1e8`` to int64 as it merges: past ~9.2e10 the product
    overflowed, every such vertex fell in one cell, and a part that far out collapsed (a
    1 x 2 x 3 box at x = 1e11 came out 4 vertices, 0 wide, in OBJ files and merged GLBs)."""
    largest = float(np.abs(points).max()) if np.size(points) else 0.0
    if largest * 10.0 ** MERGE_DIGITS < 2.0 ** 62:
        return MERGE_DIGITS
    return int(np.floor(np.log10(2.0 ** 62 / largest)))


def _part_text(part) -> str:
    """A part as an error message names it: its type and tag."""
    return f"a {type(part).__name__} part tagged {cut_text(repr(getattr(part, 'tag', None)), 60)}"


def _part_mesh(part, colour_of, segments: int, linear_colours: bool) -> trimesh.Trimesh:
    """A part's world-space mesh (vertices merged), its faces in its tag's colour."""
    tris = part_triangles(part, segments)
    check_storable(tris, _part_text(part))
    digits = merge_digits(tris)
    mesh = trimesh.Trimesh(vertices=tris.reshape(-1, 3), faces=np.arange(len(tris) * 3).reshape(-1, 3),
                           process=digits == MERGE_DIGITS)
    if digits != MERGE_DIGITS:
        mesh.merge_vertices(digits_vertex=digits)
    rgb = np.asarray(colour_of(part.tag), dtype=np.uint8)
    colour = np.append(srgb_bytes_to_linear(rgb) if linear_colours else rgb, 255)
    mesh.visual.face_colors = np.tile(colour, (len(mesh.faces), 1))
    return mesh


def parts_to_trimesh(parts, colour_of, segments: int = 24, linear_colours: bool = False) -> trimesh.Trimesh:
    """One mesh of all parts (vertices merged per part), faces coloured by tag: the
    palette's sRGB bytes, or with ``linear_colours`` linear ones (what glTF files hold)."""
    meshes = [_part_mesh(part, colour_of, segments, linear_colours) for part in parts]
    if not meshes:
        return trimesh.Trimesh()
    return trimesh.util.concatenate(meshes)


def part_name(tag) -> str:
    """The node and mesh name of a part in a GLB: its tag (a part with none: ``part``)."""
    return str(tag) if tag not in (None, "") else "part"


MAX_PART_NODES = 500
"""A GLB of more parts holds one node per tag (see the module docstring)."""


ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963


def set_view_targets(tree: dict) -> None:
    """Give each bufferView of a glTF tree (trimesh's, before it is written: its
    ``tree_postprocessor``) the ``target`` its use says, in place: ``ARRAY_BUFFER`` for
    vertex attributes (morph targets' too), ``ELEMENT_ARRAY_BUFFER`` for indices. trimesh
    leaves it unset, which the Khronos validator hints at (BUFFER_VIEW_TARGET_MISSING); a
    view used both ways, or otherwise (an image), keeps none."""
    accessors = tree.get("accessors") or []
    views = tree.get("bufferViews") or []
    uses: dict = {}
    for mesh in tree.get("meshes") or ():
        for primitive in mesh.get("primitives") or ():
            for attributes in [primitive.get("attributes") or {}] + list(primitive.get("targets") or ()):
                for index in attributes.values():
                    uses.setdefault(accessors[index].get("bufferView"), set()).add(ARRAY_BUFFER)
            if "indices" in primitive:
                uses.setdefault(accessors[primitive["indices"]].get("bufferView"), set()).add(ELEMENT_ARRAY_BUFFER)
    for view, targets in uses.items():
        if isinstance(view, int) and 0 <= view < len(views) and len(targets) == 1:
            views[view]["target"] = targets.pop()


def scene_glb_bytes(parts, colour_of, segments: int = 24) -> bytes:
    """A GLB file of 3D parts, one node and mesh per part named after its tag (above
    :data:`MAX_PART_NODES` parts, one per tag; see the module docstring), coloured per tag
    in linear light."""
    if not parts:
        return empty_glb_bytes()
    scene = trimesh.Scene()
    if len(parts) > MAX_PART_NODES:
        by_tag: dict = {}
        for part in parts:
            by_tag.setdefault(part_name(part.tag), []).append(part)
        groups = [(name, parts_to_trimesh(group, colour_of, segments, True)) for name, group in by_tag.items()]
    else:
        groups = [(part_name(part.tag), *_placed_part_mesh(part, colour_of, segments)) for part in parts]
    shared = {}
    for unique, (name, mesh, *placement) in zip(unique_names(name for name, *_ in groups), groups):
        matrix_, same = placement if placement else (None, None)
        if same is not None and same in shared:  # a copy: a node of the mesh written for the first (linked data)
            scene.graph.update(frame_from=scene.graph.base_frame, frame_to=unique, matrix=matrix_,
                               geometry=shared[same])
            continue
        scene.add_geometry(mesh, geom_name=unique, node_name=unique, transform=matrix_)
        if same is not None:
            shared[same] = unique
    return scene.export(file_type="glb", tree_postprocessor=set_view_targets)


def unique_names(names) -> list:
    """The names made unique within one file, as a modelling tool's are (tower, tower_1,
    ...: trimesh drops a node of a name it already holds; readers that name parts after
    meshes take the shortest of the names they merge). "world" is trimesh's name for the
    scene's root: a node of that name had held every other part as its child (Blender
    imported them all parented to one part)."""
    used, counts, out = {"world"}, {}, []
    for name in names:
        unique = name
        while unique in used:
            counts[name] = counts.get(name, 0) + 1
            unique = f"{name}_{counts[name]}"
        used.add(unique)
        out.append(unique)
    return out


def obj_name(name: str) -> str:
    """``name`` as one OBJ ``o`` line holds it: line breaks and other control characters
    become spaces, and trailing backslashes and whitespace are dropped (empty: ``part``).
    A name is the rest of its line, so a tag holding a line break (a part name in an
    examples file or a glTF node's) had written its remainder as a line of its own (``v 9 9
    9``: every later face on the wrong vertices), and one ending in a backslash continued
    the line, swallowing the object's first vertex (readers then refused the file)."""
    one_line = re.sub(r"[\x00-\x1f\x7f-\x9f\u2028\u2029]", " ", name)
    return re.sub(r"[\s\\]+$", "", one_line).strip() or "part"


def scene_obj_text(parts, colour_of, segments: int = 24) -> str:
    """An OBJ file of 3D parts, one object per part named after its tag (above
    :data:`MAX_PART_NODES` parts, one per tag), in world coordinates, with the palette's
    sRGB bytes as vertex colours (see the module docstring). Written here, not by trimesh's
    scene export, which took twice as long as the one merged mesh had (500 parts ~0.9 s)."""
    if len(parts) > MAX_PART_NODES:
        by_tag: dict = {}
        for part in parts:
            by_tag.setdefault(part_name(part.tag), []).append(part)
        groups = [(name, parts_to_trimesh(group, colour_of, segments)) for name, group in by_tag.items()]
    else:
        groups = [(part_name(part.tag), _part_mesh(part, colour_of, segments, False)) for part in parts]
    out = io.StringIO()
    out.write("# procmod: one object per part, vertex colours in sRGB\n")
    first = 1  # OBJ numbers vertices from 1, through the whole file
    for unique, (_, mesh) in zip(unique_names(obj_name(name) for name, _ in groups), groups):
        faces = np.asarray(mesh.faces, dtype=np.int64)
        if not len(faces):  # (a part of zero size merges to no face: no empty object)
            continue
        vertices = np.asarray(mesh.vertices, dtype=np.float64)
        # each vertex lies on one part (merged per part): its faces' colour is its own
        colours = np.zeros((len(vertices), 3))
        colours[faces.ravel()] = np.repeat(np.asarray(mesh.visual.face_colors)[:, :3] / 255.0, 3, axis=0)
        out.write(f"o {unique}\n")
        np.savetxt(out, np.column_stack((vertices, colours)), fmt="v %.8f %.8f %.8f %.8f %.8f %.8f")
        np.savetxt(out, faces + first, fmt="f %d %d %d")
        first += len(vertices)
    return out.getvalue()


def _placed_part_mesh(part, colour_of, segments: int) -> tuple:
    """``(mesh, node matrix, key)`` of a part for a GLB node: the part in its own frame
    under its placement, ``key`` its triangles and tag (parts of one key share a mesh, as a
    tool's linked duplicates do); or, for a placement glTF cannot hold (one that shears, is
    singular, or has a last row other than 0 0 0 1), its world-space mesh under the
    identity, key None."""
    m = matrix(part.transform)
    linear = m[:3, :3]
    gram = linear.T @ linear
    scales = np.sqrt(np.diag(gram))
    if not np.isfinite(m).all() or not (scales > 1e-12 * max(float(scales.max()), 1e-300)).all() \
            or np.abs(gram / np.outer(scales, scales) - np.eye(3)).max() > 1e-9 \
            or tuple(m[3]) != (0.0, 0.0, 0.0, 1.0):
        return _part_mesh(part, colour_of, segments, True), np.eye(4), None
    # a mirrored placement keeps the part's own winding: glTF turns the faces with the node's determinant
    mesh = _part_mesh(part._replace(transform=IDENTITY), colour_of, segments, True)
    # the mesh is in the part's own frame: its world coordinates, under the node, are checked here
    check_storable(np.asarray(mesh.vertices) @ linear.T + m[:3, 3], _part_text(part))
    # alike: the same triangles in the same colour (a part's fields may be arrays or lists: no key themselves)
    key = (str(part.tag), np.asarray(mesh.vertices).tobytes(), np.asarray(mesh.faces).tobytes())
    return mesh, m, key


def empty_glb_bytes() -> bytes:
    """A GLB of one empty scene and no binary chunk. trimesh wrote an empty mesh with a
    zero-length BIN chunk and no buffer, which glTF 2.0 says a file should not hold (strict
    readers refuse it)."""
    header = json.dumps({"asset": {"version": "2.0", "generator": "procmod"}, "scene": 0, "scenes": [{}]},
                        separators=(",", ":")).encode()
    header += b" " * (-len(header) % 4)  # the JSON chunk is padded with spaces to 4 bytes
    chunk = struct.pack("<II", len(header), 0x4E4F534A) + header
    return struct.pack("<III", 0x46546C67, 2, 12 + len(chunk)) + chunk


def glb_bytes(parts, colour_of) -> bytes:
    """A GLB file of 3D parts merged into one mesh (the report viewer's), one colour per part
    tag (linear, as glTF defines ``COLOR_0``)."""
    if not parts:
        return empty_glb_bytes()
    return parts_to_trimesh(parts, colour_of, linear_colours=True).export(file_type="glb",
                                                                        tree_postprocessor=set_view_targets)


def export_mesh(parts, path: str | os.PathLike, colour_of) -> None:
    """Write parts as ``.obj`` or ``.glb`` (chosen by the suffix), atomically."""
    path = Path(path)
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("obj", "glb"):
        raise ValueError(f"mesh export writes .obj or .glb, not {path.suffix!r}")
    if kind == "glb":
        write_bytes_atomic(path, scene_glb_bytes(parts, colour_of))
        return
    text = scene_obj_text(parts, colour_of) if parts else ""
    if "\nf " not in text:
        # trimesh writes "v" and "f" lines with no numbers for an empty mesh, which readers
        # (trimesh itself: a point cloud of shape (1, 0)) take for a broken file
        write_bytes_atomic(path, b"# procmod: a derivation with no parts (an empty mesh)\n")
        return
    write_bytes_atomic(path, text.encode())
