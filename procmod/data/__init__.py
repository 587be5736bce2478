"""Target sets made at run time (glyphs, scribbles) and the target-spec parsers.

A target-image spec (:func:`target_image`) names one target image:

* ``glyph:a`` — a glyph of the default typeface; ``glyph:dejavu-serif/Q`` names the face;
* ``scribble:17`` — procedurally drawn scribble number 17;
* any other string is a path to a picture (with an optional sidecar ``NAME.json``).

Append ``:mirrored`` to any spec for its horizontally mirrored copy.

A target spec (:func:`target_from_spec`: ``procmod infer --target``, a guide trace's
``"target"``) is ``circuit``, a target file (``.json``) or a folder holding
``target.json``, or else a target-image spec, scored by shape match.
"""

from __future__ import annotations

import os
import re
from pathlib import Path

from ..core import InvalidArgumentError
from ..core.file_formats import conversion_hint
from ..core.lazy import lazy_getattr
from ..core.paths import is_dir_quietly
from ..targets import Circuit, ShapeMatch, TargetImage, load_target_file, load_target_image
from ..targets.files import MESH_SUFFIXES, TargetFileError

# Glyphs need fonts, Pillow's FreeType and scipy; a target picture needs none of them.
_LAZY = {**dict.fromkeys(("DEFAULT_TYPEFACE", "TYPEFACES", "glyph_set", "glyph_target", "render_glyph"), "glyphs"),
         **dict.fromkeys(("scribble_set", "scribble_target"), "scribbles")}
__getattr__ = lazy_getattr(__name__, _LAZY, globals())

MIRROR_SUFFIX = ":mirrored"


def _exists_quietly(spec: str) -> bool:
    try:
        return Path(spec).exists()
    except (OSError, ValueError):  # a name too long for the file system
        return False


def _built_in_target(spec: str) -> TargetImage:
    """The target of a ``glyph:...`` or ``scribble:N`` spec."""
    if spec.startswith("glyph:"):
        rest = spec[len("glyph:"):]
        from .glyphs import DEFAULT_TYPEFACE, glyph_target

        typeface, char = rest.rsplit("/", 1) if "/" in rest[:-1] else (DEFAULT_TYPEFACE, rest)
        return glyph_target(char, typeface)
    number = spec[len("scribble:"):]
    if not number.isdecimal():  # isdigit() takes "²", which int() refuses
        raise InvalidArgumentError(f"scribble:N needs a non-negative integer, got {spec!r}")
    from .scribbles import scribble_target

    return scribble_target(int(number))


def target_image(spec: str) -> TargetImage:
    """The target image a spec names (see the module docstring)."""
    if not isinstance(spec, str) or not spec:
        raise InvalidArgumentError("a target spec is glyph:CHAR, glyph:FACE/CHAR, scribble:N or a file path")
    if spec == "circuit" or spec.startswith("circuit:"):
        raise InvalidArgumentError("the circuit target is a score, not a picture: give 'circuit' alone (it has no "
                                   "mirrored copy)")
    if spec.endswith(MIRROR_SUFFIX):
        return target_image(spec[: -len(MIRROR_SUFFIX)]).mirrored()
    if spec.startswith(("glyph:", "scribble:")):
        try:
            return _built_in_target(spec)
        except InvalidArgumentError as exc:
            if _exists_quietly(spec):  # a file named like a spec: say how to name the file
                raise InvalidArgumentError(f"{exc} (for the file {spec!r} give ./{spec})") from None
            if spec.count(":") > 1:  # glyph:a:mirror -- a suffix misspelt, read as part of the glyph
                raise InvalidArgumentError(f"{exc}; a spec ends in {MIRROR_SUFFIX} for its mirrored copy "
                                           f"({spec.split(':')[0]}:...{MIRROR_SUFFIX})") from None
            raise
    if ":" in spec and not _exists_quietly(spec) and not re.match(r"^[A-Za-z]:[\\/]", spec):  # not C:\...
        shown = spec if len(spec) <= 60 else spec[:57] + "..."
        raise InvalidArgumentError(f"unknown target spec {shown!r}: a target is glyph:CHAR, glyph:FACE/CHAR, "
                                   "scribble:N, circuit, a picture file, or a target JSON file or folder (and a "
                                   "picture spec may end in :mirrored)")
    return load_target_image(spec)



def target_from_spec(spec: str):
    """The target a target spec names (see the module docstring): the one parser of
    ``procmod infer --target`` and of the targets guide traces were made on. A path
    (``pathlib.Path``) is read as its file's spec."""
    if isinstance(spec, os.PathLike):
        spec = os.fspath(spec)
        spec = spec if isinstance(spec, str) else os.fsdecode(spec)
    if not isinstance(spec, str) or not spec:
        return target_image(spec)  # refuses it, naming the forms a spec takes
    if spec == "circuit":
        return Circuit()
    path = Path(spec)
    if is_dir_quietly(path):
        return load_target_file(path / "target.json")
    if path.suffix.lower() == ".json":
        return load_target_file(path)
    hint = conversion_hint(path)
    if path.suffix.lower() in MESH_SUFFIXES or hint:  # Pillow's "cannot identify image file" said nothing of this
        raise TargetFileError(f"{spec}: a mesh is a target through a target file that says how to compare with it: "
                              "a procmod-volume/1 file (its inside, on a voxel grid) or a procmod-silhouette/1 file "
                              "(its outline, seen by cameras) whose layer or view names the mesh; README, \"Targets\""
                              + (f" ({hint})" if hint else ""))
    if path.suffix.lower() == ".npy":  # a voxel grid, or a silhouette view's weights: also named by a target file
        raise TargetFileError(f"{spec}: an .npy array is a target through a target file that says what it is: a "
                              "procmod-volume/1 file whose layer names it with the grid's \"origin\" and "
                              "\"voxel_size\" (a 3D voxel grid), or a procmod-silhouette/1 file whose view names it as "
                              "\"weights\" with a camera (a 2D array); README, \"Targets\"")
    return ShapeMatch(target_image(spec))


__all__ = ["target_image", "target_from_spec", "glyph_target", "glyph_set", "render_glyph", "scribble_target",
           "scribble_set", "TYPEFACES", "DEFAULT_TYPEFACE"]
