"""Pictures and meshes of shapes: shaded PNG previews, contact sheets, GLB/OBJ export.

Shapes are z-up (procmod strings' frame). A GLB or OBJ is written y-up: glTF's own frame,
and the frame OBJ importers assume by default (Blender, Maya, three.js) and procmod's
other mesh writers (``sample``, ``infer``, ``learn``) use. The shape is turned -90 degrees
about x, the inverse of the turn a glTF input gets as it is read
(:data:`~procmod.geometry.assets.Y_UP_TO_Z_UP`), so a y-up scene read in comes back out
standing as it stood. (An OBJ had been written z-up, in the shapes' own frame, and lay
on its side in Blender imported with its defaults.) Part meshes a shapes file names
(``parts/NAME.obj``) are data, not results: they stay in the shapes' frame."""

from __future__ import annotations

import os

import numpy as np
from PIL import Image

from ..geometry.assets import Y_UP_TO_Z_UP
from ..geometry.export import colour_of, contact_sheet, save_image_atomic, shaded_preview
from ..geometry.mesh_export import export_mesh
from .shapes import Shape, ShapeSet


PALETTE = ((196, 78, 82), (85, 140, 70), (76, 114, 176), (221, 170, 60), (129, 114, 178), (100, 181, 205),
           (147, 120, 96), (218, 139, 195), (140, 140, 140), (204, 185, 116))


def colours_for(shape_set: ShapeSet):
    """A colour function: each part name of the library its own palette colour (sorted names)."""
    table = {name: PALETTE[k % len(PALETTE)] for k, name in enumerate(sorted(shape_set.library))}
    return lambda tag: table.get(tag, colour_of(tag))


def shape_parts(shape_set: ShapeSet, shape: Shape) -> list:
    """The geometry parts of a shape (tagged by part name)."""
    return [shape_set.library[p].part(t) for p, t in zip(shape.parts, shape.transforms)]


def shape_image(shape_set: ShapeSet, shape: Shape, size: int = 256) -> Image.Image:
    """A Lambert-shaded preview (z up, seen from above at an angle)."""
    return shaded_preview(shape_parts(shape_set, shape), size, colours_for(shape_set),
                          direction=(0.9, -1.3, 1.4), up=(0.0, 0.0, 1.0))


def write_shape_png(shape_set: ShapeSet, shape: Shape, path: str | os.PathLike, size: int = 256) -> None:
    save_image_atomic(shape_image(shape_set, shape, size), path)


Z_UP_TO_Y_UP = Y_UP_TO_Z_UP.T  # the turn a shape gets as it is written to a mesh file


def write_shape_mesh(shape_set: ShapeSet, shape: Shape, path: str | os.PathLike) -> None:
    """Write a shape as ``.glb`` or ``.obj`` (by suffix), y-up, one colour per part name
    (see the module docstring)."""
    shape = Shape.of(list(shape.parts), [Z_UP_TO_Y_UP @ np.asarray(t, dtype=np.float64) for t in shape.transforms])
    export_mesh(shape_parts(shape_set, shape), path, colours_for(shape_set))


def write_sheet(shape_set: ShapeSet, shapes, path: str | os.PathLike, size: int = 160, labels=None) -> None:
    images = [shape_image(shape_set, s, size) for s in shapes]
    save_image_atomic(contact_sheet(images, labels=labels), path)
