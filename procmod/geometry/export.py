"""Pictures a person looks at: colour PNG and SVG renders of 2D geometry, contact sheets.

Renders re-rasterise a derivation's vector geometry at any resolution with the same
kernels as the scoring canvas (supersampled for smooth edges), so what you see is what
the engines scored, only sharper.
"""

from __future__ import annotations

import math
import zlib

import numpy as np
from PIL import Image, ImageDraw

# PNG writes are core's (atomic, deterministic bytes); kept importable from here
from ..core.io import save_figure_atomic, save_image_atomic  # noqa: F401
from .primitives import Disc, Ellipse, Polygon, Segment
from .raster import Canvas, Viewport

BACKGROUND = (255, 255, 255)
DEFAULT_COLOUR = (40, 40, 40)
PALETTE = {
    "stroke": (40, 40, 40),
    "stem": (74, 98, 40),
    "leaf": (96, 170, 60),
    "flower": (222, 84, 140),
    "bolt": (60, 70, 190),
    "chain": (30, 30, 30),
    "hull": (150, 160, 175),
    "nose": (200, 90, 60),
    "wing": (70, 110, 170),
    "gun": (60, 60, 60),
    "fin": (210, 170, 60),
    "trunk": (110, 80, 50),
    "branch": (120, 90, 55),
    "foliage": (80, 150, 60),
    "building": (170, 170, 180),
}


def colour_of(tag: str) -> tuple:
    """The RGB colour a tag is drawn in: the palette's, else a stable colour picked by the
    tag's name (so the parts of learned programs and shape sets get distinct colours)."""
    colour = PALETTE.get(tag)
    if colour is None:
        # surrogatepass: a lone surrogate a JSON file spelled ("\\ud800") is a colour too, not a traceback
        colour = (_EXTRA_COLOURS[zlib.crc32(tag.encode("utf-8", "surrogatepass")) % len(_EXTRA_COLOURS)] if tag
                  else DEFAULT_COLOUR)
    return colour


# Tableau-like colours for tags the palette does not name.
_EXTRA_COLOURS = ((78, 121, 167), (242, 142, 43), (225, 87, 89), (118, 183, 178), (89, 161, 79),
                  (237, 201, 72), (176, 122, 161), (255, 157, 167), (156, 117, 95), (186, 176, 172))


def canvas_height(viewport, width: int) -> int:
    """Pixel height that keeps the viewport's aspect ratio at ``width`` pixels."""
    vp = Viewport(*viewport)
    return max(1, int(round(width * (vp.ymax - vp.ymin) / (vp.xmax - vp.xmin))))


def render_image(geometries, viewport, width: int, supersample: int = 3,
                 background=BACKGROUND, underlay=None) -> Image.Image:
    """A colour RGB render of ``geometries`` (later ones drawn on top).

    ``underlay`` is an optional boolean ``(h, w)`` mask (e.g. a target) shown in light
    grey beneath the geometry.
    """
    height = canvas_height(viewport, width)
    tags = sorted({g.tag for g in geometries})
    index = {tag: i + 1 for i, tag in enumerate(tags)}
    big_w, big_h = width * supersample, height * supersample
    if any(isinstance(g, Polygon) for g in geometries):  # even-odd fills: the scoring raster
        canvas = Canvas(viewport, big_w, big_h)
        for geometry in geometries:
            canvas.value = index[geometry.tag]
            canvas.add(geometry)
        pixels = canvas.pixels
    else:
        pixels = _draw_with_pil(geometries, Viewport(*viewport), big_w, big_h, index)
    palette = np.array([background] + [colour_of(t) for t in tags], dtype=np.uint8)
    # PIL's palette lookup and box filter (the mean of each supersample x supersample block)
    # in C: numpy's fancy indexing of the full supersampled canvas cost 3-4x as much
    indexed = Image.frombuffer("P", (big_w, big_h), pixels.tobytes(), "raw", "P", 0, 1)
    indexed.putpalette(palette.tobytes())
    image = indexed.convert("RGB").resize((width, height), Image.BOX)
    if underlay is not None:
        mask = np.asarray(Image.fromarray(np.asarray(underlay, dtype=np.uint8) * 255)
                          .resize((width, height), Image.NEAREST)) > 0
        # a block is empty when its box mean of (drawn ? 255 : 0) is 0 (one drawn sample of
        # up to 16 still averages above 15)
        drawn = Image.frombuffer("L", (big_w, big_h), ((pixels != 0).view(np.uint8) * 255).tobytes(),
                                 "raw", "L", 0, 1)
        empty = np.asarray(drawn.resize((width, height), Image.BOX)) == 0
        rgb = np.array(image)
        rgb[mask & empty] = (215, 215, 215)
        image = Image.fromarray(rgb, "RGB")
    return image


_UNIT_CIRCLE = tuple((math.cos(2 * math.pi * k / 24), math.sin(2 * math.pi * k / 24)) for k in range(24))


def _draw_with_pil(geometries, vp: Viewport, w: int, h: int, index: dict) -> np.ndarray:
    """Segments, discs and ellipses drawn by PIL (in C) into a ``(h, w)`` array of palette
    indices. A picture, not a score: the scoring raster (:class:`Canvas`, a pixel covered
    when its centre is inside) costs ~0.2 ms a primitive at report sizes, PIL ~10 us,
    and a report renders every primitive of the best output at 512 px x 3."""
    sx, sy = w / (vp.xmax - vp.xmin), h / (vp.ymax - vp.ymin)
    image = Image.new("P", (w, h), 0)
    draw = ImageDraw.Draw(image)

    def px(x, y):  # world -> PIL coordinates, where pixel (i, j)'s centre is (j, i)
        return (x - vp.xmin) * sx - 0.5, (y - vp.ymin) * sy - 0.5

    def disc(cx, cy, r, value):  # PIL's box is inclusive of its last pixel: a diameter of 2r pixels
        q = max(r - 0.5, 0.0)
        draw.ellipse((cx - q, cy - q, cx + q, cy + q), fill=value)

    for g in geometries:
        value = index[g.tag]
        if isinstance(g, Segment):
            (x0, y0), (x1, y1) = px(g.x0, g.y0), px(g.x1, g.y1)
            r = max(0.5 * g.width * sx, 0.5)  # never thinner than a pixel, as the raster
            dx, dy = x1 - x0, y1 - y0
            length = math.hypot(dx, dy)
            if length > 0:
                nx, ny = -dy / length * r, dx / length * r
                draw.polygon([(x0 + nx, y0 + ny), (x1 + nx, y1 + ny), (x1 - nx, y1 - ny), (x0 - nx, y0 - ny)],
                             fill=value)
            disc(x0, y0, r, value)
            disc(x1, y1, r, value)
        elif isinstance(g, Disc):
            cx, cy = px(g.x, g.y)
            disc(cx, cy, max(g.radius * sx, 0.5), value)
        elif isinstance(g, Ellipse):
            cx, cy = px(g.x, g.y)
            ca, sa = math.cos(g.angle), math.sin(g.angle)
            a, b = 0.5 * g.length, 0.5 * g.width
            # the axes in pixels, then a polygon of _UNIT_CIRCLE's vertices
            ax, ay, bx, by = a * ca * sx, a * sa * sy, -b * sa * sx, b * ca * sy
            draw.polygon([(cx + u * ax + v * bx, cy + u * ay + v * by) for u, v in _UNIT_CIRCLE], fill=value)
        else:
            raise TypeError(f"cannot render {g!r}")
    return np.asarray(image, dtype=np.uint8)


def _hex(colour) -> str:
    return "#%02x%02x%02x" % colour


def render_svg(geometries, viewport, width: int) -> str:
    """An SVG document of ``geometries`` in world coordinates (viewBox = viewport)."""
    vp = Viewport(*viewport)
    height = canvas_height(vp, width)
    w, h = vp.xmax - vp.xmin, vp.ymax - vp.ymin
    out = [f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
           f'viewBox="{vp.xmin:g} {vp.ymin:g} {w:g} {h:g}">',
           f'<rect x="{vp.xmin:g}" y="{vp.ymin:g}" width="{w:g}" height="{h:g}" fill="{_hex(BACKGROUND)}"/>']
    for g in geometries:
        colour = _hex(colour_of(g.tag))
        if isinstance(g, Segment):
            out.append(f'<line x1="{g.x0:.6g}" y1="{g.y0:.6g}" x2="{g.x1:.6g}" y2="{g.y1:.6g}" '
                       f'stroke="{colour}" stroke-width="{g.width:.6g}" stroke-linecap="round"/>')
        elif isinstance(g, Disc):
            out.append(f'<circle cx="{g.x:.6g}" cy="{g.y:.6g}" r="{g.radius:.6g}" fill="{colour}"/>')
        elif isinstance(g, Ellipse):
            out.append(f'<ellipse cx="{g.x:.6g}" cy="{g.y:.6g}" rx="{0.5 * g.length:.6g}" '
                       f'ry="{0.5 * g.width:.6g}" transform="rotate({math.degrees(g.angle):.6g} '
                       f'{g.x:.6g} {g.y:.6g})" fill="{colour}"/>')
        elif isinstance(g, Polygon):
            pts = " ".join(f"{x:.6g},{y:.6g}" for x, y in g.points)
            out.append(f'<polygon points="{pts}" fill="{colour}" fill-rule="evenodd"/>')
        else:
            raise TypeError(f"cannot write {g!r} to SVG")
    out.append("</svg>")
    return "\n".join(out) + "\n"


def contact_sheet(images, columns: int | None = None, pad: int = 6,
                  labels=None, background=(235, 235, 235)) -> Image.Image:
    """Tile images (all the same size) into one sheet, optionally with a caption each."""
    images = list(images)
    if not images:
        raise ValueError("a contact sheet needs at least one image")
    n = len(images)
    columns = columns or int(np.ceil(np.sqrt(n)))
    rows = int(np.ceil(n / columns))
    w, h = images[0].size
    caption = 14 if labels else 0
    sheet = Image.new("RGB", (columns * (w + pad) + pad, rows * (h + pad + caption) + pad), background)
    draw = ImageDraw.Draw(sheet)
    for i, image in enumerate(images):
        r, c = divmod(i, columns)
        x, y = pad + c * (w + pad), pad + r * (h + pad + caption)
        sheet.paste(image.convert("RGB"), (x, y))
        if labels:
            draw.text((x + 2, y + h + 1), str(labels[i]), fill=(60, 60, 60))
    return sheet


def shaded_preview(parts, size: int, colour_of, direction=(1.0, 0.8, 1.4), up=(0.0, 1.0, 0.0)) -> Image.Image:
    """A ``size`` x ``size`` picture of 3D parts, framed whole from ``direction`` (with
    ``up`` up) and Lambert-shaded (:func:`procmod.geometry.camera.shaded_image`): the one
    preview recipe of 3D samples, learned programs' examples and string shapes."""
    from .camera import framing_camera, shaded_image  # numba kernels: 2D renders never load them
    from .solid import scene_bounds

    lo, hi = scene_bounds(parts)
    camera = framing_camera(lo, hi, size, size, direction=direction, up=up)
    return Image.fromarray(shaded_image(parts, camera, colour_of))
