"""Render derivations of 2D models to files a person looks at (PNG, SVG, contact sheets)."""

from __future__ import annotations

import os
from pathlib import Path

from .core import Derivation, InvalidArgumentError, write_text_atomic
from .geometry import contact_sheet, render_image, render_svg, save_image_atomic

MIN_SIZE, MAX_SIZE = 8, 4096
FORMATS = (".png", ".svg")


def check_size(size: int) -> int:
    """Validate a display size in pixels."""
    if isinstance(size, bool) or not isinstance(size, int) or not MIN_SIZE <= size <= MAX_SIZE:
        raise InvalidArgumentError(f"size must be between {MIN_SIZE} and {MAX_SIZE} pixels, got {size!r}")
    return size


def check_format(path: str | os.PathLike) -> str:
    """The output format implied by a file name (.png or .svg)."""
    suffix = Path(path).suffix.lower()
    if suffix not in FORMATS:
        raise InvalidArgumentError(f"cannot tell the format of {str(path)!r}: name it .png or .svg")
    return suffix


def derivation_image(derivation: Derivation, size: int):
    """A colour PIL image of a derivation's geometry, ``size`` pixels wide."""
    return render_image(derivation.geometry(), derivation.output.viewport, check_size(size))


def write_derivation(derivation: Derivation, path: str | os.PathLike, size: int) -> None:
    """Render a derivation to ``path`` (.png or .svg), written atomically."""
    if check_format(path) == ".png":
        save_image_atomic(derivation_image(derivation, size), path)
    else:
        write_text_atomic(path, render_svg(derivation.geometry(), derivation.output.viewport, check_size(size)))


def write_contact_sheet(derivations, path: str | os.PathLike, tile: int = 128, labels=None) -> None:
    """A grid of renders of many derivations, one PNG."""
    images = [derivation_image(d, tile) for d in derivations]
    save_image_atomic(contact_sheet(images, labels=labels), path)
