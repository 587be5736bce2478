"""PLY, OFF and COLLADA files read with their polygon faces kept, then triangulated right.

trimesh reads both, but not every file tools write: a binary PLY whose faces have
different corner counts (Blender and MeshLab write triangles and quads, or n-gons, into
one file) was refused as "unexpected length", an OFF file with a face of five or more
corners failed inside numpy, and the n-gons it did read were fanned from their first
corner, which covers more than a concave face. Here PLY goes through plyfile (the
maintained PLY library: ASCII and both binary byte orders, any list types) and OFF
through the few lines its format needs; COLLADA through pycollada (trimesh's own
reader) with its polygons, units and up axis (:func:`read_collada`). The faces are
triangulated by :func:`procmod.geometry.polygons.triangulate_faces`.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from .polygons import triangulate_faces

# OFF's header keyword, with its optional prefixes: ST (texture coordinates), C (colours),
# N (normals), 4 (homogeneous coordinates; read as x y z w and divided through)
_OFF_PREFIXES = ("ST", "C", "N", "4")


def read_ply(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, triangles)`` of a PLY file (its ``vertex`` x, y, z and its ``face``
    element's ``vertex_indices`` or ``vertex_index`` lists; a file without faces gives
    no triangles). Raises ValueError (or plyfile's parse error) for what it cannot read."""
    from plyfile import PlyData, PlyParseError

    data = None
    for corners in (3, 4):  # all triangles or all quads: a binary file's faces read as one array (~100x faster)
        try:
            data = PlyData.read(str(path), known_list_len={"face": {"vertex_indices": corners,
                                                                     "vertex_index": corners}})
            break
        except PlyParseError:  # faces of other sizes (or a bad file: read once more, to say why)
            continue
    if data is None:
        data = PlyData.read(str(path))
    names = [element.name for element in data.elements]
    if "vertex" not in names:
        raise ValueError("the PLY file has no vertex element")
    vertex = data["vertex"]
    missing = [axis for axis in "xyz" if axis not in vertex.data.dtype.names]
    if missing:
        raise ValueError(f"the PLY file's vertices have no {', '.join(missing)} property")
    vertices = np.stack([np.asarray(vertex[axis], dtype=np.float64) for axis in "xyz"], axis=1)
    if "face" not in names and "tristrips" in names:
        return vertices, strip_triangles(data["tristrips"], len(vertices))
    if "face" not in names:
        return vertices, np.zeros((0, 3), dtype=np.int64)
    face = data["face"]
    prop = next((p for p in ("vertex_indices", "vertex_index") if p in face.data.dtype.names), None)
    if prop is None:
        raise ValueError("the PLY file's faces have no vertex_indices (or vertex_index) list")
    return vertices, triangulate_faces(vertices, face[prop])


def strip_triangles(tristrips, vertex_count: int) -> np.ndarray:
    """The triangles of a PLY ``tristrips`` element (the Stanford scanning repository's
    older models, and range-scan tools, write their faces so; trimesh reads none of them
    and procmod had refused such a file as holding no triangle faces): each row's
    ``vertex_indices`` list is one or more strips separated by -1, a strip of n vertices
    being n - 2 triangles whose turning alternates. Triangles that repeat a vertex (the
    stitches between strips) are dropped. Raises ValueError for an index out of range."""
    prop = next((p for p in ("vertex_indices", "vertex_index") if p in tristrips.data.dtype.names), None)
    if prop is None:
        raise ValueError("the PLY file's tristrips have no vertex_indices list")
    triangles = []
    for row in tristrips[prop]:
        row = np.asarray(row, dtype=np.int64)
        if row.size and (row.max() >= vertex_count or row.min() < -1):
            bad = int(row.max() if row.max() >= vertex_count else row.min())
            raise ValueError(f"the PLY file's tristrips name vertex {bad}, but it has {vertex_count} vertices")
        for strip in np.split(row, np.flatnonzero(row == -1)):
            strip = strip[strip != -1]
            if len(strip) < 3:
                continue
            a, b, c = strip[:-2], strip[1:-1], strip[2:]
            odd = np.arange(len(a)) % 2 == 1  # every other triangle turns the other way: swap two corners
            triangles.append(np.stack([np.where(odd, b, a), np.where(odd, a, b), c], axis=1))
    if not triangles:
        return np.zeros((0, 3), dtype=np.int64)
    out = np.concatenate(triangles)
    keep = (out[:, 0] != out[:, 1]) & (out[:, 1] != out[:, 2]) & (out[:, 0] != out[:, 2])
    return out[keep]


def read_off(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, triangles)`` of an ASCII OFF file (header ``OFF`` with any of the
    ST/C/N/4 prefixes, ``#`` comments, colours after a face's indices, the vertex count
    run on to the keyword as ModelNet has it: ``OFF8 6 0``). Raises
    ValueError, saying what is wrong, for what it cannot read."""
    text = Path(path).read_bytes().decode("latin-1").removeprefix("\xef\xbb\xbf")  # a UTF-8 byte-order mark
    lines = [line.split("#", 1)[0].split() for line in text.splitlines()]
    lines = [fields for fields in lines if fields]
    if not lines:
        raise ValueError("the file is empty")
    glued = re.fullmatch(r"((?:ST|C|N|4)*OFF)(\d+)", lines[0][0].upper())
    if glued:  # "OFF8 6 0": the vertex count run on to the keyword, as many of ModelNet's files have it
        lines[0] = [glued.group(1), glued.group(2)] + lines[0][1:]
    head = lines[0][0].upper()
    keyword = head
    for prefix in _OFF_PREFIXES:
        keyword = keyword.removeprefix(prefix)
    if keyword != "OFF" and not head[:1].isdigit():
        raise ValueError(f"an OFF file starts with OFF, not {lines[0][0][:20]!r}")
    if len(lines[0]) > 1 and lines[0][1].upper() == "BINARY":
        raise ValueError("binary OFF is not read; export ASCII OFF, OBJ or PLY")
    homogeneous = keyword == "OFF" and "4" in head[:-3]
    counts_line = lines[0][1:] if keyword == "OFF" and len(lines[0]) > 1 else None
    rest = lines[1:] if keyword == "OFF" else lines
    if counts_line is None:
        if not rest:
            raise ValueError("the OFF file has no vertex and face counts")
        counts_line, rest = rest[0], rest[1:]
    try:
        n_vertices, n_faces = int(counts_line[0]), int(counts_line[1])
    except (IndexError, ValueError):
        raise ValueError(f"the OFF file's counts line reads {' '.join(counts_line)[:40]!r}, not "
                         "'VERTICES FACES EDGES'") from None
    if n_vertices < 0 or n_faces < 0 or len(rest) < n_vertices + n_faces:
        raise ValueError(f"the OFF file declares {n_vertices} vertices and {n_faces} faces but holds "
                         f"{len(rest)} lines of them")
    width = 4 if homogeneous else 3
    try:
        vertices = np.array([[float(v) for v in fields[:width]] for fields in rest[:n_vertices]], dtype=np.float64)
    except ValueError:
        raise ValueError("a vertex line of the OFF file is not numbers") from None
    if vertices.shape != (n_vertices, width):
        raise ValueError(f"a vertex line of the OFF file has fewer than {width} numbers")
    if homogeneous:
        vertices = vertices[:, :3] / vertices[:, 3:]
    faces = []
    for k, fields in enumerate(rest[n_vertices:n_vertices + n_faces]):
        try:
            corners = int(fields[0])
            face = [int(v) for v in fields[1:1 + corners]]
        except ValueError:
            raise ValueError(f"face {k} of the OFF file is not integers: {' '.join(fields)[:40]!r}") from None
        if len(face) != corners:
            raise ValueError(f"face {k} of the OFF file names {corners} corners but lists {len(face)}")
        faces.append(face)
    return vertices.reshape(-1, 3), triangulate_faces(vertices.reshape(-1, 3), faces)


# turns taking a COLLADA file's <up_axis> to the reader's up: y for procmod's targets and
# parts (glTF's convention), z for a URDF robot's links (ROS's; Bullet's COLLADA loader
# turns its meshes so too)
_TO_UP = {("Z_UP", "y"): np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),  # (x, y, z) -> (x, z, -y)
          ("X_UP", "y"): np.array([[0.0, -1, 0], [1, 0, 0], [0, 0, 1]]),  # (x, y, z) -> (-y, x, z)
          ("Y_UP", "z"): np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),  # (x, y, z) -> (x, -z, y)
          ("X_UP", "z"): np.array([[0.0, 0, -1], [0, 1, 0], [1, 0, 0]])}  # (x, y, z) -> (-z, y, x)


def collada_up_axis(path: str | Path) -> str | None:
    """The ``<up_axis>`` of a COLLADA file's own ``<asset>`` (``"Z_UP"``), or None (then
    Y_UP, the format's default): the XML read as a stream up to the end of that element, so
    comments, and an asset block however long, read as the reader reads them."""
    import xml.etree.ElementTree as ElementTree

    try:
        for _, element in ElementTree.iterparse(str(path), events=("end",)):
            name = element.tag.rsplit("}", 1)[-1]
            if name == "up_axis":
                return (element.text or "").strip().upper() or None
            if name == "asset":
                return None  # the file's asset ended without one
    except (OSError, ElementTree.ParseError):
        return None  # unreadable: the reader says what is wrong
    return None


def read_collada(path: str | Path, up: str | None = "y") -> tuple[np.ndarray, np.ndarray]:
    """``(vertices, triangles)`` of a COLLADA file's scene (pycollada; each geometry placed
    by its nodes), its polygons triangulated right, in metres and with ``up`` (``"y"`` or
    ``"z"``) up as its ``<unit>`` and ``<up_axis>`` declare them (``None``: its axes as
    they are, as a URDF's meshes are read). trimesh fanned its
    polygons and left its units and axis as they were: Blender's export (z up) came in
    lying on its back beside the same object exported as glTF, SketchUp's (inches) 39x too
    large. Lines are left out."""
    import collada
    from collada.polylist import BoundPolylist
    from collada.triangleset import BoundTriangleSet

    document = collada.Collada(str(path), ignore=[collada.common.DaeUnsupportedError,
                                                  collada.common.DaeBrokenRefError])
    if document.scene is not None:
        bound = list(document.scene.objects("geometry"))
    else:  # no scene: the library's geometries where they are
        bound = [g.bind(np.eye(4), {}) for g in document.geometries]
    vertices, triangles, count = [], [], 0
    for geometry in bound:
        # a node that mirrors (a negative scale) turns its faces inside out: wind them back
        mirrored = np.linalg.det(np.asarray(geometry.matrix, dtype=np.float64)[:3, :3]) < 0
        for primitive in geometry.primitives():
            if not isinstance(primitive, (BoundTriangleSet, BoundPolylist)):
                continue  # lines
            points = np.asarray(primitive.vertex, dtype=np.float64).reshape(-1, 3)
            if isinstance(primitive, BoundTriangleSet):
                faces = triangulate_faces(points, np.asarray(primitive.vertex_index, dtype=np.int64).reshape(-1, 3))
            else:  # <polylist> and <polygons>
                corners = np.asarray(primitive.original.vertex_index, dtype=np.int64).reshape(-1)
                ends = np.cumsum(np.asarray(primitive.original.vcounts, dtype=np.int64))
                faces = triangulate_faces(points, np.split(corners, ends[:-1]) if len(ends) else [])
            if len(faces) == 0:
                continue
            if mirrored:
                faces = faces[:, ::-1]
            vertices.append(points)
            triangles.append(faces + count)
            count += len(points)
    if not triangles:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    vertices = np.concatenate(vertices)
    info = document.assetInfo
    metre = float(info.unitmeter) if info is not None and info.unitmeter else 1.0
    # the up axis as collada_up_axis reads it (spaces and case aside: pycollada takes only the
    # exact words, and read "\n  Z_UP\n" as Y_UP while the target file's check read Z_UP)
    turn = _TO_UP.get((collada_up_axis(path) or "Y_UP", up))
    if turn is not None:
        vertices = vertices @ turn.T
    return vertices * metre, np.concatenate(triangles)


__all__ = ["collada_up_axis", "read_collada", "read_off", "read_ply"]
