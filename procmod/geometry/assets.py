"""Part hierarchies from asset files: glTF / GLB scenes and URDF robots.

:func:`read_assets` reads one or more asset files (or the asset files of a folder) into a
neutral structure that both the learner (``procmod learn``) and the string-based
synthesis (``procmod strings``) use:

* a **part library** (:class:`~procmod.geometry.part_library.PartShape` by name): one part
  per *distinct geometry*, shared across all the files read together;
* per file, a **forest** of :class:`AssetNode` — part name, 4x4 world transform (placing
  the library part), children, and the node's name in the file.

Readers (no file format is parsed here): trimesh reads glTF / GLB (geometry, and the
scene graph's world transforms); yourdfpy reads URDF (links, visuals, joints), trimesh
its mesh files. Only the glTF's JSON node list is looked at directly — to refuse a node
hierarchy with a cycle or a node with two parents, and to count triangles before any
buffer is decoded — because trimesh's loader silently breaks cycles.

**Hierarchy.** glTF: the node tree of the default scene; a node with a mesh is a part
node, a node without one (an empty, a bone) passes its children to its nearest ancestor
with a mesh (world transforms lose nothing). A mesh with several primitives (one per
material) is one part. URDF: the link tree of the joints, at the zero configuration
(every joint at 0); a link's first visual is its node, further visuals are children of
it, and a link without visuals passes its children on like an empty (a robot with no
visual at all is read from its collision elements the same way). Cylinders and
spheres become meshes (32 sections; an icosphere of 320 faces), boxes stay boxes; a
shape of size zero (a marker some robots carry) is no part.

**Scales** (:func:`_bake_scales`). A part is a mesh at the size and shape its node
gives it: the nodes placing one mesh (or meshes that are one mesh scaled along its axes,
as a tool's primitive is, its scale applied or not) are grouped by their scales, within
:data:`SCALE_GROUP` of each other; a group far from the mesh's own size, or one of
several, becomes a geometry of its own at the group's mean scale, its nodes keeping the
rest. So six cubes scaled into a seat, a back and four legs are three parts, and a leg
whose scale was applied is the leg whose scale was not. Copies of one mesh turned and
scaled with their transforms applied (tables of several sizes, each turned, then baked)
are first put back as one mesh placed by their nodes (:func:`_unbake_turns`). A node
whose transform shears puts its whole linear map into its geometry, unless dropping the
shear moves no vertex beyond the geometry tolerance (below): a part turned by eye under
a non-uniformly scaled parent.

**Distinct geometry** (:data:`GEOMETRY_TOLERANCE`). Two meshes are one part when a rigid
motion (and, with ``mirror=True``, a reflection: a left and a right wing) maps one onto
the other to within ``GEOMETRY_TOLERANCE`` x the bounding-box diagonal, measured both
ways as the largest distance from points of one (512 area-weighted surface samples and
up to 1024 vertices) to the other's surface. The alignment: principal axes of the
area-weighted surface (every sign choice; about a degenerate axis, every 30 degrees),
each refined by ICP (to 8192 samples of the other surface, then to their tangent planes).
Two meshes of the same triangles (a tool's copies, each with mesh data of its own, moved
or turned with their transforms applied) are first matched vertex for vertex, a stricter
test that costs a few array operations a pair; what it does not match the alignment decides.
A part with symmetries (a box, a cylinder: quarter and half turns about its own axes that
map it onto itself) fits a geometry in several ways; each geometry takes the one that
leaves the nodes placing it least turned in the world, so that a seat whose transforms
were applied in the tool, or a top modelled turned and turned back, is not placed upside
down (``_upright_symmetry``). A mesh used by several nodes (glTF nodes sharing mesh
data; URDF visuals naming one file at one scale) is one geometry without any test. Boxes
are one part when their extents agree up to a permutation (a quarter turn). A part is
named after its geometry as the tool named it — the glTF mesh name (a mesh without one,
or with a name the tool gives its primitives, ``Cube.001``, is named after its first node,
``Seat``), the URDF mesh file's
stem, for a URDF box, cylinder or sphere its visual's name or else its link's — the
shortest name among the geometries it merges (``arm`` for meshes ``arm`` and ``arm.001``); different geometries with one name
get ``_2``, ``_3``, ... in the order they were read.

**Bad files** raise :class:`AssetError` with one line naming the file and the problem:
unreadable or not the format its suffix says, no mesh, a mesh with non-finite
coordinates or zero surface area, a node hierarchy with a cycle (or a node with two
parents), more than :data:`MAX_FACES` triangles or :data:`MAX_NODES` nodes.
"""

from __future__ import annotations

import io
import itertools
import math
import os
import re
import threading
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import ProcmodError
from ..core.file_formats import XACRO_COMMAND, conversion_hint
from ..core.io import fingerprint
from ..core.paths import UnsafePathError, named_file
from .mesh_files import MESH_SUFFIXES, declared_faces, gltf_header, gltf_scene_header, load_mesh_file
from .gltf_accessors import INSTANCING, instance_count, instanced_nodes, unplaced_roots
from .part_library import PartShape

GEOMETRY_TOLERANCE = 5e-3  # of a geometry's bounding-box diagonal (see the module docstring)
MAX_FACES = 2_000_000  # triangles of the distinct meshes of one file
MAX_DEPTH = 256  # levels of a node hierarchy (asset files, and example files: procmod.learn.examples)
MAX_NODES = 10_000  # nodes (glTF) or links + visuals (URDF) of one file
MAX_MESH_BYTES = 512 * 2 ** 20  # a URDF's mesh file
ASSET_SUFFIXES = (".gltf", ".glb", ".urdf")
_SAMPLES = 512
_CHECK_VERTICES = 1024
_DENSE = 8192
# Alignment tries up to 96 starts (every sign choice of the principal axes, 12 spins when
# two moments agree, both handednesses): each start is first refined by coarse ICP on
# every 8th sample (a stratified subset), and only the best few go on with all of them.
# Ranking on the subset costs an eighth; a true match ranks near zero either way.
_SUBSET_STRIDE = 8
_KEPT_STARTS = 4


class AssetError(ProcmodError):
    """An asset file (glTF, GLB, URDF, or a mesh one names) that cannot be used."""


@dataclass
class AssetNode:
    """A part placed in an asset: library part, world transform, children, file name."""

    name: str  # the node's name in the file (glTF node, URDF link)
    part: str  # the library part it places
    transform: np.ndarray  # 4x4 world transform of the part's local frame
    children: list = field(default_factory=list)

    def walk(self):
        """This node and its descendants, depth first."""
        yield self
        for child in self.children:
            yield from child.walk()


@dataclass
class Asset:
    """One file's hierarchy: its top-level part nodes."""

    path: Path
    roots: list  # of AssetNode
    groups: tuple = ()  # the name of the file's one top-level node when it has no mesh (an empty)

    def nodes(self) -> list:
        return [n for r in self.roots for n in r.walk()]


@dataclass
class AssetSet:
    """Files read together: one shared part library and a hierarchy per file."""

    parts: dict  # name -> PartShape
    assets: list  # of Asset
    tolerance: float = GEOMETRY_TOLERANCE


# glTF is y-up (its specification), URDF z-up (ROS's REP 103): +90 degrees about x takes
# a y-up frame to a z-up one (y -> z, z -> -y); its transpose goes back. procmod's models
# and `learn` are y-up, `strings` z-up: each turns the files it reads.
Y_UP_TO_Z_UP = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])


# ---- which files ------------------------------------------------------------------------------

def is_asset_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` names a file :func:`read_assets` reads (by its suffix)."""
    return Path(path).suffix.lower() in ASSET_SUFFIXES


def _folder_assets(folder: Path) -> tuple[list, list]:
    """``(asset files read, subfolders left out)`` of a folder: its own asset files, or,
    where it has none, those of its subfolders one level down (an asset kept in a folder
    of its own with its textures, h128); the subfolders holding asset files beside a
    folder's own are left out, as ``(subfolder, its asset files)``."""
    own = _assets_in(folder)
    if any(f.suffix.lower() == ".urdf" for f in own):
        return own, []  # its subfolders hold the robot's meshes (ROS's meshes/)
    nested = []
    here = folder.resolve()
    for sub in sorted(d for d in folder.iterdir() if d.is_dir()):
        if sub.resolve() in (here, *here.parents):  # a link back up: the same files again
            continue
        try:
            files = _assets_in(sub)
        except OSError:  # a subfolder that cannot be listed holds nothing of the set
            continue
        if files:
            nested.append((sub, files))
    if own:
        return own, nested
    if any(f.suffix.lower() == ".urdf" for _, files in nested for f in files):
        # a robot's urdf/ beside its meshes/ (ROS's layout): the robots, not their meshes
        return [f for _, files in nested for f in files if f.suffix.lower() == ".urdf"], []
    return [f for _, files in nested for f in files], []


def _assets_in(folder: Path) -> list:
    """A folder's own asset files, sorted; beside a URDF only the URDFs (the .glb or .gltf
    files there are its meshes)."""
    files = sorted(f for f in folder.iterdir() if f.is_file() and is_asset_file(f))
    robots = [f for f in files if f.suffix.lower() == ".urdf"]
    return robots or files


def asset_files(paths) -> list[Path]:
    """The asset files named by ``paths``: files, or folders (their asset files, sorted; a
    folder with none of its own: those of its subfolders, one level down)."""
    if isinstance(paths, (str, os.PathLike)):
        paths = [paths]
    out = []
    for p in map(Path, paths):
        if p.is_dir():
            found, _ = _folder_assets(p)
            if not found:
                files = sorted(f for f in p.iterdir() if f.is_file())
                hints = [(f, conversion_hint(f, hierarchy=True)) for f in files]
                other = next(((f, h) for f, h in hints if h), None)
                raise AssetError(f"folder {p} holds no {', '.join(ASSET_SUFFIXES)} file, nor do its subfolders"
                                 + (f" ({other[0].name}: {other[1]})" if other else ""))
            out += found
        elif not p.exists():
            raise AssetError(f"asset file {p} does not exist")
        elif not p.is_file():
            raise AssetError(f"{p} is not a regular file")
        elif not is_asset_file(p):
            hint = conversion_hint(p, hierarchy=True)
            raise AssetError(f"{p}: not an asset file (expected a name ending in {', '.join(ASSET_SUFFIXES)})"
                             + (f"; {hint}" if hint else ""))
        else:
            out.append(p)
    if not out:
        raise AssetError("no asset files given")
    once = {}
    for f in out:  # each file once, where first given
        once.setdefault(_same_file(f), f)
    return list(once.values())


def _same_file(path: Path):
    """What two spellings of one file share (its resolved path; the spelling where that fails)."""
    try:
        return path.resolve()
    except (OSError, RuntimeError):
        return path


def repeated_files(paths) -> list:
    """The asset files ``paths`` name more than once (``learn a.glb a.glb``, a folder and a
    file in it), each read once (:func:`asset_files`; h162: it had counted as two examples)."""
    seen, repeated = set(), []
    for p in map(Path, [paths] if isinstance(paths, (str, os.PathLike)) else paths):
        for f in (_folder_assets(p)[0] if p.is_dir() else [p]):
            key = _same_file(f)
            if key in seen and f not in repeated:
                repeated.append(f)
            seen.add(key)
    return repeated


def left_out_note(paths) -> str | None:
    """A note naming what the given folders hold and was not read: 3D files that are not
    asset files (an OBJ beside the glTF scenes keeps no part hierarchy), with what to
    export, and subfolders of asset files beside a folder's own (a later batch in ``v2/``,
    h128: half a set had been left out without a word); None when there is nothing.
    Files no 3D tool writes (a README, a .txt) are not named."""
    skipped, subfolders = [], []
    for p in map(Path, [paths] if isinstance(paths, (str, os.PathLike)) else paths):
        if not p.is_dir():
            continue
        read, nested = _folder_assets(p)
        subfolders += nested
        for folder in sorted({f.parent for f in read}):
            if not any(f.suffix.lower() == ".urdf" for f in folder.iterdir()):  # (a URDF's meshes lie beside it)
                skipped += [(f, conversion_hint(f, hierarchy=True)) for f in sorted(folder.iterdir())
                            if f.is_file() and not is_asset_file(f)]
    skipped = [(f, hint) for f, hint in skipped if hint]
    said = []
    repeated = repeated_files(paths)
    if repeated:
        said.append(f"{', '.join(f.name for f in repeated[:3])}{' and more' if len(repeated) > 3 else ''} "
                    f"{'was' if len(repeated) == 1 else 'were'} given more than once and read once")
    if skipped:
        names = ", ".join(f.name for f, _ in skipped[:4]) + (f" and {len(skipped) - 4} more" if len(skipped) > 4
                                                             else "")
        said.append(f"left out {names}, not read as examples ({skipped[0][0].name}: {skipped[0][1]})")
    if subfolders:
        count = sum(len(files) for _, files in subfolders)
        names = ", ".join(f"{sub.name}/" for sub, _ in subfolders[:3]) + (
            f" and {len(subfolders) - 3} more" if len(subfolders) > 3 else "")
        said.append(f"{count} asset file{'s' if count > 1 else ''} in the subfolder{'s' if len(subfolders) > 1 else ''}"
                    f" {names} {'were' if count > 1 else 'was'} not read (a folder's own files are, not its "
                    f"subfolders' beside them): give {'them' if len(subfolders) > 1 else 'it'} too, e.g. "
                    f"{subfolders[0][0]}")
    return "; ".join(said) if said else None


def faceless_note(paths) -> str | None:
    """A note naming the glTF mesh nodes of the given files (or folders' files) that draw
    no triangles (points or lines only: Blender's loose edges, a curve exported as a mesh):
    they are no part and were read as empties; None when there are none."""
    found = []
    for p in map(Path, [paths] if isinstance(paths, (str, os.PathLike)) else paths):
        files = _folder_assets(p)[0] if p.is_dir() else [p]
        for f in files:
            if f.suffix.lower() not in (".gltf", ".glb"):
                continue
            try:
                header = _gltf_json(f)
            except AssetError:
                continue  # the reader says what is wrong with the file
            meshes = header.get("meshes")
            for k, node in enumerate(header.get("nodes") or []):
                mesh = node.get("mesh") if isinstance(node, dict) else None
                if isinstance(mesh, bool) or not isinstance(mesh, int) or not isinstance(meshes, list) \
                        or not 0 <= mesh < len(meshes) or not isinstance(meshes[mesh], dict):
                    continue
                modes = [q.get("mode", 4) for q in meshes[mesh].get("primitives") or [] if isinstance(q, dict)]
                if modes and not any(m in (4, 5, 6) for m in modes):  # POINTS, LINES, LINE_LOOP, LINE_STRIP only
                    found.append(f"{node.get('name', f'node {k}')!r} in {f.name}")
    if not found:
        return None
    more = f" and {len(found) - 3} more" if len(found) > 3 else ""
    return (f"{', '.join(found[:3])}{more} {'draws' if len(found) == 1 else 'draw'} no faces (points or lines "
            "only), so not read as parts; give them faces (Blender: fill them, or convert a curve to a mesh "
            "with a bevel) to learn them")


def json_or_assets(paths, what: str, json_format: str) -> tuple[Path | None, list[Path]]:
    """Split a command's inputs: ``(json_file, [])`` for one ``json_format`` JSON file
    given on its own, else ``(None, paths)`` for asset files and folders of them.

    ``paths`` is one path or several. An empty list, or a JSON file beside other inputs, is
    an :class:`AssetError` naming ``what`` the inputs are (e.g. "shapes", "examples").
    """
    paths = [Path(p) for p in ([paths] if isinstance(paths, (str, os.PathLike)) else paths)]
    if not paths:
        raise AssetError(f"no {what} given: name a {json_format} JSON file, or asset files or folders")
    json_files = [p for p in paths if p.suffix.lower() == ".json"]
    if not json_files:
        return None, paths
    if len(paths) > 1:
        raise AssetError(f"{json_files[0]}: give one {json_format} JSON file on its own, or asset files "
                         "(.gltf, .glb, .urdf) and folders of them, not both or several JSON files")
    return paths[0], []


# ---- raw geometry and nodes, as each reader finds them ------------------------------------------

@dataclass
class _Geometry:
    key: tuple  # identity within the whole read: nodes with one key share the geometry
    name: str
    where: str  # for messages
    kind: str = "mesh"  # or "box"
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None
    size: np.ndarray | None = None
    named_by_node: str = ""  # its mesh had no name of its own: "unnamed", or "default" (a tool's "Cube")


@dataclass
class _Raw:
    name: str
    geometry: tuple | None  # a _Geometry key, or None (an empty)
    world: np.ndarray
    children: list = field(default_factory=list)


def _clean_mesh(vertices, faces, where: str) -> tuple[np.ndarray, np.ndarray]:
    """Checked float64 vertices and int faces; merged duplicate vertices (UV seams)."""
    v = np.asarray(vertices, dtype=np.float64).reshape(-1, 3)
    f = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(f) == 0 or len(v) == 0:
        raise AssetError(f"{where} holds no triangles")
    if not np.isfinite(v).all():
        raise AssetError(f"{where} has non-finite vertex coordinates (NaN or infinity); fix or re-export it")
    if f.min() < 0 or f.max() >= len(v):
        raise AssetError(f"{where}: a triangle refers to a vertex that does not exist")
    # merged in the file's order (each vertex where it first occurs), not np.unique's sorted
    # order: copies of one mesh turned apart keep one vertex order (_unbake_turns matches them
    # vertex for vertex), and a part mesh is written back in its author's order
    uniq, first, inverse = np.unique(v, axis=0, return_index=True, return_inverse=True)
    order = np.argsort(first, kind="stable")
    rank = np.empty(len(uniq), dtype=np.int64)
    rank[order] = np.arange(len(uniq))
    f = rank[inverse.reshape(-1)][f]
    used = np.zeros(len(uniq), dtype=bool)
    used[f.reshape(-1)] = True
    remap = np.cumsum(used) - 1
    v, f = uniq[order][used], remap[f]
    tri = v[f]
    area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
    if not area.sum() > 1e-12 * max(float(np.ptp(v, axis=0).max()), 1e-300) ** 2:
        raise AssetError(f"{where} has zero surface area (every triangle is degenerate)")
    return v, f


# ---- glTF / GLB -------------------------------------------------------------------------------

def _gltf_json(path: Path) -> dict:
    """The JSON of a .gltf file, or of a .glb file's JSON chunk, as AssetError when it
    cannot be read (:func:`procmod.geometry.mesh_files.gltf_header`)."""
    try:
        return gltf_header(path)
    except OSError as exc:
        raise AssetError(f"cannot read {path} ({exc.strerror or exc})") from None
    except ValueError as exc:
        raise AssetError(f"{path} {exc}") from None


def _gltf_instances_expanded(header: dict, path: Path) -> dict:
    """``header`` with each node drawn as GPU instances (``EXT_mesh_gpu_instancing``) an
    empty over a node per instance, as the reader reads the file
    (:func:`~procmod.geometry.mesh_files.gltf_scene_header`): each instance a part node. More
    nodes than :data:`MAX_NODES` so are refused before any is made."""
    chosen = instanced_nodes(header) if isinstance(header.get("nodes"), list) \
        and all(isinstance(n, dict) for n in header["nodes"]) else []
    if not chosen:
        return header
    instances = sum(instance_count(header, n) for n in chosen)
    expanded = len(header["nodes"]) + instances
    if expanded > MAX_NODES:
        raise AssetError(f"{path} draws {instances:,} GPU instances ({INSTANCING}), {expanded:,} nodes once expanded, "
                         f"more than procmod reads ({MAX_NODES}); export fewer copies, or join "
                         "copies that belong together into one mesh")
    try:
        return gltf_scene_header(path, header)
    except OSError as exc:
        raise AssetError(f"cannot read {path} ({exc.strerror or exc})") from None
    except ValueError as exc:
        raise AssetError(f"cannot read {path} as glTF ({str(exc)[:300]})") from None


def _gltf_nodes(header: dict, path: Path) -> tuple[list, list]:
    """The default scene's root node indices and every node's children, checked: a tree
    (each node has one parent, none is its own ancestor), at most MAX_NODES nodes."""
    nodes = header.get("nodes", [])
    if not isinstance(nodes, list) or not all(isinstance(n, dict) for n in nodes):
        raise AssetError(f"{path}: 'nodes' is not a list of node objects")
    if len(nodes) > MAX_NODES:
        raise AssetError(f"{path} has {len(nodes)} nodes, more than procmod reads ({MAX_NODES}); join objects "
                         "that belong together before exporting")
    scenes = header.get("scenes", [])
    scene = header.get("scene", 0)
    if not scenes:  # a library of objects: its top nodes, as the reader is given them (unplaced_roots)
        roots = unplaced_roots(header) or []
    elif not isinstance(scene, int) or not 0 <= scene < len(scenes) or not isinstance(scenes[scene], dict):
        raise AssetError(f"{path}: its default scene {scene!r} does not exist")
    else:
        roots = scenes[scene].get("nodes", [])

    def index(i, where):
        if isinstance(i, bool) or not isinstance(i, int) or not 0 <= i < len(nodes):
            raise AssetError(f"{path}: {where} refers to node {i!r}, which does not exist")
        return i

    for k, n in enumerate(nodes):  # trimesh replaces a non-finite matrix by the identity, silently
        for key, size in (("matrix", 16), ("translation", 3), ("rotation", 4), ("scale", 3)):
            value = n.get(key)
            if value is None:
                continue
            if (not isinstance(value, list) or len(value) != size
                    or not all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)
                               for x in value)):
                raise AssetError(f"{path}: node {k} ({n.get('name', 'unnamed')!r}) has a non-finite or malformed "
                                 f"transform ({key} must be {size} finite numbers)")
    roots = [index(i, f"scene {scene}") for i in roots]
    children = [[index(c, f"node {k} ({n.get('name', 'unnamed')!r})") for c in n.get("children", [])]
                for k, n in enumerate(nodes)]
    parent = {}
    for k, cs in enumerate(children):
        for c in cs:
            if c == k:
                raise AssetError(f"{path}: node {c} ({nodes[c].get('name', 'unnamed')!r}) lists itself among its "
                                 "children; a glTF node hierarchy must be a tree")
            if c in parent and parent[c] == k:  # one parent listing it twice (h128: said as "two parents")
                raise AssetError(f"{path}: node {c} ({nodes[c].get('name', 'unnamed')!r}) is listed twice among the "
                                 f"children of node {k} ({nodes[k].get('name', 'unnamed')!r}); a glTF node's "
                                 "children must be distinct: list it once")
            if c in parent or c in roots:
                raise AssetError(f"{path}: node {c} ({nodes[c].get('name', 'unnamed')!r}) has two parents; a glTF "
                                 "node hierarchy must be a tree")
            parent[c] = k
    for start in range(len(nodes)):  # a cycle: following parents comes back to the start
        seen, k = {start}, start
        while k in parent:
            k = parent[k]
            if k in seen:
                raise AssetError(f"{path}: the node hierarchy has a cycle (node {k}, "
                                 f"{nodes[k].get('name', 'unnamed')!r}, is its own ancestor)")
            seen.add(k)
        if len(seen) > MAX_DEPTH:  # refused here: trimesh's scene graph took minutes to build first
            raise AssetError(f"{path}: the node hierarchy is deeper than {MAX_DEPTH} levels (node {start}, "
                             f"{nodes[start].get('name', 'unnamed')!r}); flatten it before exporting")
    meshes = header.get("meshes", [])
    for k, n in enumerate(nodes):
        mesh = n.get("mesh")
        if mesh is not None and (isinstance(mesh, bool) or not isinstance(mesh, int)
                                 or not 0 <= mesh < (len(meshes) if isinstance(meshes, list) else 0)):
            raise AssetError(f"{path}: node {k} ({n.get('name', 'unnamed')!r}) refers to mesh {mesh!r}, which the "
                             "file does not have; export it again")
    return roots, children


def _gltf_triangles(header: dict, path: Path) -> int:
    """Triangles the file's meshes declare (accessor counts), before any buffer is read."""
    accessors = header.get("accessors", [])
    total = 0
    for m in header.get("meshes", []) if isinstance(header.get("meshes"), list) else []:
        for p in m.get("primitives", []) if isinstance(m, dict) else []:
            if not isinstance(p, dict):
                continue
            mode = p.get("mode", 4)
            acc = p.get("indices", (p.get("attributes") or {}).get("POSITION"))
            if isinstance(acc, int) and 0 <= acc < len(accessors) and isinstance(accessors[acc], dict):
                count = accessors[acc].get("count", 0)
                if isinstance(count, int) and count > 0:
                    total += count // 3 if mode == 4 else max(count - 2, 0) if mode in (5, 6) else 0
    return total


def _read_gltf(path: Path, geometries: dict) -> list:
    """The forest of _Raw nodes of a glTF / GLB file; its geometries into ``geometries``."""
    from trimesh.util import unique_name

    header = _gltf_instances_expanded(_gltf_json(path), path)
    roots, children = _gltf_nodes(header, path)
    declared = _gltf_triangles(header, path)
    if declared > MAX_FACES:
        raise AssetError(f"{path} has {declared} triangles, more than procmod reads ({MAX_FACES}); "
                         "decimate the meshes (Blender: Decimate modifier) before exporting")
    try:
        scene = load_mesh_file(path, force="scene", process=False, skip_materials=True)  # geometry only: no textures decoded
    except Exception as exc:  # trimesh raises many types for unreadable files; procmod's checks say ValueError
        said = str(exc)[:300] if type(exc) is ValueError and str(exc) else f"{type(exc).__name__}: {str(exc)[:200]}"
        raise AssetError(f"cannot read {path} as glTF ({said})") from None
    nodes = header.get("nodes", [])
    # trimesh names a node as its loader does: the file's name made unique, in index order
    names, taken, counts = {}, {}, {}
    for i, n in enumerate(nodes):
        name = unique_name(n.get("name", str(i)), taken, counts=counts)
        taken[name] = i
        names[i] = name
    if "world" in taken:  # trimesh renames a node that collides with its base frame
        names[taken["world"]] = unique_name("world", set(names.values()))
    graph = scene.graph
    data = graph.transforms.node_data
    meshes = header.get("meshes", [])

    node_frames = set(names.values())

    def geometry_of(i: int):
        node = nodes[i]
        if "mesh" not in node:
            return None
        frame = names[i]
        own = data.get(frame, {}).get("geometry")
        # a mesh of several primitives (materials) is placed by trimesh as frames under the
        # node's, named NODE_<random id>: the node's own children may be named NODE_... too
        # (a child "wing_tip" of "wing", trimesh's "Wing_1" for a second "Wing"), and had
        # been merged into its mesh (h144)
        parts = [own] if own is not None else sorted(
            data[c]["geometry"] for c in graph.transforms.children.get(frame, [])
            if c.startswith(frame + "_") and c not in node_frames and data.get(c, {}).get("geometry") is not None)
        if not parts:
            return None  # a mesh of points or lines only: nothing to place
        mesh_index = node["mesh"]
        if isinstance(mesh_index, bool) or not isinstance(mesh_index, int) or not 0 <= mesh_index < len(meshes):
            raise AssetError(f"{path}: node {frame!r} refers to mesh {mesh_index!r}, which does not exist")
        mesh_name = meshes[mesh_index].get("name") if isinstance(meshes[mesh_index], dict) else None
        key = ("gltf", str(path), tuple(parts))
        if key not in geometries:
            # an unnamed mesh is named after the first node that places it (trimesh's own
            # name for it, "GLTF", "GLTF_1", means nothing to the user), and so is one named
            # as the tool names its primitives ("Cube.001": the user named the object "Seat")
            by_node = ""
            if not (isinstance(mesh_name, str) and mesh_name):
                name, by_node = frame, "unnamed"
            elif _NUMBERED.sub("", mesh_name).lower() in _DEFAULT_MESH_NAMES:
                if isinstance(node.get("name"), str) and node["name"]:
                    name, by_node = _NUMBERED.sub("", frame) or frame, "default"  # "Seat", not "Seat.001"
                else:  # a node without a name: its frame is trimesh's index ("1", "2"); the tool's name then
                    name = _NUMBERED.sub("", mesh_name) or mesh_name
            else:
                name = mesh_name
            where = f"{path}: mesh {name!r}"
            # a mesh's points and lines primitives (Blender's "loose edges") are no surface
            pieces = [p for p in (scene.geometry[g] for g in parts) if len(getattr(p, "faces", ())) > 0]
            if not pieces:
                return None
            v = np.concatenate([np.asarray(p.vertices, dtype=np.float64) for p in pieces])
            offsets = np.cumsum([0] + [len(p.vertices) for p in pieces[:-1]])
            f = np.concatenate([np.asarray(p.faces, dtype=np.int64) + o for p, o in zip(pieces, offsets)])
            v, f = _clean_mesh(v, f, where)
            geometries[key] = _Geometry(key, name, where, "mesh", v, f, named_by_node=by_node)
        return key

    def build(i: int) -> _Raw | None:
        frame = names[i]
        if frame not in graph.nodes:
            if "mesh" not in nodes[i] and not children[i]:
                return None  # a leaf with nothing to place (trimesh leaves out a camera's node)
            raise AssetError(f"{path}: node {i} ({nodes[i].get('name', 'unnamed')!r}) is missing from the "
                             "scene trimesh read; the file may use a feature procmod cannot read")
        try:
            world = np.asarray(graph.get(frame)[0], dtype=np.float64)
        except ValueError:  # trimesh's "No path from world->...": a node its scene left unconnected
            raise AssetError(f"{path}: node {i} ({nodes[i].get('name', 'unnamed')!r}) is not connected to the "
                             "scene trimesh read; the file may use a feature procmod cannot read") from None
        if not np.isfinite(world).all():
            raise AssetError(f"{path}: node {frame!r} has a non-finite transform (NaN or infinity)")
        return _Raw(frame, geometry_of(i), world, [b for b in map(build, children[i]) if b is not None])

    forest = [b for b in map(build, roots) if b is not None]
    if not any(n.geometry for r in forest for n in _walk(r)):
        raise AssetError(f"{path} holds no mesh (nothing to use as a part)")
    return forest


def _walk(raw: _Raw):
    yield raw
    for c in raw.children:
        yield from _walk(c)


_NUMBERED = re.compile(r"[._ -]?\d+$")  # "Leg.001", "Leg2": the tool's numbering of copies
# meshes as tools name their primitives (Blender, Maya, 3ds Max): a scaled one is named
# after its node instead, which the user named for what it is ("Seat", "Leg")
_DEFAULT_MESH_NAMES = {"cube", "cylinder", "sphere", "uv sphere", "icosphere", "cone", "plane", "torus", "circle",
                       "grid", "monkey", "suzanne", "mesh", "box", "pcube", "pcylinder", "psphere", "pcone",
                       "pplane", "ptorus", "teapot", "gltf"}


def _given_name(g: _Geometry) -> str | None:
    """The name the user gave a mesh, without the tool's numbering of copies (``Pole``
    for ``Pole.001``), or None for a mesh named as the tool names its primitives or not
    at all (named after its node: the sizes tell its parts apart, :func:`_bake_scales`),
    as a URDF's cylinders and spheres are (named after their links)."""
    if g.named_by_node or g.key[0] in ("cylinder", "sphere"):
        return None
    base = _NUMBERED.sub("", g.name).lower()
    return None if base in _DEFAULT_MESH_NAMES else base


# words of node names that say nothing of what a part is: a tool's names for primitives and
# nodes, and where a copy sits (Leg_FL, LeftArm, Wing.R are legs, arms and wings)
_GENERIC_NAME_WORDS = _DEFAULT_MESH_NAMES | {
    "link", "joint", "node", "object", "part", "geom", "geometry", "group", "body", "shape", "model", "obj",
    "default", "untitled", "poly", "surface", "transform", "empty", "instance", "copy", "mirror", "mirrored",
    "geo", "grp", "lod", "proxy", "low", "high", "ctrl"}
_PLACE_WORDS = {"left", "right", "front", "back", "rear", "top", "bottom", "upper", "lower", "inner", "outer",
                "middle", "mid", "center", "centre", "side", "north", "south", "east", "west"}


def _name_words(name: str) -> set:
    """The words of a node's name that may say what its part is, lower case: camel case and
    separators split (``UpperArm``: upper, arm), the tool's copy numbering, words under
    three letters (``L``, ``FR``) and :data:`_PLACE_WORDS` left out."""
    words = {w.lower() for w in re.findall(r"[A-Z]+(?![a-z])|[A-Z]?[a-z]+", _NUMBERED.sub("", name or ""))}
    return {w for w in words if len(w) >= 3 and w not in _PLACE_WORDS}


def _named_apart(names: list) -> list | None:
    """The nodes (indices into ``names``) that their names tell apart, as groups in order of
    their first node: nodes whose names share a word are one group (``Leg`` and
    ``Leg.001``, ``Leg_FL`` and ``FrontLeftLeg``); ``Head``, ``Torso`` and ``Forearm`` are
    three. None where any node's name is only a tool's (``Cube.003``, ``pCube1``, ``link_2``):
    the user did not name it, and its sizes alone tell its part (:func:`_bake_scales`)."""
    words = [_name_words(n) - _GENERIC_NAME_WORDS for n in names]
    if not all(words):
        return None
    owner, groups = {}, []  # word -> group index; groups as (indices, words), merged as words are shared
    for k, ws in enumerate(words):
        joined = sorted({owner[w] for w in ws if w in owner})
        if not joined:
            groups.append(([k], set(ws)))
            target = len(groups) - 1
        else:
            target = joined[0]
            for other in joined[1:]:  # this name links groups apart so far: one group
                groups[target][0].extend(groups[other][0])
                groups[target][1].update(groups[other][1])
                for w in groups[other][1]:
                    owner[w] = target
                groups[other] = ([], set())
            groups[target][0].append(k)
            groups[target][1].update(ws)
        for w in ws:
            owner[w] = target
    return [sorted(indices) for indices, _ in groups if indices]


def _recurring(groups: list, files: list, count: int) -> bool:
    """Whether every name group (indices into ``files``, each node's file) recurs across
    the ``count`` files as a kind does: in two files or more and in at least half of them
    (a robot's Torso, Head and Forearm in every file). Names given per file (books by
    title, a car's wheels called Wheel in one file, Tyre and Tire in others, under a body
    of its own each: h108) are no kinds: each file's became a part type of its own."""
    least = max(2, math.ceil(count / 2))
    return all(len({files[k] for k in group}) >= least for group in groups)


def _hangs_under(raw, parent_of: dict, unit_of: dict):
    """Where ``raw`` hangs: its nearest ancestor that draws something, as that one's mesh's
    unit shape (the part kind before sizes, :func:`_bake_scales`) or its geometry, with
    the words of its name (a robot made of cubes: a head under the Torso, forearms under
    the UpperArms); None for a root. Read before any mesh is baked, so that it does not
    depend on the order the meshes are baked in (h110)."""
    node = parent_of.get(id(raw))
    while node is not None and node.geometry is None:  # an empty (a group) between them
        node = parent_of.get(id(node))
    if node is None:
        return None
    kind = unit_of[node.geometry][0] if node.geometry in unit_of else node.geometry
    return kind, frozenset(_name_words(node.name) - _GENERIC_NAME_WORDS)


def _apart_in_size(groups: list, sizes: np.ndarray, positions: list, files: list) -> list:
    """``groups`` (of indices into ``sizes``, log-extents of nodes) joined where their names
    alone tell them apart. Two name groups stay apart only where they are found together
    (``files``: each node's file; in at least half the files either is in), hang in
    different places (``positions``: per node, where it hangs, :func:`_hangs_under`, None
    for a root; no place in common) and, along some axis, every node of one is
    smaller than every node of the other: a robot's torso (a root), head (under the
    torso) and forearms (under the upper arms), in every file. Parts hanging side by side
    under one kind of parent are one kind to names, however named (books named by colour
    or title, steps called Step in some files and Tread in others, tops named per file:
    each had become a part type of its own, h106); so are names that take each other's
    place from file to file (wheels called Wheel by one author and Tire by another, under
    bodies of their own: h109), and groups whose sizes overlap along every axis; sizes
    then tell them apart, as before."""
    boxes = [(sizes[g].min(axis=0), sizes[g].max(axis=0)) for g in groups]
    places = [{positions[k] for k in g} for g in groups]
    found = [{files[k] for k in g} for g in groups]
    parent = list(range(len(groups)))

    def root(i: int) -> int:
        while parent[i] != i:
            i = parent[i]
        return i

    for i, j in itertools.combinations(range(len(groups)), 2):
        (lo_i, hi_i), (lo_j, hi_j) = boxes[i], boxes[j]
        together = len(found[i] & found[j]) >= 0.5 * len(found[i] | found[j])
        if not together or places[i] & places[j] or not ((hi_i < lo_j) | (hi_j < lo_i)).any():
            parent[root(j)] = root(i)
    joined = {}
    for i, group in enumerate(groups):
        joined.setdefault(root(i), []).extend(group)
    return sorted((sorted(group) for group in joined.values()), key=lambda group: group[0])


BAKED_TURN_FIT = 1e-4
"""How closely (x a mesh's bounding-box diagonal, at every vertex) a mesh must be an affine
image of another of its name and triangles to be taken for a copy of it turned and scaled
with its transforms applied (:func:`_unbake_turns`): float32 coordinates, not a tolerance
on shape."""
_NATURAL_FRAME = 1e-3  # a mesh's own axes are its box's when its extents exceed its least box's by no more


def _least_box_frame(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray] | None:
    """A mesh's least-volume box as ``(axes, centre)``: the box's axes as the columns of a
    rotation, the least turned from the mesh's own axes (of the box's 24 proper signed
    permutations), or None when the mesh lies along its own axes already (its box is the
    least within :data:`_NATURAL_FRAME`, or it is mirror-symmetric in them) or is flat."""
    import trimesh

    own = np.ptp(vertices, axis=0)
    spread = np.linalg.svd(vertices - vertices.mean(axis=0), compute_uv=False)
    if not spread.min() > 1e-9 * float(spread.max()):
        return None  # flat (a plane, turned or not): a least box of it says nothing of a turn
    if _mirrored_in_own_axes(vertices):
        return None  # a tool's primitive along its axes: a round one's least box lies half a facet off them
    with np.errstate(all="ignore"):
        to_origin, extents = trimesh.bounds.oriented_bounds(vertices, angle_digits=3)
    if own.sum() <= (1.0 + _NATURAL_FRAME) * float(np.sum(extents)):
        return None
    box_to_mesh = np.linalg.inv(to_origin)
    axes, centre = box_to_mesh[:3, :3], box_to_mesh[:3, 3]
    best, best_trace = axes, -np.inf
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            candidate = axes[:, list(perm)] * signs
            if np.linalg.det(candidate) > 0 and np.trace(candidate) > best_trace + 1e-12:
                best, best_trace = candidate, float(np.trace(candidate))
    return best, centre


def _mirrored_in_own_axes(vertices: np.ndarray) -> bool:
    """Whether a mesh's vertices map onto themselves (to 1e-6 of its diagonal) reflected
    in each plane through its box's centre across one of its own axes: a box, a cylinder
    or an n-gon with a vertex on an axis, modelled along the tool's axes. Turned, they are
    not (but at a symmetry's angle, where turned and unturned are one shape)."""
    from scipy.spatial import cKDTree

    lo, hi = vertices.min(axis=0), vertices.max(axis=0)
    centre, diagonal = 0.5 * (lo + hi), float(np.linalg.norm(hi - lo))
    tree = cKDTree(vertices)
    for axis in range(3):
        mirrored = vertices.copy()
        mirrored[:, axis] = 2.0 * centre[axis] - mirrored[:, axis]
        if tree.query(mirrored, distance_upper_bound=1e-6 * diagonal)[0].max() > 1e-6 * diagonal:
            return False
    return True


def _unbake_turns(forests: list, geometries: dict) -> None:
    """Meshes that are one mesh turned and scaled with the transforms applied, put back as
    that mesh placed by their nodes (so that :func:`_bake_scales` groups them by size).

    A tool's copies of one mesh (``Leg``, ``Leg.001``, ...: one given name, the same
    triangles) turned in the scene and then exported with their transforms applied
    (Blender's Apply All Transforms, exporters that bake) hold their geometry turned in
    their own axes. Their shapes along those axes differ from table to table, so the scale
    grouping, which compares shapes along a mesh's own axes, had made each table's legs
    and top part types of their own: four turned tables were eight part types for two.
    Here each such family gets one representative in its natural frame (its least box's
    axes, :func:`_least_box_frame`; a mesh already along its axes keeps them); a member
    that is, vertex for vertex, the representative scaled along those axes, turned and
    moved (within :data:`BAKED_TURN_FIT`), is placed as it, the map folded into its nodes'
    transforms. A family whose members share their shape along their own axes (copies
    not turned) is left to :func:`_bake_scales` as read."""
    placers = {}
    for raw in (r for forest in forests for top in forest for r in _walk(top)):  # in file order
        if raw.geometry is not None and geometries[raw.geometry].kind == "mesh":
            placers.setdefault(raw.geometry, []).append(raw)
    families = {}
    for key in placers:  # in the order read (dicts keep it): the first read represents
        g = geometries[key]
        name = _given_name(g)
        if name is None and g.key[0] not in ("cylinder", "sphere"):
            name = ""  # a tool's primitive (Cube, Cube.001): one family; _bake_scales parts it by size
        if name is not None:
            families.setdefault((name, len(g.vertices), np.asarray(g.faces).tobytes()), []).append(key)
    for keys in families.values():
        if len(keys) < 2:
            continue
        shapes = [_unit_shape(geometries[key].vertices)[0] for key in keys]
        if all(np.abs(shape - shapes[0]).max() <= UNIT_SHAPE_TOLERANCE for shape in shapes[1:]):
            continue  # not turned apart: _bake_scales groups them along their own axes
        _unbake_family(keys, geometries, placers)


def _unbake_family(keys: list, geometries: dict, placers: dict) -> None:
    """:func:`_unbake_turns` for one family of meshes (``keys``, the first read first)."""
    frames = [(key, _least_box_frame(geometries[key].vertices)) for key in keys]
    # the representative: the first mesh already in its natural frame, else the first, turned into it
    rep_key, frame = next(((k, f) for k, f in frames if f is None), frames[0])
    rep = geometries[rep_key]
    vertices = rep.vertices if frame is None else (rep.vertices - frame[1]) @ frame[0]
    # named as _library names a part its geometries merge into: the shortest name (Leg, not Leg.003)
    name = min((geometries[k].name for k in keys), key=lambda n: (len(n), n))
    rep = _Geometry(("unbaked", rep_key), name, rep.where, "mesh", vertices, rep.faces,
                    named_by_node=rep.named_by_node)
    homogeneous = np.hstack([rep.vertices, np.ones((len(rep.vertices), 1))])
    maps, resized = {}, False
    for key in keys:
        v = geometries[key].vertices
        solution, *_ = np.linalg.lstsq(homogeneous, v, rcond=None)  # v ~ rep @ m + t
        m, t = solution[:3], solution[3]
        if np.abs(homogeneous @ solution - v).max() > BAKED_TURN_FIT * float(np.linalg.norm(np.ptp(v, axis=0))):
            continue  # not a copy of it (other vertices, or bent)
        gram = m @ m.T  # m = diag(scales) @ turn exactly when this is diagonal: scaled along its own axes
        scales = np.sqrt(np.diag(gram))
        if not (scales > 0).all() or np.abs(gram / np.outer(scales, scales) - np.eye(3)).max() > _NATURAL_FRAME:
            continue  # sheared, or scaled along other axes: a shape of its own
        maps[key] = np.vstack([np.column_stack([m.T, t]), [0.0, 0.0, 0.0, 1.0]])
        resized |= bool(np.abs(scales - 1.0).max() > BAKED_TURN_FIT)
    if len(maps) < 2 or not resized:
        return  # copies of one size: one part by _library's rigid alignment, in their own frames
    geometries[rep.key] = rep
    for key, placed in maps.items():
        for raw in placers[key]:
            raw.geometry, raw.world = rep.key, raw.world @ placed


UNIT_SHAPE_TOLERANCE = 1e-5
"""Two meshes of one topology are one mesh moved and scaled along its axes when their unit
shapes (:func:`_unit_shape`) agree within this, vertex by vertex: float32 vertices of a
primitive scaled and applied at another size differ by ~1e-7."""


def _unit_shape(vertices: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``(vertices scaled to unit extents from the mesh's own corner; the extents)``: a
    mesh moved and scaled along its axes has the unit shape of its original (a location
    applied moves it off its origin alike). A flat axis keeps its extent 1."""
    extents = np.ptp(vertices, axis=0)
    extents[extents <= 1e-12 * max(float(extents.max()), 1e-300)] = 1.0  # a flat mesh's flat axis
    return (vertices - vertices.min(axis=0)) / extents, extents


def _bake_scales(forests: list, geometries: dict) -> None:
    """Tell the parts a tool made of one mesh by scaling it apart, and give each its size.

    Blender users scale primitives without applying the scale: a chair of six scaled
    cubes was one part type, "Cube", six times over (seat, back and legs alike), and its
    learned program sampled chairs of 1, 2 or 10 boxes. And an object whose scale was
    applied in the tool was another part than its twin whose scale was not. So the nodes
    that place one mesh, or meshes that are one mesh moved and scaled along its axes (a
    primitive added at other sizes, or its scale or location applied) under one name
    (the tool's copies ``Pole``, ``Pole.001``, or a primitive's name such as ``Cube``;
    meshes the user named apart, ``column`` and ``wall``, stay apart), are grouped by
    their sizes (single linkage: within :data:`SCALE_GROUP` of each other on every axis
    are one group), within the kinds their objects' names tell apart where the names
    recur across the files, hang in different places and their sizes agree
    (:func:`_named_apart`, :func:`_recurring`, :func:`_apart_in_size`: a robot's Torso,
    Head and Forearm cubes). One mesh whose nodes form one group with a scale within that
    factor of 1 keeps it on the nodes, as read (a part whose size varies from example to example,
    the learner's to model). Otherwise each group is a geometry of its own: the mesh with
    the group's mean size put into it, the nodes keeping what differs from that mean (a
    pole added at five depths, its scale applied in every example, was five part types,
    and a sample drew none or two of them). A node that shears (a turned child
    under a non-uniformly scaled parent) puts its whole linear map into a geometry of its
    own and keeps its rotation-free place. A baked geometry keeps its mesh's name, but one
    a tool gives its primitives (``Cube``, ``Cylinder.001``) says nothing of what the
    scale made of it: it is named after its first node instead, without the tool's copy
    numbering (``Leg.001`` is ``Leg``). A shear within the geometry tolerance is dropped
    (:func:`_without_small_shear`)."""
    by_geometry, unit_of, unit_shapes = {}, {}, {}
    read_order = {id(raw): k for k, raw in enumerate(r for forest in forests for top in forest for r in _walk(top))}
    file_of = {id(raw): f for f, forest in enumerate(forests) for top in forest for raw in _walk(top)}
    stack = [raw for forest in forests for raw in forest]
    parent_of = {}  # id(node) -> its parent node
    while stack:
        raw = stack.pop()
        stack.extend(raw.children)
        for child in raw.children:
            parent_of[id(child)] = raw
        if raw.geometry is None or geometries[raw.geometry].kind != "mesh":
            continue  # an empty, or a URDF box (its joints are rigid)
        linear = raw.world[:3, :3]
        norms = np.linalg.norm(linear, axis=0)
        if not (norms > 1e-300).all():
            continue  # singular: the learner says so
        turn = linear / norms
        if np.abs(turn.T @ turn - np.eye(3)).max() > 1e-6:
            # a shear too small to change the part's shape (a part turned by eye under a
            # non-uniformly scaled parent) is dropped, as the geometry test would
            unsheared = _without_small_shear(raw, geometries[raw.geometry].vertices)
            if unsheared is not None:
                linear = unsheared
                norms = np.linalg.norm(linear, axis=0)
                turn = linear / norms
        if np.abs(turn.T @ turn - np.eye(3)).max() <= 1e-6:  # a rotation (or mirror) times axis scales
            # meshes that are one mesh scaled along its axes (a tool's primitive, in several
            # files, its scale applied in some) are grouped: each as its unit-extent shape,
            # placed at the node's scale times its own extents
            if raw.geometry not in unit_of:  # once per mesh, however many nodes place it
                g = geometries[raw.geometry]
                unit, extents = _unit_shape(g.vertices)
                # one mesh when the faces are and the unit shapes agree within UNIT_SHAPE_TOLERANCE:
                # an exact match of unit shapes rounded to 9 digits split float32 cylinders
                # scaled across their axis (1.7e-8 apart), so applied plates and candles of
                # other sizes were each a part type of their own (h98)
                topology = (fingerprint(np.asarray(g.faces).tobytes() + str(unit.shape).encode()), _given_name(g))
                shapes = unit_shapes.setdefault(topology, [])
                index = next((k for k, other in enumerate(shapes)
                              if np.abs(other - unit).max() <= UNIT_SHAPE_TOLERANCE), None)
                if index is None:
                    index = len(shapes)
                    shapes.append(unit)
                unit_of[raw.geometry] = ((topology, index), extents)
            same, extents = unit_of[raw.geometry]
            by_geometry.setdefault(same, []).append((raw, turn, norms, extents))
        else:  # shears: the whole linear map goes into a geometry of its own
            _bake(raw, geometries, linear, np.eye(3), np.ones(3))
    # where each node hangs, before any baking renames its parent's geometry
    hangs = {id(raw): _hangs_under(raw, parent_of, unit_of) for placed in by_geometry.values() for raw, *_ in placed}
    for (topology, _), placed in by_geometry.items():
        sizes = np.log([norms * extents for _, _, norms, extents in placed])  # of the unit shape
        scaled = np.log([norms for _, _, norms, _ in placed])
        # a tool's primitive the user named per node (Torso, Head, Forearm: three cubes
        # within 3x of each other, h98's robots) is a part per name, then per size
        named = _named_apart([raw.name for raw, *_ in placed]) if topology[1] is None else None
        files = [file_of[id(raw)] for raw, *_ in placed]
        if named is not None and not _recurring(named, files, len(forests)):
            named = None  # names the user gave per file (titles, synonyms): no kinds
        if named is not None:
            named = _apart_in_size(named, sizes, [hangs[id(raw)] for raw, *_ in placed], files)
        groups = sorted(([members[k] for k in group] for members in (named or [list(range(len(placed)))])
                         for group in _scale_groups(sizes[members])), key=lambda group: group[0])
        meshes = {raw.geometry for raw, *_ in placed}
        if len(groups) == 1 and np.abs(scaled).max() <= math.log(SCALE_GROUP) and len(meshes) == 1:
            continue  # one mesh whose nodes' sizes vary, near its own size: as read
        for members in groups:
            if np.abs(sizes[members] - sizes[members[0]]).max() <= 1e-9 and np.abs(scaled[members]).max() <= 1e-9:
                continue  # one size, unscaled: as read
            # the size the group's geometry is made at: that of its first node in file order
            # that places its mesh as read (unscaled), so that a mesh kept as read still is
            # the twin of its mirrored copy (a wing, and the same wing 2% longer in another
            # file: the wing's mirror image stays the wing's); else the sizes' mean
            unscaled = [k for k in members if np.abs(scaled[k]).max() <= 1e-9]
            mean = (np.exp(sizes[min(unscaled, key=lambda k: read_order[id(placed[k][0])])]) if unscaled
                    else np.exp(sizes[members].mean(0)))
            for k in members:
                raw, turn, norms, extents = placed[k]
                _bake(raw, geometries, np.diag(mean / extents), turn, norms * extents / mean)
    used = {raw.geometry for forest in forests for top in forest for raw in _walk(top)}
    for key in [k for k in geometries if k not in used]:  # read, but no node places it as read
        del geometries[key]


def _without_small_shear(raw: _Raw, vertices: np.ndarray) -> np.ndarray | None:
    """The rotation times axis scales nearest ``raw``'s shearing world map (the polar
    decomposition's rotation times its stretch's diagonal), put on ``raw`` with its
    translation moved so the mesh's middle stays, when that moves no vertex further than
    :data:`GEOMETRY_TOLERANCE` x the placed mesh's diagonal: the distance within which two
    meshes are one part anyway. None (``raw`` untouched) for a larger shear: a shape of
    its own. Without this a part turned 1 degree under a parent scaled 1.5x along one
    axis was a part type of its own in every example."""
    linear = raw.world[:3, :3]
    u, sigma, vt = np.linalg.svd(linear)
    stretch = (vt.T * sigma) @ vt  # linear = (u @ vt) @ stretch
    nearest = (u @ vt) * np.diag(stretch)  # its columns: the rotation's, each scaled
    middle = 0.5 * (vertices.min(axis=0) + vertices.max(axis=0))
    moved = float(np.linalg.norm((vertices - middle) @ (linear - nearest).T, axis=1).max())
    diagonal = float(np.linalg.norm(np.ptp(vertices @ linear.T, axis=0)))
    if not moved <= GEOMETRY_TOLERANCE * diagonal:
        return None
    world = raw.world.copy()
    world[:3, :3] = nearest
    world[:3, 3] += (linear - nearest) @ middle
    raw.world = world
    return nearest


SCALE_GROUP = 3.0
"""Nodes of one mesh whose axis scales are within this factor of each other are one part
(:func:`_bake_scales`): a chair's legs, 0.45 to 0.54 tall, are one; its seat and back,
scaled from the same cube, are others."""


def _scale_groups(logs: np.ndarray) -> list:
    """Single-linkage groups (lists of indices) of log-scale rows within log(SCALE_GROUP)
    of each other on every axis, in order of their first member.

    The connected components of the rows' closeness, found on the distinct rows (a
    scene's copies share their scale) by a k-d tree: a pairwise union of 5,000 copies
    took ~10 s."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components
    from scipy.spatial import cKDTree

    distinct, inverse = np.unique(np.asarray(logs, dtype=np.float64).reshape(len(logs), -1), axis=0,
                                  return_inverse=True)
    pairs = cKDTree(distinct).query_pairs(math.log(SCALE_GROUP), p=np.inf, output_type="ndarray")
    n = len(distinct)
    graph = coo_matrix((np.ones(len(pairs)), (pairs[:, 0], pairs[:, 1])), shape=(n, n))
    _, component = connected_components(graph, directed=False)
    out = {}
    for i, c in enumerate(component[np.asarray(inverse).reshape(-1)].tolist()):
        out.setdefault(c, []).append(i)
    return list(out.values())


def _bake(raw: _Raw, geometries: dict, local: np.ndarray, turn: np.ndarray, residual: np.ndarray) -> None:
    """Place ``raw`` by a geometry of its mesh mapped by ``local`` (3x3), its world then
    ``turn`` times the axis scales ``residual``, its translation unchanged."""
    g = geometries[raw.geometry]
    key = ("baked", raw.geometry, tuple(np.round(local, 9).ravel().tolist()))
    if key not in geometries:
        faces = g.faces if np.linalg.det(local) > 0 else g.faces[:, ::-1]  # keep the winding outward
        by_node = g.named_by_node or ("default" if _NUMBERED.sub("", g.name).lower() in _DEFAULT_MESH_NAMES else "")
        name = {"": g.name, "unnamed": raw.name}.get(by_node) or _NUMBERED.sub("", raw.name) or raw.name
        geometries[key] = _Geometry(key, name, f"{g.where} (node {raw.name!r}, its scale applied)", "mesh",
                                    g.vertices @ local.T, faces, named_by_node=by_node)
    world = np.eye(4)
    world[:3, :3], world[:3, 3] = turn * residual, raw.world[:3, 3]
    raw.geometry, raw.world = key, world

# ---- URDF -------------------------------------------------------------------------------------

# a package:// URI's package not among the URDF's ancestors is looked for as rospack finds
# one, by the package.xml files of a workspace's folders: below the URDF's folder and its
# nearest ancestors (the home folder the highest, the file system's root never), to a depth,
# within a budget of folder entries read in one read_assets run
PACKAGE_CRAWL_ANCESTORS = 5  # the URDF's folder and 4 above it: ws/src/REPO/PKG/urdf/robot.urdf reaches src
PACKAGE_CRAWL_DEPTH = 3  # ws/src/PKG, src/REPO/PKG, src/ORG/REPO/PKG
PACKAGE_CRAWL_ENTRIES = 20000
_CRAWL_IGNORE = ("CATKIN_IGNORE", "COLCON_IGNORE", "AMENT_IGNORE")  # catkin, colcon and ament pass over these
_crawl_runs = threading.local()  # each thread's read_assets run its own: a dask worker runs tasks in threads


def _crawled() -> dict:
    """This thread's read_assets run's folders read and packages found (see
    :func:`_ros_package_folders`)."""
    state = getattr(_crawl_runs, "state", None)
    if state is None:
        state = _crawl_runs.state = {}
    return state


def _ros_package_name(folder: Path) -> str | None:
    """The package a ROS package folder's ``package.xml`` names, or None (no such file,
    or none readable)."""
    path = folder / "package.xml"
    try:
        if not path.is_file():  # (a FIFO or a device under that name had blocked or read without end)
            return None
        with open(path, "rb") as handle:  # a package.xml is a few KB: its start is enough
            text = handle.read(65536).decode("utf-8", errors="replace")
    except OSError:
        return None
    text = re.sub(r"<!--.*?-->", "", text, flags=re.DOTALL)  # a template's commented-out <name>
    found = re.search(r"<name>\s*([^<\s]+)\s*</name>", text)
    return found.group(1) if found else None


def _crawl_name(folder: Path) -> str | None:
    """:func:`_ros_package_name` of a folder met in a crawl (None where it holds an ignore
    marker), read once a run."""
    names = _crawled().setdefault("names", {})
    if folder not in names:
        name = _ros_package_name(folder)
        if name is not None and any(os.path.lexists(folder / marker) for marker in _CRAWL_IGNORE):
            name = None
        names[folder] = name
    return names[folder]


def _crawl_subfolders(folder: Path) -> list:
    """The subfolders of ``folder`` as ``((device, inode), path)`` by name, hidden ones left
    out (none where it holds an ignore marker); linked folders are followed (workspaces link
    packages into ``src``). Listed once a run, its entries counted against the run's
    :data:`PACKAGE_CRAWL_ENTRIES`: past them, nothing more is listed."""
    state = _crawled()
    listed = state.setdefault("listed", {})
    if folder not in listed:
        found = []
        try:
            with os.scandir(folder) as entries:
                for entry in entries:
                    state["entries"] = state.get("entries", 0) + 1
                    if entry.name in _CRAWL_IGNORE:
                        found = []
                        break
                    if state["entries"] > PACKAGE_CRAWL_ENTRIES:
                        break
                    if entry.name.startswith("."):
                        continue
                    try:
                        if entry.is_dir():
                            st = entry.stat()
                            found.append((entry.name, (st.st_dev, st.st_ino), Path(entry.path)))
                    except OSError:  # a dangling link, a folder we may not enter
                        continue
        except OSError:
            pass
        listed[folder] = [(key, path) for _, key, path in sorted(found)]
    return listed[folder]


def _crawl_packages(root: Path) -> list:
    """The ROS packages below ``root`` as ``(name, folder)``, breadth first to
    :data:`PACKAGE_CRAWL_DEPTH` folders down; as rospack, no package is looked for inside
    another, and each folder is entered once (a link to a folder above it loops no more)."""
    roots = _crawled().setdefault("roots", {})
    if root not in roots:
        found = []
        try:
            st = os.stat(root)
            seen = {(st.st_dev, st.st_ino)}
        except OSError:
            seen = set()
        level = [root]
        for depth in range(1, PACKAGE_CRAWL_DEPTH + 1):
            below = []
            for folder in level:
                for key, sub in _crawl_subfolders(folder):
                    if key in seen:
                        continue
                    seen.add(key)
                    name = _crawl_name(sub)
                    if name is not None:
                        found.append((name, sub))
                    elif depth < PACKAGE_CRAWL_DEPTH:
                        below.append(sub)
            level = below
        roots[root] = found
    return roots[root]


def _ros_package_folders(pkg: str, urdf_folder: Path) -> list:
    """The folders of the ROS packages whose ``package.xml`` names ``pkg``, nearest first,
    as rospack and ament find a package not among the URDF's ancestors (a sibling in a
    workspace's ``src``, its folder named as a download names it: ``ur_description-main``):
    below the URDF's folder and its :data:`PACKAGE_CRAWL_ANCESTORS` - 1 nearest ancestors (not
    above the home folder; never the file system's root), then below the folders of
    ``ROS_PACKAGE_PATH`` and in ``share/pkg`` of those of ``AMENT_PREFIX_PATH``. The folders
    read are kept for the rest of the read_assets run (a URDF names many meshes)."""
    here = urdf_folder.resolve()
    try:
        home = Path.home().resolve()
    except (RuntimeError, OSError):  # no home folder known
        home = None
    roots = []
    for folder in [here, *here.parents][:PACKAGE_CRAWL_ANCESTORS]:
        if folder.parent == folder:  # the file system's root: the whole disk
            break
        roots.append(folder)
        if folder == home:
            break
    env = [Path(p) for p in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep) if p.strip()]
    out = [root for root in env if _crawl_name(root) == pkg]  # a ROS_PACKAGE_PATH folder that is the package
    for root in roots + env:
        out += [sub for name, sub in _crawl_packages(root) if name == pkg]
    for prefix in os.environ.get("AMENT_PREFIX_PATH", "").split(os.pathsep):
        if prefix.strip() and _crawl_name(Path(prefix) / "share" / pkg) == pkg:
            out.append(Path(prefix) / "share" / pkg)
    return list(dict.fromkeys(out))


def _urdf_mesh_path(filename: str, urdf: Path, where: str) -> Path:
    """A URDF mesh file name resolved against the URDF's folder: plain relative paths,
    ``file://`` (relative, or an absolute ``file:///...`` URI where it is) and
    ``package://PKG/rest``: ``rest`` in the package's folder, looked for as a ROS
    workspace lays packages out (the URDF's folder or an ancestor that is the package, by
    its name or its ``package.xml``, or holds a ``PKG`` folder; then a folder nearby whose
    ``package.xml`` names PKG, found as rospack crawls a workspace: :func:`_ros_package_folders`),
    and failing that a bare ``rest`` under the URDF's folder or an ancestor (a robot's meshes
    copied beside it, into a package of the user's own too; where no package of another name
    holds that folder, before the crawl). Package folders come first: many packages hold a
    ``meshes/base_link.stl``, and the first ancestor holding one had been taken for any
    package's (h144), the URDF's own package's for a sibling package's whose folder has
    another name (``ur_description-main``, h156)."""
    base = urdf.parent
    name = filename
    candidates, later = [], None
    if name.startswith("file://"):
        name = name[len("file://"):]
        if name.startswith("localhost/"):
            name = name[len("localhost"):]
        if name.startswith("/"):
            # an absolute file URI, %-encoded (xacro's file://$(find pkg)/meshes/... expands to
            # one): it names the file wherever it is, as a ROS tool reads it
            from urllib.parse import unquote

            absolute = Path(unquote(name))
            candidates.append((Path(absolute.anchor), str(absolute.relative_to(absolute.anchor))))
    if not candidates and name.startswith("package://"):
        from urllib.parse import unquote

        pkg, _, rest = name[len("package://"):].partition("/")
        if not rest.strip("/"):
            raise AssetError(f"{where} {filename!r} names a package but no file in it; give the mesh's path in the "
                             "package (package://PKG/meshes/part.stl)")
        # as written, and %-decoded as ROS's resource retriever reads a URI ("base%20link.stl")
        spellings = [rest] + ([unquote(rest)] if unquote(rest) != rest else [])
        # ancestors of the resolved folder: "robot.urdf" run from its own folder has a base
        # of "." whose .parents is empty, and the package lies above it
        folders = [base, *base.resolve().parents]
        names = {folder: _ros_package_name(folder) for folder in folders}
        for folder in folders:  # the package's own folder first, wherever it is
            # (by its package.xml, or by its folder's name: a package renamed, or a template's
            # package.xml naming another, is still found where its URDF says)
            is_package = pkg in (names[folder], folder.resolve().name)
            for spelt in spellings:
                candidates += ([(folder, spelt)] if is_package else []) + [(folder, f"{pkg}/{spelt}")]

        # a bare path in a folder that no package of another name holds is a robot's meshes
        # copied beside its URDF (a CAD exporter's "robot_description" folder): taken before a
        # package of that name the crawl finds nearby, another robot's (h157); one in the URDF's
        # own package is that package's file, taken only where no package nearby is PKG (h156)
        in_other = [any(names[above] not in (None, pkg) for above in folders[i:]) for i in range(len(folders))]

        def nearby():  # meshes copied beside the URDF; a package nearby, by its package.xml; the rest
            yield from ((folder, spelt) for folder, other in zip(folders, in_other) if not other for spelt in spellings)
            yield from ((folder, spelt) for folder in _ros_package_folders(pkg, base) for spelt in spellings)
            yield from ((folder, spelt) for folder, other in zip(folders, in_other) if other for spelt in spellings)

        later = nearby()
    elif not candidates:
        candidates.append((base, name))
    # the crawl only where the package's own folder holds no such file: it lists folders
    for folder, rel in itertools.chain(candidates, later or ()):
        try:
            return named_file(folder, rel, where, suffixes=MESH_SUFFIXES, kind="mesh")
        except UnsafePathError as exc:
            last = exc
    if later is not None and "does not exist" in str(last):
        # the last folder tried is the file system's root: name the URI and where it was sought
        raise AssetError(f"{where} {filename!r} is neither {rest!r} nor {pkg + '/' + rest!r} under the URDF's "
                         f"folder {base} or a folder above it, nor in a package folder nearby whose package.xml "
                         f"names {pkg!r}; copy the package's meshes there") from None
    raise AssetError(str(last)) from None


def _load_mesh_file(path: Path, where: str) -> tuple[np.ndarray, np.ndarray]:
    size = path.stat().st_size
    if size > MAX_MESH_BYTES:
        raise AssetError(f"{where}: {path} is {size / 2 ** 20:.0f} MiB, more than procmod reads "
                         f"({MAX_MESH_BYTES // 2 ** 20} MiB); decimate it")
    declared = declared_faces(path)  # from the header (a binary STL, PLY, OFF) or a scan, before reading
    if declared is not None and declared > MAX_FACES:
        raise AssetError(f"{where}: {path} declares {declared:,} triangles, more than procmod reads "
                         f"({MAX_FACES:,}); decimate it")
    try:
        # a COLLADA mesh's vertices are taken in the link's frame as they are, its <up_axis>
        # left out, as RViz and MoveIt read a URDF's meshes (they drop the root turn that
        # Assimp makes of it), and ROS packages are drawn for them: a Y_UP (or unmarked, the
        # COLLADA default) mesh had been turned on its side beside the same part as an STL
        mesh = load_mesh_file(path, up=None, force="mesh", process=False, skip_materials=True)
    except Exception as exc:
        raise AssetError(f"{where}: cannot read {path} as a triangle mesh ({type(exc).__name__}: "
                         f"{str(exc)[:240]})") from None
    faces = getattr(mesh, "faces", None)
    if faces is None or len(faces) == 0:
        raise AssetError(f"{where}: {path} holds no triangles")
    if len(faces) > MAX_FACES:
        raise AssetError(f"{where}: {path} has {len(faces)} triangles, more than procmod reads ({MAX_FACES}); "
                         "decimate it")
    return np.asarray(mesh.vertices), np.asarray(mesh.faces)


def _mimic_value(joint, joints: dict, path: Path, known: dict) -> float:
    """A URDF joint's value in the robot's zero configuration: 0, except for a joint that
    mimics another (``<mimic joint= multiplier= offset=>``), whose value is ``multiplier x
    the other's + offset`` (the URDF specification), the other's own value resolved the
    same way (a mimic of a mimic), as robot_state_publisher and MoveIt place it. Followed
    in a loop (a chain of hundreds of mimics had exceeded Python's recursion, h90), each
    joint's value kept in ``known`` (name -> value) for the joints after it (re-walking
    each chain took minutes for thousands, h92)."""
    chain, seen = [], set()
    while getattr(joint, "mimic", None) is not None and joint.name not in known:
        if joint.name in seen:
            cycle = [j.name for j in chain[[j.name for j in chain].index(joint.name):]]
            said = (f"joint {cycle[0]!r} mimics itself" if len(cycle) == 1 else
                    f"joints {', '.join(repr(n) for n in cycle)} mimic one another in a cycle")
            raise AssetError(f"{path}: {said}; a mimic joint must follow a joint that moves of its own")
        seen.add(joint.name)
        chain.append(joint)
        joint = joints.get(joint.mimic.joint)  # a joint not in the file: taken at its zero
    value = known.get(joint.name, 0.0) if joint is not None else 0.0
    for mimicking in reversed(chain):
        mimic = mimicking.mimic
        multiplier = 1.0 if mimic.multiplier is None else float(mimic.multiplier)
        offset = 0.0 if mimic.offset is None else float(mimic.offset)
        value = multiplier * value + offset
        if not (math.isfinite(value) and abs(value) <= MAX_MIMIC_VALUE):
            raise AssetError(f"{path}: joint {mimicking.name!r} mimics another with multiplier {mimic.multiplier} and "
                             f"offset {mimic.offset}, which place it at {value:g}; they must be numbers that place it "
                             f"within {MAX_MIMIC_VALUE:g} (radians or metres)")
        known[mimicking.name] = value
    return value


MAX_MIMIC_VALUE = 1e6  # radians or metres a mimic joint may stand at: beyond, a file's error


def _mimic_motion(joint, joints: dict, path: Path, known: dict) -> np.ndarray:
    """The motion of a URDF joint in the robot's zero configuration (:func:`_mimic_value`):
    none, except for a joint that mimics another with an offset. A gripper's second finger
    that mimics the first with an offset had stood at zero, through the first (h73)."""
    value = _mimic_value(joint, joints, path, known)
    if value == 0.0 or joint.type not in ("revolute", "continuous", "prismatic"):
        return np.eye(4)
    axis = np.array([1.0, 0.0, 0.0]) if joint.axis is None else np.asarray(joint.axis, dtype=np.float64)
    top = float(np.abs(axis).max()) if axis.shape == (3,) and np.isfinite(axis).all() else 0.0
    if top > 0.0:
        axis = axis / top  # first: the length of an axis of 1e300s overflowed (h90)
    length = float(np.linalg.norm(axis)) if top > 0.0 else 0.0
    if length == 0.0:
        raise AssetError(f"{path}: joint {joint.name!r} mimics another, at {value:g} in the zero configuration, "
                         f"about axis {joint.axis}; the axis must be three numbers, not all zero")
    axis = axis / length
    motion = np.eye(4)
    if joint.type == "prismatic":
        motion[:3, 3] = value * axis
    else:  # a rotation by the value about the axis (Rodrigues)
        k = np.array([[0.0, -axis[2], axis[1]], [axis[2], 0.0, -axis[0]], [-axis[1], axis[0], 0.0]])
        motion[:3, :3] = np.eye(3) + math.sin(value) * k + (1.0 - math.cos(value)) * (k @ k)
    return motion


# what a URDF written with xacro holds until xacro expands it: ${expressions}, $(find ...)
# substitutions and <xacro:...> elements (its output may keep the xmlns:xacro declaration)
_XACRO_LEFT = re.compile(rb"\$\{[^}\n]{0,40}|\$\((?:find|arg|eval|env|optenv|dirname)\b[^)\n]{0,40}|<\s*xacro:[\w-]+")


def _read_urdf(path: Path, geometries: dict) -> list:
    import logging

    import trimesh
    import yourdfpy
    from lxml import etree

    try:
        data = path.read_bytes()
    except OSError as exc:
        raise AssetError(f"cannot read {path} ({exc.strerror})") from None
    macro = _XACRO_LEFT.search(re.sub(rb"<!--.*?-->", b"", data, flags=re.DOTALL))
    if macro is not None:  # it had failed on "${pi/2}" as a float, or on the xacro: prefix
        said = macro.group(0).decode("utf-8", "replace")
        raise AssetError(f"{path} still holds xacro macros ({said!r}...); expand them into a plain URDF first "
                         f"({XACRO_COMMAND}) and give that file")
    try:  # strict XML first: yourdfpy recovers from broken XML and reads half a robot. The
        # declaration is left out of the check: robots ship with <?xml version="0.0" ?>
        body = re.sub(rb"^\s*<\?xml[^>]*\?>", b"", data, count=1)
        root = etree.fromstring(body, etree.XMLParser(resolve_entities=False, no_network=True))
    except etree.XMLSyntaxError as exc:
        raise AssetError(f"cannot read {path} as URDF (not well-formed XML: {str(exc)[:120]})") from None
    source = str(path)
    if isinstance(root.tag, str) and root.tag.startswith("{") and root.prefix is None:
        # <robot xmlns="...">: ROS's parser reads its elements by their names and loads the
        # robot; yourdfpy looked for un-namespaced ones and found no link. Read without it
        for element in root.iter():
            if isinstance(element.tag, str):  # (comments and processing instructions have none)
                element.tag = etree.QName(element).localname
        etree.cleanup_namespaces(root)
        source = io.BytesIO(etree.tostring(root))
    quiet = logging.getLogger("yourdfpy")
    level = quiet.level
    quiet.setLevel(logging.CRITICAL)  # it logs the XML declaration it had to recover from
    try:
        robot = yourdfpy.URDF.load(source, build_scene_graph=False, load_meshes=False,
                                   build_collision_scene_graph=False, load_collision_meshes=False).robot
    except Exception as exc:
        raise AssetError(f"cannot read {path} as URDF ({type(exc).__name__}: {str(exc)[:120]})") from None
    finally:
        quiet.setLevel(level)
    links = {link.name: link for link in robot.links}
    if not links:
        raise AssetError(f"{path} holds no link")
    if len(links) + sum(len(link.visuals) for link in robot.links) > MAX_NODES:
        raise AssetError(f"{path} has more than {MAX_NODES} links and visuals, more than procmod reads")
    parent_joint, kids = {}, {name: [] for name in links}
    joints_by_name = {j.name: j for j in robot.joints}
    if len(joints_by_name) < len(robot.joints) and any(j.mimic is not None for j in robot.joints):
        # a mimic names the joint it follows, and its value is kept by name: which one? (h93;
        # ROS's parser refuses any such file; files without mimics read as before)
        twice = sorted(n for n in joints_by_name if sum(j.name == n for j in robot.joints) > 1)
        raise AssetError(f"{path}: two joints are named {twice[0]!r}, and joints mimic others by name; a URDF's "
                         "joint names must be unique")
    mimic_values = {}  # joint name -> its value in the zero configuration (_mimic_value)
    for j in robot.joints:
        for end in (j.parent, j.child):
            if end not in links:
                raise AssetError(f"{path}: joint {j.name!r} refers to link {end!r}, which does not exist")
        if j.child in parent_joint:
            raise AssetError(f"{path}: link {j.child!r} is the child of two joints ({parent_joint[j.child].name!r}, "
                             f"{j.name!r}); a URDF's links must form a tree")
        parent_joint[j.child] = j
        kids[j.parent].append(j.child)
    for start in links:
        seen, k = {start}, start
        while k in parent_joint:
            k = parent_joint[k].parent
            if k in seen:
                raise AssetError(f"{path}: the joints form a cycle (link {k!r} is its own ancestor)")
            seen.add(k)
            if len(seen) > MAX_DEPTH:  # as a glTF file's: a chain of 500 links exceeded Python's recursion (h90)
                raise AssetError(f"{path}: the link hierarchy is deeper than {MAX_DEPTH} levels (link {start!r}), "
                                 "more than procmod reads")
    faces_read = [0]

    def geometry_of(visual, link: str, k: int, kind: str = "visual"):
        g = visual.geometry
        where = f"{path}: link {link!r} {kind} {k}"
        if g is None:
            return None, np.eye(4)
        if g.box is not None:
            size = np.asarray(g.box.size, dtype=np.float64)
            if size.shape != (3,) or not np.isfinite(size).all() or (size < 0).any():
                raise AssetError(f"{where}: box size must be three positive numbers, got {g.box.size}")
            if (size == 0).any():  # a flat or empty box: an invisible marker
                return None, np.eye(4)
            key = ("box", tuple(size))
            geometries.setdefault(key, _Geometry(key, visual.name or link, where, "box", size=size))
            return key, np.eye(4)
        if g.cylinder is not None or g.sphere is not None:
            if g.cylinder is not None:
                r, h = float(g.cylinder.radius), float(g.cylinder.length)
                ok, key, make = r > 0 and h > 0, ("cylinder", r, h), lambda: trimesh.creation.cylinder(r, h, sections=32)
            else:
                r = float(g.sphere.radius)
                ok, key, make = r > 0, ("sphere", r), lambda: trimesh.creation.icosphere(2, r)
            if not all(map(math.isfinite, key[1:])) or min(key[1:]) < 0:
                raise AssetError(f"{where}: {key[0]} dimensions must be positive numbers, got {key[1:]}")
            if not ok:  # zero size: an invisible marker (laikago's toes); nothing to place
                return None, np.eye(4)
            if key not in geometries:
                m = make()
                geometries[key] = _Geometry(key, visual.name or link, where, "mesh",
                                            *_clean_mesh(m.vertices, m.faces, where))
            return key, np.eye(4)
        if g.mesh is not None:
            file = _urdf_mesh_path(g.mesh.filename, path, f"{where}: mesh")
            scale = np.ones(3) if g.mesh.scale is None else np.broadcast_to(
                np.asarray(g.mesh.scale, dtype=np.float64), 3)
            if not np.isfinite(scale).all() or (scale == 0).any():
                raise AssetError(f"{where}: mesh scale must be non-zero numbers, got {g.mesh.scale}")
            key = ("file", str(file.resolve()))
            if key not in geometries:
                v, f = _load_mesh_file(file, where)
                faces_read[0] += len(f)
                if faces_read[0] > MAX_FACES:
                    raise AssetError(f"{path}: its meshes have more than {MAX_FACES} triangles, more than procmod "
                                     "reads; decimate them")
                geometries[key] = _Geometry(key, visual.name or file.stem, f"{where}: {file.name}", "mesh",
                                            *_clean_mesh(v, f, f"{where}: {file.name}"))
            return key, np.diag([*scale, 1.0])
        return None, np.eye(4)

    def build(link_name: str, world: np.ndarray, kind: str) -> list:
        link = links[link_name]
        below = []
        for child in kids[link_name]:
            j = parent_joint[child]
            origin = np.eye(4) if j.origin is None else np.asarray(j.origin, dtype=np.float64)
            below += build(child, world @ origin @ _mimic_motion(j, joints_by_name, path, mimic_values), kind)
        nodes = []
        for k, visual in enumerate(link.visuals if kind == "visual" else link.collisions):
            key, scale = geometry_of(visual, link_name, k, kind)
            if key is None:
                continue
            origin = np.eye(4) if visual.origin is None else np.asarray(visual.origin, dtype=np.float64)
            m = world @ origin @ scale
            if not np.isfinite(m).all():
                raise AssetError(f"{path}: link {link_name!r} has a non-finite transform (NaN or infinity)")
            nodes.append(_Raw(link_name if not nodes else f"{link_name}#{k}", key, m))
        if not nodes:
            return below  # an empty link passes its children on
        nodes[0].children = nodes[1:] + below
        return [nodes[0]]

    forest = [n for root in links if root not in parent_joint for n in build(root, np.eye(4), "visual")]
    if not forest:
        # a robot drawn only by its collision geometry (simulators' URDFs: pybullet's, MuJoCo
        # exports): its collision shapes are its parts, as a simulator's view shows them
        if len(links) + sum(len(link.collisions) for link in robot.links) > MAX_NODES:
            raise AssetError(f"{path} has no visual geometry and more than {MAX_NODES} links and collision "
                             "elements, more than procmod reads")
        forest = [n for root in links if root not in parent_joint for n in build(root, np.eye(4), "collision")]
    if not forest:
        raise AssetError(f"{path} holds no visual or collision geometry (nothing to use as a part)")
    return forest


# ---- distinct geometry ------------------------------------------------------------------------

class _Surface:
    """What alignment needs of a mesh: samples, a few vertices, moments, a proximity query."""

    def __init__(self, g: _Geometry):
        import trimesh
        self.mesh = trimesh.Trimesh(g.vertices, g.faces, process=False)
        tri = g.vertices[g.faces]
        area = 0.5 * np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1)
        self.area = float(area.sum())
        w = area / self.area
        self.centroid = (w[:, None] * tri.mean(1)).sum(0)
        # second moment of the uniform distribution over each triangle, area-weighted
        c = tri - self.centroid
        s = c.sum(1)
        second = (np.einsum("n,nki,nkj->ij", w, c, c) + np.einsum("n,ni,nj->ij", w, s, s)) / 12
        self.moments, self.axes = np.linalg.eigh(second)
        self.diagonal = float(np.linalg.norm(np.ptp(g.vertices, axis=0)))
        self.samples, _ = self._sample(tri, w, _SAMPLES)
        self.subset = self.samples[::_SUBSET_STRIDE]  # stratified too: samples follow the triangles
        # a denser sampling with normals: ICP matches to its tangent planes
        self.dense, which = self._sample(tri, w, _DENSE)
        n = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
        self.normals = n[which] / np.maximum(np.linalg.norm(n[which], axis=1, keepdims=True), 1e-300)
        step = max(1, len(g.vertices) // _CHECK_VERTICES)
        self.check = np.concatenate([self.samples, g.vertices[::step]])
        from scipy.spatial import cKDTree
        self.tree = cKDTree(self.dense)

    @staticmethod
    def _sample(tri: np.ndarray, w: np.ndarray, count: int) -> tuple[np.ndarray, np.ndarray]:
        """``count`` area-weighted points (stratified, fixed seed) and their triangles."""
        cum = np.cumsum(w)
        which = np.minimum(np.searchsorted(cum, (np.arange(count) + 0.5) / count), len(tri) - 1)
        rng = np.random.default_rng(0)
        u, v = rng.random(count), rng.random(count)
        flip = u + v > 1
        u[flip], v[flip] = 1 - u[flip], 1 - v[flip]
        t = tri[which]
        return t[:, 0] + u[:, None] * (t[:, 1] - t[:, 0]) + v[:, None] * (t[:, 2] - t[:, 0]), which

    def match(self, points: np.ndarray, plane: bool) -> np.ndarray:
        """Points of (an approximation of) this surface matching ``points``: the nearest
        dense sample, or (``plane``) the point's projection onto that sample's tangent plane."""
        _, idx = self.tree.query(points)
        q = self.dense[idx]
        if not plane:
            return q
        n = self.normals[idx]
        return points - ((points - q) * n).sum(1, keepdims=True) * n

    def closest(self, points: np.ndarray) -> np.ndarray:
        """The closest points of this surface to ``points``."""
        from trimesh.proximity import closest_point
        return np.asarray(closest_point(self.mesh, points)[0])

    def distance_to(self, points: np.ndarray) -> float:
        """The largest distance from ``points`` to this surface."""
        return float(np.linalg.norm(self.closest(points) - points, axis=1).max())

    def similar(self, other: "_Surface") -> bool:
        """A cheap necessary condition: areas and principal radii agree within 5%."""
        if abs(self.area - other.area) > 0.05 * max(self.area, other.area):
            return False
        radii = np.sqrt(np.maximum(self.moments, 0)), np.sqrt(np.maximum(other.moments, 0))
        return bool(np.abs(radii[0] - radii[1]).max() <= 0.05 * max(self.diagonal, other.diagonal))


def _kabsch(p: np.ndarray, q: np.ndarray, improper: bool) -> np.ndarray:
    """The orthogonal map (det -1 when ``improper``) + translation taking p closest to q."""
    pc, qc = p.mean(0), q.mean(0)
    u, _, vt = np.linalg.svd((p - pc).T @ (q - qc))
    d = np.sign(np.linalg.det(vt.T @ u.T)) or 1.0
    want = -1.0 if improper else 1.0
    r = vt.T @ np.diag([1.0, 1.0, d * want]) @ u.T
    m = np.eye(4)
    m[:3, :3] = r
    m[:3, 3] = qc - r @ pc
    return m


def _starts(a: _Surface, b: _Surface, improper: bool) -> list:
    """Rotations taking b's principal axes onto a's (every sign choice of the given
    handedness; every 30 degrees about an axis whose two partners are degenerate; when
    all three are, as for a sphere or a regular solid, whose principal axes say nothing,
    the 60 rotations of the icosahedral group, spread over all orientations, and maps
    between pairs of vertices, :func:`_vertex_pair_starts`)."""
    from scipy.spatial.transform import Rotation

    out = []
    scale = max(float(a.moments.max()), 1e-300)
    gaps = np.diff(a.moments) / scale
    spins = [np.eye(3)]
    for k, axis in ((0, 2), (1, 0)):  # moments k, k+1 degenerate: spin about the third axis
        if gaps[k] < 1e-2:
            spins = [Rotation.from_rotvec(b.axes[:, axis] * t).as_matrix() for t in np.arange(12) * np.pi / 6]
    signs_tried = ((1, 1, 1), (1, -1, -1), (-1, 1, -1), (-1, -1, 1), (-1, -1, -1), (-1, 1, 1), (1, -1, 1), (1, 1, -1))
    if gaps.max() < 1e-2:
        spins = list(Rotation.create_group("I").as_matrix())
        signs_tried = ((1, 1, 1), (-1, -1, -1))  # the spins cover every rotation: one base a handedness
    for signs in signs_tried:
        base = a.axes @ np.diag(signs) @ b.axes.T
        if (np.linalg.det(base) < 0) != improper:
            continue
        for spin in spins:
            r = base @ spin
            m = np.eye(4)
            m[:3, :3] = r
            m[:3, 3] = a.centroid - r @ b.centroid
            out.append(m)
    if gaps.max() < 1e-2:
        out += _vertex_pair_starts(a, b, improper)
    return out


# A coarse polyhedron of equal moments (an icosphere of 80 faces, a die) turned by "Apply
# rotation" before export: ICP's basin on a nearly round surface is a few degrees wide,
# narrower than any spread of start rotations, so starts also come from its vertices.
_PAIR_VERTICES = 2000  # meshes with more vertices are round enough that any start fits
_PAIR_STARTS = 24


def _frame(u: np.ndarray, v: np.ndarray) -> np.ndarray:
    """The orthonormal frame (columns) of ``u`` and the part of ``v`` across it."""
    e1 = u / np.linalg.norm(u)
    e2 = v - (v @ e1) * e1
    e2 /= np.linalg.norm(e2)
    return np.column_stack([e1, e2, np.cross(e1, e2)])


def _vertices_and_degrees(surface: _Surface) -> tuple[np.ndarray, np.ndarray]:
    """A mesh's distinct vertices about its centroid (seams merged) and the number of
    edges at each."""
    vertices, index = np.unique(np.asarray(surface.mesh.vertices), axis=0, return_inverse=True)
    faces = index.ravel()[np.asarray(surface.mesh.faces)]
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]]), axis=1), axis=0)
    edges = edges[edges[:, 0] != edges[:, 1]]
    return vertices - surface.centroid, np.bincount(edges.ravel(), minlength=len(vertices))


def _vertex_pair_starts(a: _Surface, b: _Surface, improper: bool) -> list:
    """Maps taking a pair of b's vertices onto a's farthest vertex and its nearest
    neighbour away from the centre's line (pairs of b at the same distances, within the
    tolerance): when b is a copy of a, one of them is the exact map."""
    if not 3 <= len(a.mesh.vertices) <= _PAIR_VERTICES or not 3 <= len(b.mesh.vertices) <= _PAIR_VERTICES:
        return []
    (va, da), (vb, db) = _vertices_and_degrees(a), _vertices_and_degrees(b)
    eps = 2 * GEOMETRY_TOLERANCE * max(a.diagonal, b.diagonal)
    ra, rb = np.linalg.norm(va, axis=1), np.linalg.norm(vb, axis=1)
    i = int(np.argmax(ra))
    apart = np.linalg.norm(va - va[i], axis=1)
    across = np.linalg.norm(np.cross(va, va[i]), axis=1) / max(ra[i], 1e-300)  # distance from the centre's line
    apart[(apart < 2 * eps) | (across < 2 * eps)] = np.inf
    j = int(np.argmin(apart))
    if not np.isfinite(apart[j]):
        return []
    target = _frame(va[i], va[j])
    flip = np.diag([1.0, 1.0, -1.0 if improper else 1.0])
    pairs = []  # (how far the pair's distances are from a's, k, l)
    # vertices of as many edges as a's pair (a copy's own tessellation): a midpoint of an
    # icosphere lies as far from its neighbours as a corner does from its own
    same = (db == da[i]).any() and (db == da[j]).any()
    for k in np.flatnonzero((np.abs(rb - ra[i]) <= eps) & ((db == da[i]) | (not same))):
        gap = np.linalg.norm(vb - vb[k], axis=1)
        off = np.abs(rb - ra[j]) + np.abs(gap - apart[j]) + abs(rb[k] - ra[i])
        for l in np.flatnonzero((off <= 2 * eps) & ((db == da[j]) | (not same))):
            if np.linalg.norm(np.cross(vb[l], vb[k])) / max(rb[k], 1e-300) >= eps:
                pairs.append((float(off[l]), int(k), int(l)))
    out = []
    for _, k, l in sorted(pairs)[:_PAIR_STARTS]:  # a copy's own pair first: its distances agree exactly
        r = target @ flip @ _frame(vb[k], vb[l]).T
        m = np.eye(4)
        m[:3, :3] = r
        m[:3, 3] = a.centroid - r @ b.centroid
        out.append(m)
    return out


def _icp(a: _Surface, b: _Surface, m: np.ndarray, improper: bool, plane: bool, steps: int,
         points: np.ndarray | None = None) -> np.ndarray:
    """Refine ``m`` (b onto a) by ICP: ``points`` of b (default: its samples) matched to
    a's dense samples (``plane`` False: coarse) or to their tangent planes (fine)."""
    points = b.samples if points is None else points
    for _ in range(steps):
        moved = points @ m[:3, :3].T + m[:3, 3]
        m_new = _kabsch(points, a.match(moved, plane), improper)
        if np.abs(m_new - m).max() <= 1e-12 * max(a.diagonal, 1.0):
            return m_new
        m = m_new
    return m


def _residual(a: _Surface, m: np.ndarray, points: np.ndarray) -> float:
    """Mean distance of ``points`` moved by ``m`` to a's tangent planes."""
    moved = points @ m[:3, :3].T + m[:3, 3]
    return float(np.linalg.norm(a.match(moved, True) - moved, axis=1).mean())


def _align(a: _Surface, b: _Surface, tol: float, mirror: bool) -> np.ndarray | None:
    """A rigid map M (improper only when no proper one fits and ``mirror``) with
    M(b) = a within ``tol`` x the diagonal, or None. Every start is refined by coarse
    ICP on a subset of b's samples; the best :data:`_KEPT_STARTS` by coarse ICP on all
    of them, the two best of those by point-to-plane ICP, then checked exactly (point to
    surface)."""
    if not a.similar(b):
        return None
    limit = tol * max(a.diagonal, b.diagonal)

    def fits(m):
        inv = np.linalg.inv(m)
        return (a.distance_to(b.check @ m[:3, :3].T + m[:3, 3]) <= limit
                and b.distance_to(a.check @ inv[:3, :3].T + inv[:3, 3]) <= limit)

    same = np.eye(4)
    same[:3, 3] = a.centroid - b.centroid
    if np.abs(same[:3, 3]).max() <= limit and fits(np.eye(4)):
        return np.eye(4)  # the same geometry (a duplicate): exactly the identity
    for improper in ((False, True) if mirror else (False,)):
        starts = _starts(a, b, improper)
        # a start that is already the map (a copy's vertex pair; its residual is that of
        # the tangent planes' sampling): ICP against samples would only move it off by the
        # samples' spacing
        raw = [(_residual(a, m, b.subset), k) for k, m in enumerate(starts)]
        best, k = min(raw, default=(math.inf, 0))
        if best <= 0.05 * limit and fits(starts[k]):
            return starts[k]
        ranked = []
        for m in starts:
            m = _icp(a, b, m, improper, plane=False, steps=20, points=b.subset)
            ranked.append((_residual(a, m, b.subset), len(ranked), m))
        coarse = []
        for _, _, m in sorted(ranked, key=lambda c: c[:2])[:_KEPT_STARTS]:
            m = _icp(a, b, m, improper, plane=False, steps=20)
            coarse.append((_residual(a, m, b.samples), len(coarse), m))
        for _, _, m in sorted(coarse, key=lambda c: c[:2])[:2]:
            m = _icp(a, b, m, improper, plane=True, steps=30)
            if _residual(a, m, b.samples) > limit:
                continue  # apart on average, so surely somewhere: skip the exact check
            snapped = _snap(m, a, b)
            if snapped is not None and fits(snapped):
                return snapped
            if fits(m):
                return m
    return None


def _vertex_map(a: _Geometry, b: _Geometry, tol: float) -> np.ndarray | None:
    """A proper rigid map M with M(b) = a within ``tol`` x the diagonal found vertex for
    vertex, for two meshes of the same triangles (a copy, moved or turned with its
    transforms applied, as a tool's duplicates are exported), or None: then
    :func:`_align` decides.

    A sufficient test, stricter than :func:`_align`'s: a point of a triangle is the same
    affine combination of its vertices in both meshes, so when every vertex of M(b) lies
    within the limit of its counterpart in a, every point of M(b) lies within it of a
    point of a, and back, which is what :func:`_align`'s check asks; but a map that fits
    the surfaces without pairing the vertices (a plate turned within its own plane) is
    left to :func:`_align`. It costs a few array operations where :func:`_align`'s
    point-to-surface queries cost ~40 ms a pair (a 5,000-part scene of copies, each mesh
    data of its own, took minutes). The identity is taken exactly, and a quarter turn up
    to rounding is rounded to it (as :func:`_snap` does) when the rounded turn still
    fits vertex for vertex."""
    if a.vertices.shape != b.vertices.shape or not np.array_equal(a.faces, b.faces):
        return None
    limit = tol * max(float(np.linalg.norm(np.ptp(a.vertices, axis=0))),
                      float(np.linalg.norm(np.ptp(b.vertices, axis=0))))
    # a rigid map keeps the vertices' RMS distance from their centroid, and moves it by at
    # most the largest vertex error: meshes of one face list at other sizes (a sphere at
    # ten sizes, ten parts) are told apart at this cost, before a fit
    spread = [float(np.sqrt(((v - v.mean(0)) ** 2).sum(1).mean())) for v in (a.vertices, b.vertices)]
    if abs(spread[0] - spread[1]) > limit:
        return None

    def fits(m):
        moved = b.vertices @ m[:3, :3].T + m[:3, 3]
        return float(np.linalg.norm(moved - a.vertices, axis=1).max()) <= limit

    if fits(np.eye(4)):
        return np.eye(4)
    m = _kabsch(b.vertices, a.vertices, improper=False)
    r = np.round(m[:3, :3])
    if np.abs(m[:3, :3] - r).max() <= 0.05 and np.allclose(np.abs(r).sum(0), 1) and np.allclose(np.abs(r).sum(1), 1):
        snapped = np.eye(4)
        snapped[:3, :3] = r
        snapped[:3, 3] = a.vertices.mean(0) - r @ b.vertices.mean(0)
        if fits(snapped):
            return snapped
    return m if fits(m) else None


def _snap(m: np.ndarray, a: _Surface, b: _Surface) -> np.ndarray | None:
    """``m`` with its rotation rounded to the nearest signed axis permutation (a quarter
    turn, a flip), when it is one up to ICP's error; None otherwise. An exact quarter
    turn commutes with axis scalings, so a node's non-uniform scale does not shear it."""
    r = m[:3, :3]
    p = np.round(r)
    if np.abs(r - p).max() > 0.05 or not np.allclose(np.abs(p).sum(0), 1) or not np.allclose(np.abs(p).sum(1), 1):
        return None
    out = np.eye(4)
    out[:3, :3] = p
    out[:3, 3] = a.centroid - p @ b.centroid
    return out


def _box_map(a: np.ndarray, b: np.ndarray, tol: float) -> np.ndarray | None:
    """A proper axis permutation M with M(box b) = box a (extents within tolerance)."""
    limit = tol * max(float(np.linalg.norm(a)), float(np.linalg.norm(b)))
    for perm in itertools.permutations(range(3)):
        if np.abs(a[list(perm)] - b).max() <= limit:
            m = np.zeros((4, 4))
            m[3, 3] = 1
            for j, i in enumerate(perm):  # b's axis j becomes a's axis perm[j]
                m[i, j] = 1.0
            if np.linalg.det(m[:3, :3]) < 0:
                m[:3, 0] *= -1  # a box is symmetric: flip an axis to keep the map proper
            return m
    return None


def unused_name(base: str, taken: set, fold=None) -> str:
    """``base``, else ``base_2``, ``base_3``, ...: the first whose ``fold(name)`` (the name
    itself without ``fold``) is not in ``taken``; that key is added to ``taken``."""
    name, k = base, 1
    key = name if fold is None else fold(name)
    while key in taken:
        k += 1
        name = f"{base}_{k}"
        key = name if fold is None else fold(name)
    taken.add(key)
    return name


def _library(geometries: list, tol: float, mirror: bool, worlds: dict | None = None) -> tuple[dict, dict]:
    """Part library and, per geometry key, (part name, M) with geometry = M(part).

    ``worlds``: per geometry key, the world transforms of the nodes that use it. A part
    with symmetries (a box, a cylinder) maps onto a geometry in several ways; each
    geometry takes the one that places its nodes nearest to unrotated in the world
    (:func:`_upright_symmetry`)."""
    surfaces = {}  # geometry key -> _Surface, made when a comparison needs it (~8 ms each)

    def surface_of(g: _Geometry) -> _Surface:
        if g.key not in surfaces:
            surfaces[g.key] = _Surface(g)
        return surfaces[g.key]

    classes = []  # [representative, [(geometry, M: geometry = M(representative))]]
    for g in geometries:
        kin = [cls for cls in classes if cls[0].kind == g.kind]
        if g.kind == "box":
            found = ((cls, _box_map(g.size, cls[0].size, tol)) for cls in kin)
        else:  # a copy's triangles first (cheap, :func:`_vertex_map`), then surfaces
            found = itertools.chain(((cls, _vertex_map(g, cls[0], tol)) for cls in kin),
                                    ((cls, _align(surface_of(g), surface_of(cls[0]), tol, mirror)) for cls in kin))
        placed = next(((cls, m) for cls, m in found if m is not None), None)
        if placed is None:
            classes.append([g, [(g, np.eye(4))]])
        else:
            placed[0][1].append((g, placed[1]))
    parts, of_key, used = {}, {}, set()
    for rep, members in classes:
        # the part takes the shortest (then first in order) of its geometries' names, and
        # that geometry's local frame
        canon, m_canon = min(members, key=lambda gm: (len(gm[0].name), gm[0].name))
        name = unused_name(canon.name or "part", used)
        if canon.kind == "box":
            parts[name] = PartShape(name, "box", size=tuple(float(s) for s in canon.size),
                                    source=[float(s) for s in canon.size])
        shift = np.eye(4)
        if canon.kind != "box":
            shift[:3, 3] = _far_pivot_shift(canon.vertices)
            parts[name] = PartShape(name, "mesh", vertices=tuple(map(tuple, (canon.vertices - shift[:3, 3]).tolist())),
                                    faces=tuple(map(tuple, canon.faces.tolist())), source=None)
        inv = np.linalg.inv(m_canon)
        symmetries = _symmetries(canon, surface_of(canon) if canon.kind == "mesh" else None, tol)
        for g, m in members:  # g = m(rep) and canon = m_canon(rep), so g = m m_canon^-1 (canon)
            # (and canon = shift(part): the part's frame moved to its middle where its pivot was far off)
            of_key[g.key] = (name, _upright_symmetry(m @ inv, symmetries, (worlds or {}).get(g.key, ())) @ shift)
    return parts, of_key


FAR_PIVOT = 0.5
"""A mesh whose own origin lies farther than this many bounding-box diagonals outside its
bounding box gets a part frame at the box's centre (:func:`_far_pivot_shift`)."""


def _far_pivot_shift(vertices: np.ndarray) -> np.ndarray:
    """Where a part's frame moves to (in its mesh's coordinates): the bounding box's centre
    when the mesh's origin lies far outside it, else nowhere (zero). A mesh exported with
    its transforms applied (Blender's Apply All Transforms) has its geometry in world
    coordinates about the world's origin: a table's leg turned about a point 0.75 m away,
    and its placements encoded that offset, so learned legs strayed 0.3 m outside the top.
    A pivot an artist placed (a hinge, a leg's top) lies on or near the geometry: kept."""
    lo, hi = vertices.min(0), vertices.max(0)
    outside = np.linalg.norm(np.maximum(lo, 0.0) + np.maximum(-hi, 0.0))  # the origin to the box
    if outside <= FAR_PIVOT * np.linalg.norm(hi - lo):
        return np.zeros(3)
    return (lo + hi) / 2.0


def _symmetries(canon: _Geometry, surface, tol: float) -> list:
    """The maps of a part onto itself among the quarter turns and half turns about its own
    axes through its centre (proper signed permutations; the identity first): for a box,
    those that only swap equal extents; for a mesh, those that keep it within ``tol`` of
    its diagonal. A part modelled along its axes, as tools make them, has its symmetries
    among these; a symmetry at other angles is not sought (the identity always fits)."""
    out = []
    for perm in itertools.permutations(range(3)):
        for signs in itertools.product((1.0, -1.0), repeat=3):
            d = np.zeros((3, 3))
            d[list(perm), range(3)] = signs  # axis j goes to axis perm[j], with a sign
            if np.linalg.det(d) < 0:
                continue
            if canon.kind == "box":
                size = np.asarray(canon.size, dtype=np.float64)
                if np.abs(np.abs(d) @ size - size).max() > tol * float(np.linalg.norm(size)):
                    continue
                centre = np.zeros(3)
            else:
                centre = surface.centroid
                moved = (surface.check - centre) @ d.T + centre
                if np.abs(d - np.eye(3)).max() > 0 and surface.distance_to(moved) > tol * surface.diagonal:
                    continue
            m = np.eye(4)
            m[:3, :3] = d
            m[:3, 3] = centre - d @ centre
            out.append(m)
    out.sort(key=lambda m: -np.trace(m[:3, :3]))  # the identity first: kept on ties
    return out


def _upright_symmetry(m: np.ndarray, symmetries: list, worlds) -> np.ndarray:
    """``m @ S`` for the symmetry ``S`` that turns the nodes placed by it (world transforms
    ``worlds``) least: summed over them, the trace of the rotation of ``world @ m @ S``
    (its orthogonal factor) is largest. Without it, a box-like part (a seat, a table top)
    of an example whose transforms were applied in the tool, or whose mesh was modelled
    turned, could take a half turn that fits the geometry as well, and the learned program
    sampled whole chairs tipped over."""
    if len(symmetries) < 2 or not len(worlds):
        return m
    candidates = [m] + [m @ sym for sym in symmetries[1:]]  # symmetries[0] is the identity
    # every candidate for every node in one batched SVD (a scene of 5,000 copies took ~5 s one by one)
    linear = np.einsum("kij,sjl->skil", np.array([w[:3, :3] for w in worlds]),
                       np.array([c[:3, :3] for c in candidates]))
    u, _, vt = np.linalg.svd(linear)
    scores = np.trace(u @ vt, axis1=-2, axis2=-1).sum(1).tolist()
    best = 0
    for k in range(1, len(candidates)):
        if scores[k] > scores[best] + 1e-6 * len(worlds):  # a real gain, not rounding between equals
            best = k
    return candidates[best]


def _place(raw: _Raw, of_key: dict) -> list:
    below = [n for c in raw.children for n in _place(c, of_key)]
    if raw.geometry is None:
        return below
    part, m = of_key[raw.geometry]
    return [AssetNode(raw.name, part, raw.world @ m, below)]


def read_assets(paths, tolerance: float = GEOMETRY_TOLERANCE, mirror: bool = True) -> AssetSet:
    """Read asset files (glTF, GLB, URDF; or folders of them) into one part library and
    one hierarchy per file (see the module docstring).

    Parameters
    ----------
    paths : path or list of paths
        Files, or folders whose asset files (by suffix) are read in name order.
    tolerance : float
        Two meshes are one part when a rigid motion maps one onto the other within this
        fraction of the bounding-box diagonal.
    mirror : bool
        Also identify mirror images (the mirrored one is placed with a negative scale).

    Raises
    ------
    AssetError
        For a file that cannot be used; the message names it and the problem.
    """
    files = asset_files(paths)
    geometries, forests = {}, []
    _crawled().clear()  # the folders a URDF's packages were looked for in: read once a run, afresh the next
    try:
        for path in files:
            reader = _read_urdf if path.suffix.lower() == ".urdf" else _read_gltf
            # a transform of 1e999 is refused by its reader, in one line: without numpy's own
            # warnings of it (trimesh's matrix products had printed four lines first)
            with np.errstate(invalid="ignore", over="ignore", divide="ignore"):
                forests.append(reader(path, geometries))
    finally:
        _crawled().clear()
    _unbake_turns(forests, geometries)
    _bake_scales(forests, geometries)
    worlds = {}
    stack = [raw for forest in forests for raw in forest]
    while stack:  # the nodes that place each geometry, for _upright_symmetry
        raw = stack.pop()
        if raw.geometry is not None:
            worlds.setdefault(raw.geometry, []).append(raw.world)
        stack.extend(raw.children)
    parts, of_key = _library(list(geometries.values()), tolerance, mirror, worlds)
    assets = [Asset(path, [n for r in forest for n in _place(r, of_key)],
                    (forest[0].name,) if len(forest) == 1 and forest[0].geometry is None else ())
              for path, forest in zip(files, forests)]
    return AssetSet(parts, assets, tolerance)


__all__ = ["Y_UP_TO_Z_UP", "ASSET_SUFFIXES", "Asset", "AssetError", "AssetNode", "AssetSet", "GEOMETRY_TOLERANCE", "MAX_FACES",
           "MAX_NODES", "asset_files", "faceless_note", "is_asset_file", "read_assets"]
