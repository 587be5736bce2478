"""Target sets made at run time (glyphs, scribbles) and the target-spec parser.

A target spec names one target image:

* ``glyph:a`` — a glyph of the default typeface; ``glyph:dejavu-serif/Q`` names the face;
* ``scribble:17`` — procedurally drawn scribble number 17;
* any other string is a path to a picture (with an optional sidecar ``NAME.json``).

Append ``:mirrored`` to any spec for its horizontally mirrored copy.
"""

from __future__ import annotations

from ..core import InvalidArgumentError
from ..core.lazy import lazy_getattr
from ..targets import TargetImage, load_target_image

# Glyphs need fonts, Pillow's FreeType and scipy; a target picture needs none of them.
_LAZY = {**dict.fromkeys(("DEFAULT_TYPEFACE", "TYPEFACES", "glyph_set", "glyph_target", "render_glyph"), "glyphs"),
         **dict.fromkeys(("scribble_set", "scribble_target"), "scribbles")}
__getattr__ = lazy_getattr(__name__, _LAZY, globals())

MIRROR_SUFFIX = ":mirrored"


def target_image(spec: str) -> TargetImage:
    """The target image a spec names (see the module docstring)."""
    if not isinstance(spec, str) or not spec:
        raise InvalidArgumentError("a target spec is glyph:CHAR, glyph:FACE/CHAR, scribble:N or a file path")
    if spec.endswith(MIRROR_SUFFIX):
        return target_image(spec[: -len(MIRROR_SUFFIX)]).mirrored()
    if spec.startswith("glyph:"):
        rest = spec[len("glyph:"):]
        from .glyphs import DEFAULT_TYPEFACE, glyph_target

        typeface, char = rest.rsplit("/", 1) if "/" in rest[:-1] else (DEFAULT_TYPEFACE, rest)
        return glyph_target(char, typeface)
    if spec.startswith("scribble:"):
        number = spec[len("scribble:"):]
        if not number.isdigit():
            raise InvalidArgumentError(f"scribble:N needs a non-negative integer, got {spec!r}")
        from .scribbles import scribble_target

        return scribble_target(int(number))
    return load_target_image(spec)


__all__ = ["target_image", "glyph_target", "glyph_set", "render_glyph", "scribble_target",
           "scribble_set", "TYPEFACES", "DEFAULT_TYPEFACE"]
