"""Render derivations of 2D models to files a person looks at (PNG, SVG, contact sheets)."""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from .core import Derivation, InvalidArgumentError, write_text_atomic
from .core.errors import argument, shown_value, whole_number
from .core.limits import MAX_COORDINATE
from .geometry import colour_of, contact_sheet, render_image, render_svg, save_image_atomic, shaded_preview

MIN_SIZE, MAX_SIZE = 8, 4096
FORMATS_2D = (".png", ".svg")
FORMATS_3D = (".png", ".obj", ".glb")
FORMATS = FORMATS_2D + FORMATS_3D[1:]


def check_size(size: int) -> int:
    """Validate a display size in pixels."""
    pixels = whole_number(size)
    if pixels is None or not MIN_SIZE <= pixels <= MAX_SIZE:
        raise InvalidArgumentError(f"{argument('size')} must be between {MIN_SIZE} and {MAX_SIZE} pixels (a whole "
                                   f"number), got {shown_value(size)}")
    return pixels


def is_2d(derivation: Derivation) -> bool:
    """True for models that draw into a 2D raster canvas (an output of dimension 2)."""
    return derivation.output.dimension == 2


def output_formats(derivation: Derivation) -> tuple:
    """The file formats a derivation can be written to."""
    return FORMATS_2D if is_2d(derivation) else FORMATS_3D


def check_format(path: str | os.PathLike, formats=FORMATS) -> str:
    """The output format implied by a file name."""
    suffix = Path(path).suffix.lower()
    if suffix in FORMATS and suffix not in formats:
        kind = "a 2D" if formats == FORMATS_2D else "a 3D"
        raise InvalidArgumentError(f"{kind} derivation is not written as {suffix}: name the file "
                                   + " or ".join(formats))
    if suffix not in formats:
        raise InvalidArgumentError(f"cannot tell the format of {str(path)!r}: name it "
                                   + " or ".join(formats))
    return suffix


def derivation_image(derivation: Derivation, size: int, underlay=None, supersample: int = 3):
    """A colour PIL image of a derivation, ``size`` pixels wide (a shaded view for 3D).

    2D renders are antialiased by drawing ``supersample`` x ``supersample`` pixels per
    output pixel (small tiles of a contact sheet need fewer than a full-size render)."""
    size = check_size(size)
    check_renderable(derivation)
    geometry = derivation.geometry()
    if is_2d(derivation):
        return render_image(geometry, derivation.output.viewport, size, supersample=supersample, underlay=underlay)
    return shaded_preview(geometry, size, colour_of)  # loads the numba kernels for 3D only


def derivation_images(derivations, size: int, underlay=None, supersample: int = 3) -> list:
    """:func:`derivation_image` of each derivation, drawing each distinct 2D output once.

    The final particles of an SMC run are mostly copies of a few ancestors, so a report's
    contact sheet would otherwise draw the same vine up to 16 times (~2 ms a 128 px tile).
    Two 2D derivations share a picture when their viewport and their primitives (type and
    fields) are equal: the picture is a function of nothing else. Shared pictures are one
    object: copy one before drawing on it. 3D outputs are drawn one by one."""
    size = check_size(size)
    images, drawn = [], {}
    for derivation in derivations:
        if not is_2d(derivation):
            images.append(derivation_image(derivation, size, underlay=underlay, supersample=supersample))
            continue
        geometry = derivation.geometry()
        viewport = derivation.output.viewport
        try:
            key = (tuple(viewport), tuple((type(g), g) for g in geometry))
            image = drawn.get(key)
        except TypeError:  # a primitive that is not hashable: draw it, unshared
            key = image = None
        if image is None:
            image = render_image(geometry, viewport, size, supersample=supersample, underlay=underlay)
            if key is not None:
                drawn[key] = image
        images.append(image)
    return images


# fields of the geometry primitives that are sizes: a negative one is a model's bug
_SIZE_FIELDS = ("width", "radius", "length", "size", "top_radius")


def _bad_number(value, size: bool, solid: bool) -> str | None:
    """What is wrong with a primitive's field ``value`` (a size when ``size``; of a 3D
    part when ``solid``), or None."""
    try:
        array = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        return None  # not numbers (a tag, a mesh's faces are checked by their readers)
    if not np.isfinite(array).all() or (size and (array < 0).any()):
        return "a size must be finite and not negative" if size else "it must hold finite numbers"
    if solid and array.size and np.abs(array).max() > MAX_COORDINATE:
        # a mesh file's triangles' arithmetic overflows (inf vertices in a GLB, from a
        # hand-edited log-scale of 100); a 2D picture draws a far line as it is
        return f"it is beyond +-{MAX_COORDINATE:g}, more than any scene holds"
    return None


def check_renderable(derivation: Derivation) -> None:
    """Refuse a derivation whose output is neither 2D nor 3D (a model of one's own output,
    a running sum): it was drawn as 3D parts, a TypeError deep in the mesh code."""
    from .core.errors import InvalidArgumentError

    dimension = getattr(derivation.output, "dimension", None)
    if dimension not in (2, 3):
        raise InvalidArgumentError(f"model {derivation.model.name!r} draws into an output of dimension "
                                   f"{shown_value(dimension)}, which procmod cannot render (pictures are of "
                                   "dimension 2, meshes of 3); score and save its derivations instead")
    # a picture is drawn in the output's viewport: a Canvas's (or an object standing in for one)
    if dimension == 2 and getattr(derivation.output, "viewport", None) is None:
        raise InvalidArgumentError(f"model {derivation.model.name!r} draws into a {type(derivation.output).__name__} "
                                   "of dimension 2, which procmod cannot render: dimension 2 is a procmod Canvas "
                                   "(procmod.geometry.Canvas, a raster it draws pictures of); declare dimension 0 for "
                                   "an output of your own, and score and save its derivations instead")


def check_geometry(derivation: Derivation) -> None:
    """Refuse a derivation whose geometry holds a NaN or an infinity, or a negative size:
    the canvas draws such a primitive as nothing (or a dot), an SVG or a mesh file would
    hold ``nan`` or a negative radius; or a 3D part beyond +-:data:`MAX_COORDINATE`. Names
    the rule that emitted it, and the call's choices (an edited file's)."""
    from .core.choicemap import format_address
    from .core.errors import ModelError
    from .core.runtime import rule_name
    from .geometry.solid import Cylinder

    check_renderable(derivation)
    solid = not is_2d(derivation)
    for node in derivation.nodes():
        for part in node.geometry:
            fields = getattr(part, "_fields", ())
            for name in fields:
                if name in ("tag", "faces"):
                    continue
                value = getattr(part, name)
                # a cylinder of negative length points along -z, and draws so
                size = name in _SIZE_FIELDS and not (name == "length" and isinstance(part, Cylinder))
                wrong = None if value is None else _bad_number(value, size, solid)
                if wrong is not None:
                    made_of = ", ".join(f"{choice} = {shown_value(made.value, 12)}"
                                        for choice, made in list(node.choices.items())[:4])
                    raise ModelError(f"rule {rule_name(node.rule)!r} at {format_address(node.address)} emitted "
                                     f"{type(part).__name__} with {name} = {value!r:.60}: {wrong}; find the "
                                     "rule's arithmetic that makes it"
                                     + (f", or the call's choices ({made_of}) in an edited file" if made_of else ""))


def write_derivation(derivation: Derivation, path: str | os.PathLike, size: int) -> None:
    """Render or export a derivation to ``path`` (2D: .png, .svg; 3D: .png, .obj, .glb)."""
    suffix = check_format(path, output_formats(derivation))
    check_geometry(derivation)
    if suffix == ".png":
        save_image_atomic(derivation_image(derivation, size), path)
    elif suffix == ".svg":
        write_text_atomic(path, render_svg(derivation.geometry(), derivation.output.viewport, check_size(size)))
    else:
        from .geometry.mesh_export import export_mesh  # trimesh: a second to import, 3D only

        export_mesh(derivation.geometry(), path, colour_of)


def write_contact_sheet(derivations, path: str | os.PathLike, tile: int = 128, labels=None) -> None:
    """A grid of renders of many derivations, one PNG."""
    images = derivation_images(derivations, tile)
    save_image_atomic(contact_sheet(images, labels=labels), path)


def write_contact_page(derivations, path: str | os.PathLike, labels=None, links=None,
                       title: str = "procmod samples") -> None:
    """An HTML page of 3D derivations, each in its own orbitable view (``contact_sheet.html``
    of a 3D sample folder; see :mod:`procmod.viewer`): the models are inline, so the page
    opens from disk with no network. ``links`` (optional) are file names the captions link to."""
    from .viewer.layers import parts_glb
    from .viewer.pages import contact_page_html

    derivations = list(derivations)
    if any(is_2d(d) for d in derivations):
        raise InvalidArgumentError("a contact page of orbitable views is for 3D models; 2D samples have "
                                   "contact_sheet.png")
    labels = [str(i) for i in range(len(derivations))] if labels is None else labels
    glbs = [parts_glb(d.geometry()) for d in derivations]
    write_text_atomic(path, contact_page_html(glbs, labels, links, title))
