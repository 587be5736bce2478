"""Shapes from asset files: glTF / GLB scenes (and URDF robots) as a :class:`ShapeSet`.

``procmod strings graph|augment`` take, besides a ``procmod-shapes/1`` JSON file, asset
files or folders of them, **one shape per file**. They are read by
:func:`procmod.geometry.assets.read_assets` (trimesh; the reader ``procmod learn`` uses):

* the node tree becomes the parts placed at their **world transforms** (a string's shape
  graph comes from contacts, so the hierarchy itself is not kept);
* the meshes become the **part library**, one part per distinct geometry up to a rigid
  motion (proper: a mirror image is another part, since a string's parts are placed by
  rotations; but a node that mirrors a mesh whose mirror image is the mesh turned, a box
  or any mirror-symmetric mesh, places the part itself, turned: :func:`_unmirrored`) within
  :data:`~procmod.geometry.assets.GEOMETRY_TOLERANCE` of the
  geometry's bounding-box diagonal, named after its mesh data (the glTF mesh name);
* glTF is y-up (its specification), procmod strings is z-up (the whole-shape turns of
  :mod:`.frames` are about z): a glTF scene is turned +90 degrees about x as it is read,
  as Blender's importer does. URDF is z-up already;
* a placement that scales (a node's scale, or a parent's) is split into a rotation and a
  scale; the scale is applied to the part's geometry, so every placement is rigid. Nodes
  that place one mesh at different scales get one part per scale (``tower``,
  ``tower_2``, ...): they are different geometries.

Mesh parts have no file of their own; writing the set (:func:`~.shapes.write_shapes`)
writes each as ``parts/NAME.obj`` beside the shapes file, exactly (every float as Python
writes it back).

Bad files raise :class:`~procmod.geometry.assets.AssetError` (a
:class:`~procmod.ProcmodError`) naming the file: unreadable, empty, zero-area, NaN
vertices, a hierarchy with a cycle, too many triangles (see that module).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from ..core.paths import FileNames
from ..geometry.assets import (GEOMETRY_TOLERANCE, Y_UP_TO_Z_UP, AssetError, asset_files, json_or_assets,
                               read_assets, unused_name)
from ..geometry.part_library import PartShape
from ..geometry.units import mixed_sizes_note
from .shapes import Shape, ShapeSet, ShapesFormatError, read_shapes, type_letters

SCALE_TOLERANCE = 1e-5  # two placements' scales agree within this fraction of the larger


def _rotation_and_scale(linear: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``linear = R S`` with ``R`` a proper rotation and ``S`` symmetric (polar decomposition;
    ``S`` has a negative eigenvalue when ``linear`` mirrors)."""
    u, sigma, vt = np.linalg.svd(linear)
    d = np.ones(3)
    if np.linalg.det(u @ vt) < 0:
        d[2] = -1.0
    r = u @ np.diag(d) @ vt
    return r, r.T @ linear


def _scaled_part(shape: PartShape, name: str, s: np.ndarray) -> PartShape:
    """``shape`` with the linear map ``s`` applied to its geometry (about its local origin)."""
    if shape.kind == "box" and np.allclose(s, np.diag(np.diag(s)), atol=1e-12) and (np.diag(s) > 0).all():
        size = tuple(float(a * b) for a, b in zip(shape.size, np.diag(s)))
        return PartShape(name, "box", size=size, source=list(size))
    v, f = _mesh_arrays(shape)
    v = v @ s.T
    if np.linalg.det(s) < 0:
        f = f[:, ::-1]  # keep the winding outward
    return PartShape(name, "mesh", vertices=tuple(map(tuple, v.tolist())), faces=tuple(map(tuple, f.tolist())))


def _mesh_arrays(shape: PartShape) -> tuple[np.ndarray, np.ndarray]:
    """A part's local geometry as vertices and triangles (a box as its 12 triangles)."""
    if shape.kind == "box":
        v, f = np.unique(shape.local_triangles().reshape(-1, 3), axis=0, return_inverse=True)
        return v, f.reshape(-1, 3)
    return np.asarray(shape.vertices, dtype=np.float64), np.asarray(shape.faces, dtype=np.int64)


def _unmirrored(shape: PartShape, s: np.ndarray, tolerance: float) -> tuple[np.ndarray, np.ndarray] | None:
    """For a scale ``s`` that mirrors: ``(s_pos, T)`` with ``s(shape) = T(s_pos(shape))``,
    ``s_pos`` the scale without the mirror and ``T`` a proper rigid motion (4x4), when the
    mirrored geometry is the geometry turned (a box, a cylinder, any mirror-symmetric mesh:
    within ``tolerance`` x its diagonal, as parts are told apart); None when it is chiral
    (a left and a right bracket are two parts)."""
    from types import SimpleNamespace

    from ..geometry.assets import _align, _Surface

    w, vecs = np.linalg.eigh((s + s.T) / 2)
    s_pos = vecs @ np.diag(np.abs(w)) @ vecs.T
    surfaces = []
    for linear in (s, s_pos):
        v, f = _mesh_arrays(shape)
        surfaces.append(_Surface(SimpleNamespace(vertices=v @ linear.T, faces=f)))
    t = _align(surfaces[0], surfaces[1], tolerance, mirror=False)  # t(s_pos geometry) = s geometry
    if t is None or np.linalg.det(t[:3, :3]) < 0:
        return None
    return s_pos, t


def _scale_index(known: list, s: np.ndarray) -> int:
    """The position in ``known`` of the first scale that ``s`` agrees with (entries within
    :data:`SCALE_TOLERANCE` times the known scale's largest entry, or 1), ``s`` appended
    when none does."""
    for i, k in enumerate(known):
        if np.abs(s - k).max() <= SCALE_TOLERANCE * max(float(np.abs(k).max()), 1.0):
            return i
    known.append(s)
    return len(known) - 1


def _rigid_placements(parts: dict, placed: list, tolerance: float, flat_error) -> tuple[dict, list, tuple]:
    """Every placement made rigid: ``placed`` holds per shape ``[(part, 4x4, label)]``; each
    placement is split into a rotation and a scale (polar decomposition) and the scale goes
    into the part, one part per (geometry, scale) (``part``, ``part_2``, ...), a mirror
    into the part turned where that is the same geometry (:func:`_unmirrored`). Returns
    the library (mesh parts with a ``parts/NAME.obj`` source, held in memory), the shapes
    and the parts resized a little (:func:`_resized`). ``flat_error(label)`` is the error
    for a placement that scales to nothing."""
    rows_of = []  # per shape: [(part, rigid 4x4, index of its scale in scales[part])]
    # one part per (geometry, scale): the scales each geometry is placed at, in reading order
    scales: dict[str, list] = {}
    unmirrored: dict[tuple, tuple | None] = {}  # (part, mirroring scale) -> _unmirrored's answer
    for placements in placed:
        rows = []
        for part, m, label in placements:
            r, s = _rotation_and_scale(m[:3, :3])
            if abs(np.linalg.det(s)) < 1e-12 * max(float(np.abs(s).max()), 1e-300) ** 3:
                raise flat_error(label)
            rigid = np.eye(4)
            rigid[:3, :3], rigid[:3, 3] = r, m[:3, 3]
            if np.linalg.det(s) < 0:  # a mirrored placement: the part itself, turned, if that is the same
                key = (part, tuple(np.round(s, 9).reshape(-1).tolist()))
                if key not in unmirrored:
                    unmirrored[key] = _unmirrored(parts[part], s, tolerance)
                if unmirrored[key] is not None:
                    s, turn = unmirrored[key]
                    rigid = rigid @ turn
            rows.append((part, rigid, _scale_index(scales.setdefault(part, []), s)))
        rows_of.append(rows)
    names_taken = set(parts)
    library: dict[str, PartShape] = {}
    renamed: dict[tuple, str] = {}
    for part, known in scales.items():
        for k, s in enumerate(known):
            name = unused_name(part, names_taken) if k else part  # part is taken: part_2, part_3, ...
            shape = parts[part]
            unit = np.abs(s - np.eye(3)).max() <= SCALE_TOLERANCE
            library[name] = shape._replace(name=name) if unit else _scaled_part(shape, name, s)
            renamed[(part, k)] = name
    # the project's one rule for file names from untrusted names: plain ones kept, others
    # (too long, device names such as CON, odd characters) mapped to a safe stem + digest
    files = FileNames(".obj", source="the asset files", field="mesh name")
    for name, shape in list(library.items()):
        if shape.kind == "mesh":
            library[name] = shape._replace(source=f"parts/{files.name_for(name)}")
    shapes = [Shape.of([renamed[(part, k)] for part, _, k in rows], [rigid for _, rigid, _ in rows])
              for rows in rows_of]
    other_sizes = [(renamed[(part, k)], renamed[(part, 0)], np.linalg.det(known[k]) * np.linalg.det(known[0]) < 0)
                   for part, known in scales.items() for k in range(1, len(known))]
    return library, shapes, _resized(library, other_sizes)


SAME_SIZE = 1e-4
"""Two parts whose sizes differ by at most this share are the same size (a mirror image
read back from a file written in single precision)."""

NEAR_SIZE = 0.05
"""Two parts of one geometry whose sizes differ by at most this share (along any axis) are
named in a note (:func:`resized_note`): likely one part resized a little by hand."""


def _resized(library: dict, other_sizes: list) -> tuple:
    """``(name, base name, largest relative size difference, mirrored)`` for each part of
    ``other_sizes`` (``(name, base name, mirrored)``: a geometry placed at another scale,
    ``rail_2`` of ``rail``, :func:`_rigid_placements`; mirrored: the one's scale mirrors
    the other's) whose size is within :data:`NEAR_SIZE` of the part of that geometry
    first placed: parts of two sizes are two types, which a user who resized a copy by
    0.3% did not mean (its shapes then never combine with the others; h139). A mirror
    image of the same size is not named: a chiral part's mirror (a left and a right
    wing) is another type, as it should be (h144)."""
    out = []
    for name, base, mirrored in other_sizes:
        lo, hi = (np.asarray(v, dtype=np.float64) for v in library[base].local_bounds())
        lo2, hi2 = (np.asarray(v, dtype=np.float64) for v in library[name].local_bounds())
        extent, extent2 = np.sort(hi - lo), np.sort(hi2 - lo2)
        if (extent <= 0).any():
            continue
        difference = float(np.abs(extent2 / extent - 1.0).max())
        if (not mirrored or difference > SAME_SIZE) and difference <= NEAR_SIZE:
            out.append((name, base, difference, mirrored))
    return tuple(out)


def resized_note(shape_set: ShapeSet) -> str | None:
    """One line naming the parts that are another part resized by under :data:`NEAR_SIZE`
    (:attr:`ShapeSet.resized`), or None."""
    if not shape_set.resized:
        return None
    named = ", ".join(f"{name} is {base}{' mirrored and' if mirrored else ''} {100 * d:.2g}% off its size"
                      for name, base, d, mirrored in shape_set.resized[:4])
    more = f" and {len(shape_set.resized) - 4} more" if len(shape_set.resized) > 4 else ""
    return (f"{named}{more}: parts of two sizes are two types, so shapes built with one never combine with shapes "
            "built with the other; if that is a copy resized by hand, give it the size of the first")


def size_note(shape_set: ShapeSet, labels: list | None = None) -> str | None:
    """One line when some shapes are over :data:`~procmod.geometry.units.MIXED_SIZES`
    times the size (world bounding-box diagonal) of others: likely exported in other units
    (a Maya file in centimetres among metres), whose parts are then other types, at 100x
    the size (:func:`procmod.geometry.units.mixed_sizes_note`); ``labels`` name the shapes
    (default ``shape i``). None otherwise. ``procmod learn`` says the same of its examples;
    strings had said nothing (h144)."""
    corners = np.array([[x, y, z] for x in (0, 1) for y in (0, 1) for z in (0, 1)], dtype=np.float64)
    boxes = {}  # part -> its local box's 8 corners
    sizes = []
    for shape in shape_set.shapes:
        points = []
        for name, t in zip(shape.parts, shape.transforms):
            if name not in boxes:
                lo, hi = (np.asarray(v, dtype=np.float64) for v in shape_set.library[name].local_bounds())
                boxes[name] = lo + corners * (hi - lo)
            t = np.asarray(t, dtype=np.float64)
            points.append(boxes[name] @ t[:3, :3].T + t[:3, 3])
        points = np.concatenate(points) if points else np.zeros((1, 3))
        sizes.append(float(np.linalg.norm(np.ptp(points, axis=0))))
    labels = labels or [f"shape {i}" for i in range(len(sizes))]
    return mixed_sizes_note(sizes, labels, "shapes", "parts of two sizes are two types (parts are rigid), so shapes "
                            "of one size never combine with shapes of the other")


def shapes_from_assets(paths, tolerance: float = GEOMETRY_TOLERANCE) -> ShapeSet:
    """A :class:`ShapeSet` from asset files (or folders of them), one shape per file (see
    the module docstring). Raises :class:`AssetError` for a file that cannot be used."""
    files = asset_files(paths)
    asset_set = read_assets(files, tolerance=tolerance, mirror=False)
    placed = []
    for asset in asset_set.assets:
        up = Y_UP_TO_Z_UP if asset.path.suffix.lower() in (".gltf", ".glb") else np.eye(4)
        placed.append([(node.part, up @ np.asarray(node.transform, dtype=np.float64), (asset.path, node.name))
                       for node in asset.nodes()])

    def flat(label):
        return AssetError(f"{label[0]}: node {label[1]!r} has a scale of zero (a flat placement); give it a size "
                          "or remove it")

    library, shapes, resized = _rigid_placements(asset_set.parts, placed, tolerance, flat)
    return ShapeSet(library, shapes, type_letters(library), None, resized=resized)


def rigid_shape_set(shape_set: ShapeSet) -> ShapeSet:
    """A shapes file's set with every placement rigid, as asset inputs are read
    (:func:`_rigid_placements`): a placement that scales its part places a part of that
    size (``post_2``). procmod strings takes parts as rigid: the edge categories are
    relative poses of the parts' frames, the docks rigid motions. A fence of unit boxes
    scaled per placement had fitted 32 edge categories for 4, and 3 of 6 samples failed
    to instantiate. A set whose placements are all rigid is returned as it is."""
    if all(np.allclose(t[:3, :3] @ t[:3, :3].T, np.eye(3), atol=SCALE_TOLERANCE) and np.linalg.det(t[:3, :3]) > 0
           for shape in shape_set.shapes for t in shape.transforms):
        return shape_set
    placed = [[(part, np.asarray(t, dtype=np.float64), (i, j))
               for j, (part, t) in enumerate(zip(shape.parts, shape.transforms))]
              for i, shape in enumerate(shape_set.shapes)]
    where = shape_set.source or "shapes"

    def flat(label):
        return ShapesFormatError(f"{where}: shapes[{label[0]}].nodes[{label[1]}].transform scales its part to "
                                 "nothing (a flat placement); give it a size or remove it")

    library, shapes, resized = _rigid_placements(shape_set.library, placed, GEOMETRY_TOLERANCE, flat)
    # held in memory, as an asset set's meshes: written as parts/NAME.obj with the collection
    return ShapeSet(library, shapes, type_letters(library), None, shape_set.tolerance, source=shape_set.source,
                    resized=resized)


def read_shape_inputs(paths) -> ShapeSet:
    """The shapes of ``procmod strings graph|augment``'s inputs: one ``procmod-shapes/1``
    JSON file, a collection folder (its ``shapes.json``, as ``strings train`` reads it: a
    collection grows again), or asset files (``.gltf``, ``.glb``, ``.urdf``) and folders
    of them, one shape per file (:func:`shapes_from_assets`).

    Raises
    ------
    ShapesFormatError
        For a bad shapes file, a mix of JSON and asset files, or a bad asset file (the
        message names the file and the problem).
    """
    given = [paths] if isinstance(paths, (str, os.PathLike)) else list(paths)
    if len(given) == 1 and Path(given[0]).is_dir() and (Path(given[0]) / "shapes.json").is_file():
        paths = [Path(given[0]) / "shapes.json"]  # a collection 'strings augment' wrote
    try:
        json_file, assets = json_or_assets(paths, "shapes", "procmod-shapes/1")
        if json_file is not None:
            return rigid_shape_set(read_shapes(json_file))
        return shapes_from_assets(assets)
    except AssetError as exc:
        raise ShapesFormatError(str(exc)) from None


__all__ = ["Y_UP_TO_Z_UP", "read_shape_inputs", "rigid_shape_set", "shapes_from_assets"]
