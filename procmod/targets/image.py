"""Target images: a binary mask plus the start point and direction a model grows from.

Masks are kept at their source resolution and resampled to a model's canvas size when a
target is bound to a model, so one target serves any ``--size``.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from ..core import InvalidArgumentError, ProcmodError


class TargetFileError(ProcmodError):
    """A target image or its sidecar JSON cannot be used."""


@dataclass(frozen=True)
class TargetImage:
    """A binary target mask and where a model should start growing.

    Attributes
    ----------
    name : str
        What the target is called (``glyph:a``, a file name, ...).
    mask : numpy.ndarray
        Boolean ``(height, width)`` array, True = foreground.
    start : tuple
        Start point in normalised image coordinates (x right, y down, both in [0, 1]).
    direction : tuple
        Start direction (x right, y down), e.g. ``(0, -1)`` grows up the image.
    """

    name: str
    mask: np.ndarray = field(repr=False)
    start: tuple = (0.5, 0.9166)
    direction: tuple = (0.0, -1.0)

    def mirrored(self) -> "TargetImage":
        """The horizontally mirrored target (start and direction mirrored too)."""
        return replace(self, name=f"{self.name}:mirrored", mask=self.mask[:, ::-1].copy(),
                       start=(1.0 - self.start[0], self.start[1]),
                       direction=(-self.direction[0], self.direction[1]))

    def at_size(self, width: int, height: int) -> np.ndarray:
        """The mask resampled to ``height x width`` (area average, then threshold 1/2)."""
        return resample_mask(self.mask, width, height)


def resample_mask(mask: np.ndarray, width: int, height: int) -> np.ndarray:
    """Resample a boolean mask by area averaging and a 1/2 threshold."""
    mask = np.asarray(mask, dtype=bool)
    if mask.shape == (height, width):
        return mask.copy()
    image = Image.fromarray(mask.astype(np.uint8) * 255)
    small = np.asarray(image.resize((width, height), Image.BOX), dtype=np.float64)
    return small >= 127.5


def lowest_point_start(mask: np.ndarray, reach: float = 0.2) -> tuple:
    """Start at the lowest foreground pixel (middle of its run), heading along the shape.

    The direction points from the start to the centroid of the foreground within
    ``reach`` (a fraction of the image size) of it, so a model starting at the bottom of
    a "c" grows along the curve rather than straight up into the empty middle. It falls
    back to straight up.
    """
    rows = np.flatnonzero(mask.any(axis=1))
    row = rows[-1]
    cols = np.flatnonzero(mask[row])
    col = cols[len(cols) // 2]
    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    near = (xs - col) ** 2 + (ys - row) ** 2 <= (reach * max(h, w)) ** 2
    dx, dy = xs[near].mean() - col, ys[near].mean() - row
    norm = float(np.hypot(dx, dy))
    direction = (float(dx / norm), float(dy / norm)) if norm > 1e-9 else (0.0, -1.0)
    return ((col + 0.5) / w, (row + 0.5) / h), direction


def check_mask(mask: np.ndarray, name: str) -> np.ndarray:
    """Reject masks a shape target cannot use: empty, or filling the whole frame."""
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2 or mask.size == 0:
        raise TargetFileError(f"{name}: a target mask must be a 2D image")
    if not mask.any():
        raise TargetFileError(f"{name}: the target mask is empty (no foreground pixels); "
                              "draw the shape in a colour that differs from the border")
    if mask.all():
        raise TargetFileError(f"{name}: the target mask fills the whole frame; "
                              "leave some background around the shape")
    return mask


def mask_from_image(image: Image.Image) -> np.ndarray:
    """Binary mask of a picture: foreground = pixels unlike the border.

    With transparency, foreground is the opaque part. Otherwise the mean brightness of
    the border decides the convention: dark ink on a light ground or light on dark.
    Non-square pictures are padded with background to a square, centred, because the
    built-in models' viewport is square.
    """
    alpha = None
    if image.mode in ("RGBA", "LA", "PA") or "transparency" in image.info:
        alpha = np.asarray(image.convert("RGBA"))[:, :, 3]
    if alpha is not None and (alpha < 128).any():  # real transparency: the opaque part
        mask = alpha >= 128
    else:
        grey = np.asarray(image.convert("L"), dtype=np.float64)
        border = np.concatenate([grey[0], grey[-1], grey[:, 0], grey[:, -1]])
        mask = grey < 128 if border.mean() >= 128 else grey >= 128
    h, w = mask.shape
    side = max(h, w)
    square = np.zeros((side, side), dtype=bool)
    top, left = (side - h) // 2, (side - w) // 2
    square[top:top + h, left:left + w] = mask
    return square


def _read_sidecar(path: Path, shape_padding) -> tuple | None:
    sidecar = path.with_suffix(".json")
    if not sidecar.exists():
        return None
    try:
        data = json.loads(sidecar.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise TargetFileError(f"{sidecar}: cannot read the sidecar JSON ({exc})") from exc
    if not isinstance(data, dict):
        raise TargetFileError(f"{sidecar}: expected an object like "
                              '{"start": [0.5, 0.9166], "direction": [0, -1]}')
    start = data.get("start", (0.5, 0.9166))
    direction = data.get("direction", (0.0, -1.0))
    for key, value in (("start", start), ("direction", direction)):
        if (not isinstance(value, (list, tuple)) or len(value) != 2
                or not all(isinstance(v, (int, float)) and math.isfinite(v) for v in value)):
            raise TargetFileError(f"{sidecar}: {key!r} must be two numbers, got {value!r}")
    if not all(0.0 <= v <= 1.0 for v in start):
        raise TargetFileError(f"{sidecar}: 'start' is in normalised image coordinates and must lie in [0, 1]")
    if direction[0] == 0 and direction[1] == 0:
        raise TargetFileError(f"{sidecar}: 'direction' must be a non-zero vector")
    # The sidecar refers to the original picture; map it into the padded square.
    (h, w) = shape_padding
    side = max(h, w)
    sx = (start[0] * w + (side - w) // 2) / side
    sy = (start[1] * h + (side - h) // 2) / side
    return (sx, sy), (float(direction[0]), float(direction[1]))


def load_target_image(path: str | os.PathLike) -> TargetImage:
    """Read a target picture (any format Pillow reads) and its optional sidecar JSON."""
    path = Path(path)
    try:
        with Image.open(path) as image:
            image.load()
            shape = (image.height, image.width)
            mask = mask_from_image(image)
    except FileNotFoundError:
        raise TargetFileError(f"target file {path} does not exist") from None
    except (UnidentifiedImageError, OSError, ValueError) as exc:
        raise TargetFileError(f"{path}: not an image Pillow can read ({exc})") from None
    mask = check_mask(mask, str(path))
    placement = _read_sidecar(path, shape)
    start, direction = placement if placement else lowest_point_start(mask)
    return TargetImage(path.name, mask, tuple(start), tuple(direction))


def place_model(model, image: TargetImage):
    """``model`` configured to start where the target says, if it takes start/direction."""
    params = {}
    if "start" in model.params:
        params["start"] = [float(v) for v in image.start]
    if "direction" in model.params:
        params["direction"] = [float(v) for v in image.direction]
    return model.configure(**params) if params else model


def out_of_bounds_penalty(canvas, oob_sigma: float | None) -> float:
    """vines.md's penalty ``(ex^2 + ey^2) / oob_sigma^2`` for geometry beyond the viewport."""
    if oob_sigma is None or canvas.extent is None:
        return 0.0
    ex, ey = canvas.out_of_bounds()
    return (ex * ex + ey * ey) / (oob_sigma * oob_sigma)


def check_canvas(output, what: str):
    """The scoring canvas of a 2D model, or a clear error for other models."""
    if not hasattr(output, "gain") or not hasattr(output, "pixels"):
        raise InvalidArgumentError(f"{what} needs a 2D model that draws into a raster canvas")
    return output
