"""Shapes made of rigid parts and their graphs, as files (seed 001, section 3).

A shapes file (``procmod-shapes/1``) is ``{"format": "procmod-shapes/1", "parts": {...},
"shapes": [{"nodes": [{"part": NAME, "transform": [[4x4]]}, ...]}, ...]}``: a part library
(as in ``procmod-examples/1``) and flat lists of part instances in world space.

Each part name gets a one-letter node type (:func:`type_letters`). A shape graph
(``procmod-graph/1``) is a typed graph, one node per part. Contacts are computed in
:mod:`.contacts`, the tiling grammar in :mod:`.grammar`.
"""

from __future__ import annotations

import json
import math
import os
import posixpath
import re
from dataclasses import dataclass, field
from pathlib import Path

import networkx as nx
import numpy as np

from ..core.errors import InvalidArgumentError, ProcmodError
from ..core.paths import contained_path, named_file
from ..core.io import check_format, read_json, write_text_atomic
from ..core.runfolder import check_output_file
from ..geometry.part_library import (PartLibraryError, part_library_to_json, read_part_library, read_transform,
                                     transform_to_json)
from .codec import LETTERS, GraphError, check_graph

SHAPES_FORMAT = "procmod-shapes/1"
GRAPH_FORMAT = "procmod-graph/1"


class ShapesFormatError(ProcmodError):
    """A shapes or graph file that cannot be read; the message names the JSON path."""


@dataclass(frozen=True)
class Shape:
    """One shape: part names and their 4x4 world transforms (numpy arrays)."""

    parts: tuple  # part names
    transforms: tuple  # 4x4 float arrays

    def __len__(self) -> int:
        return len(self.parts)

    @staticmethod
    def of(parts, transforms) -> "Shape":
        return Shape(tuple(parts), tuple(np.asarray(t, dtype=np.float64).reshape(4, 4) for t in transforms))


@dataclass
class ShapeSet:
    """A part library, its type letters and shapes (what a shapes file holds)."""

    library: dict  # name -> PartShape
    shapes: list  # of Shape
    letters: dict  # part name -> one-letter type
    base_dir: Path | None = None  # where mesh paths are relative to (None: meshes from asset files, held here)
    # the contact tolerance in world units (a shapes file's "contact_tolerance", augment's
    # --tolerance); None: contacts.tolerance_for the library
    tolerance: float | None = None
    source: str | None = field(default=None, compare=False)  # the file read, for messages about its fields
    # (name, base name, size difference, mirrored) of parts that are another resized a little (strings.assets)
    resized: tuple = field(default=(), compare=False)

    @property
    def part_of_letter(self) -> dict:
        return {v: k for k, v in self.letters.items()}

    def types(self, shape: Shape) -> list[str]:
        return [self.letters[p] for p in shape.parts]


def type_letters(names) -> dict[str, str]:
    """One distinct letter per part name, in sorted name order.

    A name that is itself one letter keeps it; otherwise the first letter of the name
    upper-cased, else lower-cased, else the name's other letters, else the first unused
    letter A-Z, a-z.
    """
    names = sorted(names)
    used: set[str] = set()
    out: dict[str, str] = {}
    for name in names:
        if len(name) == 1 and name in LETTERS:
            out[name] = name
            used.add(name)
    for name in names:
        if name in out:
            continue
        candidates = [c for ch in name if ch in LETTERS for c in (ch.upper(), ch.lower())]
        candidates += sorted(LETTERS)
        letter = next((c for c in candidates if c not in used), None)
        if letter is None:
            raise ShapesFormatError(f"more than {len(LETTERS)} part names; node types are single letters")
        out[name] = letter
        used.add(letter)
    return out


def read_shapes(path: str | os.PathLike) -> ShapeSet:
    """Read a ``procmod-shapes/1`` file (mesh paths relative to it), checked.

    Raises
    ------
    ShapesFormatError
        Naming the JSON path of the problem (``shapes[2].nodes[5].part``).
    """
    _check_path(path, "shapes file")
    path = Path(path)
    if not path.exists():
        raise ShapesFormatError(f"shapes file {path} does not exist")
    if not path.is_file():
        raise ShapesFormatError(f"shapes file {path} is not a regular file (a folder, a device or a pipe); give a "
                                "procmod-shapes/1 file")
    return shapes_from_dict(read_json(path, ShapesFormatError, "shapes file"), path.parent, str(path))


def shapes_from_dict(data, base_dir, source: str = "shapes") -> ShapeSet:
    """A :class:`ShapeSet` from the parsed JSON of a shapes file."""
    check_format(data, SHAPES_FORMAT, source, ShapesFormatError)
    try:
        library = read_part_library(data.get("parts"), base_dir)
    except PartLibraryError as exc:
        raise ShapesFormatError(f"{source}: {exc}") from None
    shapes_json = data.get("shapes")
    if not isinstance(shapes_json, list) or not shapes_json:
        raise ShapesFormatError(f"{source}: 'shapes' must be a non-empty list of {{\"nodes\": [...]}}")
    shapes = []
    for i, s in enumerate(shapes_json):
        where = f"shapes[{i}]"
        if not isinstance(s, dict) or not isinstance(s.get("nodes"), list) or not s["nodes"]:
            raise ShapesFormatError(f"{source}: {where}: expected {{\"nodes\": [...]}} with at least one node")
        names, transforms = [], []
        for j, node in enumerate(s["nodes"]):
            w = f"{where}.nodes[{j}]"
            if not isinstance(node, dict):
                raise ShapesFormatError(f"{source}: {w}: expected {{\"part\": NAME, \"transform\": [[4x4]]}}")
            name = node.get("part")
            if name not in library:
                raise ShapesFormatError(f"{source}: {w}.part: unknown part {name!r}; the library has "
                                        f"{', '.join(sorted(library))}")
            try:
                transforms.append(read_transform(node.get("transform"), f"{w}.transform"))
            except PartLibraryError as exc:
                raise ShapesFormatError(f"{source}: {exc}") from None
            names.append(name)
        shapes.append(Shape.of(names, transforms))
    return ShapeSet(library, shapes, type_letters(library), Path(base_dir),
                    checked_tolerance(data.get("contact_tolerance"), f"{source}: contact_tolerance", ShapesFormatError),
                    source=source)


def checked_tolerance(value, where: str, error=InvalidArgumentError) -> float | None:
    """A contact tolerance (world units): None, or a finite number >= 0; else ``error``
    naming ``where``."""
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value) or value < 0:
        raise error(f"{where} must be a finite number >= 0 (world units: gaps up to it count as contacts), "
                    f"got {value!r:.40}")
    return float(value)


def shapes_to_dict(shape_set: ShapeSet, shapes=None) -> dict:
    """The JSON object of a shapes file for ``shapes`` (default: the set's own)."""
    shapes = shape_set.shapes if shapes is None else shapes
    data = {"format": SHAPES_FORMAT, "parts": part_library_to_json(shape_set.library),
            "shapes": [{"nodes": [{"part": p, "transform": transform_to_json(t)}
                                  for p, t in zip(s.parts, s.transforms)]} for s in shapes]}
    if shape_set.tolerance is not None:  # the collection and a model trained on it keep the user's
        data["contact_tolerance"] = shape_set.tolerance
    return data


def mesh_obj_text(vertices, faces) -> str:
    """A triangle mesh as OBJ text that reads back exactly (every float as Python writes
    it back, vertices in order, no normals or texture coordinates)."""
    lines = [f"v {float(x)!r} {float(y)!r} {float(z)!r}" for x, y, z in vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    return "\n".join(lines) + "\n"


def _gltf_file_copy(folder: Path, target: Path, name: str, where: str) -> Path:
    """Where the file a ``.gltf`` copied to ``target`` names (``name``, relative to it) is
    copied: at the same relative place, which must lie inside ``folder`` (the new shapes
    file's), not only inside the glTF's own folder: ``meshes/m.gltf`` naming
    ``../textures/wood.png`` is copied (it had been refused), ``../x.bin`` at the top is not."""
    if ".." in re.split(r"[/\\]", name) and not posixpath.isabs(name.replace("\\", "/")):
        inside = target.parent.relative_to(folder).as_posix()
        joined = posixpath.normpath(posixpath.join(inside, name.replace("\\", "/")))
        if joined != ".." and not joined.startswith("../"):
            return contained_path(folder, joined, where)
    return contained_path(target.parent, name, where)  # refused there with the name as written


def _copy_gltf_files(source: Path, target: Path, where: str, folder: Path) -> None:
    """The files a copied ``.gltf`` names (external buffers, images), copied beside the
    copy at the same relative places: without them the copy cannot be read."""
    import shutil
    from urllib.parse import unquote

    from ..geometry.mesh_files import gltf_header

    if source.suffix.lower() != ".gltf":
        return
    try:
        header = gltf_header(source)
    except (OSError, ValueError):
        return  # unreadable: the copy fails to load with the loader's own message
    for kind in ("buffers", "images"):
        for item in header.get(kind) or []:
            uri = item.get("uri") if isinstance(item, dict) else None
            if not isinstance(uri, str) or uri.startswith("data:"):
                continue
            name = unquote(uri)
            found = source.parent / name
            if kind == "images" and not found.is_file():
                continue  # the mesh reads without its textures (trimesh skips a missing one)
            copy = _gltf_file_copy(folder, target, name, f"{where}: {source.name}: {kind} {uri!r}")
            copy.parent.mkdir(parents=True, exist_ok=True)
            shutil.copyfile(named_file(source.parent, name, f"{where}: {source.name}", kind=kind[:-1]), copy)


def _copied_files(shape_set: ShapeSet, folder: Path):
    """``(relative path, where)`` of each file :func:`write_shapes` copies into ``folder``
    (mesh files and the buffers and images a ``.gltf`` names): none when the set is written
    in its own folder or its meshes are written out (``base_dir`` None)."""
    from urllib.parse import unquote

    from ..core.paths import UnsafePathError
    from ..geometry.mesh_files import gltf_header

    if shape_set.base_dir is None or folder.resolve() == Path(shape_set.base_dir).resolve():
        return
    for shape in shape_set.library.values():
        if shape.kind != "mesh":
            continue
        where = f"{shape_set.source + ': ' if shape_set.source else ''}parts.{shape.name}.mesh"
        try:
            target = contained_path(folder, shape.source, where)
        except UnsafePathError:
            continue  # write_shapes refuses it with its own message
        yield target.relative_to(folder).as_posix(), where
        source = Path(shape_set.base_dir) / target.relative_to(folder)  # a path written with backslashes too
        if source.suffix.lower() != ".gltf":
            continue
        try:
            header = gltf_header(source)
        except (OSError, ValueError):
            continue
        for kind in ("buffers", "images"):
            for item in header.get(kind) or []:
                uri = item.get("uri") if isinstance(item, dict) else None
                if isinstance(uri, str) and not uri.startswith("data:"):
                    try:
                        copy = _gltf_file_copy(folder, target, unquote(uri), where)
                    except UnsafePathError:
                        continue
                    yield copy.relative_to(folder).as_posix(), f"{where}: {source.name}: {kind} {uri!r}"


def check_copies(shape_set: ShapeSet, path: str | os.PathLike, own_files: tuple = ()) -> None:
    """ShapesFormatError when a file :func:`write_shapes` would copy beside the shapes file
    ``path`` would land on the shapes file itself or on an entry the caller writes there
    (``own_files``: regular expressions of the folder's top-level names, a run folder's
    :attr:`~procmod.core.runfolder.RunKind.patterns`): the caller's file would replace the
    copy (a glTF buffer named ``strings.txt`` in a collection), leaving the written set
    unreadable."""
    path = Path(path)
    mine = (re.escape(path.name), *own_files)
    for relative, where in _copied_files(shape_set, path.parent):
        top = relative.split("/")[0]  # (a file in the caller's folder, graphs/, is the caller's too)
        if any(re.fullmatch(pattern, top, re.IGNORECASE) for pattern in mine):
            raise ShapesFormatError(f"{where}: the file {relative!r} would be copied where procmod writes a file of "
                                    "its own (the written shapes could not read it back); rename it (and the "
                                    "name that gives it)")


def write_shapes(shape_set: ShapeSet, path: str | os.PathLike, shapes=None, own_files: tuple = ()) -> None:
    """Write a shapes file atomically. Mesh paths are written as they were read; mesh files
    are copied beside the new file when it goes to another folder; meshes read from asset
    files (``base_dir`` None) are written as OBJ files at their ``parts/NAME.obj``.

    ``own_files``: regular expressions of the top-level names the caller writes beside it
    (a run folder's patterns); a copied file at one of them is refused (see
    :func:`check_copies`)."""
    import shutil

    _check_path(path, "shapes file")
    path = check_output_file(path, "path")  # its '..' resolved: written there
    check_copies(shape_set, path, own_files)
    if shape_set.base_dir is None:  # meshes read from asset files: written out as they are held
        for shape in shape_set.library.values():
            if shape.kind == "mesh":
                target = contained_path(path.parent, shape.source, f"parts.{shape.name}.mesh")
                target.parent.mkdir(parents=True, exist_ok=True)
                write_text_atomic(target, mesh_obj_text(shape.vertices, shape.faces))
    elif path.parent.resolve() != Path(shape_set.base_dir).resolve():
        for shape in shape_set.library.values():
            if shape.kind == "mesh":
                # inside the new file's folder only (a mesh the shapes file reached with ".." is refused)
                where = f"{shape_set.source + ': ' if shape_set.source else ''}parts.{shape.name}.mesh"
                target = contained_path(path.parent, shape.source, where)
                target.parent.mkdir(parents=True, exist_ok=True)
                source = named_file(shape_set.base_dir, shape.source, where)
                shutil.copyfile(source, target)
                _copy_gltf_files(source, target, where, path.parent)
    write_text_atomic(path, json.dumps(shapes_to_dict(shape_set, shapes)) + "\n")


# ---------------------------------------------------------------------------------------------
# Graph files


def graph_to_dict(g: nx.Graph) -> dict:
    """The ``procmod-graph/1`` JSON object of a typed graph."""
    n = g.number_of_nodes()
    return {"format": GRAPH_FORMAT, "types": [g.nodes[v]["type"] for v in range(n)],
            "edges": sorted([min(u, v), max(u, v)] for u, v in g.edges)}


def graph_from_dict(data, source: str = "graph") -> nx.Graph:
    """A typed graph from ``procmod-graph/1`` JSON, checked (connected, letters, no self-loops)."""
    if not isinstance(data, dict) or data.get("format") != GRAPH_FORMAT:
        raise ShapesFormatError(f"{source}: expected a JSON object with \"format\": {GRAPH_FORMAT!r}")
    types, edges = data.get("types"), data.get("edges")
    if not isinstance(types, list) or not types:
        raise ShapesFormatError(f"{source}: 'types' must be a non-empty list of one-letter strings")
    g = nx.Graph()
    for i, t in enumerate(types):
        if not isinstance(t, str) or len(t) != 1 or t not in LETTERS:
            raise ShapesFormatError(f"{source}: types[{i}] is {t!r}; node types are single letters A-Z or a-z")
        g.add_node(i, type=t)
    if not isinstance(edges, list):
        raise ShapesFormatError(f"{source}: 'edges' must be a list of [i, j] pairs")
    for k, e in enumerate(edges):
        if (not isinstance(e, list) or len(e) != 2 or not all(isinstance(x, int) and not isinstance(x, bool)
                                                                 for x in e)):
            raise ShapesFormatError(f"{source}: edges[{k}] is {e!r}; expected [i, j] with node indices")
        if not all(0 <= x < len(types) for x in e):
            raise ShapesFormatError(f"{source}: edges[{k}] = {e} names a node outside 0..{len(types) - 1}")
        g.add_edge(*e)
    try:
        check_graph(g)
    except GraphError as exc:
        raise ShapesFormatError(f"{source}: {exc}") from None
    return g


def read_graph(path: str | os.PathLike) -> nx.Graph:
    """Read a ``procmod-graph/1`` file."""
    _check_path(path, "graph file")
    path = Path(path)
    if not path.exists():
        raise ShapesFormatError(f"graph file {path} does not exist")
    if not path.is_file():
        raise ShapesFormatError(f"graph file {path} is not a regular file (a folder, a device or a pipe); give a "
                                "procmod-graph/1 file written by 'procmod strings graph'")
    return graph_from_dict(read_json(path, ShapesFormatError, "graph file"), str(path))


def write_graph(g: nx.Graph, path: str | os.PathLike) -> None:
    """Write ``g`` as a ``procmod-graph/1`` file, atomically."""
    _check_path(path, "graph file")
    path = check_output_file(path, "path")  # its '..' resolved: written there
    write_text_atomic(path, json.dumps(graph_to_dict(g)) + "\n")


def _check_path(path, what: str) -> None:
    if not isinstance(path, (str, os.PathLike)):
        raise InvalidArgumentError(f"{what} must be given as a path (a str or pathlib.Path), got "
                                   f"{type(path).__name__} {path!r:.40}")


def first_poses(shape_set: ShapeSet) -> dict[str, np.ndarray]:
    """Per type letter, the pose of its first instance in the set's shapes (where an
    instantiation places its first part)."""
    out: dict[str, np.ndarray] = {}
    for shape in shape_set.shapes:
        for p, t in zip(shape.parts, shape.transforms):
            out.setdefault(shape_set.letters[p], np.asarray(t, dtype=np.float64))
    return out


def type_histogram(types) -> tuple:
    """A hashable node-type histogram: sorted ``(letter, count)`` pairs."""
    counts: dict[str, int] = {}
    for t in types:
        counts[t] = counts.get(t, 0) + 1
    return tuple(sorted(counts.items()))


def histogram_distance(types_x, types_y) -> float:
    """Seed 001's E(x, y) = sum over types |T_x - T_y| / (N_x + N_y)."""
    hx, hy = dict(type_histogram(types_x)), dict(type_histogram(types_y))
    total = sum(hx.values()) + sum(hy.values())
    return sum(abs(hx.get(t, 0) - hy.get(t, 0)) for t in set(hx) | set(hy)) / max(total, 1)
