"""Reading one mesh file with trimesh, with the OBJ details trimesh's parser gets wrong.

Every place procmod reads a mesh file (volume and silhouette targets, part libraries,
asset meshes) goes through :func:`load_mesh_file`. For OBJ files it first rewrites what
trimesh 4 misreads, in memory (the file is left as it is):

* **Relative indices.** ``f -4 -3 -2`` means "the vertices 4, 3 and 2 back from this
  line"; trimesh resolves them against the *whole file's* vertices, so in a file of two
  objects every face of the first pointed at the second's vertices and the first object
  vanished without a word. They are rewritten as absolute indices.
* **Whitespace.** A tab after the keyword (``v\\t1 2 3``) or an indented line is dropped
  by trimesh, silently losing those vertices or faces; lines are re-spaced.
* **Line continuations** (a ``\\`` at the end of a line) are joined first, so that the
  two rules above see whole statements.
* **Comments at a line's end** (``f 1 2 3 # top``) are cut from vertex and face
  statements (names in ``o``, ``g``, ``usemtl`` lines may hold a ``#`` and keep it); a
  UTF-8 byte-order mark (Windows editors, .NET tools) is dropped, and lines ended by a lone
  carriage return (old Mac files) are split: trimesh read the first as part of the first
  statement and the last as one long line.

Binary STL files whose header count disagrees with their size are read by their size
where that is unambiguous (bytes left over after the last triangle; a count of zero);
a file cut off inside its triangles is refused saying so. An ASCII STL is read as
exporters write it: without its closing ``endsolid`` or its opening ``solid`` line, with a
UTF-8 byte-order mark, or with tabs between its numbers (each was taken for a binary STL
of 10^8-10^9 triangles). A file whose bytes are plainly another format than its suffix
says is read as what it is where procmod can tell (a binary glTF named ``.gltf``) or
refused naming its format (OBJ text named ``.stl``).

For glTF, the files a ``.gltf`` names (buffers, images) are found as procmod finds named
files (README, "Files that name other files"): relative to the ``.gltf``, ``..`` allowed,
absolute paths refused, and percent-encoded (``my%20ship.bin``, as the glTF spec writes a
space) as well as plain, ``\\`` or ``/`` between folders. A file whose meshes are
Draco-compressed is refused with what to do, rather than read as placeholder zeros, and
so is one whose buffers are meshopt-compressed. Positions stored as normalized integers (``KHR_mesh_quantization``)
or in sparse accessors, which trimesh reads wrongly, are decoded first
(:mod:`procmod.geometry.gltf_accessors`). A ``.gltf`` whose buffer file is missing or
shorter than it declares is refused naming that file. Triangle fans are rewritten as
triangle lists (trimesh dropped them), and a node drawn as GPU instances
(``EXT_mesh_gpu_instancing``) as a node per instance (:func:`gltf_scene_header` gives the
node list so read); a file requiring an extension that could change its geometry is refused.
trimesh's log messages stay off procmod's one-line error channel.

Concave polygon faces of an OBJ are split into triangles here (trimesh fans them from
their first corner, covering more than the face); PLY, OFF and COLLADA files are read
with their polygons by :mod:`procmod.geometry.polygon_files`, a COLLADA file in its
declared units and up axis.
"""

from __future__ import annotations

import contextlib
import io
import json
import logging
import os
import re
import stat
import struct
import warnings
from pathlib import Path, PurePosixPath, PureWindowsPath
from urllib.parse import unquote

import numpy as np

from ..core.errors import cut_text, whole_number
from ..core.io import MAX_JSON_BYTES, lone_surrogate_at, lone_surrogate_text
from ..core.limits import relaxed_gc
from .gltf_accessors import INSTANCING, decoded_gltf, expanded_header, instance_count, instanced_nodes

# the mesh files :func:`load_mesh_file` reads (trimesh's formats procmod checks and fixes)
MESH_SUFFIXES = frozenset({".obj", ".glb", ".gltf", ".ply", ".stl", ".off", ".dae"})

_INDEXED = ("f", "l", "p")  # statements that index vertices (v/vt/vn per field)
_COUNTED = {"v": 0, "vt": 1, "vn": 2}
_BOM = "\xef\xbb\xbf"  # UTF-8's byte-order mark, as latin-1 decodes it


def normalised_obj(text: str) -> str | None:
    """``text`` (an OBJ file, decoded as latin-1) with relative indices made absolute,
    each statement re-spaced and cut at a ``#``, a byte-order mark dropped, lines ended by
    ``\\n`` and concave faces split into triangles (:func:`_split_concave_faces`); None
    when nothing needed changing (trimesh reads the file as it is).

    Raises ValueError for a face that names vertex 0: OBJ counts from 1, and trimesh read
    a file counted from 0 (a script's own exporter) without a word, each 0 as the last
    vertex."""
    with relaxed_gc():  # a million lines' lists: the collector scanned them over and over
        return _normalised_obj(text)


def _normalised_obj(text: str) -> str | None:
    changed = text.startswith(_BOM) or bool(re.search(r"\r(?!\n)", text))
    text = text.removeprefix(_BOM)
    text, line_of = _joined_statements(text)
    counts = [0, 0, 0]
    out = []
    positions = []  # the line in out of each v statement (read only if there are polygons)
    polygons = {}  # corners -> ([line in out], [its vertex numbers, space-separated]) of faces of 4+ corners
    for number, line in enumerate(text.splitlines(), 1):  # splits at \n, \r\n and a lone \r alike
        fields = line.split()
        if not fields or fields[0].startswith("#"):
            out.append(line)
            continue
        key = fields[0]
        if key in _COUNTED or key in _INDEXED:
            fields = line.split("#", 1)[0].split()  # a comment at the end of the statement
        if key in _COUNTED:
            counts[_COUNTED[key]] += 1
            if key == "v":
                positions.append(len(out))
                if len(fields) < 4 and "," in line:
                    raise ValueError(f"line {line_of(number)} ({' '.join(fields)[:40]!r}) separates its numbers "
                                     "with commas; OBJ separates them with spaces")
                if len(fields) < 4:  # trimesh read every vertex of the file as that many numbers
                    raise ValueError(f"line {line_of(number)} ({' '.join(fields)[:40]!r}) gives a vertex "
                                     f"{len(fields) - 1} coordinate{'s' * (len(fields) != 2)}, but an OBJ vertex "
                                     "takes three (x y z): export the file again in 3D")
        elif key in _INDEXED:
            if key == "f" and "," in line and "," in "".join(fields):  # (f 1,2,3 had been dropped without a word)
                raise ValueError(f"line {line_of(number)} ({' '.join(fields)[:40]!r}) separates its vertex numbers "
                                 "with commas; OBJ separates them with spaces")
            polygon = key == "f" and len(fields) > 4
            numbers = []
            for i in range(1, len(fields)):
                refs = fields[i].split("/")
                for slot, ref in enumerate(refs[:3]):
                    if "." in ref and re.fullmatch(r"[-+]?\d+\.0*", ref):  # 3.0: a script's exporter's float
                        refs[slot] = ref.split(".", 1)[0]
                # a face's vertex 0 (OBJ counts from 1): a 0 of a texture coordinate or normal,
                # or in a line, is no part of the geometry read
                if key == "f" and "0" in refs[0] and not refs[0].strip("+-0"):
                    raise ValueError(f"line {line_of(number)} ({' '.join(fields)[:40]!r}) names vertex 0, but OBJ "
                                     "numbers vertices from 1 (this file counts from 0, as some scripts' exporters "
                                     "do); export it again with numbers from 1")
                for slot, ref in enumerate(refs[:3]):
                    if ref.startswith("-"):
                        try:
                            refs[slot] = str(counts[slot] + 1 + int(ref))
                        except ValueError:  # not a number: trimesh decides what it makes of it
                            continue
                        if key == "f" and slot == 0 and int(refs[0]) < 1:
                            # left negative, trimesh counted it back from the file's end: a face on
                            # another object's vertex, without a word
                            raise ValueError(f"line {line_of(number)} ({' '.join(line.split())[:40]!r}) names "
                                             f"vertex {ref}, {-int(ref)} back, but only {counts[0]} vertices come "
                                             "before it; export it again")
                if polygon:
                    numbers.append(refs[0])
                fields[i] = "/".join(refs)
            if polygon:  # kept small: a million faces' field lists cost more than reading them
                lines, corners = polygons.setdefault(len(fields) - 1, ([], []))
                lines.append(len(out))
                corners.append(" ".join(numbers))
        statement = " ".join(fields)
        changed = changed or statement != line
        out.append(statement)
    changed = _split_concave_faces(out, positions, polygons) or changed
    return "\n".join(out) + "\n" if changed else None


_CONTINUATION = re.compile(r"\\\r?\n")  # a backslash that ends a line: the statement goes on


def _joined_statements(text: str) -> tuple:
    """``(text with line continuations joined, line_of)``: ``line_of(n)`` is the line of
    the file where the ``n``-th line of the joined text starts, for messages (a continued
    vertex had put every later line's number off by one)."""
    joined = _CONTINUATION.sub(" ", text)
    if len(joined) == len(text):
        return text, lambda number: number

    def line_of(number: int) -> int:
        line, statement = 1, 1
        for raw in text.splitlines(keepends=True):
            if statement == number:
                return line
            line += 1
            statement += not (raw.endswith("\\\n") or raw.endswith("\\\r\n"))
        return line

    return joined, line_of


def _split_concave_faces(out: list, positions: list, polygons: dict) -> bool:
    """Replace each concave face statement in ``out`` (``positions``: the lines of its
    vertices; ``polygons``: corner count -> faces) by its triangles, each corner's
    ``v/vt/vn`` reference kept (trimesh would fan it from its first corner, covering
    more than the face: :mod:`procmod.geometry.polygons`). The convex ones, nearly all,
    are told apart in one vectorised test per corner count. Faces whose corners are not
    all numbered vertices stay for trimesh to judge. Returns whether any was replaced."""
    from .polygons import fan_covers, polygon_triangles

    if not polygons:
        return False
    table = _numbers(" ".join(out[line][2:] for line in positions), np.float64, len(positions), 3)  # less "v "
    if table is None:  # other than three numbers a vertex (colours, w): one by one
        try:
            table = np.array([out[line].split()[1:4] for line in positions], dtype=np.float64)
        except ValueError:  # a vertex that is not three numbers: trimesh says what it makes of the file
            return False
    replaced = False
    for k, (lines, numbers) in polygons.items():
        corners = _numbers(" ".join(numbers), np.int64, len(lines), k)
        if corners is None:
            continue
        corners -= 1
        valid = ((corners >= 0) & (corners < len(table))).all(axis=1)
        if not valid.any():
            continue
        corners, lines = corners[valid], [line for line, ok in zip(lines, valid) if ok]
        points = table[corners]
        concave = ~fan_covers(points)
        for face in np.flatnonzero(concave):
            refs = out[lines[face]].split()[1:]
            out[lines[face]] = "\n".join("f " + " ".join(refs[j] for j in triangle)
                                         for triangle in polygon_triangles(points[face]))
            replaced = True
    return replaced


def _numbers(text: str, dtype, rows: int, width: int) -> np.ndarray | None:
    """The whitespace-separated numbers of ``text`` as ``rows`` rows of ``width`` (numpy's
    text parser: ~10x a split and convert), or None unless it is just that."""
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # numpy warns where a token is not a number, and stops there
        try:
            values = np.fromstring(text, dtype=dtype, sep=" ")
        except (ValueError, DeprecationWarning):
            return None
    return values.reshape(rows, width) if values.size == rows * width else None


def obj_problem(text: str) -> str | None:
    """What trimesh could not read in an OBJ file, said plainly (it raised "index 98 is
    out of bounds for axis 0 with size 12", "could not be read to its end due to
    unmatched data"), or None: a face corner that is no vertex number (``f a b c``), a face
    naming a vertex the file lacks, numbers written with decimal commas or separated by
    commas. Looked for only after trimesh failed."""
    vertices, highest = 0, (0, 0)
    text, line_of = _joined_statements(text.removeprefix(_BOM))
    for number, line in enumerate(text.splitlines(), 1):
        fields = line.split("#", 1)[0].split()
        if not fields:
            continue
        if fields[0] == "v":
            vertices += 1
            numbers = fields[1:4]
            if any(re.fullmatch(r"[-+]?\d*,\d+", f) for f in numbers):
                return (f"line {line_of(number)} ({' '.join(fields)[:40]!r}) writes numbers with decimal commas; "
                        "OBJ numbers take a point (1.5, not 1,5): export it again with a point as the decimal mark")
            if any(f.endswith(",") for f in numbers):
                return (f"line {line_of(number)} ({' '.join(fields)[:40]!r}) separates its numbers with commas; OBJ "
                        "separates them with spaces")
        elif fields[0] == "f":
            for field in fields[1:]:
                ref = field.split("/", 1)[0]
                if not re.fullmatch(r"[-+]?\d+(\.0*)?", ref, re.ASCII):  # (1.0: read as 1, normalised_obj)
                    return (f"line {line_of(number)} ({' '.join(fields)[:40]!r}) has {cut_text(field, 20)!r} "
                            "where a face names a vertex: a face line is 'f' and three or more vertex numbers "
                            "(counted from 1), each alone or as v/vt, v/vt/vn or v//vn; export it again")
                if ref.isdigit() and int(ref) > highest[0]:
                    highest = (int(ref), number)
    if highest[0] > vertices:
        return (f"line {line_of(highest[1])} names vertex {highest[0]}, but the file has {vertices} vertices; "
                "export it again")
    return None


# --- face counts, read without parsing ------------------------------------------------

_LINE_START = 64  # bytes of a line the patterns look at
_SCAN_BLOCK = 1 << 24


def _scan_lines(file: Path, pattern: re.Pattern) -> int:
    """Lines of a file that ``pattern`` matches at their start, read in blocks (a lower
    bound on a text mesh's faces). Of a line that runs on past a block only its start is
    kept: a file with no newline at all (CR line ends) is read in constant memory."""
    count, head = 0, b""  # the start of the line the last block left unfinished
    with open(file, "rb") as handle:
        while block := handle.read(_SCAN_BLOCK):
            first = block.find(b"\n")
            if first < 0:  # the unfinished line goes on
                head += block[:max(_LINE_START - len(head), 0)]
                continue
            count += 1 if pattern.match(head + block[:_LINE_START]) else 0
            last = block.rfind(b"\n") + 1
            count += sum(1 for _ in pattern.finditer(block, first + 1, last))
            head = block[last:last + _LINE_START]
    return count + (1 if head and pattern.match(head) else 0)


# an OBJ face line ("f 1 2 3", also after spaces or a tab, or "f\t1 2 3", as readers take
# them) and an ASCII STL's facet end in any case (ENDFACET): "\nf " and "endfacet" alone
# missed those, and a 4-million-face file was read for 24 s before it was refused
_OBJ_FACE = re.compile(rb"^[ \t]*f[ \t]", re.MULTILINE)
_STL_FACET = re.compile(rb"^[ \t]*endfacet\b", re.MULTILINE | re.IGNORECASE)


def declared_faces(file: Path) -> int | None:
    """The number of faces a mesh file declares or holds, read without parsing it (None
    where the format gives no cheap count): a binary STL's header, a PLY's or OFF's
    element counts, OBJ ``f`` lines, a glTF's index accessors times the nodes of its default
    scene that draw each mesh, a COLLADA file's primitive counts."""
    suffix = file.suffix.lower()
    try:
        if suffix == ".stl":
            with open(file, "rb") as handle:
                start = handle.read(STL_SNIFF)
            if _ascii_stl(start):
                return _scan_lines(file, _STL_FACET)
            if len(start) < 84:
                return None
            count = struct.unpack("<I", start[80:84])[0]
            if 84 + 50 * count != file.stat().st_size and _other_format(start) is not None:
                return 0  # not an STL at all: read, then named (the loader says what it holds)
            return count
        if suffix == ".ply":
            with open(file, "rb") as handle:
                header = handle.read(1 << 16).split(b"end_header", 1)[0]
            for line in header.splitlines():
                parts = line.split()
                if len(parts) == 3 and parts[0] == b"element" and parts[1] == b"face":
                    return int(parts[2])
            return None
        if suffix == ".off":
            with open(file, "rb") as handle:
                lines = [l.split(b"#", 1)[0].split() for l in handle.read(1 << 16).splitlines()]
            lines = [l for l in lines if l]
            if lines and lines[0][0].upper().endswith(b"OFF"):
                counts = lines[0][1:] if len(lines[0]) > 1 else (lines[1] if len(lines) > 1 else [])
                return int(counts[1]) if len(counts) >= 2 else None
            return None
        if suffix == ".obj":
            return _scan_lines(file, _OBJ_FACE)
        if suffix in (".glb", ".gltf"):
            return _gltf_faces(file)
        if suffix == ".dae":
            return _collada_faces(file)
    except (OSError, ValueError, struct.error):
        return None  # trimesh will say what is wrong with it
    return None


_COLLADA_PRIMITIVE = re.compile(rb"<(triangles|polylist|polygons)\b[^>]*?\bcount\s*=\s*[\"'](\d+)")


def _collada_faces(file: Path) -> int:
    """The faces a COLLADA file's triangle, polylist and polygon elements declare (each
    polygon counted once: a lower bound on the triangles), read in blocks."""
    faces, tail = 0, b""
    with open(file, "rb") as handle:
        while block := handle.read(1 << 24):
            data = tail + block
            cut = data.rfind(b"<")  # an element cut by the block's end is read with the next block
            if cut <= 0 or len(data) - cut > 4096:
                cut = len(data)
            faces += sum(int(m.group(2)) for m in _COLLADA_PRIMITIVE.finditer(data, 0, cut))
            tail = data[cut:]
    faces += sum(int(m.group(2)) for m in _COLLADA_PRIMITIVE.finditer(tail))
    return faces


def _gltf_faces(file: Path) -> int | None:
    try:
        spec = gltf_header(file, limit=1 << 26)
    except (OSError, ValueError):
        return None
    try:
        accessors = spec.get("accessors", [])
        per_mesh = []
        for mesh in spec.get("meshes", []):
            faces = 0
            for primitive in mesh.get("primitives", []):
                mode = primitive.get("mode", 4)
                index = primitive.get("indices", primitive.get("attributes", {}).get("POSITION"))
                if mode not in (4, 5, 6) or not (isinstance(index, int) and 0 <= index < len(accessors)):
                    continue  # points and lines have no faces
                count = int(accessors[index].get("count", 0))
                faces += count // 3 if mode == 4 else max(count - 2, 0)  # a list; a strip or fan
            per_mesh.append(faces)
        return _gltf_drawn_faces(spec, per_mesh)
    except (ValueError, TypeError, AttributeError, IndexError):
        return None


def _gltf_drawn_faces(spec: dict, per_mesh: list) -> int:
    """The faces a glTF's default scene draws: each node's mesh counted once per node that
    draws it (a mesh 1000 nodes draw is 1000 meshes once flattened: its faces had been
    counted once, and a 1.5 MB file filled 10 GB before it was refused). Without nodes or
    a scene, every mesh once."""
    nodes = spec.get("nodes") or []
    if not nodes:
        return sum(per_mesh)
    scenes = spec.get("scenes") or []
    default = spec.get("scene", 0)
    if not (scenes and isinstance(default, int) and 0 <= default < len(scenes)):
        return sum(per_mesh)  # no scene to draw: each mesh once (trimesh reads none of it, and says so)
    stack = list(scenes[default].get("nodes", []))
    seen, total = set(), 0
    while stack:
        i = stack.pop()
        if not isinstance(i, int) or not 0 <= i < len(nodes) or i in seen:
            continue  # a cycle or a node named twice: the reader refuses it
        seen.add(i)
        node = nodes[i]
        mesh = node.get("mesh")
        if isinstance(mesh, int) and 0 <= mesh < len(per_mesh):
            total += per_mesh[mesh] * max(1, instance_count(spec, i))  # GPU instances: a copy each
        stack.extend(node.get("children", []))
    return total


DRACO = "KHR_draco_mesh_compression"
MESHOPT = "EXT_meshopt_compression"
# words in the names of extensions a file may require that leave its geometry as trimesh
# reads it (materials, textures, lights, metadata: KHR_materials_*, MSFT_texture_dds,
# EXT_mesh_features) or that procmod decodes itself (KHR_mesh_quantization, gltf_accessors)
_HARMLESS = ("material", "texture", "light", "xmp", "metadata", "features", "animation", "camera", "audio",
             "variants", "emissive", "quantization", "lod")


def gltf_header(path: Path, limit: int | None = None) -> dict:
    """The JSON object of a ``.gltf``, or of a ``.glb``'s JSON chunk (glTF 2.0 container:
    12-byte header 'glTF', version, length; then chunk length, type 'JSON', data).

    Raises OSError (unreadable) or ValueError (not glTF, damaged, or JSON of more than
    ``limit`` bytes, default :data:`procmod.core.io.MAX_JSON_BYTES`), with a message that
    continues the file's name ("is not a ...")."""
    path = Path(path)
    limit = MAX_JSON_BYTES if limit is None else limit
    with open(path, "rb") as handle:
        # each read as what it is: a GLB under a .gltf name, a text glTF under a .glb name
        if is_binary_gltf(path) or (path.suffix.lower() == ".glb" and not _json_text(path)):
            head = handle.read(20)
            if len(head) < 20 or head[:4] != b"glTF":
                raise ValueError("is not a GLB file (no 'glTF' header); is it damaged or another format?")
            if struct.unpack("<I", head[4:8])[0] == 1:
                raise ValueError(_GLTF_1)
            length, kind = struct.unpack("<I4s", head[12:20])
            if length > limit:
                raise ValueError(f"has a JSON chunk of {length:,} bytes, more than {limit:,}")
            text = handle.read(length) if kind == b"JSON" else b""
            if len(text) < length or kind != b"JSON":
                raise ValueError("is a damaged GLB file (its JSON chunk is missing or cut off)")
        else:
            if os.path.getsize(path) > limit:
                raise ValueError(f"is more than {limit:,} bytes of JSON")
            handle.seek(0)
            text = handle.read()
    try:
        text = text.decode("utf-8-sig")  # a byte-order mark is no part of the JSON
        header = json.loads(text)
    except RecursionError:
        raise ValueError("is not a glTF file (its JSON nests more deeply than Python can read; a glTF file "
                         "nests a few levels)") from None
    except (UnicodeDecodeError, ValueError) as exc:
        raise ValueError(f"is not a glTF file (its JSON does not parse: {cut_text(str(exc), 80)})") from None
    lone = lone_surrogate_at(header, text)
    if lone is not None:  # (trimesh's scene graph raised a traceback hashing such a node name)
        raise ValueError(f"is a glTF file whose {lone_surrogate_text(lone)}")
    if not isinstance(header, dict):
        raise ValueError("is not a glTF file (its JSON is not an object)")
    asset = header.get("asset")
    version = asset.get("version") if isinstance(asset, dict) else None
    if (isinstance(version, str) and version.strip().startswith("1")) or \
            any(isinstance(header.get(key), dict) for key in ("nodes", "meshes", "accessors")):  # 1.0's objects by id
        raise ValueError(_GLTF_1)
    return header


_GLTF_1 = ("is glTF 1.0, which procmod does not read (glTF 2.0 only); convert it to glTF 2.0: "
           "`npx gltf-pipeline -i OLD.gltf -o NEW.gltf` upgrades it")


def _draco_without_fallback(header: dict) -> bool:
    """Whether a file that uses Draco (not requires it) has a compressed primitive with
    no plain positions beside it: the glTF spec lets a file keep uncompressed data for
    readers without Draco, which is read then; without it trimesh read placeholder zeros."""
    accessors = header.get("accessors") if isinstance(header.get("accessors"), list) else []
    for mesh in header.get("meshes") or ():
        for primitive in (mesh.get("primitives") or ()) if isinstance(mesh, dict) else ():
            if not isinstance(primitive, dict) or DRACO not in (primitive.get("extensions") or {}):
                continue
            index = (primitive.get("attributes") or {}).get("POSITION")
            accessor = accessors[index] if isinstance(index, int) and 0 <= index < len(accessors) else None
            if not isinstance(accessor, dict) or ("bufferView" not in accessor and "sparse" not in accessor):
                return True
    return False


def _check_gltf(path: Path) -> dict | None:
    """Refuse what cannot be read right; returns the file's JSON (None if it does not parse:
    the loader says what is wrong with it)."""
    try:
        header = gltf_header(path, limit=64 * 2 ** 20)
    except ValueError as exc:
        if str(exc) == _GLTF_1:
            raise
        return None
    except OSError:
        return None
    required = header.get("extensionsRequired")
    if (isinstance(required, list) and DRACO in required) or _draco_without_fallback(header):
        raise ValueError(f"its meshes are Draco-compressed ({DRACO}), which procmod cannot decode; export "
                         "it without mesh compression")
    if isinstance(required, list) and MESHOPT in required:
        raise ValueError(f"its buffers are meshopt-compressed ({MESHOPT}), which procmod cannot decode; export "
                         "it without compression (gltfpack without -c, or `gltf-transform copy` after "
                         "decompressing)")
    # GPU instances are expanded into nodes (gltf_accessors.expanded_instances), not refused
    unknown = [name for name in required if isinstance(name, str) and name != INSTANCING
               and not any(word in name.lower() for word in _HARMLESS)] \
        if isinstance(required, list) else []
    if unknown:
        raise ValueError(f"it requires the glTF extension {unknown[0]}, which procmod does not read (so its "
                         "geometry might be misread); export it without that extension")
    glb = is_binary_gltf(path)  # a GLB under a .gltf name too; a text glTF under a .glb name is text
    _check_buffer_files(header, path, glb)  # (a GLB's buffers after its binary chunk may name files too)
    if glb:  # a GLB's header gives its whole length
        with open(path, "rb") as handle:
            declared = struct.unpack("<I", handle.read(12)[8:12])[0]
        actual = os.path.getsize(path)
        if actual < declared:
            raise ValueError(f"a cut-off GLB file: its header says {declared:,} bytes but the file holds {actual:,}; "
                             "export or copy it again")
    _check_buffer_layout(header, glb)
    return header


_COMPONENT_BYTES = {5120: 1, 5121: 1, 5122: 2, 5123: 2, 5125: 4, 5126: 4}
_TYPE_COMPONENTS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT2": 4, "MAT3": 9, "MAT4": 16}


def _whole(value, default=None):
    """``value`` if it is a whole number of 0 or more (:func:`~procmod.core.errors.whole_number`),
    else ``default``."""
    number = whole_number(value)
    return number if number is not None and number >= 0 else default


def _check_buffer_layout(header: dict, glb: bool) -> None:
    """Refuse buffers, buffer views and accessors that do not fit each other, naming the
    field (trimesh failed on them with an empty AssertionError, ``KeyError: 'uri'`` or a
    reshape of 10^12 rows): a ``.gltf`` buffer without a file (a GLB's JSON saved alone),
    a view reaching past its buffer, an accessor reaching past its view. Fields of other
    types are left to the reader."""
    buffers = header.get("buffers") if isinstance(header.get("buffers"), list) else []
    lengths = []
    for i, buffer in enumerate(buffers):
        buffer = buffer if isinstance(buffer, dict) else {}
        extensions = buffer.get("extensions") if isinstance(buffer.get("extensions"), dict) else {}
        if isinstance(extensions.get(MESHOPT), dict) and extensions[MESHOPT].get("fallback") \
                and not isinstance(buffer.get("uri"), str):
            # a fallback buffer without a file holds no data, by design (gltfpack -cf's has one: read)
            raise ValueError(f"its buffers are meshopt-compressed ({MESHOPT}), which procmod cannot decode; export "
                             "it without compression")
        if not isinstance(buffer.get("uri"), str) and not (glb and i == 0):
            raise ValueError(f"buffers[{i}] names no file (\"uri\"): a .gltf keeps its buffers in files beside it "
                             "(this looks like a GLB's JSON saved alone); export a .glb, or the .gltf with its .bin"
                             if not glb else f"buffers[{i}] names no file (\"uri\"), and only the first buffer of "
                             "a GLB is its binary chunk; export the file again")
        lengths.append(_whole(buffer.get("byteLength")))
    views = header.get("bufferViews") if isinstance(header.get("bufferViews"), list) else []
    view_lengths = []
    for j, view in enumerate(views):
        view = view if isinstance(view, dict) else {}
        b, offset, length = _whole(view.get("buffer")), _whole(view.get("byteOffset"), 0), _whole(view.get("byteLength"))
        view_lengths.append(length)
        if b is None or length is None:
            continue
        if b >= len(buffers):
            raise ValueError(f"bufferViews[{j}] refers to buffer {b}, which the file does not have; export it again")
        if lengths[b] is not None and offset + length > lengths[b]:
            raise ValueError(f"bufferViews[{j}] reaches byte {offset + length:,} of buffer {b}, which holds "
                             f"{lengths[b]:,}: the file is damaged; export it again")
    accessors = header.get("accessors") if isinstance(header.get("accessors"), list) else []
    for k, accessor in enumerate(accessors):
        accessor = accessor if isinstance(accessor, dict) else {}
        v, count = _whole(accessor.get("bufferView")), _whole(accessor.get("count"))
        size = _COMPONENT_BYTES.get(accessor.get("componentType"))
        components = _TYPE_COMPONENTS.get(accessor.get("type"))
        if v is None or count is None or size is None or components is None:
            continue
        if v >= len(views):
            raise ValueError(f"accessors[{k}] refers to bufferView {v}, which the file does not have; export it again")
        have = view_lengths[v]
        stride = _whole(views[v].get("byteStride"), 0) if isinstance(views[v], dict) else 0
        need = _whole(accessor.get("byteOffset"), 0) + (
            (count - 1) * max(stride, size * components) + size * components if count else 0)
        if have is not None and need > have:
            raise ValueError(f"accessors[{k}] needs {need:,} bytes of bufferViews[{v}], which holds {have:,} "
                             f"({count:,} {accessor['type']} values): the file is damaged; export it again")


def _check_buffer_files(header: dict, path: Path, glb: bool = False) -> None:
    """Refuse a glTF whose buffer file (found as :func:`_resolver` finds it) is missing,
    no regular file (a named pipe: reading it waits for ever) or shorter than the
    ``byteLength`` the file gives it. A GLB's first buffer is its binary chunk."""
    buffers = header.get("buffers")
    for i, buffer in enumerate(buffers if isinstance(buffers, list) else ()):
        uri = buffer.get("uri") if isinstance(buffer, dict) else None
        if not isinstance(uri, str) or uri.startswith("data:") or (glb and i == 0):
            continue
        names, absolute = _uri_names(uri)
        sizes = [os.path.getsize(path.parent / n) for n in names if (path.parent / n).is_file()]
        if not sizes and absolute:
            raise _absolute_uri_error(uri)
        kind = next(filter(None, (special_file_kind(path.parent / n) for n in names if n)), None)
        if not sizes and kind is not None:  # (a named pipe had been called missing; reading it waits for ever)
            raise ValueError(f"the buffer file {uri!r} it names is {kind}, not a file; put the buffer's file "
                             f"itself beside {path.name}, or export a .glb, which holds its buffers")
        if not sizes:
            raise ValueError(f"the buffer file {uri!r} it names is missing (looked for beside {path.name}); copy "
                             "it along, or export a .glb, which holds its buffers")
        declared = buffer.get("byteLength")
        if isinstance(declared, int) and not isinstance(declared, bool) and sizes[0] < declared:
            raise ValueError(f"its buffer file {uri!r} is {sizes[0]:,} bytes but the glTF says {declared:,}: the "
                             "file is cut off; copy it again or export the model again")


def special_file_kind(path: Path) -> str | None:
    """What ``path`` is when it is there but no regular file: ``"a named pipe (FIFO)"``,
    ``"a folder"``, ``"a device"`` or ``"a socket"``; None for a regular file, or a name
    that is not there or cannot be looked up (opening it says what is wrong)."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISREG(mode):
        return None
    return ("a named pipe (FIFO)" if stat.S_ISFIFO(mode) else "a folder" if stat.S_ISDIR(mode) else
            "a socket" if stat.S_ISSOCK(mode) else "a device")


STL_SNIFF = 1 << 20  # bytes of an STL looked at to tell ASCII from binary (a solid's name may be long)
_ASCII_VERTEX = re.compile(rb"vertex[ \t]+[-+0-9.]", re.IGNORECASE)
_UTF8_BOM = _BOM.encode("latin-1")  # the mark's bytes, as an STL holds them


def _ascii_stl(head: bytes) -> bool:
    """Whether the first bytes of an STL are ASCII STL text: a ``vertex`` and its first
    number past the 84 bytes of a binary file's header and count, where a binary file holds
    its packed triangles; with its ``solid`` line or without (some exporters leave it out),
    a UTF-8 byte-order mark, tabs, NUL bytes (padding, a C string's end) or not."""
    return _ASCII_VERTEX.search(head, 84, STL_SNIFF) is not None


def _stl_binary_fits(data: bytes) -> bool:
    """Whether ``data`` is a binary STL whose triangle count fits its size exactly."""
    return len(data) >= 84 and 84 + 50 * struct.unpack("<I", data[80:84])[0] == len(data)


def _repaired_stl(data: bytes) -> bytes | None:
    """A binary STL whose header count disagrees with its size, read by its size where
    that is unambiguous, or an ASCII STL made what trimesh reads: its byte-order mark
    dropped, tabs made spaces, its ``solid`` and ``endsolid`` lines added where missing;
    None when the file needs nothing. Raises ValueError for a binary STL cut off inside
    its triangles, and names the format of another kind of file given an ``.stl`` name."""
    if _ascii_stl(data) and not _stl_binary_fits(data):
        text = data[len(_UTF8_BOM):] if data.startswith(_UTF8_BOM) else data
        text = text.replace(b"\t", b" ").replace(b"\0", b" ")
        if not text.lstrip().lower().startswith(b"solid"):
            text = b"solid\n" + text
        if b"endsolid" not in text[-(1 << 20):].lower():
            text += b"\nendsolid\n"
        return None if text == data else text
    if len(data) < 84:
        return None  # the loader says what is wrong with it
    count = struct.unpack("<I", data[80:84])[0]
    records = (len(data) - 84) // 50
    if 84 + 50 * count == len(data):
        return None
    if count == 0 and records and (len(data) - 84) % 50 == 0:
        return data[:80] + struct.pack("<I", records) + data[84:]  # an exporter that left the count out
    if 0 < count <= records:
        return data[:84 + 50 * count]  # bytes after the last triangle (padding, a tool's trailer)
    if (kind := _other_format(data)) is not None:  # no binary STL either way: say what it is
        raise ValueError(f"it holds {kind}, not STL; rename it to its format's suffix")
    if count > records:
        raise ValueError(f"a cut-off binary STL: its header says {count:,} triangles but the file holds "
                         f"{records:,}; export or copy it again")
    return None


def _other_format(head: bytes) -> str | None:
    """The format of a mesh file's first bytes when they are plainly another format's
    start (a GLB's header, a PLY's or an OFF's first lines, OBJ statements), or None. For
    files that are no binary STL either (their count does not fit their size): an STL's
    80-byte header is free text and may start with any of these words."""
    if head.startswith(b"glTF") and len(head) >= 12 and struct.unpack("<I", head[4:8])[0] == 2:
        return "a binary glTF (GLB)"
    text = head[len(_UTF8_BOM):] if head.startswith(_UTF8_BOM) else head
    if re.match(rb"ply\r?\n\s*format\s", text):
        return "a PLY mesh"
    sample = text[:1 << 16]
    if b"\0" in sample:
        return None  # OFF and OBJ files are text
    if re.match(rb"\s*[CN]?OFF\s*\r?\n", sample):
        return "an OFF mesh"
    if re.search(rb"(^|\n)\s*v\s", sample) and re.search(rb"(^|\n)\s*f\s", sample):
        return "OBJ text"
    return None


def _uri_names(uri: str) -> tuple[list[str], bool]:
    """The names, relative to the ``.gltf``, a URI it holds may mean (as written,
    percent-decoded and with ``\\`` read as ``/``), and whether it is absolute: an exporter's absolute path means the
    file of that name beside the ``.gltf``, as trimesh looks for it, and nothing
    elsewhere on the machine."""
    plain = unquote(uri)
    # a Windows tool's separator (buf\\data.bin), as procmod's own files may use it too
    names = list(dict.fromkeys([uri, plain, plain.replace("\\", "/")]))
    if any(PurePosixPath(n).is_absolute() or PureWindowsPath(n).is_absolute() for n in names):
        return [PureWindowsPath(unquote(uri)).name], True
    return names, False


def _absolute_uri_error(uri: str) -> ValueError:
    return ValueError(f"{uri!r} is an absolute path and no {_uri_names(uri)[0][0]!r} lies beside the file; a file a "
                      "glTF names must be relative to it")


def _resolver(path: Path):
    """A resolver for the files a ``.gltf`` names (see the module docstring)."""
    import trimesh

    class NamedFileResolver(trimesh.resolvers.FilePathResolver):
        def get(self, name: str):
            names, absolute = _uri_names(name)
            for candidate in names:
                try:
                    return super().get(candidate)
                except FileNotFoundError:
                    continue
                except ValueError:
                    if absolute:
                        break
                    raise
            if absolute:
                raise _absolute_uri_error(name) from None
            raise FileNotFoundError(name)

    return NamedFileResolver(str(path), allow_anywhere=True)


@contextlib.contextmanager
def quiet_trimesh():
    """trimesh logs warnings (a missing material file, an extension it cannot decode) and
    numpy warns on odd data: neither belongs on procmod's one-line error channel."""
    logger = logging.getLogger("trimesh")
    level = logger.level
    logger.setLevel(logging.CRITICAL)
    try:
        with warnings.catch_warnings(), np.errstate(all="ignore"):
            warnings.simplefilter("ignore")
            yield
    finally:
        logger.setLevel(level)


def load_mesh_file(path: str | Path, up: str | None = "y", **options):
    """``trimesh.load(path, **options)`` (a mesh or, with ``force="scene"``, a scene):
    OBJ read through :func:`normalised_obj` (materials and other files it names are still
    found beside it), glTF with procmod's rules for the files it names (module docstring),
    PLY, OFF and COLLADA by :mod:`procmod.geometry.polygon_files` (a COLLADA file turned
    from its own up axis to ``up``, ``"y"`` or ``"z"``; ``None`` leaves its axes as they are)."""
    import trimesh

    path = Path(path)
    suffix = path.suffix.lower()
    file_type = None
    if suffix == ".gltf" and is_binary_gltf(path):
        suffix, file_type = ".glb", "glb"  # a binary glTF under a .gltf name: read as what it is
    elif suffix == ".glb" and not is_binary_gltf(path) and _json_text(path):
        suffix, file_type = ".gltf", "gltf"  # a text glTF under a .glb name (a renamed export): likewise
    with quiet_trimesh():
        if suffix == ".obj":
            # latin-1 maps every byte to one character and back: names in other encodings survive
            text = path.read_bytes().decode("latin-1")
            fixed = normalised_obj(text)
            try:
                if fixed is not None:
                    mesh = trimesh.load(io.BytesIO(fixed.encode("latin-1")), file_type="obj",
                                        resolver=trimesh.resolvers.FilePathResolver(str(path)), **options)
                else:
                    mesh = trimesh.load(path, **options)
            except Exception:
                problem = obj_problem(text)
                if problem is None:
                    raise
                raise ValueError(problem) from None
            if len(getattr(mesh, "faces", ())) == 0 and (problem := obj_problem(text)) is not None:
                raise ValueError(problem)  # trimesh read nothing, without a word
            return mesh
        if suffix == ".stl":
            fixed = _repaired_stl(path.read_bytes())
            if fixed is not None:
                return trimesh.load(io.BytesIO(fixed), file_type="stl", **options)
        if suffix in (".ply", ".off", ".dae"):  # polygon faces kept and triangulated right (polygon_files)
            from .polygon_files import read_collada, read_off, read_ply

            vertices, faces = read_collada(path, up) if suffix == ".dae" else \
                (read_ply if suffix == ".ply" else read_off)(path)
            mesh = trimesh.Trimesh(vertices=vertices, faces=faces, process=False)
            return trimesh.Scene(mesh) if options.get("force") == "scene" else mesh
        if suffix in (".gltf", ".glb"):
            header = _check_gltf(path)
            if header is not None:
                decoded = decoded_gltf(path, header, _resolver(path))
                if decoded is not None:  # positions trimesh would misread, rewritten as floats
                    return trimesh.load(io.BytesIO(decoded), file_type="gltf", resolver=_resolver(path), **options)
            if suffix == ".gltf":
                if _first_bytes(path, len(_UTF8_BOM)) == _UTF8_BOM:  # a Windows editor's mark: no part of the JSON
                    return trimesh.load(io.BytesIO(path.read_bytes()[len(_UTF8_BOM):]), file_type="gltf",
                                        resolver=_resolver(path), **options)
                return trimesh.load(path, file_type="gltf", resolver=_resolver(path), **options)
        if file_type is not None:
            return trimesh.load(path, file_type=file_type, **options)
        return trimesh.load(path, **options)


def gltf_scene_header(path: str | Path, header: dict) -> dict:
    """The JSON of a glTF (``header``, :func:`gltf_header`'s) as :func:`load_mesh_file` reads
    it: each node drawn as GPU instances an empty over a node per instance
    (:func:`~procmod.geometry.gltf_accessors.expanded_instances`), so that a reader walking
    the nodes finds the scene trimesh reads. Raises ValueError where those instances cannot
    be read and the file requires them, and for what :func:`load_mesh_file` refuses before
    reading any buffer (a buffer file missing, cut off or a named pipe, Draco)."""
    path = Path(path)
    if not instanced_nodes(header):
        return header
    # the checks load_mesh_file makes before it reads a buffer, made here first: reading the
    # instances' accessors had waited for ever on a buffer file that is a named pipe, and
    # said only "(NAME.bin)" for one that is missing
    _check_gltf(path)
    with quiet_trimesh():
        return expanded_header(path, header, _resolver(path))


def is_binary_gltf(path: Path) -> bool:
    """Whether a file starts as a GLB does (whatever its suffix)."""
    return _first_bytes(Path(path), 4) == b"glTF"


def _json_text(path: Path) -> bool:
    """Whether a file starts as a JSON object does (after a byte-order mark and blanks):
    a text glTF, whatever its suffix."""
    head = _first_bytes(Path(path), 64)
    head = head[len(_UTF8_BOM):] if head.startswith(_UTF8_BOM) else head
    return head.lstrip(b" \t\r\n").startswith(b"{")


def _first_bytes(path: Path, count: int) -> bytes:
    """The first ``count`` bytes of a file (fewer if it is shorter; none if unreadable:
    the loader then says what is wrong)."""
    try:
        with open(path, "rb") as handle:
            return handle.read(count)
    except OSError:
        return b""


__all__ = ["MESH_SUFFIXES", "declared_faces", "gltf_header", "gltf_scene_header", "load_mesh_file", "normalised_obj",
           "quiet_trimesh", "special_file_kind"]
