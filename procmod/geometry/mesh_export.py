"""Mesh export of 3D parts: OBJ and GLB (through trimesh), with one colour per part tag."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import trimesh

from ..core.io import write_bytes_atomic
from .solid import part_triangles


def parts_to_trimesh(parts, colour_of, segments: int = 24) -> trimesh.Trimesh:
    """One mesh of all parts (vertices merged per part), faces coloured by tag."""
    meshes = []
    for part in parts:
        tris = part_triangles(part, segments)
        mesh = trimesh.Trimesh(vertices=tris.reshape(-1, 3), faces=np.arange(len(tris) * 3).reshape(-1, 3),
                               process=True)
        colour = np.append(np.asarray(colour_of(part.tag), dtype=np.uint8), 255)
        mesh.visual.face_colors = np.tile(colour, (len(mesh.faces), 1))
        meshes.append(mesh)
    if not meshes:
        return trimesh.Trimesh()
    return trimesh.util.concatenate(meshes)


def export_mesh(parts, path: str | os.PathLike, colour_of) -> None:
    """Write parts as ``.obj`` or ``.glb`` (chosen by the suffix), atomically."""
    path = Path(path)
    kind = path.suffix.lower().lstrip(".")
    if kind not in ("obj", "glb"):
        raise ValueError(f"mesh export writes .obj or .glb, not {path.suffix!r}")
    mesh = parts_to_trimesh(parts, colour_of)
    if kind == "obj" and len(mesh.faces) == 0:
        # trimesh writes "v" and "f" lines with no numbers for an empty mesh, which readers
        # (trimesh itself: a point cloud of shape (1, 0)) take for a broken file
        write_bytes_atomic(path, b"# procmod: a derivation with no parts (an empty mesh)\n")
        return
    data = mesh.export(file_type=kind)
    write_bytes_atomic(path, data.encode() if isinstance(data, str) else data)
