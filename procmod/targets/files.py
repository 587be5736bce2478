"""Reading 3D target files: ``procmod-volume/1`` and ``procmod-silhouette/1`` JSON, and the
voxel grids, weight images, pictures and meshes they name.

Everything a file says is checked when it is read, before any work: a bad field is refused
with one line naming the file and the field by its JSON path, e.g.
``T.json: layers[1].w_fill must be a finite number, got inf``; a size the machine cannot
hold (a voxel grid, a mesh, an image) is refused from what the file declares, before it
is loaded. Files named inside a target file follow :func:`procmod.core.paths.named_file`:
relative to the target file's folder, an existing regular file of the expected kind.

Meshes (``.obj .glb .gltf .ply .stl .off .dae``, read by trimesh; COLLADA through pycollada) are taken as modelling tools
write them (:func:`read_mesh`): UV and normal seams, which split vertices, are merged;
faces are wound consistently and outward per connected piece; a volume layer's inside is
then decided by the generalised winding number (:mod:`procmod.geometry.inside`), so
overlapping pieces, flipped faces, small holes and non-manifold edges need no repair. A
mesh is refused only when no inside exists (no faces, every face of zero area, vertices
that are not numbers) or when it is too large (more than :data:`MAX_MESH_FACES` faces).
"""

from __future__ import annotations

import glob
import math
import os
import re
from pathlib import Path

import numpy as np

from ..core.errors import cut_text, shown_value
from ..core.limits import MAX_COORDINATE, MIN_LENGTH, ResourceLimitError, check_memory, format_bytes
from ..core.paths import UnsafePathError, named_file
from ..core.serialize import read_json
from ..geometry.camera import Camera, Silhouettes
from ..geometry.mesh_files import MESH_SUFFIXES, declared_faces, load_mesh_file, special_file_kind
from ..geometry.voxel import VoxelGrid
from .image import (FRAMES, MAX_IMAGE_PIXELS, SIDECAR_KEYS, TargetFileError, _fills_its_box, _fully_transparent,
                    _see_through_drawing, grey_levels, mask_from_image, meant_key, opaque_part, open_image,
                    picture_in_square)
from .silhouette import Silhouette
from .volume import ProxyVolume, Volume

# The largest mesh procmod reads as a target. Reading costs about BYTES_PER_FACE of memory
# per face at its peak (trimesh's parser, the merged copy, the half-edge sort) and some
# 10 s per million faces of OBJ; a voxel grid does not resolve more detail than this.
MAX_MESH_FACES = 4_000_000
BYTES_PER_FACE = 400
# Memory per voxel of a volume target: the combined weights and the engine's gain copy
# (float64 each), the layer masks, the inside test's crossing counts (int32), the scene's
# hit counts.
BYTES_PER_VOXEL = 24
SCORES = ("svol", "proxy")
DEFAULT_MESH_VIEW = 128  # pixels a side of a silhouette view drawn from a mesh, unless given


def read_target_json(path: str | os.PathLike):
    """The parsed JSON of a target description, or a TargetFileError saying why not."""
    return read_json(path, TargetFileError, "target file")  # one line also for absurdly deep JSON


# --- fields --------------------------------------------------------------------------------

def number(value, where: str, positive: bool = False, minimum: float | None = None) -> float:
    """A finite number from a file (not a bool), else TargetFileError naming ``where``."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise TargetFileError(f"{where} must be a finite number, got {shown_value(value)}")
    if positive and not value > 0:
        raise TargetFileError(f"{where} must be positive, got {value:g}")
    if minimum is not None and value < minimum:
        raise TargetFileError(f"{where} must be at least {minimum:g}, got {value:g}")
    return float(value)


# A weight's magnitude: weights are relative, and a score sums one per voxel or pixel, so a
# weight near 1e308 made the score infinite (and settings.json invalid JSON).
MAX_WEIGHT = 1e6


def weight(value, where: str, minimum: float | None = None) -> float:
    """A finite weight from a file of magnitude at most :data:`MAX_WEIGHT`."""
    value = number(value, where, minimum=minimum)
    if abs(value) > MAX_WEIGHT:
        raise TargetFileError(f"{where} must be between -{MAX_WEIGHT:g} and {MAX_WEIGHT:g} (weights are relative), "
                              f"got {value:g}")
    return value




def vector3(value, where: str) -> tuple:
    """Three finite numbers within +-:data:`MAX_COORDINATE` from a file."""
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise TargetFileError(f"{where} must be three numbers, got {shown_value(value)}")
    out = tuple(number(v, f"{where}[{i}]") for i, v in enumerate(value))
    if max(abs(v) for v in out) > MAX_COORDINATE:
        raise TargetFileError(f"{where} must lie within +-{MAX_COORDINATE:g}, got {shown_value(list(value))}")
    return out


def length(value, where: str) -> float:
    """A positive length from a file, from :data:`MIN_LENGTH` to :data:`MAX_COORDINATE`."""
    value = number(value, where, positive=True)
    if not MIN_LENGTH <= value <= MAX_COORDINATE:
        raise TargetFileError(f"{where} must lie in {MIN_LENGTH:g}..{MAX_COORDINATE:g}, got {value:g}")
    return value


def _count(value, where: str, largest: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or not 1 <= value <= largest:
        raise TargetFileError(f"{where} must be a whole number from 1 to {largest:,}, got {shown_value(value)}")
    return value


def _object(value, where: str) -> dict:
    if not isinstance(value, dict):
        raise TargetFileError(f"{where} must be a JSON object, got {shown_value(value)}")
    return value


def _file(path: Path, value, where: str, suffixes, kind: str) -> Path:
    """The file a target file names (see :func:`procmod.core.paths.named_file`)."""
    try:
        return named_file(path.parent, value, where, suffixes, kind)
    except UnsafePathError as exc:
        raise TargetFileError(str(exc)) from None


# --- .npy arrays ---------------------------------------------------------------------------

def npy_header(file: Path, where: str, what: str):
    """``(shape, dtype)`` from an .npy file's header, without reading its data."""
    try:
        with open(file, "rb") as handle:
            version = np.lib.format.read_magic(handle)
            read = np.lib.format.read_array_header_1_0 if version == (1, 0) else np.lib.format.read_array_header_2_0
            shape, _, dtype = read(handle)
    except (OSError, ValueError, TypeError, SyntaxError) as exc:
        raise TargetFileError(f"{where}: cannot read the {what} ({cut_text(str(exc), 120)})") from None
    return tuple(int(n) for n in shape), dtype


def load_npy(file: Path, where: str, what: str) -> np.ndarray:
    """An .npy array of numbers (its header checked first by the caller), refusing NaN."""
    try:
        array = np.load(file, allow_pickle=False)
    except (OSError, ValueError, TypeError, EOFError) as exc:
        raise TargetFileError(f"{where}: cannot read the {what} ({cut_text(str(exc), 120)})") from None
    if array.dtype.kind == "f" and not np.isfinite(array).all():
        raise TargetFileError(f"{where}: the {what} holds NaN or infinity; it must hold finite numbers")
    return array


def _numeric(dtype, where: str, what: str) -> None:
    if dtype.kind not in "biuf":
        raise TargetFileError(f"{where}: the {what} must hold numbers, got dtype {dtype}")


# --- meshes --------------------------------------------------------------------------------

def _too_many_faces(where: str, file: Path, faces: int, exact: bool) -> ResourceLimitError:
    return ResourceLimitError(
        f"{where}: {cut_text(str(file), 120)} has {'' if exact else 'at least '}{faces:,} faces; procmod reads target "
        f"meshes of up to {MAX_MESH_FACES:,} faces (reading this one would need about "
        f"{format_bytes(faces * BYTES_PER_FACE)} of memory, and a voxel or pixel grid does not resolve that much "
        "detail): decimate it first (e.g. Blender's Decimate modifier)")


def read_mesh(file: str | os.PathLike, where: str | None = None, orient: bool = True, notes: list | None = None):
    """``(vertices (n, 3) float64, faces (m, 3) int64)`` of a mesh file, ready for
    :func:`procmod.geometry.inside.inside_voxels`.

    trimesh reads it (a scene is flattened with its transforms); vertices that UV or
    normal seams split are merged (:func:`merged_seams`, to a tolerance relative to the
    mesh's size: the same mesh in metres, kilometres or micrometres reads the same);
    faces with a repeated vertex or zero area are dropped; with ``orient``, repeated and
    double-sided faces are resolved (:func:`procmod.geometry.inside.single_sided`) and faces
    are wound consistently and outward (:func:`procmod.geometry.inside.orient_faces`).
    Faces on a vertex that is NaN or infinite (a scanner's dropout) are left out, with a
    line in ``notes``: the hole they leave is bridged like any other. Refused in one line
    naming ``where``: a file trimesh cannot read, no faces, every face on a non-finite
    vertex, every face of zero area, more than :data:`MAX_MESH_FACES` faces.
    """
    import trimesh

    from ..geometry.inside import orient_faces, single_sided

    file = Path(file)
    where = where or cut_text(str(file))
    kind = special_file_kind(file)
    if kind is not None:  # (a named pipe had been called empty; reading one waits for a writer)
        raise TargetFileError(f"{where}: {cut_text(str(file), 120)} is {kind}, not a mesh file; give the mesh "
                              "file itself (save what a pipe carries to a file first)")
    try:
        size = file.stat().st_size
    except OSError as exc:
        raise TargetFileError(f"{where}: cannot read the mesh {cut_text(str(file), 120)} ({exc.strerror})") from None
    if size == 0:
        raise TargetFileError(f"{where}: {cut_text(str(file), 120)} is empty")
    declared = declared_faces(file)
    if declared is not None and declared > MAX_MESH_FACES:
        raise _too_many_faces(where, file, declared, exact=file.suffix.lower() in (".stl", ".ply", ".off"))
    if declared is not None:
        check_memory(f"{where}: reading {declared:,} faces", declared * BYTES_PER_FACE)
    try:
        # skip_materials: a target needs the geometry only; with materials trimesh decoded every
        # texture and packed them into one atlas (12 textures of 2048²: 20 s and 3.3 GB, not 2 s)
        mesh = load_mesh_file(file, force="mesh", process=False, skip_materials=True)  # quiet: quiet_trimesh
    except Exception as exc:  # noqa: BLE001 -- trimesh raises many types for unreadable files
        raise TargetFileError(f"{where}: cannot read the mesh ({cut_text(str(exc) or type(exc).__name__, 200)})") from None
    if not isinstance(mesh, trimesh.Trimesh) or len(mesh.faces) == 0:
        raise TargetFileError(f"{where}: {cut_text(str(file), 120)} holds no triangle faces (nothing to take an "
                              "inside or a silhouette of; is it a mesh file?)")
    if len(mesh.faces) > MAX_MESH_FACES:
        raise _too_many_faces(where, file, len(mesh.faces), exact=True)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    vertices = np.asarray(mesh.vertices, dtype=np.float64)
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise TargetFileError(f"{where}: a face refers to a vertex the mesh does not have")
    finite = np.isfinite(vertices).all(axis=1)
    if not finite.all():  # a vertex no face uses may be anything
        on_bad = ~finite[faces].all(axis=1)
        if on_bad.all():
            bad = int(np.flatnonzero(~finite)[0])
            raise TargetFileError(f"{where}: every face of the mesh is on a vertex that is not a finite number (NaN or "
                                  f"infinity), e.g. vertex {bad} = {vertices[bad].tolist()}; fix the vertices in a "
                                  "modelling tool, or export the mesh again")
        if on_bad.any() and notes is not None:
            count = int(np.unique(faces[on_bad][~finite[faces[on_bad]]]).size)
            one = count == 1
            dropped = int(on_bad.sum())
            faces_text = "the face on" if dropped == 1 else f"the {dropped:,} faces on"
            notes.append(f"{where}: {count:,} {'vertex is' if one else 'vertices are'} not a finite number (NaN or "
                         f"infinity); {faces_text} {'it' if one else 'them'} {'was' if dropped == 1 else 'were'} left "
                         f"out, a hole the inside test bridges (fix {'it' if one else 'them'} in a modelling tool if "
                         "the shape is wrong there)")
        faces = faces[~on_bad]
    vertices, faces = merged_seams(vertices, faces)
    faces = faces[(faces[:, 0] != faces[:, 1]) & (faces[:, 1] != faces[:, 2]) & (faces[:, 2] != faces[:, 0])]
    tris = vertices[faces]
    with np.errstate(over="ignore", invalid="ignore"):  # coordinates near 1e300: not a warning on the error channel
        area = 0.5 * np.linalg.norm(np.cross(tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 0]), axis=1)
        # zero area up to rounding, judged by the face's own size: against the whole mesh's
        # extent, one stray face 1e6 units off (a marker left in the scene) made every face of
        # a model of faces 0.05 wide "zero area", dropped, and the model refused as off the grid
        longest = np.maximum.reduce([np.einsum("ij,ij->i", d, d) for d in (
            tris[:, 1] - tris[:, 0], tris[:, 2] - tris[:, 1], tris[:, 0] - tris[:, 2])]) if len(tris) else np.zeros(0)
        nonzero = area > 1e-14 * longest
    if not nonzero.any():
        raise TargetFileError(f"{where}: every face of the mesh has zero area (its triangles are points or lines), "
                              "so it has neither an inside nor a silhouette")
    faces = faces[nonzero]
    if orient:
        faces, _ = orient_faces(vertices, single_sided(faces))
    return vertices, faces


# Seam vertices merge when they agree on a grid of 10^(floor(log10(edge)) - MERGE_DIGITS), edge
# the mesh's median edge length: 1e-8 for edges of 0.1 to 1 units, as trimesh's fixed merge
# tolerance, and in proportion for a mesh of any other size. The median edge, not the
# extent: one stray face far off (a marker left in the scene) stretches the extent, and a
# grid coarse enough for it had merged a whole model into a few points
MERGE_DIGITS = 7


def merged_seams(vertices: np.ndarray, faces: np.ndarray) -> tuple:
    """``(vertices, faces)`` with the vertices the faces use merged where they agree to
    :data:`MERGE_DIGITS` digits of the mesh's median edge length (UV and normal seams split
    one vertex into copies at one place), each kept where it first occurs; vertices no face
    uses are dropped. trimesh's ``merge_vertices`` rounds to a fixed 1e-8 in int64: a
    sphere of radius 1e-8 (a part in metres from a chip) collapsed into a few faces, and
    a mesh at +-1e30 overflowed into one vertex and was refused as of zero area."""
    referenced = np.zeros(len(vertices), dtype=bool)
    referenced[faces] = True
    used = np.flatnonzero(referenced)
    points = vertices[used]
    if len(points) == 0:
        return vertices[:0], faces
    sample = faces[::max(1, len(faces) // 100_000)]  # (a median needs no million faces)
    with np.errstate(over="ignore", invalid="ignore"):
        edges = np.linalg.norm(vertices[sample] - vertices[np.roll(sample, 1, axis=1)], axis=2).ravel()
    edges = edges[np.isfinite(edges) & (edges > 0)]
    edge = float(np.median(edges)) if len(edges) else 0.0
    # the grid's step as a power of ten (a mesh scaled by 1000 rounds alike), coarsened where
    # the largest coordinate over the step would pass 1e300 (a speck far off: it then rounds
    # below its own float spacing, which is as exact as its file holds it)
    reach = float(np.abs(points).max())
    digits = MERGE_DIGITS - math.floor(math.log10(edge)) if edge > 0 else 0
    if reach > 0:
        digits = min(digits, 300 - math.ceil(math.log10(reach)))
    digits = max(digits, -300)
    keys = np.round(points * float(10 ** digits) if digits >= 0 else points / float(10 ** -digits)) + 0.0  # no -0
    index = np.empty(len(vertices), dtype=np.int64)
    if np.abs(keys).max() < 2.0 ** 53:  # whole numbers a float holds exactly: trimesh's hashing (4x a float sort)
        from trimesh.grouping import unique_rows

        kept, index[used] = unique_rows(keys.astype(np.int64), keep_order=True)  # each where it first occurs
    else:  # a speck far off its origin: rows compared as floats
        _, first, inverse = np.unique(keys, axis=0, return_index=True, return_inverse=True)
        order = np.argsort(first, kind="stable")  # the file's order, as trimesh kept it
        rank = np.empty(len(first), dtype=np.int64)
        rank[order] = np.arange(len(first))
        kept, index[used] = first[order], rank[inverse.reshape(-1)]
    return np.ascontiguousarray(points[kept], dtype=np.float64), index[faces]


def mesh_bounds(vertices: np.ndarray, faces: np.ndarray) -> tuple:
    """World bounds (lo, hi) of the vertices the faces use."""
    used = np.zeros(len(vertices), dtype=bool)
    used[np.asarray(faces).ravel()] = True
    return vertices[used].min(axis=0), vertices[used].max(axis=0)


def check_grid(grid: VoxelGrid, where: str, advice: str) -> None:
    """Refuse a voxel grid memory cannot hold, before anything is allocated."""
    count = math.prod(int(n) for n in grid.shape)
    check_memory(f"{where} ({'x'.join(str(int(n)) for n in grid.shape)} = {count:,} voxels)",
                 count * BYTES_PER_VOXEL, advice)


# Said when a mesh's grid is too large or the mesh too small for its voxels: most often
# the mesh is in other units than the model (a Maya file in centimetres is 100x too large).
OTHER_UNITS = ("if the mesh was made in other units than the model (Maya writes centimetres), give "
               "\"mesh_scale\" first (0.01 for centimetres to metres, 0.001 for millimetres, 0.0254 for inches)")


def span_text(lo, hi) -> str:
    """A box's extents, ``"2 x 0.5 x 3"``."""
    return " x ".join(f"{float(h - l):.3g}" for l, h in zip(lo, hi))


DEFAULT_MARGIN = 0.1
"""A mesh-fitted grid's margin on each side (model units) when the file gives none..."""

SMALL_MESH_MARGIN = 0.25
"""...but at most this share of the meshes' largest extent (and at least two voxels): a
20 mm part from a CAD tool, in metres, had been given 100 mm on each side, a grid of a
billion voxels refused as if its voxel size were at fault."""


def default_margin(lo, hi, voxel_size: float) -> float:
    """The margin of a grid fitted to meshes spanning [lo, hi] when none is given:
    :data:`DEFAULT_MARGIN`, or for a small mesh :data:`SMALL_MESH_MARGIN` of its largest
    extent, but not under two voxels (so nothing changes for a mesh of 0.4 units or more,
    or for voxels of 0.05 or more)."""
    extent = float(np.max(np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64)))
    return min(DEFAULT_MARGIN, max(SMALL_MESH_MARGIN * extent, 2.0 * voxel_size))


def grid_around(lo, hi, voxel_size: float, margin: float, where: str, meshes=()) -> VoxelGrid:
    """The grid of voxel edge ``voxel_size`` around [lo, hi] grown by ``margin``, refused
    (naming ``where``) when memory cannot hold it; its shape is counted in Python integers
    first, so that a tiny voxel size is refused instead of overflowing. A refusal names a
    stray piece of ``meshes`` (``(vertices, faces)`` pairs) far from the rest, if any
    (:func:`stray_piece_text`): that, not the units, is then what stretched the grid."""
    span = span_text(lo, hi)
    extent = float(np.max(np.asarray(hi, dtype=np.float64) - np.asarray(lo, dtype=np.float64)))
    # a margin larger than the mesh is what a refusal's grid is mostly made of: say so
    advice = (f"the mesh spans {span} and the grid is mostly its margin of {margin:g} on each side: give a "
              f"smaller \"margin\", or use a larger voxel_size" if margin > extent else
              f"the mesh spans {span}: use a larger voxel_size, or, {OTHER_UNITS}")
    lo = np.asarray(lo, dtype=np.float64) - margin
    hi = np.asarray(hi, dtype=np.float64) + margin
    # at most 1e18 a side (a voxel size of 1e-300 is refused by the memory check, not an overflow)
    shape = tuple(max(1, math.ceil(min(float(hi[a] - lo[a]) / voxel_size, 1e18))) for a in range(3))
    grid = VoxelGrid(tuple(float(v) for v in lo), float(voxel_size), shape)
    try:
        check_grid(grid, where, advice)
    except ResourceLimitError as exc:
        stray = next(filter(None, (stray_piece_text(v, f) for v, f in meshes)), None)
        if stray is None:
            raise
        raise type(exc)(f"{str(exc).split('; the mesh spans', 1)[0]}; {stray}") from None
    return grid


STRAY_DISTANCE = 10.0
"""A small piece of a mesh (:func:`stray_piece_text`) lying more than this many times the
size of the mesh's largest piece away from it is a stray."""


def stray_piece_text(vertices: np.ndarray, faces: np.ndarray) -> str | None:
    """One clause naming the smaller pieces of a mesh (connected by shared vertices) that
    lie far from its largest piece (a stray triangle left at 1000, 1000, 1000 by a
    modelling slip), or None."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    if len(faces) < 2:
        return None
    n = len(vertices)
    rows = np.concatenate([faces[:, 0], faces[:, 1]])
    cols = np.concatenate([faces[:, 1], faces[:, 2]])
    _, label = connected_components(coo_matrix((np.ones(len(rows)), (rows, cols)), shape=(n, n)), directed=False)
    piece = label[faces[:, 0]]
    sizes = np.bincount(piece)
    main = int(np.argmax(sizes))
    used = np.unique(faces[piece == main])
    lo, hi = vertices[used].min(axis=0), vertices[used].max(axis=0)
    reach = STRAY_DISTANCE * max(float(np.linalg.norm(hi - lo)), 1e-12)
    strays, where = [], None
    for p in np.flatnonzero(sizes):
        if p == main or sizes[p] >= sizes[main]:
            continue
        points = vertices[np.unique(faces[piece == p])]
        gap = np.maximum(np.maximum(lo - points, points - hi), 0.0)
        if float(np.linalg.norm(gap, axis=1).min()) > reach:
            strays.append(p)
            where = where if where is not None else points.mean(axis=0)
    if not strays:
        return None
    lo, hi = mesh_bounds(vertices, faces[~np.isin(piece, strays)])
    strays = int(sizes[strays].sum())
    return (f"{strays} face{'s' if strays > 1 else ''} of the mesh {'lie' if strays > 1 else 'lies'} far from the "
            "rest (near "
            f"({', '.join(f'{v:.4g}' for v in where)}), while the rest spans {span_text(lo, hi)}): delete that stray "
            "piece in a modelling tool")


# A mesh whose oriented faces' areas, added as vectors, keep more than half their total is
# mostly a sheet facing one way: a terrain, a single wall, two triangles (a closed surface
# adds up to nothing; a box without its lid keeps a fifth).
OPEN_SHEET = 0.5


def open_mesh_note(vertices, faces, where: str) -> str | None:
    """A line of advice when a mesh from :func:`read_mesh` is mostly an open sheet, whose
    inside (where the winding number is at least 1/2) is a guess: a terrain read as a
    volume fills a scattered skin under it."""
    tri = np.asarray(vertices, dtype=np.float64)[np.asarray(faces)]
    normals = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    total = float(np.linalg.norm(normals, axis=1).sum())
    if total <= 0:
        return None
    sheet = float(np.linalg.norm(normals.sum(axis=0))) / total
    if sheet <= OPEN_SHEET:
        return None
    return (f"{where}: the mesh is mostly an open sheet ({100 * sheet:.0f}% of its area faces one way, as a terrain "
            "or a single wall does), so its inside is a guess; close it in a modelling tool for a solid, or use a "
            "silhouette view of it")


# A separate piece of a mesh this flat (thinnest extent over widest), at least this many
# times as wide as the rest, and lying under it (or beside it, standing), is taken for a
# ground, a floor or a backdrop the mesh was exported with (:func:`ground_piece_note`).
GROUND_FLAT, GROUND_WIDE = 0.05, 3.0


def ground_piece_note(vertices, faces, where: str, closed_only: bool = False) -> str | None:
    """A line naming a separate flat piece far wider than the rest of the mesh and lying
    under (or behind) it: a Blender scene's floor exported with the model. A solid slab
    0.75 m under a ship was 92% of the volume to fill, and a ground plane filled a
    silhouette view, whose note then blamed the mesh's units; neither said what it was.
    ``closed_only``: only a closed piece (a volume's inside; an open plane is left out of
    it, :func:`mesh_inside`)."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    vertices, faces = np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)
    if len(faces) == 0:
        return None
    n = len(vertices)
    edges = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]]])
    graph = coo_matrix((np.ones(len(edges)), (edges[:, 0], edges[:, 1])), shape=(n, n))
    count, label = connected_components(graph, directed=False)
    piece_of_face = label[faces[:, 0]]
    used = np.unique(faces)
    if len(np.unique(label[used])) < 2:
        return None  # one piece (vertices no face uses, a sliver's, are none: h80)
    # every piece's box at once (a mesh of 100,000 leaf cards is 100,000 pieces), then the
    # rest's box only for the few flat pieces as wide as the whole mesh
    lows = np.full((count, 3), np.inf)
    highs = np.full((count, 3), -np.inf)
    np.minimum.at(lows, label[used], vertices[used])
    np.maximum.at(highs, label[used], vertices[used])
    spans = highs - lows
    whole = float((vertices[used].max(axis=0) - vertices[used].min(axis=0)).max())
    wide = np.flatnonzero((spans.max(axis=1) >= (1 - 1 / GROUND_WIDE) * whole)
                          & (spans.min(axis=1) <= GROUND_FLAT * spans.max(axis=1)))
    for piece in wide[:4]:
        lo, hi = lows[piece], highs[piece]
        rest = vertices[used[label[used] != piece]]
        r_lo, r_hi = rest.min(axis=0), rest.max(axis=0)
        extent, r_extent = hi - lo, r_hi - r_lo
        thin = int(np.argmin(extent))
        if extent[thin] > GROUND_FLAT * extent.max() or extent.max() < GROUND_WIDE * max(float(r_extent.max()), 1e-12):
            continue
        below = hi[thin] <= r_lo[thin] + 0.5 * r_extent[thin]
        if not (below or (thin != 1 and lo[thin] >= r_hi[thin] - 0.5 * r_extent[thin])):
            # through the middle of the rest (a wing, a deck), or a flat piece over it (a
            # table's top, a parasol: h80), which is the model's own; a backdrop stands either side
            continue
        if closed_only:
            own_faces = np.sort(faces[piece_of_face == piece], axis=1)
            _, uses = np.unique(np.concatenate([own_faces[:, [0, 1]], own_faces[:, [1, 2]], own_faces[:, [0, 2]]]),
                                axis=0, return_counts=True)
            if (uses != 2).any():
                continue  # an open sheet: no inside of its own
        size = " x ".join(f"{v:.3g}" for v in np.delete(extent, thin))
        return (f"{where}: a separate flat piece {size} wide, {extent.max() / max(float(r_extent.max()), 1e-12):.1f}x "
                f"as wide as the rest of the mesh, lies {'under' if below and thin == 1 else 'beside'} it (a ground, "
                "floor or backdrop exported with the model?): it is part of the target; delete it in the "
                "modelling tool if the model is not to fill it")
    return None


# Flat open pieces bound a room when, at most of the voxels leaving them out changes, their
# own winding number is within this of a nonzero whole number: surfaces that close a region
# (walls around a room, however they meet) wind a whole number of times around it, while
# scattered fragments (leaf cards) sum to fractions (Jacobson et al. 2013)
ENCLOSING = 0.15
ENCLOSING_PROBES = 400  # voxels the test above looks at, at most


def mesh_inside(vertices, faces, grid: VoxelGrid, where: str, notes: list | None = None) -> np.ndarray:
    """The voxels of ``grid`` inside a mesh from :func:`read_mesh` (generalised winding
    number >= 1/2), refused when none is.

    Open flat pieces (:func:`procmod.geometry.inside.flat_open_pieces`: leaf cards,
    decals) are left out, with a line in ``notes``, when they enclose nothing: when, at
    the voxels leaving them out changes, their own winding number is mostly not within
    :data:`ENCLOSING` of a nonzero whole number (a room of separate wall planes keeps its
    walls; leaf cards sum to fractions), or when the inside with them cannot be computed
    within the work limit (100,000 leaf cards had been refused) and the rest has an
    inside. ``notes`` also gets :func:`open_mesh_note`'s line, of the faces whose inside
    the mask is."""
    from ..core.limits import ResourceLimitError
    from ..geometry.inside import flat_open_pieces, inside_voxels, winding_numbers

    faces = np.asarray(faces)
    flat = flat_open_pieces(vertices, faces)
    mask, used = None, faces
    if flat.any() and not flat.all():
        solid = inside_voxels(vertices, faces[~flat], grid, what=where)
        try:
            whole = inside_voxels(vertices, faces, grid, what=where)
        except ResourceLimitError:
            if not solid.any():
                raise
            whole = None
        if whole is not None:
            changed = np.argwhere(solid != whole)
            if len(changed) == 0:
                # they change nothing: the inside is the rest's (a ground plane under a closed
                # ship had been called "mostly an open sheet", its inside "a guess")
                mask, used = whole, faces[~flat]
            else:
                probes = changed[np.random.default_rng(0).permutation(len(changed))[:ENCLOSING_PROBES]]
                points = np.asarray(grid.origin, dtype=np.float64) + grid.size * (probes + 0.5)
                w = winding_numbers(vertices, faces[flat], points)
                if ((np.abs(w - np.round(w)) <= ENCLOSING) & (np.round(w) != 0)).mean() >= 0.5:
                    mask = whole  # they close a region: kept
                else:
                    # or they close one with the other pieces: a floor and a roof plane over walls
                    # folded into one open piece (the planes alone enclose nothing) had been left
                    # out, the room's inside the open walls' guess; leaf cards around a closed
                    # trunk still sum to fractions (at most 2e7 solid angles: well under a second)
                    probes = probes[:max(16, min(len(probes), int(2e7 // len(faces))))]
                    points = points[:len(probes)]
                    w = winding_numbers(vertices, faces, points)
                    if (np.abs(w - np.round(w)) <= ENCLOSING).mean() >= 0.5:
                        mask = whole
        if mask is None:
            mask, used = solid, faces[~flat]
            if notes is not None:
                notes.append(f"{where}: {int(flat.sum()):,} faces of open flat pieces (leaf cards, planes, decals) "
                             f"enclose nothing and are left out of the volume; the inside is that of the other "
                             f"{int((~flat).sum()):,} faces (a silhouette view keeps them)")
    if mask is None:
        mask = inside_voxels(vertices, faces, grid, what=where)
    sheet = open_mesh_note(vertices, used, where) if notes is not None else None
    if sheet is not None:  # of the faces whose inside it is (left-out leaf cards all facing up are no sheet)
        notes.append(sheet)
    if not mask.any():
        lo, hi = mesh_bounds(vertices, faces)
        g_lo = np.asarray(grid.origin, dtype=np.float64)
        g_hi = g_lo + grid.size * np.asarray(grid.shape, dtype=np.float64)
        grid_is = f"the {'x'.join(map(str, grid.shape))} grid (voxel size {grid.size:g})"
        if np.any(lo > g_hi) or np.any(hi < g_lo):  # a grid given in the file, beside the mesh
            raise TargetFileError(
                f"{where}: {grid_is} spans {_corner(g_lo)} to {_corner(g_hi)} and does not cover the mesh, which "
                f"spans {_corner(lo)} to {_corner(hi)}: the grid belongs where the model builds (around its "
                "origin); bring the mesh onto it with \"mesh_offset\" (and \"mesh_scale\" if it was made in "
                "other units)")
        if float(np.max(hi - lo)) < 2 * grid.size:  # the whole mesh within two voxels
            # (after a "mesh_scale" the note advised, the voxel size chosen for the mesh's old
            # units is what is left too large: the value to give is named)
            raise TargetFileError(
                f"{where}: the mesh spans only {span_text(lo, hi)}, under two voxels of {grid.size:g}, so no voxel "
                "centre lies inside it: if it was made in other units than the model, give \"mesh_scale\" to bring "
                "it to them (1000 for a mesh in metres used with a model in millimetres); if it is in the model's "
                f"units (\"mesh_scale\" given), give a voxel_size in them, such as {float(np.max(hi - lo)) / 32:.3g} "
                "(32 voxels along its longest side)")
        raise TargetFileError(
            f"{where}: no voxel centre of {grid_is} lies inside the mesh: an open sheet or a flat mesh has no "
            "inside, and parts thinner than a voxel fall between voxel centres; use a smaller voxel_size, or "
            "close the mesh")
    return mask


def _corner(point) -> str:
    return "(" + ", ".join(f"{float(v):.4g}" for v in point) + ")"


def voxelize_mesh_file(path: str | os.PathLike, voxel_size: float, margin: float | None = None,
                       notes: list | None = None):
    """``(grid, mask)``: a mesh file (any format :func:`read_mesh` takes) voxelized on the
    grid of edge ``voxel_size`` around it grown by ``margin`` (default:
    :func:`default_margin`, 0.1 but for small meshes). ``notes`` gets a line for each
    part of the file left out or read in a way to check (:func:`read_mesh`'s faces on
    NaN vertices, :func:`mesh_inside`'s open flat pieces and open surfaces), as the CLI
    prints them."""
    where = cut_text(str(path))
    voxel_size = length(voxel_size, f"{where}: voxel_size")
    if margin is not None:
        margin = number(margin, f"{where}: margin", minimum=0.0)
    vertices, faces = read_mesh(path, where, notes=notes)
    bounds = mesh_bounds(vertices, faces)
    if margin is None:
        margin = default_margin(*bounds, voxel_size)
    grid = grid_around(*bounds, voxel_size, margin, f"{where}: voxel size {voxel_size:g}",
                       [(vertices, faces)])
    return grid, mesh_inside(vertices, faces, grid, where, notes)


# --- volume targets ------------------------------------------------------------------------

# A mesh's up axis (its file's "mesh_up") -> the rotation that stands it up in procmod's
# y-up frame, the least rotation taking that axis to +y: a z-up file (3ds Max, a CAD tool,
# Blender's OBJ and STL exports with "Z up") turns as Blender's glTF exporter turns z-up
# scenes, (x, y, z) -> (x, z, -y).
UP_AXES = ("y", "z", "x", "-x", "-y", "-z")


def up_rotation(up: str) -> np.ndarray:
    """The 3x3 rotation taking the axis ``up`` (one of :data:`UP_AXES`) to +y."""
    axis = np.zeros(3)
    axis["xyz".index(up[-1])] = -1.0 if up.startswith("-") else 1.0
    if axis[1] == -1.0:  # upside down: half a turn about x
        return np.diag([1.0, -1.0, -1.0])
    c = np.cross(axis, [0.0, 1.0, 0.0])  # sin of the angle times the axis of the turn
    k = np.array([[0.0, -c[2], c[1]], [c[2], 0.0, -c[0]], [-c[1], c[0], 0.0]])
    return np.eye(3) + k + k @ k / (1.0 + axis[1])  # Rodrigues, for unit vectors (axis . y = cos)


def _mesh_placement(spec: dict, where: str):
    """``(scale, offset, rotation)`` of a target file's ``"mesh_scale"`` (a positive number,
    default 1), ``"mesh_offset"`` (three numbers, default 0) and ``"mesh_up"`` (the mesh's
    up axis, default "y"): a mesh's point p is taken at ``rotation @ p * scale + offset``,
    in the model's frame (a mesh exported in centimetres for a model in metres takes
    ``"mesh_scale": 0.01``; one from a z-up tool ``"mesh_up": "z"``)."""
    scale = number(spec.get("mesh_scale", 1.0), f"{where}: mesh_scale", positive=True)
    offset = np.asarray(vector3(spec.get("mesh_offset", (0.0, 0.0, 0.0)), f"{where}: mesh_offset"))
    if not (1e-12 <= scale <= 1e12 and np.all(np.abs(offset) <= 1e12)):
        raise TargetFileError(f"{where}: mesh_scale must lie in 1e-12..1e12 and mesh_offset within +-1e12, got "
                              f"{scale:g} and {shown_value(offset.tolist())}")
    up = spec.get("mesh_up", "y")
    if up not in UP_AXES:
        raise TargetFileError(f"{where}: mesh_up is the mesh's up axis, one of {', '.join(map(repr, UP_AXES))} "
                              f"(procmod's models are y-up; \"z\" for a z-up tool's file), got {shown_value(up)}")
    return scale, offset, up_rotation(up)


def _placement_needs_meshes(spec: dict, where: str, has_meshes: bool, what: str) -> None:
    """Refuse a placement key in a file without meshes to place, and in one with meshes a
    placement said in other words (:func:`_placement_synonyms`): a file of pictures or
    grids may carry a tool's "scale" or "offset", which means nothing to procmod."""
    try:
        if has_meshes:
            _placement_synonyms(spec, _VOLUME_KEYS if what == "layer" else _SILHOUETTE_KEYS)
        elif what == "view" and "up" in spec:  # pictures only: a top-level "up" is a camera's, misplaced
            raise TargetFileError("the file has 'up', which procmod does not read at its top level; did you mean "
                                  "a view's camera \"up\" (\"camera\": {..., \"up\": [x, y, z]})?")
    except TargetFileError as exc:
        raise TargetFileError(f"{where}: {exc}") from None
    given = [key for key in ("mesh_scale", "mesh_offset", "mesh_up") if key in spec]
    if given and not has_meshes:
        raise TargetFileError(f"{where}: {' and '.join(given)} {'place' if len(given) > 1 else 'places'} mesh {what}s and this file has none (an .npy "
                              "grid or a picture is placed by its own grid or camera)")


def _check_up_once(file: Path, spec: dict, at: str) -> None:
    """Refuse ``"mesh_up"`` for a COLLADA file that declares an up axis other than y: it is
    read standing by that already, and ``mesh_up`` turned it a second time (Blender's z-up
    export, given ``"mesh_up": "z"`` as the README says for a z-up tool, stood on its tail).
    A file that says Y_UP (trimesh writes it into every file) may still be turned."""
    up = spec.get("mesh_up", "y")
    if up == "y" or file.suffix.lower() != ".dae":
        return
    from ..geometry.polygon_files import collada_up_axis

    declared = collada_up_axis(file)
    if declared not in (None, "Y_UP"):  # Y_UP (the default) is procmod's frame: read unturned
        raise TargetFileError(f"{at}: {cut_text(file.name, 80)} is COLLADA, which declares its up axis "
                              f"(<up_axis>{declared}</up_axis>), and procmod reads it standing by that already; "
                              f"leave out \"mesh_up\" (\"{up}\" would turn it a second time), or export the "
                              "mesh as glTF or OBJ")


def _placed(mesh, placement):
    """A mesh ``(vertices, faces)`` moved by a :func:`_mesh_placement`."""
    vertices, faces = mesh
    scale, offset, rotation = placement
    if scale == 1.0 and not offset.any() and np.array_equal(rotation, np.eye(3)):
        return mesh
    return np.asarray(vertices, dtype=np.float64) @ rotation.T * scale + offset, faces


def _given_grid(spec: dict, where: str):
    """``(origin, voxel size, shape or None)`` of a volume file's ``"grid"``."""
    g = _object(spec["grid"], f"{where}: grid")
    _misplaced_keys(g, _GRID_KEYS, f"{where}: grid", cutoff=_STRICT)
    for key in ("origin", "voxel_size"):
        if key not in g:
            raise TargetFileError(f"{where}: grid needs {key!r} "
                                  "(\"grid\": {\"origin\": [x, y, z], \"voxel_size\": h})")
    origin = vector3(g["origin"], f"{where}: grid.origin")
    size = length(g["voxel_size"], f"{where}: grid.voxel_size")
    shape = None
    if "shape" in g:
        if not isinstance(g["shape"], list) or len(g["shape"]) != 3:
            raise TargetFileError(f"{where}: grid.shape must be three whole numbers, got {shown_value(g['shape'])}")
        shape = tuple(_count(n, f"{where}: grid.shape[{i}]", 10 ** 12) for i, n in enumerate(g["shape"]))
    return origin, size, shape


def load_volume_target(path: str | os.PathLike):
    """Read a volume target description (``procmod-volume/1`` JSON).

    ::

        {"format": "procmod-volume/1", "score": "svol" | "proxy",
         "layers": [{"file": "ship.obj" | "fill.npy", "w_fill": 1, "w_avoid": -1}, ...],
         "grid": {"origin": [x, y, z], "voxel_size": h},   # needed with .npy layers
         "voxel_size": 0.25, "margin": 0.1,                # meshes only, without "grid"
         "mesh_scale": 1, "mesh_offset": [0, 0, 0],        # meshes only
         "mesh_up": "y",                                   # meshes only: "z" for a z-up tool's
         "w_self": 0}

    Files are relative to the JSON file. All layers lie on one grid: the ``"grid"`` when
    given (its shape that of the .npy layers, or ``"shape": [nx, ny, nz]`` with meshes
    only; meshes are voxelized on it), else the grid of edge ``voxel_size`` around every
    mesh layer grown by ``margin`` (default 0.1, less around a small mesh:
    :func:`default_margin`). An .npy layer is a 3D array, nonzero
    inside. ``w_fill`` (default 1), ``w_avoid`` (default 0) and ``w_self`` (default 0, at
    least 0) are finite numbers; ``"score": "proxy"`` takes one layer. Mesh layers are
    placed in the model's frame by ``mesh_up``, ``mesh_scale`` and ``mesh_offset`` (:func:`_mesh_placement`)
    before anything else: ``grid``, ``voxel_size`` and ``margin`` are in the model's units.
    """
    path = Path(path)
    where = cut_text(str(path))
    spec = read_target_json(path)
    if not isinstance(spec, dict) or spec.get("format") != "procmod-volume/1":
        raise TargetFileError(f"{where}: expected a JSON object with \"format\": \"procmod-volume/1\"")
    _at_top_level(spec, _VOLUME_KEYS, where, inside=("grid", _GRID_KEYS))
    score = spec.get("score", "svol")
    if score not in SCORES:
        raise TargetFileError(f"{where}: score must be \"svol\" or \"proxy\", got {shown_value(score)}")
    layers_spec = spec.get("layers")
    if not isinstance(layers_spec, list) or not layers_spec:
        raise TargetFileError(f"{where}: layers must be a non-empty list of {{\"file\": ...}} objects")
    if score == "proxy" and len(layers_spec) != 1:
        raise TargetFileError(f"{where}: \"score\": \"proxy\" compares the ship with one target volume; "
                              f"layers has {len(layers_spec)}")
    if score == "proxy":  # its score has no weights: others than its own were dropped without a word
        layer = layers_spec[0] if isinstance(layers_spec[0], dict) else {}
        weighted = [key for key in ("w_self",) if spec.get(key, 0.0) != 0.0] + [
            f"layers[0].{key}" for key, own in (("w_fill", 1.0), ("w_avoid", -1.0)) if layer.get(key, own) != own]
        if weighted:
            raise TargetFileError(f"{where}: \"score\": \"proxy\" takes no weights (it is the fraction of voxels "
                                  f"where the ship and the target agree: w_fill 1, w_avoid -1, w_self 0), so "
                                  f"{', '.join(weighted)} would be left unused: remove them, or use \"score\": "
                                  "\"svol\" to weigh the layers")
    w_self = weight(spec.get("w_self", 0.0), f"{where}: w_self", minimum=0.0)
    placement = _mesh_placement(spec, where)
    # every field first, then the files' headers, then the work
    entries = []
    for i, layer in enumerate(layers_spec):
        at = f"{where}: layers[{i}]"
        _object(layer, at)
        _misplaced_keys(layer, _LAYER_KEYS, at, cutoff=_STRICT, top=_VOLUME_WIDE)
        if "file" not in layer:
            raise TargetFileError(f"{at} needs \"file\" (an .npy voxel grid or a mesh file)")
        file = _file(path, layer["file"], f"{at}.file", MESH_SUFFIXES | {".npy"}, "voxel grid (.npy) or mesh")
        w_fill = weight(layer.get("w_fill", 1.0), f"{at}.w_fill")
        w_avoid = weight(layer.get("w_avoid", 0.0), f"{at}.w_avoid")
        entries.append((at, file, w_fill, w_avoid))
    arrays = [e for e in entries if e[1].suffix.lower() == ".npy"]
    meshes = [e for e in entries if e[1].suffix.lower() != ".npy"]
    _placement_needs_meshes(spec, where, bool(meshes), "layer")
    given = _given_grid(spec, where) if "grid" in spec else None
    if given is not None and "voxel_size" in spec and spec["voxel_size"] != spec["grid"].get("voxel_size"):
        raise TargetFileError(f"{where}: voxel_size {shown_value(spec['voxel_size'])} and grid.voxel_size "
                              f"{shown_value(spec['grid'].get('voxel_size'))} disagree: give the voxel size once")
    shape = None
    if arrays:
        if given is None:
            raise TargetFileError(f"{where}: an .npy layer needs \"grid\": {{\"origin\": [x, y, z], "
                                  "\"voxel_size\": h} (where its voxel [0, 0, 0] lies, and the voxel edge)")
        for at, file, _, _ in arrays:
            layer_shape, dtype = npy_header(file, f"{at}.file", "voxel grid")
            if len(layer_shape) != 3:
                raise TargetFileError(f"{at}.file: a voxel grid must be a 3D array, got shape {layer_shape}")
            _numeric(dtype, f"{at}.file", "voxel grid")
            if shape is None:
                shape = layer_shape
                check_grid(VoxelGrid(given[0], given[1], shape), f"{at}.file: a voxel grid of shape {shape}",
                           "use a coarser voxel grid")
            elif layer_shape != shape:
                raise TargetFileError(f"{at}.file: shape {layer_shape} differs from the first .npy layer's {shape}; "
                                      "all layers lie on one grid")
        if given[2] is not None and given[2] != shape:
            raise TargetFileError(f"{where}: grid.shape {list(given[2])} differs from the .npy layers' {list(shape)}")
    elif given is not None and given[2] is None:
        raise TargetFileError(f"{where}: with only mesh layers, \"grid\" needs \"shape\": [nx, ny, nz] (or leave "
                              "\"grid\" out and give \"voxel_size\": the grid then fits the meshes)")
    grid = None
    if given is not None:
        grid = VoxelGrid(given[0], given[1], shape or given[2])
        check_grid(grid, f"{where}: grid", "use a larger grid.voxel_size")
    elif "voxel_size" not in spec:
        raise TargetFileError(f"{where}: mesh layers need \"voxel_size\": the voxel edge, in the model's units "
                              "(after \"mesh_scale\"; the grid then fits the meshes)")
    else:
        voxel_size = length(spec["voxel_size"], f"{where}: voxel_size")
        margin = spec.get("margin")  # None: default_margin, once the meshes' bounds are known
        if margin is not None:
            margin = number(margin, f"{where}: margin", minimum=0.0)
        if margin is not None and margin > MAX_COORDINATE:
            raise TargetFileError(f"{where}: margin must be at most {MAX_COORDINATE:g}, got {margin:g}")
    read, mesh_notes = {}, []
    for at, file, _, _ in meshes:
        _check_up_once(file, spec, f"{at}.file")
        read[at] = _placed(read_mesh(file, f"{at}.file", notes=mesh_notes), placement)
    if grid is None:
        bounds = [mesh_bounds(*read[at]) for at, _, _, _ in meshes]
        lo = np.min([b[0] for b in bounds], axis=0)
        hi = np.max([b[1] for b in bounds], axis=0)
        if margin is None:
            margin = default_margin(lo, hi, voxel_size)
        grid = grid_around(lo, hi, voxel_size, margin, f"{where}: voxel_size {voxel_size:g} around the mesh layers",
                           [read[at] for at, _, _, _ in meshes])
    layers = []
    notes = mesh_notes
    for at, file, w_fill, w_avoid in entries:
        if at in read:
            mask = mesh_inside(*read[at], grid, f"{at}.file", notes)
            ground = ground_piece_note(*read[at], f"{at}.file", closed_only=True)
            if ground is not None:
                notes.append(ground)
        else:
            mask = load_npy(file, f"{at}.file", "voxel grid") != 0
            if not mask.any():
                raise TargetFileError(f"{at}.file: the voxel grid is empty (no nonzero voxel)")
        layers.append((mask, w_fill, w_avoid))
    name = path.parent.name if path.name == "target.json" else path.stem
    target = ProxyVolume(grid, layers[0][0], name=name) if score == "proxy" else Volume(grid, layers, w_self, name=name)
    if score == "svol" and target.best_attainable <= 0:  # every derivation would score 0 or less: nothing to steer to
        raise TargetFileError(f"{where}: nothing to fill: no voxel gains from being covered (w_fill and w_avoid are 0 "
                              "or less everywhere); give a layer a positive w_fill (inside it) or w_avoid (outside it)")
    # how the file places its shape, for advice when it misses the model (targets.placement)
    target.placed_by = ("grid" if arrays else "meshes", *placement[:2])
    target.grid_from_voxel_size = given is None  # the grid fits the meshes at "voxel_size" (not a "grid" given)
    target.mesh_up = spec.get("mesh_up", "y")
    target.file_notes = notes  # said with the placement advice (targets.placement)
    return target


# --- silhouette targets --------------------------------------------------------------------

VERTICAL = 1e-9
"""A camera's up may be no closer to its view direction than this (the sine between them)."""


def default_up(forward) -> tuple:
    """A camera's up when its file gives none: y, except for a view straight down (a plan)
    or up, along y itself, where the picture's top is -z (down) or +z (up), as in
    Blender's top and bottom views of the same scene."""
    direction = np.asarray(forward, dtype=np.float64) / np.linalg.norm(forward)
    if np.linalg.norm(np.cross(direction, (0.0, 1.0, 0.0))) >= VERTICAL:  # y is an up for it (as before)
        return (0.0, 1.0, 0.0)
    return (0.0, 0.0, -1.0) if direction[1] < 0 else (0.0, 0.0, 1.0)


def _camera(spec, where: str, sized: bool) -> Camera:
    """A view's camera; ``sized``: it may give ``width`` and ``height`` (a mesh view's pixels)."""
    if not isinstance(spec, dict):
        raise TargetFileError(f"{where}: \"camera\" must be an object with eye, look_at, ...")
    where = f"{where}.camera"
    for key in ("eye", "look_at"):
        if key not in spec:
            raise TargetFileError(f"{where} needs {key!r} (three numbers)")
    eye, look_at = vector3(spec["eye"], f"{where}.eye"), vector3(spec["look_at"], f"{where}.look_at")
    up = vector3(spec["up"], f"{where}.up") if "up" in spec else None
    projection = spec.get("projection", "perspective")
    if projection not in ("perspective", "orthographic"):
        raise TargetFileError(f"{where}.projection must be perspective or orthographic, got {shown_value(projection)}")
    fov = number(spec.get("fov", 40.0), f"{where}.fov")
    if projection == "perspective" and not 1e-6 <= fov < 180:
        raise TargetFileError(f"{where}.fov is the vertical field of view in degrees and must lie from 1e-06 "
                              f"to under 180, got {fov:g}")
    if projection == "orthographic" and not MIN_LENGTH <= fov <= MAX_COORDINATE:
        raise TargetFileError(f"{where}.fov is the height of the view in world units and must lie in "
                              f"{MIN_LENGTH:g}..{MAX_COORDINATE:g}, got {fov:g}")
    forward = np.subtract(look_at, eye)
    # on the distance itself: allclose's tolerance grows with the coordinates (a camera 30
    # units from its look_at, a million units from the origin, "coincided")
    if not np.linalg.norm(forward) > 1e-9 * max(1.0, float(np.abs(eye).max()), float(np.abs(look_at).max())):
        raise TargetFileError(f"{where}: the camera's eye and look_at coincide")
    if up is None:
        up = default_up(forward)
    length = np.linalg.norm(up)
    if length == 0 or np.linalg.norm(np.cross(forward / np.linalg.norm(forward), np.divide(up, length))) < VERTICAL:
        raise TargetFileError(f"{where}.up must be a non-zero vector not along the view direction "
                              f"(look_at - eye), got {list(up)}")
    size = {}
    for key in ("width", "height"):
        if key in spec:
            if not sized:
                raise TargetFileError(f"{where}.{key}: a picture's or weights' size is its own; width and height "
                                      "are for views drawn from a \"mesh\"")
            size[key] = _count(spec[key], f"{where}.{key}", 100_000)
    width, height = size.get("width", DEFAULT_MESH_VIEW), size.get("height", DEFAULT_MESH_VIEW)
    if width * height > MAX_IMAGE_PIXELS:
        raise TargetFileError(f"{where}: a {width}x{height} view is {width * height / 1e6:.0f} megapixels; procmod "
                              f"draws views up to {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels")
    return Camera(eye, look_at, up, projection, fov, width, height)


def _load_weights(file: Path, where: str) -> np.ndarray:
    """A 2D float array from an .npy file, its size checked from the header before it is read."""
    shape, dtype = npy_header(file, where, "weights")
    if len(shape) != 2:
        raise TargetFileError(f"{where}: weights must be a 2D array, got shape {shape}")
    if shape[0] * shape[1] > MAX_IMAGE_PIXELS:
        raise TargetFileError(f"{where}: the weights are {shape[1]}x{shape[0]} pixels; procmod reads views up to "
                              f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels: scale them down")
    _numeric(dtype, where, "weights")
    weights = load_npy(file, where, "weights").astype(np.float64)
    if weights.size and np.nanmax(np.abs(weights)) > MAX_WEIGHT:
        raise TargetFileError(f"{where}: weights must lie between -{MAX_WEIGHT:g} and {MAX_WEIGHT:g} (they are "
                              f"relative), got up to {np.nanmax(np.abs(weights)):g}")
    return weights


def mesh_silhouette(vertices, faces, camera: Camera) -> np.ndarray:
    """Boolean ``(height, width)`` image of the pixels whose centres the mesh's triangles
    cover seen through ``camera`` (the silhouette of the solid it bounds)."""
    from ..geometry.solid import Mesh

    out = Silhouettes([camera])
    out.add(Mesh(np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)))
    return out.image(0)


# A silhouette picture whose mid-grey pixels joined to its dark ones are at least this
# share of the two gets a note: its shape is partly "either" (a shaded photo's lit side).
GREY_BAND = 0.25
GREY_SHADED = 12.0  # and their grey levels spread this far (a standard deviation): shading, not one grey


def _grey_band_share(grey: np.ndarray) -> float | None:
    """The share of mid-grey pixels among the shape's (the dark pixels and the mid-grey ones
    joined to them), when it is at least :data:`GREY_BAND`; else None. A product photo
    shaded from grey 170 to 40 had its upper half read as "either", and the run fitted
    its lower half alone, no better than forward samples, without a word."""
    if not ((grey >= HIT_BELOW) & (grey <= AVOID_ABOVE)).any():
        return None  # no mid-grey at all (a black-and-white mask)
    from scipy import ndimage  # after the cheap check: importing it costs ~0.2 s of start-up

    step = max(1, math.ceil(math.sqrt(grey.size / 4e6)))
    grey = grey[::step, ::step]  # a share: a picture of 81 MP took 4.4 s whole (h80), this about 4 MP
    dark = grey < HIT_BELOW
    parts, _ = ndimage.label(grey <= AVOID_ABOVE)
    joined = np.isin(parts, np.unique(parts[dark])) & (parts > 0)
    # beyond two pixels of the dark ones: a drawing's smoothed edges are no band
    band = joined & ~ndimage.binary_dilation(dark, iterations=2)
    share = int(band.sum()) / max(int(joined.sum()), 1)
    if share < GREY_BAND or float(np.std(grey[band])) < GREY_SHADED:
        return None  # (one grey painted on: "either" meant, as scenes/city_skyline's ground)
    return share


def _picture_view_weights(file: Path, at: str, hit: float, avoid: float, notes: list) -> np.ndarray:
    """A silhouette view's weights from its picture (``at``: where the file names it): grey
    levels under :data:`HIT_BELOW` to hit, over :data:`AVOID_ABOVE` to avoid, transparent
    pixels white; a light cut-out on a transparent ground from its alpha channel; a colour
    picture with nothing dark by its colours. What reading it guessed goes into ``notes``."""
    picture = open_image(file, f"{at}.image")
    if _fully_transparent(picture):  # (it had been read black: to hit everywhere, h90)
        raise TargetFileError(f"{at}.image: the picture is fully transparent: it shows nothing to hit; "
                              "export it with the shape opaque")
    if picture.mode == "F" and not np.isfinite(np.asarray(picture)).any():  # (read black: all to hit, h90)
        raise TargetFileError(f"{at}.image: the picture's pixels are all NaN or infinite: it shows nothing; "
                              "export it as an 8-bit picture")
    opaque = opaque_part(picture)
    grey = _transparent_as_white(grey_levels(picture), opaque)
    frames = picture.info.get(FRAMES, 1)
    if frames > 1:  # the shape may be on another (as a picture target says, h90)
        notes.append(f"{at}.image: the file holds {frames} frames or pages and procmod read the first; "
                     "save the one with the shape on its own if it is another")
    weights = np.where(grey < HIT_BELOW, hit, np.where(grey > AVOID_ABOVE, avoid, 0.0))
    cut_out = hit > 0 and opaque is not None and opaque.any() and not opaque.all()
    drawing = _see_through_drawing(picture, opaque) if cut_out and not (grey < HIT_BELOW).any() else None
    if drawing is not None and drawing is not opaque:
        # a page with the drawing cut out of it, its ink the file's transparent colour (a GIF
        # whose tool made the ink's palette index the transparent one): read as a picture
        # target reads it (its opaque page, to hit, had made the view inverted)
        weights = np.where(drawing, hit, avoid)
        notes.append(f"{at}.image: the picture is a blank opaque page with strokes drawn see-through, so the "
                     "strokes are the shape to hit and the page is to avoid; give the shape dark on white if "
                     "the page is the shape")
    elif drawing is not None:
        # a light cut-out on a transparent ground, or a mask drawn in the alpha channel
        # of a white picture: the file says where the shape is (it had been refused)
        weights = np.where(opaque, hit, avoid)
        notes.append(f"{at}.image: no pixel is dark enough to hit, so the shape is read from the picture's "
                     "alpha channel (its opaque pixels to hit, the transparent ones to avoid)")
    elif cut_out and float((grey[opaque] > AVOID_ABOVE).mean()) >= CUT_OUT_LIGHT \
            and not (opaque.mean() > 0.5 and _fills_its_box(opaque, 0.95)):
        # (an opaque page, a transparent margin or pixel aside, is a silhouette drawn
        # in greys on it: the grey levels hold, as a 2D target's page is read, h87)
        # a light object cut out of a photo with a dark logo or print on it: its grey
        # levels made the logo alone the shape to hit and the object itself to avoid (h79)
        dark = float((grey[opaque] < HIT_BELOW).mean())
        weights = np.where(opaque, hit, avoid)
        notes.append(f"{at}.image: the picture's opaque part is mostly light (to avoid, by its grey levels) "
                     f"with {100 * dark:.0f}% of it dark, as a cut-out with a print on it is, so the shape is "
                     "read from its alpha channel (its opaque pixels to hit, the transparent ones to avoid); "
                     "for the grey levels' meaning, give the picture without transparency")
    elif hit > 0:
        band = _grey_band_share(grey)
        if band is not None:
            notes.append(f"{at}.image: {100 * band:.0f}% of the shape's pixels are mid-grey (between "
                         f"{HIT_BELOW} and {AVOID_ABOVE} of 255), which counts as neither to hit nor to avoid: "
                         "if they are a shaded photo's lit side, make the whole shape dark (black to hit); "
                         "if \"either\" is meant there, nothing to do")
    if hit > 0 and not (weights > 0).any() and _has_colour(picture):
        # a red or yellow object photographed on white: nothing is dark, but it is plain
        # to see; read as a 2D target picture is, by its unlikeness to the border's
        # colour (it had been refused as having no dark pixel, h79), when that reads an
        # object on its ground: under half the picture, off most of its border (an object
        # filling the frame had been read inverted, a two-tone ground as the shape, h87)
        h, w = grey.shape
        top, left, _, _ = picture_in_square(h, w)
        unlike = mask_from_image(picture)[top:top + h, left:left + w]
        border = np.concatenate([unlike[0], unlike[-1], unlike[:, 0], unlike[:, -1]])
        if unlike.any() and unlike.mean() < 0.5 and border.mean() < COLOUR_BORDER:
            weights = np.where(unlike, hit, avoid)
            notes.append(f"{at}.image: no pixel is dark enough to hit (under {HIT_BELOW} of 255), so the "
                         "shape is read from the picture's colours, as the pixels unlike its border's colour "
                         "(as a 2D target picture is read); for the grey levels' meaning (black to hit, "
                         "white to avoid, grey between: either), give the picture in greys")
    if hit > 0 and not (weights > 0).any():  # a pencil sketch on grey paper
        raise TargetFileError(f"{at}.image: no pixel is dark enough to hit (under {HIT_BELOW} of 255; the "
                              f"darkest is {int(grey.min())}): darken the shape (black to hit, white to avoid, "
                              "grey between: either), or give the view's weights as an .npy (\"weights\")")
    return weights


def _has_colour(picture) -> bool:
    """Whether a picture is in colour: :data:`COLOUR_SHARE` of its pixels or more have
    channels that differ by :data:`COLOUR_SPREAD` or more (a grey picture saved as RGB has
    none; a grey one with a coloured dot is grey, h87)."""
    if picture.mode in ("1", "L", "LA", "I", "F") or picture.mode.startswith("I;16"):
        return False
    rgb = np.asarray(picture.convert("RGB"), dtype=np.int16)
    return float(((rgb.max(axis=2) - rgb.min(axis=2)) >= COLOUR_SPREAD).mean()) >= COLOUR_SHARE


COLOUR_SPREAD = 30  # of 255 between a pixel's channels: colour, not a grey's rounding or a scan's tint
COLOUR_SHARE = 0.01  # of a picture's pixels in colour for it to be a colour picture
COLOUR_BORDER = 0.25  # of a picture's border the shape read from its colours may cover (an object, not the ground)


def _transparent_as_white(grey: np.ndarray, opaque) -> np.ndarray:
    """``grey`` with a picture's transparent pixels (outside ``opaque``, its
    :func:`opaque_part`; None: none) white (to avoid), as the picture shows on a page: a
    shape exported as a transparent PNG (drawn in its alpha channel, its transparent
    pixels black) was read as "hit" everywhere."""
    return grey if opaque is None else np.where(opaque, grey, 255.0)


HIT_BELOW, AVOID_ABOVE = 85, 170  # a silhouette picture's grey levels: darker is to hit, lighter to avoid
CUT_OUT_LIGHT = 0.5  # a picture with transparency whose opaque part is this much light is a cut-out: the shape
_PLACEMENT_KEYS = ("mesh_scale", "mesh_offset", "mesh_up")
_VOLUME_WIDE = ("grid", "voxel_size", "margin", "w_self") + _PLACEMENT_KEYS  # the file's, for every layer
_VOLUME_KEYS = ("format", "score", "layers") + _VOLUME_WIDE
_GRID_KEYS = ("origin", "voxel_size", "shape")
_LAYER_KEYS = ("file", "w_fill", "w_avoid")
_SILHOUETTE_KEYS = ("format", "views") + _PLACEMENT_KEYS
_VIEW_KEYS = ("weights", "image", "mesh", "camera", "hit", "avoid")
# outside a view, and for the file-wide keys, a tool's own keys are likelier ("mesh_source" is
# 0.76 like "mesh_scale", "mesh_url" 0.8 like "mesh_up"): only closer misses are refused
# ("marign" 0.83, "mesh-up" 0.86, "w_avod" 0.92, "mesh_scle" 0.95)
_STRICT = 0.82


def _at_top_level(spec: dict, known: tuple, where: str, inside: tuple | None = None) -> None:
    """:func:`_misplaced_keys` for a file's top level, the message naming the file."""
    try:
        _misplaced_keys(spec, known, None, inside, cutoff=_STRICT)
    except TargetFileError as exc:
        raise TargetFileError(f"{where}: {exc}") from None


# top-level keys that say what a placement key says, in words a user or another tool
# uses (compared without case, spaces, "-" or "_"): ignored, they had left a z-up mesh
# lying on its side, or a millimetre mesh 1000 times too large, without a word
_SAYS = {"mesh_up": ("up", "upaxis", "axisup", "upvector", "upaxes", "yup", "zup", "meshupaxis", "meshaxis",
                     "meshupvector", "upside"),
         "mesh_scale": ("scale", "scalefactor", "units", "unit", "meshunits", "meshunit", "unitscale",
                        "meshscalefactor"),
         "mesh_offset": ("offset", "translation", "translate", "meshtranslation", "meshtranslate", "position",
                         "meshposition", "shift", "meshshift", "move", "meshmove", "center", "centre"),
         "voxel_size": ("resolution", "voxelresolution", "voxeledge", "cellsize"),
         "w_self": ("selfweight", "weightself", "wself")}
# turns other than the up axis: procmod takes none (a mesh is turned in its modelling tool)
_TURNS = ("rotation", "rotate", "rotations", "orientation", "meshrotation", "meshrotate", "meshorientation",
          "quaternion", "euler", "meshturn", "turn")


def _placement_synonyms(spec: dict, known: tuple) -> None:
    """Refuse a top-level key that means a placement key (or a turn, which procmod does
    not take) in other words: ``up_axis`` or ``mesh_up_axis`` for ``mesh_up``, ``units``
    for ``mesh_scale``, ``translation`` for ``mesh_offset``. A tool's own keys
    (``mesh_source``, ``mesh_url``) are left alone."""
    for key in spec:
        if not isinstance(key, str) or key in known:
            continue
        word = re.sub(r"[\s_\-]", "", key).lower()
        words = {word, word[len("mesh"):]} if word.startswith("mesh") else {word}  # mesh_units: units
        meant = next((k for k, said in _SAYS.items() if words & set(said) and k in known), None)
        if meant == "mesh_up" and word == "up" and "views" in known:  # a silhouette file: a camera's too
            raise TargetFileError(f"the file has {key!r}, which procmod does not read at its top level; did you "
                                  "mean \"mesh_up\" (the meshes' up axis) or a view's camera \"up\"?")
        if meant is not None:
            raise TargetFileError(f"the file has {key!r}, which procmod does not read; did you mean {meant!r}?")
        if words & set(_TURNS) and "mesh_up" in known:
            raise TargetFileError(f"the file has {key!r}, which procmod does not read: it turns a mesh only by "
                                  "\"mesh_up\" (the axis that is up in the mesh's tool); turn the mesh in the tool "
                                  "otherwise")


_CAMERA_KEYS = ("eye", "look_at", "up", "projection", "fov", "width", "height")


def _misplaced_keys(spec: dict, known: tuple, at: str, inside: tuple | None = None, cutoff: float = 0.75,
                    top: tuple = ()) -> None:
    """Refuse a key that is a near miss of one of ``known`` (``"look-at"``, ``"hits"``),
    one that belongs in the object ``name`` of ``inside = (name, keys)`` (a view's
    ``"width"`` is its camera's), or one of ``top``, which belong at the file's top level
    (a view's ``"mesh_scale"``), or a near miss of those: silently ignored, it left the
    file meaning something else. Other keys (a tool's own notes) are left alone. ``at``
    names the object by its path in the file (``views[0]``), or is None for the top level."""
    for key in spec:
        if not isinstance(key, str) or key in known:
            continue
        if inside is not None and key in inside[1]:
            raise TargetFileError(f"{key if at is None else f'{at}.{key}'} belongs inside its \"{inside[0]}\" object "
                                  f"(\"{inside[0]}\": {{..., \"{key}\": ...}})")
        meant = key if key in top else meant_key(key, top, cutoff=max(cutoff, _STRICT))  # mesh_source: no mesh_scale
        if meant:
            said = "" if meant == key else f" (did you mean {meant!r}?)"
            raise TargetFileError(f"{at}.{key}{said} belongs at the file's top level, where it applies to every mesh "
                                  f"of the file ({{\"{meant}\": ..., ...}}); here it would be ignored")
        meant = meant_key(key, known, cutoff=cutoff)
        if meant:
            raise TargetFileError(f"{'the file' if at is None else at} has {key!r}, which procmod does not read; did "
                                  f"you mean {meant!r}?")


def load_silhouette_target(path: str | os.PathLike) -> Silhouette:
    """Read a ``procmod-silhouette/1`` target (see :mod:`procmod.targets.silhouette`)."""
    path = Path(path)
    where = cut_text(str(path))
    spec = read_target_json(path)
    views = spec.get("views") if isinstance(spec, dict) else None
    if not isinstance(views, list) or not views:
        raise TargetFileError(f"{where}: \"views\" must be a non-empty list")
    _at_top_level(spec, _SILHOUETTE_KEYS, where)
    placement = _mesh_placement(spec, where)
    parsed = []
    for i, view in enumerate(views):
        at = f"{where}: views[{i}]"
        if not isinstance(view, dict):
            raise TargetFileError(f"{at} must be an object")
        kinds = [k for k in ("weights", "image", "mesh") if k in view]
        if not kinds:
            raise TargetFileError(f"{at} needs \"image\", \"weights\" or \"mesh\" (what the view should show)")
        if len(kinds) > 1:
            raise TargetFileError(f"{at} gives {' and '.join(repr(k) for k in kinds)}; give one of them")
        kind = kinds[0]
        # a picture's or weights' size is its own: width and height are a mesh view's only
        camera_keys = _CAMERA_KEYS if kind == "mesh" else tuple(k for k in _CAMERA_KEYS if k not in ("width", "height"))
        _misplaced_keys(view, _VIEW_KEYS, at, inside=("camera", camera_keys), top=_PLACEMENT_KEYS)
        if isinstance(view.get("camera"), dict):
            _misplaced_keys(view["camera"], _CAMERA_KEYS, f"{at}.camera")
        camera = _camera(view.get("camera"), at, sized=kind == "mesh")
        hit = weight(view.get("hit", 1.0), f"{at}.hit")
        avoid = weight(view.get("avoid", -1.0), f"{at}.avoid")
        suffixes = {"weights": {".npy"}, "image": None, "mesh": MESH_SUFFIXES}[kind]
        file = _file(path, view[kind], f"{at}.{kind}", suffixes, {"weights": "weights", "image": "picture",
                                                                  "mesh": "mesh"}[kind])
        parsed.append((at, kind, file, camera, hit, avoid))
    _placement_needs_meshes(spec, where, any(entry[1] == "mesh" for entry in parsed), "view")
    out, notes = [], []
    mesh_boxes = [None] * len(parsed)  # a mesh view's placed box, for the notes on how it stands
    grounded = set()  # views whose mesh has a floor or backdrop (ground_piece_note)
    for at, kind, file, camera, hit, avoid in parsed:
        if kind == "weights":
            weights = _load_weights(file, f"{at}.weights")
        elif kind == "image":
            weights = _picture_view_weights(file, at, hit, avoid, notes)
        else:
            _check_up_once(file, spec, f"{at}.mesh")
            placed = _placed(read_mesh(file, f"{at}.mesh", orient=False, notes=notes), placement)  # y up
            ground = ground_piece_note(*placed, f"{at}.mesh")
            covered = mesh_silhouette(*placed, camera)
            if ground is not None:
                notes.append(ground)
                grounded.add(len(out))  # its box is the floor's: no word on how the mesh stands (h81)
            else:
                corners = np.asarray(placed[0], dtype=np.float64)[np.unique(np.asarray(placed[1]))]
                mesh_boxes[len(out)] = (corners.min(axis=0), corners.max(axis=0))
            if not covered.any():
                raise TargetFileError(f"{at}.mesh: the mesh covers no pixel centre of the {camera.width}x"
                                      f"{camera.height} view: the camera (in the model's units, looking at the "
                                      "model, which builds at its origin) should see the mesh where the model is to "
                                      "be: place it there with \"mesh_offset\" and, for a mesh in other units, "
                                      "\"mesh_scale\"; or give more pixels")
            weights = np.where(covered, hit, avoid)
        if not (weights > 0).any():
            raise TargetFileError(f"{at}: nothing to hit (no positive weight)")
        out.append((weights, camera))
    name = path.parent.name if path.name == "target.json" else path.stem
    target = Silhouette(out, name=name)
    target.file_notes = notes  # said with the placement advice (targets.placement)
    target.mesh_boxes = mesh_boxes
    target.grounded_views = grounded
    target.mesh_up = spec.get("mesh_up", "y")
    target.placed_by = ("meshes", *placement[:2])
    target.view_kinds = [entry[1] for entry in parsed]  # "mesh", "image" or "weights": for the notes' advice
    return target


def load_target_file(path: str | os.PathLike):
    """A 3D target from its JSON description, dispatched on its ``format``."""
    path = Path(path)
    spec = read_target_json(path)
    kind = spec.get("format") if isinstance(spec, dict) else None
    if kind == "procmod-silhouette/1":
        return load_silhouette_target(path)
    if kind == "procmod-volume/1":
        return load_volume_target(path)
    if kind is None and isinstance(spec, dict) and any(key in spec for key in SIDECAR_KEYS):
        # a picture's sidecar given in the picture's place: told it needs a "format", the user
        # of a 2D picture was sent to the 3D targets
        stem = path.with_suffix("")  # NAME.png.json's picture is NAME.png
        pictures = [stem.name] if stem.is_file() else sorted(
            p.name for p in path.parent.glob(f"{glob.escape(stem.name)}.*")
            if p.suffix.lower() != ".json" and p.is_file())
        picture = cut_text(pictures[0] if pictures else f"{stem.name}.png", 60)
        raise TargetFileError(f"{cut_text(str(path))}: a picture's sidecar (its \"start\" and \"direction\"), not "
                              f"a target: give the picture beside it as --target ({picture}), which reads this file "
                              "with it")
    said = "has no \"format\"" if kind is None else f"\"format\" is {shown_value(kind)}"
    raise TargetFileError(f"{cut_text(str(path))}: {said}; a 3D target file's is \"procmod-volume/1\" or "
                          "\"procmod-silhouette/1\" (README, \"Targets\")")


__all__ = ["BYTES_PER_FACE", "BYTES_PER_VOXEL", "MAX_MESH_FACES", "MESH_SUFFIXES", "declared_faces",
           "load_silhouette_target", "load_target_file", "load_volume_target", "merged_seams", "mesh_inside",
           "mesh_silhouette", "read_mesh", "read_target_json", "voxelize_mesh_file"]
