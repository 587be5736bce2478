"""Glyph targets rendered at run time from fonts that ship with installed packages.

Seed 004's Glyph set is every glyph of one bold typeface that has one foreground
component and at least 500 foreground pixels at 129x97. We render the bold DejaVu and
STIX faces that matplotlib ships (no download), fit each glyph into the centre 80% of a
``RESOLUTION``-pixel square, and keep those with one 8-connected component and at least
``MIN_FILL`` of the square filled (4%, about 500 / (129 x 97)).
"""

from __future__ import annotations

import string
from functools import lru_cache
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from ..core import InvalidArgumentError
from ..targets import TargetImage, lowest_point_start
from ..targets.components import part_count

RESOLUTION = 100
MIN_FILL = 0.04
TYPEFACES = {
    "dejavu-sans": "DejaVuSans-Bold.ttf",
    "dejavu-serif": "DejaVuSerif-Bold.ttf",
    "dejavu-mono": "DejaVuSansMono-Bold.ttf",
    "stix": "STIXGeneralBol.ttf",
}
DEFAULT_TYPEFACE = "dejavu-sans"
CHARACTERS = string.ascii_letters + string.digits


def font_path(typeface: str) -> Path:
    """The TrueType file of a typeface name."""
    if typeface not in TYPEFACES:
        raise InvalidArgumentError(f"unknown typeface {typeface!r}; choose one of {', '.join(TYPEFACES)}")
    return _matplotlib_data() / "fonts" / "ttf" / TYPEFACES[typeface]


@lru_cache(maxsize=None)
def render_glyph(char: str, typeface: str = DEFAULT_TYPEFACE) -> np.ndarray:
    """Boolean ``RESOLUTION``-square mask of one character, centred, 80% of the frame."""
    font = ImageFont.truetype(str(font_path(typeface)), 4 * RESOLUTION)
    canvas = Image.new("L", (8 * RESOLUTION, 8 * RESOLUTION), 0)
    ImageDraw.Draw(canvas).text((2 * RESOLUTION, 2 * RESOLUTION), char, fill=255, font=font)
    box = canvas.getbbox()
    if box is None:
        raise InvalidArgumentError(f"typeface {typeface!r} draws nothing for {char!r}")
    glyph = canvas.crop(box)
    scale = 0.8 * RESOLUTION / max(glyph.size)
    size = (max(1, round(glyph.size[0] * scale)), max(1, round(glyph.size[1] * scale)))
    glyph = glyph.resize(size, Image.BOX)
    square = Image.new("L", (RESOLUTION, RESOLUTION), 0)
    square.paste(glyph, ((RESOLUTION - size[0]) // 2, (RESOLUTION - size[1]) // 2))
    return np.asarray(square) >= 128


@lru_cache(maxsize=1)
def _matplotlib_data() -> Path:
    """matplotlib's data folder (``matplotlib.get_data_path()``: ``mpl-data`` beside its
    package), found without importing matplotlib: the import took 0.14 s of every
    ``procmod infer --target glyph:X``, more than its SMC's inference at 200 particles."""
    import importlib.util

    spec = importlib.util.find_spec("matplotlib")
    return Path(spec.origin).parent / "mpl-data"


def glyph_problem(mask: np.ndarray) -> str | None:
    """Why a glyph is left out of the set (None if it is kept)."""
    components = part_count(mask)
    if components != 1:
        return f"it has {components} connected parts (glyph targets need one)"
    if mask.mean() < MIN_FILL:
        return f"it fills only {100 * mask.mean():.1f}% of the frame (needs {100 * MIN_FILL:.0f}%)"
    return None


def glyph_target(char: str, typeface: str = DEFAULT_TYPEFACE) -> TargetImage:
    """One glyph target; raises if the glyph is not in the set (and says why)."""
    if len(char) != 1:
        raise InvalidArgumentError(f"a glyph is one character, got {char!r}")
    mask = render_glyph(char, typeface)
    problem = glyph_problem(mask)
    if problem:
        raise InvalidArgumentError(f"glyph {char!r} of {typeface} is not a usable target: {problem}")
    start, direction = lowest_point_start(mask)
    return TargetImage(f"glyph:{typeface}/{char}", mask, start, direction)


def glyph_set(typeface: str = DEFAULT_TYPEFACE, mirror: bool = False) -> list:
    """Every usable glyph of a typeface (plus mirrored copies if asked)."""
    out = []
    for char in CHARACTERS:
        if glyph_problem(render_glyph(char, typeface)) is None:
            target = glyph_target(char, typeface)
            out.append(target)
            if mirror:
                out.append(target.mirrored())
    return out
