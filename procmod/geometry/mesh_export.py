"""Mesh export of 3D parts: OBJ and GLB (through trimesh), with one colour per part tag.

Colours: procmod's palette is sRGB (the PNG pictures' colours). An OBJ's vertex colours
are sRGB by custom (Blender's OBJ importer and exporter treat them so); a glTF's
``COLOR_0`` is linear by its specification, so a GLB gets the palette converted
(:func:`srgb_bytes_to_linear`). Written as sRGB, every GLB had shown washed out in
Blender's glTF importer and three.js next to ``best.png`` and the OBJ.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from ..core.io import write_bytes_atomic
from .solid import part_triangles


def srgb_bytes_to_linear(rgb) -> np.ndarray:
    """sRGB colour bytes -> linear-light colour bytes (the sRGB transfer function's
    inverse, IEC 61966-2-1), as uint8."""
    c = np.asarray(rgb, dtype=np.float64) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    return np.round(linear * 255.0).astype(np.uint8)


def parts_to_trimesh(parts, colour_of, segments: int = 24, linear_colours: bool = False) -> trimesh.Trimesh:
    """One mesh of all parts (vertices merged per part), faces coloured by tag: the
    palette's sRGB bytes, or with ``linear_colours`` linear ones (what glTF files hold)."""
    meshes = []
    for part in parts:
        tris = part_triangles(part, segments)
        mesh = trimesh.Trimesh(vertices=tris.reshape(-1, 3), faces=np.arange(len(tris) * 3).reshape(-1, 3),
                               process=True)
        rgb = np.asarray(colour_of(part.tag), dtype=np.uint8)
        colour = np.append(srgb_bytes_to_linear(rgb) if linear_colours else rgb, 255)
        mesh.visual.face_colors = np.tile(colour, (len(mesh.faces), 1))
        meshes.append(mesh)
    if not meshes:
        return trimesh.Trimesh()
    return trimesh.util.concatenate(meshes)


def glb_bytes(parts, colour_of) -> bytes:
    """A GLB file of 3D parts, one colour per part tag (linear, as glTF defines ``COLOR_0``)."""
    return parts_to_trimesh(parts, colour_of, linear_colours=True).export(file_type="glb")


def export_mesh(parts, path: str | os.PathLike, colour_of) -> None:
    """Write parts as ``.obj`` or ``.glb`` (chosen by the suffix), atomically."""
    path = Path(path)
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("obj", "glb"):
        raise ValueError(f"mesh export writes .obj or .glb, not {path.suffix!r}")
    if kind == "glb":
        write_bytes_atomic(path, glb_bytes(parts, colour_of))
        return
    mesh = parts_to_trimesh(parts, colour_of)
    if len(mesh.faces) == 0:
        # trimesh writes "v" and "f" lines with no numbers for an empty mesh, which readers
        # (trimesh itself: a point cloud of shape (1, 0)) take for a broken file
        write_bytes_atomic(path, b"# procmod: a derivation with no parts (an empty mesh)\n")
        return
    data = mesh.export(file_type="obj")
    write_bytes_atomic(path, data.encode() if isinstance(data, str) else data)
