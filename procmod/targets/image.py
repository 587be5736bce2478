"""Target images: a binary mask plus the start point and direction a model grows from.

Masks are kept at their source resolution and resampled to a model's canvas size when a
target is bound to a model, so one target serves any canvas size.
"""

from __future__ import annotations

import difflib
import io
import math
import os
import re
import stat
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from ..core import InvalidArgumentError, ProcmodError
from ..core.errors import cut_text
from ..core.model import picture_placed
from ..core.paths import is_link_quietly
from ..core.serialize import read_json

# The largest picture procmod reads as a target: Pillow's own decompression-bomb limit
# (89 megapixels, about 9500 x 9500). A mask this size already costs 89 MB per copy, and
# the models draw at 50 x 50 pixels; a larger picture is refused before it is decoded.
MAX_IMAGE_PIXELS = 89_478_485


class TargetFileError(ProcmodError):
    """A target image or its sidecar JSON cannot be used."""


def _is_special_file(path: Path) -> bool:
    """Whether ``path`` is there but neither a regular file, a folder nor a pipe (a device,
    a socket)."""
    try:
        return path.exists() and not path.is_file() and not path.is_dir() and not path.is_fifo()
    except (OSError, ValueError):  # a name too long to look up: opening it says so
        return False


MAX_PIPED_BYTES = 1 << 30
"""The most procmod reads from a pipe given as a picture (``--target /dev/stdin``)."""


def _piped_bytes(path: Path, where: str):
    """The bytes a pipe given as a picture holds (``cat a.png | procmod ... --target
    /dev/stdin``), or None where ``path`` is no pipe. Opened without waiting: a named pipe
    nothing writes to reads as empty (Pillow had waited on it for ever), one being written
    to as it is written."""
    try:
        if not stat.S_ISFIFO(os.stat(path).st_mode):
            return None
        fd = os.open(path, os.O_RDONLY | os.O_NONBLOCK)
    except (OSError, ValueError):  # opening it as a file says what is wrong
        return None
    try:
        os.set_blocking(fd, True)  # (opened without waiting for a writer; read as they write)
        chunks, size = [], 0
        while chunk := os.read(fd, 1 << 20):
            chunks.append(chunk)
            size += len(chunk)
            if size > MAX_PIPED_BYTES:
                raise TargetFileError(f"{where}: the pipe holds more than {MAX_PIPED_BYTES >> 20} MB; give a "
                                      "picture file")
    finally:
        os.close(fd)
    return io.BytesIO(b"".join(chunks))


def open_image(path: str | os.PathLike, where: str | None = None, square: bool = False) -> Image.Image:
    """A picture file, decoded, or a :class:`TargetFileError` in one line naming ``where``
    (default: the path). A picture over :data:`MAX_IMAGE_PIXELS` (a decompression bomb,
    or just too big) is refused from its header, before its pixels are decoded; with
    ``square``, so is one whose padding to a square (a target mask) would be."""
    path = Path(path)
    if _is_special_file(path):  # Pillow would read a device (/dev/zero) for ever
        raise TargetFileError(f"{where + ': ' if where else ''}{cut_text(str(path))} is not a regular file (a device "
                              "or a socket); give a picture file")
    where = where or cut_text(str(path))
    piped = _piped_bytes(path, where)
    source = path if piped is None else piped
    try:
        with warnings.catch_warnings():
            # Pillow warns between its limit and twice it, and raises above: both are refused
            warnings.simplefilter("error", Image.DecompressionBombWarning)
            with Image.open(source) as image:
                if image.width * image.height > MAX_IMAGE_PIXELS:
                    raise _too_big(where, image.width, image.height)
                side = max(image.width, image.height)
                if square and side * side > MAX_IMAGE_PIXELS:
                    raise TargetFileError(
                        f"{where}: the picture is {image.width}x{image.height} pixels; padded to the square frame "
                        f"the models draw in it would be {side}x{side} ({side * side / 1e6:.0f} megapixels, more "
                        f"than the {MAX_IMAGE_PIXELS / 1e6:.0f} procmod reads): crop or scale it down")
                tile = list(image.tile)  # (what load() empties: a 16-bit PNG's is decoded again at full depth)
                image.load()
                return _non_finite_as_clear(_as_shown(image, _full_depth_png(image, tile, source)))
    except (Image.DecompressionBombError, Image.DecompressionBombWarning) as exc:
        # Pillow refuses before we see the size; its message holds the pixel count
        found = re.search(r"\((\d+) pixels\)", str(exc))
        size = f"{int(found.group(1)) / 1e6:.0f} megapixels" if found else "too large"
        raise TargetFileError(f"{where}: the picture is {size}; procmod reads pictures up to "
                              f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels (about 9500x9500): scale it down") from None
    except FileNotFoundError:
        raise TargetFileError(f"{where}: image file {cut_text(str(path))} does not exist") from None
    except IsADirectoryError:
        raise TargetFileError(f"{where}: {cut_text(str(path))} is a folder, not an image file") from None
    except (UnidentifiedImageError, OSError, ValueError, SyntaxError) as exc:
        head = None if piped is None else piped.getvalue()[:512]  # (a pipe is read once)
        if _is_svg(path, head):
            raise TargetFileError(f"{where}: a vector drawing (SVG), which procmod does not read; export it as a "
                                  "PNG (Inkscape: File > Export; a browser's screenshot does too)") from None
        other = _unread_format(path, head)
        if other is not None:
            raise TargetFileError(f"{where}: {other}") from None
        if head == b"":  # (a named pipe nobody wrote to had been waited on for ever)
            raise TargetFileError(f"{where}: a pipe with no picture written to it; give a picture file, or write "
                                  "one to the pipe as procmod reads it") from None
        empty = piped is None and path.is_file() and path.stat().st_size == 0
        if empty:
            raise TargetFileError(f"{where}: an empty file (0 bytes), no picture; save the picture again") from None
        said = str(exc) if piped is None else str(exc).replace(repr(piped), str(path))  # (not "<_io.BytesIO ...>")
        if "truncated" in said.lower():  # a download or copy cut short: its format is fine
            raise TargetFileError(f"{where}: the picture file is cut short ({cut_text(said, 120)}): an "
                                  "interrupted download or copy; copy or save it again") from None
        raise TargetFileError(f"{where}: not an image Pillow can read ({cut_text(said, 120)}); save it as a PNG "
                              "or JPEG") from None


def _first_bytes(path: Path, head: bytes | None, count: int) -> bytes | None:
    """The first ``count`` bytes of ``path``, or of ``head`` where given (a pipe's, read
    already: opened again it would wait for a writer); None where it cannot be read."""
    if head is not None:
        return head[:count]
    try:
        with open(path, "rb") as handle:
            return handle.read(count)
    except OSError:
        return None


def _unread_format(path: Path, head: bytes | None = None) -> str | None:
    """What a file Pillow cannot open is, by its first bytes (``head``, where read
    already), with what to do, for the formats people's pictures arrive in that Pillow does
    not read: an iPhone's HEIC, a PDF; None for others."""
    head = _first_bytes(path, head, 32)
    if head is None:
        return None
    if head[4:8] == b"ftyp" and head[8:12] in (b"heic", b"heix", b"hevc", b"heim", b"heis", b"mif1", b"msf1"):
        return ("an HEIC/HEIF photo (an iPhone's own format), which procmod does not read; convert it to JPEG or PNG "
                "(macOS Preview: File > Export; iPhone: Settings > Camera > Formats > Most Compatible)")
    if head.startswith(b"%PDF"):
        return "a PDF document, which procmod does not read; export the page with the drawing as a PNG"
    return None


def _is_svg(path: Path, head: bytes | None = None) -> bool:
    """Whether ``path`` is an SVG file, by its name or its first bytes (``head``, where
    read already)."""
    if path.suffix.lower() in (".svg", ".svgz"):
        return True
    head = _first_bytes(path, head, 512)
    if head is None:
        return False
    head = head.lstrip(b"\xef\xbb\xbf \t\r\n").lower()
    return head.startswith(b"<svg") or (head.startswith(b"<?xml") and b"<svg" in head)


def _too_big(where: str, width: int, height: int) -> TargetFileError:
    return TargetFileError(f"{where}: the picture is {width}x{height} pixels ({width * height / 1e6:.0f} "
                           f"megapixels); procmod reads pictures up to {MAX_IMAGE_PIXELS / 1e6:.0f} megapixels "
                           "(about 9500x9500): scale it down")


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
    picture : tuple or None
        ``(top, left, height, width)`` of the picture a file held inside the square mask
        it was padded to (:func:`mask_from_image`); None: the whole mask is the picture.
        Only the picture's own edges are edges of the paper (a scanner lid's shadow lies
        along them, not along the padding's).
    notes : tuple
        What reading the picture guessed, one sentence each (:func:`load_target_image`).
    """

    name: str
    mask: np.ndarray = field(repr=False)
    start: tuple = (0.5, 0.9166)
    direction: tuple = (0.0, -1.0)
    picture: tuple | None = field(default=None, repr=False, compare=False)
    # what reading the file guessed (a frame left out, the first of several frames read):
    # said by procmod.targets.placement.picture_note with its own advice
    notes: tuple = field(default=(), repr=False, compare=False)
    # at_size's masks by canvas size: a run resamples one picture several times (scoring,
    # its notes, the report's pictures), and widening thin strokes is not free
    _sized: dict = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self):
        # built from Python as well as read from files: the checks a sidecar and a picture
        # get (a grey picture passed as the mask is refused, not read with its paper as shape)
        mask = np.asarray(self.mask)
        if mask.dtype != bool and mask.size and np.isin(mask, (0, 1)).all():
            mask = mask.astype(bool)  # a 0/1 array is a mask too
        if mask.dtype != bool:
            raise InvalidArgumentError(
                f"TargetImage {cut_text(str(self.name), 60)}: the mask must be a boolean (or 0/1) array, True = shape, "
                f"got {mask.dtype} values other than 0 and 1; for a picture use procmod.targets.load_target_image(path) or mask_from_image(image)")
        object.__setattr__(self, "mask", check_mask(mask, f"TargetImage {cut_text(str(self.name), 60)}"))
        for key, low, high in (("start", 0.0, 1.0), ("direction", -math.inf, math.inf)):
            value = getattr(self, key)
            try:
                pair = tuple(float(v) for v in value)
            except (TypeError, ValueError):
                pair = ()
            if len(pair) != 2 or not all(math.isfinite(v) and low <= v <= high for v in pair):
                raise InvalidArgumentError(f"TargetImage {cut_text(str(self.name), 60)}: {key} must be two finite numbers"
                                           + (" in [0, 1] (normalised image coordinates)" if key == "start" else "")
                                           + f", got {cut_text(repr(value), 60)}")
            object.__setattr__(self, key, pair)
        if self.direction == (0.0, 0.0):
            raise InvalidArgumentError(f"TargetImage {cut_text(str(self.name), 60)}: direction must be a non-zero vector")

    def mirrored(self) -> "TargetImage":
        """The horizontally mirrored target (start and direction mirrored too)."""
        picture = self.picture
        if picture is not None:
            top, left, height, width = picture
            picture = (top, self.mask.shape[1] - left - width, height, width)
        return replace(self, name=f"{self.name}:mirrored", mask=self.mask[:, ::-1].copy(),
                       start=(1.0 - self.start[0], self.start[1]),
                       direction=(-self.direction[0], self.direction[1]), picture=picture)

    def at_size(self, width: int, height: int) -> np.ndarray:
        """The mask resampled to ``height x width`` (area average, then threshold 1/2), its
        thin strokes widened where that would lose more than :data:`THIN_LOSS` of the shape
        (:func:`stroke_preserving_mask`).

        Raises a :class:`TargetFileError` when the shape vanishes at that size (too
        small in its frame): the remedy is the picture, not a render size."""
        small = self._sized.get((width, height))
        if small is None:
            small = self._sized[(width, height)] = stroke_preserving_mask(self.mask, width, height)
        small = small.copy()
        if not small.any() and self.mask.any():
            rows, cols = np.flatnonzero(self.mask.any(axis=1)), np.flatnonzero(self.mask.any(axis=0))
            h, w = self.mask.shape
            raise TargetFileError(
                f"target {cut_text(self.name, 80)}: its shape ({cols[-1] - cols[0] + 1}x{rows[-1] - rows[0] + 1} "
                f"pixels of a {w}x{h} frame; a picture that is not square is padded to a square) vanishes "
                f"when the frame is scaled to the model's {width}x{height} canvas; crop the picture "
                "closer to the shape, or draw the shape thicker")
        return small


def resample_mask(mask: np.ndarray, width: int, height: int) -> np.ndarray:
    """Resample a boolean mask by area averaging and a 1/2 threshold."""
    mask = np.asarray(mask, dtype=bool)
    if mask.shape == (height, width):
        return mask.copy()
    image = Image.fromarray(mask.astype(np.uint8) * 255)
    small = np.asarray(image.resize((width, height), Image.BOX), dtype=np.float64)
    return small >= 127.5


# The share of a shape a plain resampling may lose before its strokes are widened: a pen
# line thinner than half a canvas pixel falls under the 1/2 threshold wherever it does not
# cross a pixel's middle, and the drawing reads as dashes (a 200-pixel drawing in a 2-4
# pixel pen lost 22-60% at the vines' 50 x 50, and SMC, procmod's and WebPPL's alike,
# scored about 0 against the fragments). Shapes drawn thick enough lose their edges'
# slivers only: at most 2% for the glyphs of four typefaces at 100 -> 50 pixels, 6.4% for
# 120 scribbles; those read as before.
THIN_LOSS = 0.15


def lost_share(mask: np.ndarray, small: np.ndarray) -> float:
    """The share of ``mask``'s shape that ``small`` (a resampling of it) does not cover,
    ``small`` scaled back up pixel for pixel."""
    mask = np.asarray(mask, dtype=bool)
    back = np.asarray(Image.fromarray(small.astype(np.uint8) * 255).resize(mask.shape[::-1], Image.NEAREST)) > 0
    return float((mask & ~back).sum()) / max(int(mask.sum()), 1)


def stroke_width(mask: np.ndarray) -> float:
    """A drawing's typical stroke width in pixels: twice its area over its boundary pixels
    (a stroke of width w and length L has area w L and about 2 L boundary pixels; a stroke
    one or two pixels wide is all boundary). A boundary pixel is one with a 4-neighbour
    off the mask or off the picture (``scipy.ndimage.binary_erosion``'s, without
    importing scipy.ndimage: a target's start is read at every ``procmod infer``)."""
    mask = np.asarray(mask, dtype=bool)
    inner = mask.copy()
    inner[1:] &= mask[:-1]
    inner[:-1] &= mask[1:]
    inner[:, 1:] &= mask[:, :-1]
    inner[:, :-1] &= mask[:, 1:]
    inner[[0, -1]] = False
    inner[:, [0, -1]] = False
    boundary = int((mask & ~inner).sum())
    return 2.0 * int(mask.sum()) / max(boundary, 1)


# Strokes typically narrower than this many canvas pixels are thin: one a pixel wide,
# off the pixel grid, half-covers two pixels along its length and falls under the 1/2
# threshold in stretches (a 1-pixel pen line read as dashes, 22-27% lost).
THIN_STROKE = 1.5
# The thin-stroke test and the widening work on the mask reduced (any pixel set) to at
# most this many times the canvas: a 9000-pixel picture's full-size distance transforms
# had taken 37 s and 2.9 GB of a 50-particle run (9.7 s and 1.4 GB without them).
WORK_SCALE = 8


def _working_mask(mask: np.ndarray, width: int, height: int) -> tuple:
    """``(mask, scale)``: the mask reduced by whole factors (a cell is set where any of its
    pixels is, so no stroke is lost) to at most :data:`WORK_SCALE` times the canvas, and
    its pixels per canvas pixel."""
    factor = max(1, int(min(mask.shape[0] / height, mask.shape[1] / width) // WORK_SCALE))
    if factor > 1:
        h, w = -(-mask.shape[0] // factor) * factor, -(-mask.shape[1] // factor) * factor
        padded = np.zeros((h, w), dtype=bool)
        padded[:mask.shape[0], :mask.shape[1]] = mask
        mask = padded.reshape(h // factor, factor, w // factor, factor).any(axis=(1, 3))
    return mask, max(mask.shape[0] / height, mask.shape[1] / width)


def _strokes(thin: np.ndarray, scale: float) -> np.ndarray:
    """The parts of ``thin`` that reach at least a canvas pixel (``scale`` pixels) along
    one axis: strokes, and the pieces of a stroke a scan broke. Smaller ones are dust on the
    page, or bumps on a thick part's outline; widened, each had become a blob of a canvas
    pixel (a review's dust), or a rim (a wobbly fill). Judged by area against the largest
    part, as the start's specks are, a filled shape's long thin rays were cut out."""
    from scipy import ndimage
    labels, count = ndimage.label(thin, structure=np.ones((3, 3), dtype=bool))
    keep = np.zeros(count + 1, dtype=bool)
    for k, box in enumerate(ndimage.find_objects(labels), start=1):
        keep[k] = max(box[0].stop - box[0].start, box[1].stop - box[1].start) >= scale
    return keep[labels]


def _thin_strokes(mask: np.ndarray, width: int, height: int) -> tuple:
    """``(plain, lost, work, scale)``: ``mask`` resampled plainly; the share of its shape
    that resampling loses where its strokes are thin (typically under :data:`THIN_STROKE` canvas
    pixels wide) and that is more than :data:`THIN_LOSS`, else None (a bar 2.5 canvas
    pixels wide, off the pixel grid, loses 20% in edge slivers: it is not thin); and, where
    it is thin, :func:`_working_mask`'s mask and scale."""
    plain = resample_mask(mask, width, height)
    if mask.shape == (height, width) or not mask.any():
        return plain, None, None, None
    lost = lost_share(mask, plain)
    if lost <= THIN_LOSS:
        return plain, None, None, None
    work, scale = _working_mask(mask, width, height)
    if stroke_width(work) >= THIN_STROKE * scale:
        return plain, None, None, None
    return plain, lost, work, scale


def stroke_preserving_mask(mask: np.ndarray, width: int, height: int) -> np.ndarray:
    """:func:`resample_mask`, unless the shape's strokes are thin (typically under
    :data:`THIN_STROKE` canvas pixels wide) and that loses more than :data:`THIN_LOSS` of
    it: then its thin parts (those a disc :data:`THIN_STROKE` canvas pixels across does not
    fit in, :func:`_strokes` of them) are first widened by half a canvas pixel on each
    side, so each stroke reads as a line where it was drawn; the thick parts keep their
    outline (a filled disc with thin rays had grown a rim all round), and nothing is taken
    away. Shapes drawn thick enough read as before, bit for bit."""
    mask = np.asarray(mask, dtype=bool)
    plain, lost, work, scale = _thin_strokes(mask, width, height)
    if lost is None:
        return plain
    from scipy import ndimage
    inside = ndimage.distance_transform_edt(work)  # each shape pixel's distance to the ground
    core = inside > 0.5 * THIN_STROKE * scale
    thick = ndimage.distance_transform_edt(~core) <= 0.5 * THIN_STROKE * scale  # an opening
    thin = _strokes(work & ~thick, scale)
    widened = work | (ndimage.distance_transform_edt(~thin) <= 0.5 * scale)
    return resample_mask(widened, width, height)


def widened_share(mask: np.ndarray, width: int, height: int) -> float | None:
    """The share of ``mask``'s shape a plain resampling to ``height x width`` would lose,
    where :func:`stroke_preserving_mask` widens it instead (None where it does not)."""
    return _thin_strokes(np.asarray(mask, dtype=bool), width, height)[1]


def lowest_point_start(mask: np.ndarray, reach: float = 0.2, along_shape: bool = True,
                       branches: bool = True) -> tuple:
    """Start at the lowest foreground pixel, heading along the shape.

    The start is the median foreground column of the lowest row: the middle of its run
    when the row has one (a row across two serif feet gives an inner edge of one).

    Parts of the mask under :data:`SPECK_SHARE` of its largest 8-connected part are
    left out: specks of noise, not the shape. The start lies on a part of at least
    :data:`START_SHARE` of the largest (a signature under a drawing is none).

    The direction points from the start to the centroid of the foreground within
    ``reach`` (a fraction of the image size) of it, so a model starting at the bottom of
    a "c" grows along the curve rather than straight up into the empty middle (falling
    back to straight up) -- unless a ray that way leaves the shape early: at the bottom
    of a "b" whose bowl is a thin stroke, the nearby foreground's centroid lies across
    the bowl's hollow. When the ray that way runs through the shape less than half as
    far as the longest ray from the start (up to ``reach``), the direction is, of those
    whose ray runs at least 80% as far as the longest, the one closest to the
    centroid's (see :func:`ray_runs`). ``along_shape=False`` keeps the centroid's
    direction always (the rule before; bench/start_directions.py compares the two).
    """
    from .components import without_specks  # numba: imported where a start is derived

    mask = without_specks(mask, SPECK_SHARE)  # a stray pixel below the shape is no start
    # the start lies on a piece of the drawing's size: a signature or a scrap under it (a
    # few percent of its pixels, more than a speck) had taken the start, and the vine grew
    # on the signature (h151); a word's letters, an "i"'s stem, stay starts
    starts = without_specks(mask, START_SHARE)
    rows = np.flatnonzero(starts.any(axis=1))
    row = rows[-1]
    cols = np.flatnonzero(starts[row])
    col = cols[len(cols) // 2]
    h, w = mask.shape
    ys, xs = np.nonzero(mask)
    near = (xs - col) ** 2 + (ys - row) ** 2 <= (reach * max(h, w)) ** 2
    dx, dy = xs[near].mean() - col, ys[near].mean() - row
    norm = float(np.hypot(dx, dy))
    if norm > 1e-9:
        toward, direction = math.atan2(dy, dx), (float(dx / norm), float(dy / norm))
    else:
        toward, direction = -0.5 * math.pi, (0.0, -1.0)
    # candidates every 5 degrees, the centroid's direction first (offset 0)
    offsets = np.radians(np.concatenate([np.arange(0, 185, 5), -np.arange(5, 180, 5)]))
    runs = ray_runs(mask, col + 0.5, row + 0.5, toward + offsets, reach * max(h, w))
    if along_shape and runs[0] < EARLY_EXIT * runs.max():  # the centroid's way leaves the shape early
        chosen = np.flatnonzero(runs >= RUN_SHARE * runs.max())
        # the closest to the centroid's; of two as close, the one that runs further
        angle = toward + offsets[chosen[np.lexsort((-runs[chosen], np.abs(offsets[chosen])))[0]]]
        direction = (math.cos(angle), math.sin(angle))
    if along_shape and branches:
        direction = _larger_branch(mask, col, row, direction)
    return ((col + 0.5) / w, (row + 0.5) / h), direction


BRANCH_DOMINANCE = 2.0
"""How many times the shape beyond the start's other branch must outweigh (in pixels) the
branch the start heads into for the start to turn to it (:func:`_larger_branch`)."""

BRANCH_SIDE = 1024  # the largest side _larger_branch reads a mask at (pixels; a 6000-pixel one took 0.3 s more)
ONE_PIECE = 0.8  # the least share of the shape the start's piece holds for it to turn (an "i"'s dot aside)


def _larger_branch(mask: np.ndarray, col: int, row: int, direction: tuple) -> tuple:
    """``direction``, or the way into the larger part of the shape where the start lies in
    the middle of a stroke whose two sides differ: at the bottom of an "S" both ways run
    along the stroke, and the centroid's rule took the short tail (a helper's S: 0.03 of
    similarity against 0.68 the other way, both systems alike). The shape less a disc
    about the start (three stroke widths, at most a tenth of the picture) falls into
    branches; the ring just outside the disc holds each branch's entrances. When the way
    ``direction`` enters is one branch and another is :data:`BRANCH_DOMINANCE` times its
    size, the start heads to that one's entrance (of several, the closest in angle). A
    filled shape, a ring (one branch, two entrances) and a stroke starting at its end
    keep ``direction``, and so does a start on one of several pieces (a word's letters:
    the rest of the word may lie past the short side, h107's "Quizzes" 0.36 -> 0.07).
    Read on the mask reduced to at most :data:`BRANCH_SIDE` pixels a side."""
    from .components import labels as parts  # numba: no scipy.ndimage to import at every start

    h, w = mask.shape
    factor = math.ceil(max(h, w) / BRANCH_SIDE)
    if factor > 1:  # a pixel of the reduced mask is set where any of its block is
        padded = np.zeros((math.ceil(h / factor) * factor, math.ceil(w / factor) * factor), dtype=bool)
        padded[:h, :w] = mask
        mask = padded.reshape(padded.shape[0] // factor, factor, padded.shape[1] // factor, factor).any(axis=(1, 3))
        col, row, h, w = col // factor, row // factor, mask.shape[0], mask.shape[1]
    pieces, _ = parts(mask)
    piece_sizes = np.bincount(pieces.ravel())
    if not pieces[row, col] or piece_sizes[pieces[row, col]] < ONE_PIECE * piece_sizes[1:].sum():
        return direction
    radius = min(max(3.0, 3.0 * stroke_width(mask)), 0.1 * max(h, w))
    top, bottom = max(0, int(row - 2 * radius) - 1), min(h, int(row + 2 * radius) + 2)
    left, right = max(0, int(col - 2 * radius) - 1), min(w, int(col + 2 * radius) + 2)
    yy, xx = np.mgrid[top:bottom, left:right]
    near = np.hypot(yy + 0.5 - (row + 0.5), xx + 0.5 - (col + 0.5))
    beyond = mask.copy()
    beyond[top:bottom, left:right] &= near >= radius
    branches, count = parts(beyond)
    if count < 2:
        return direction
    # the ring's pieces that the start's own stroke runs into (within the outer circle): a
    # spiral's inner turn crossing the ring is no way out of the start
    around = mask[top:bottom, left:right] & (near < 2 * radius)
    stroke = parts(around)[0]
    own = stroke[row - top, col - left]
    ring = around & (near >= radius) & (stroke == own) if own else np.zeros_like(around)
    entrances, n = parts(ring)
    if n < 2:
        return direction
    sizes = np.bincount(branches.ravel(), minlength=count + 1)
    local = branches[top:bottom, left:right]
    doors = []  # (branch, its size, the entrance's direction)
    for k in range(1, n + 1):
        at = entrances == k
        branch = int(np.bincount(local[at]).argmax())
        dy, dx = float(yy[at].mean() + 0.5 - (row + 0.5)), float(xx[at].mean() + 0.5 - (col + 0.5))
        norm = math.hypot(dx, dy)
        if branch and norm > 0:
            doors.append((branch, int(sizes[branch]), (dx / norm, dy / norm)))
    if len({branch for branch, _, _ in doors}) < 2:
        return direction
    # the branch the current direction enters: the entrance closest to it in angle
    heading = max(doors, key=lambda door: door[2][0] * direction[0] + door[2][1] * direction[1])
    largest = max(size for _, size, _ in doors)
    if heading[1] * BRANCH_DOMINANCE > largest:
        return direction
    best = max((door for door in doors if door[1] == largest),
               key=lambda door: door[2][0] * direction[0] + door[2][1] * direction[1])
    # the line to the entrance's middle may cut across a hollow (a wide ring over a word's
    # letters, h107: "Quizzes" 0.36 -> 0.07): of the ways within 45 degrees of it, the
    # closest whose ray stays in the shape RUN_SHARE as far as the longest there; and none
    # that leaves the shape sooner than EARLY_EXIT of the way ``direction`` runs
    toward = math.atan2(best[2][1], best[2][0])
    offsets = np.radians(np.concatenate([np.arange(0, 50, 5), -np.arange(5, 50, 5)]))
    reach = 4 * radius
    runs = ray_runs(mask, col + 0.5, row + 0.5, toward + offsets, reach)
    kept = ray_runs(mask, col + 0.5, row + 0.5, np.array([math.atan2(direction[1], direction[0])]), reach)[0]
    chosen = np.flatnonzero(runs >= RUN_SHARE * runs.max())
    pick = chosen[np.argmin(np.abs(offsets[chosen]))]
    if runs[pick] < EARLY_EXIT * kept:
        return direction
    return (math.cos(toward + offsets[pick]), math.sin(toward + offsets[pick]))


# Parts this much smaller than the largest are noise (dust on a scan, a stray pixel);
# the dot of an "i" is about a tenth of its stem.
SPECK_SHARE = 0.02
# Parts under this share of the largest are no start (a signature, a scrap under the
# drawing); a word's letters and an "i"'s stem (about half of an "m") are over it.
START_SHARE = 0.25
# The centroid's direction is kept unless its ray runs under EARLY_EXIT of the longest;
# then a direction "stays in the shape" when its ray runs RUN_SHARE of the longest.
EARLY_EXIT = 0.5
RUN_SHARE = 0.8


def ray_runs(mask: np.ndarray, x: float, y: float, angles: np.ndarray, length: float) -> np.ndarray:
    """How far (pixels, up to ``length``) a ray from (x, y) (pixel units, y down) at each
    angle runs through the foreground before leaving it or the image.

    The ray is sampled every half pixel, a quarter pixel off the centres, so that no
    sample falls on a pixel's edge (where rounding would favour two of the four
    directions); a run ends midway between its last sample inside and the first of two
    outside in a row: a gap of one sample is crossed, so that a stroke's ragged edge does
    not end a run along it.
    """
    count = max(int(round(2 * length)), 1)
    steps = (np.arange(count) + 0.5) * 0.5
    px = np.floor(x + np.cos(angles)[:, None] * steps).astype(np.int64)
    py = np.floor(y + np.sin(angles)[:, None] * steps).astype(np.int64)
    h, w = mask.shape
    inside = (px >= 0) & (px < w) & (py >= 0) & (py < h)
    inside[inside] = mask[py[inside], px[inside]]
    outside = ~inside
    ends = outside.copy()
    ends[:, :-1] &= outside[:, 1:]  # two samples out in a row
    first = np.where(ends.any(axis=1), ends.argmax(axis=1), count)
    return np.minimum(first * 0.5, length)


def check_mask(mask: np.ndarray, name: str) -> np.ndarray:
    """Reject masks a shape target cannot use: empty, or filling the whole frame."""
    mask = np.asarray(mask, dtype=bool)
    if mask.ndim != 2 or mask.size == 0:
        raise TargetFileError(f"{name}: a target mask must be a 2D image")
    if not mask.any():
        raise TargetFileError(f"{name}: the target mask is empty (no foreground pixels: in a picture, no pixel "
                              f"differs from the border's colour by {MIN_CONTRAST:.0f} of 255 grey levels or more, "
                              "as faint pencil may not); draw the shape darker, or in a colour further from the "
                              "paper's")
    if mask.all():
        raise TargetFileError(f"{name}: the target mask fills the whole frame; "
                              "leave some background around the shape")
    return mask


_EXIF_ORIENTATION = 0x0112
# EXIF orientation -> the turn that shows the stored pixels as the camera saw them
_TURNS = {2: (Image.Transpose.FLIP_LEFT_RIGHT,), 3: (Image.Transpose.ROTATE_180,),
          4: (Image.Transpose.FLIP_TOP_BOTTOM,), 5: (Image.Transpose.TRANSPOSE,),
          6: (Image.Transpose.ROTATE_270,), 7: (Image.Transpose.TRANSVERSE,), 8: (Image.Transpose.ROTATE_90,)}


def _as_shown(image: Image.Image, pixels: Image.Image | None = None) -> Image.Image:
    """A copy of a decoded picture (or of ``pixels`` decoded from it another way) turned the
    way its EXIF orientation says it is shown (a phone photo stores its pixels sideways): the
    mask must be what the user sees. Only the pixels are turned (Pillow's exif_transpose also
    rewrites the EXIF, and fails on tags it cannot write back); an unreadable orientation
    leaves the picture as stored."""
    try:
        orientation = image.getexif().get(_EXIF_ORIENTATION, 1)
    except Exception:  # noqa: BLE001 -- a malformed EXIF block: keep the stored pixels
        orientation = 1
    turns = _TURNS.get(orientation, ()) if isinstance(orientation, int) else ()
    out = (image if pixels is None else pixels).copy()
    for turn in turns:
        out = out.transpose(turn)
    white = _white_level(image)
    if white is not None:
        out.info[WHITE_LEVEL] = white
    # a JPEG's MP Format images after the first (a phone's preview or HDR gain map, a stereo
    # camera's other eye) are no pages of their own: every such photo had got the note to
    # save the frame with the drawing on its own
    out.info[FRAMES] = 1 if image.format == "MPO" else int(getattr(image, "n_frames", 1) or 1)
    return out


# Pillow's raw modes for a 16-bit colour PNG, which it decodes to 8 bits a channel, each
# channel's high byte; and the raw mode that decodes the same rows to each channel's low byte
# (Pillow's unpacker of little-endian samples takes the odd bytes), or None where one decode
# into RGBA's four bytes a pixel holds both bytes of grey and alpha
_LOW_BYTES = {"RGB;16B": "RGB;16L", "RGBA;16B": "RGBA;16L", "LA;16B": None}


def _full_depth_png(image: Image.Image, tile: list, source) -> Image.Image | None:
    """A 16-bit colour PNG (RGB, RGBA, grey with alpha) whose values use only 10, 12 or 14
    bits (a scanner's or camera's, stored in 16), as 8 bits a channel scaled from that depth's
    white; None for other pictures. Pillow keeps each channel's high byte only, 0..15 of a
    12-bit scan, and the drawing read near black (refused as empty). Decoded again by
    Pillow's own PNG decoder (its filters and interlacing) with the raw mode that keeps the
    low bytes. The white is chosen as :func:`_white_level` chooses a 16-bit grey PNG's; a
    picture that uses all 16 bits (or one whose values are all under 256, as dark in 16 bits
    as a grey one reads) is left as Pillow read it: its high bytes are its 8 bits."""
    if image.format != "PNG" or len(tile) != 1 or tile[0].args not in _LOW_BYTES or image.mode not in ("RGB", "RGBA"):
        return None
    high = np.asarray(image)
    colour = high[:, :, :1] if tile[0].args == "LA;16B" else high[:, :, :3]
    if not colour.size or not 0 < int(colour.max()) < 64:  # (values of 256..16383: 9 to 14 bits)
        return None
    try:
        if hasattr(source, "seek"):
            source.seek(0)
        with Image.open(source) as again:
            low_mode = _LOW_BYTES[tile[0].args]
            again.tile = [tile[0]._replace(args=low_mode or "RGBA")]
            again.load()
            low = np.asarray(again)
    except (OSError, ValueError, SyntaxError):  # (read once already: keep what Pillow read then)
        return None
    if low_mode is None:  # RGBA's four bytes: grey's high and low byte, alpha's high and low byte
        pairs = low.reshape(low.shape[0], low.shape[1], 2, 2).astype(np.uint16)
        values = pairs[:, :, :, 0] << 8 | pairs[:, :, :, 1]
    else:
        values = high.astype(np.uint16) << 8 | low
    channels = values.shape[2] - (image.mode == "RGBA")
    white = _depth_white(int(values[:, :, :channels].max()))

    def eight_bits(samples: np.ndarray, top: int) -> np.ndarray:  # (a table: a 48-megapixel scan in floats took GBs)
        table = np.clip(np.round(np.arange(65536) * (255.0 / top)), 0, 255).astype(np.uint8)
        return table[samples]

    out = eight_bits(values[:, :, :channels], white)
    if channels == 1:
        out = np.repeat(out, 3, axis=2)
    alpha = None
    if image.mode == "RGBA":
        alpha = values[:, :, -1]
        alpha = eight_bits(alpha, white if int(alpha.max()) <= white else 65535)
    clear = image.info.get("transparency")
    if alpha is None and isinstance(clear, tuple) and len(clear) == 3:
        # tRNS's colour, in 16 bits as the pixels are: see-through where a pixel has it
        alpha = np.where((values == np.array(clear, dtype=np.uint16)).all(axis=2), 0, 255).astype(np.uint8)
    if alpha is not None:
        out = np.concatenate([out, alpha[:, :, None]], axis=2)
    pixels = Image.fromarray(out, "RGB" if alpha is None else "RGBA")
    pixels.info.update({key: value for key, value in image.info.items() if key != "transparency"})
    return pixels


def _non_finite_as_clear(image: Image.Image) -> Image.Image:
    """A real-valued picture some of whose pixels are NaN or infinite (a render's or a
    scientific export's background, a depth map's misses) as a grey picture with alpha
    (:func:`grey_levels`'s greys, rounded), those pixels see-through: they are no part of the
    picture, as a transparent ground is none (NaN had read black and infinity as its white,
    and the drawing was lost against them or refused as empty). Others, and one with no
    finite pixel (it shows nothing, and is refused as such), are returned as they are."""
    if image.mode != "F":
        return image
    finite = np.isfinite(np.asarray(image))
    if finite.all() or not finite.any():
        return image
    grey = np.where(finite, np.round(grey_levels(image)), 255.0).astype(np.uint8)
    clear = Image.fromarray(np.stack([grey, np.where(finite, 255, 0).astype(np.uint8)], axis=2), "LA")
    clear.info.update(image.info)
    return clear


FRAMES = "procmod_frames"
"""The key in a decoded picture's ``info`` of how many frames or pages its file holds
(an animated GIF, a multi-page TIFF): procmod reads the first."""


WHITE_LEVEL = "procmod_white_level"
"""The key in a decoded picture's ``info`` of the integer value that is white, where the file
says it (:func:`_white_level`); :func:`grey_levels` scales by it."""


WHITE_SLACK = 0.1
"""A real-valued picture (or an integer one whose file declares no white) whose values go up
to this share past a depth's white (255.5 or 256 after a resample's or a filter's overshoot,
1.004 of a 0..1 render's paper) is read against that white: the next depth's (1023, or 255
for 0..1) had read its paper as dark grey, its pencil as too faint to be a drawing."""


def _depth_white(top: float, slack: float = 0.0) -> int:
    """The white of a 16-bit sample whose largest value is ``top``: that of the 10, 12 or 14
    bits its values use, where they use no more and some exceed 255 (a scanner's or camera's
    12 bits stored in 16: read as 16 bits, the drawing was near black and refused as empty);
    else 65535 (a 16-bit picture every value of which is under 256 is a dark one). With
    ``slack`` (:data:`WHITE_SLACK`, for values that are no integers of a stated depth) a
    ``top`` up to that share past a white is read against it."""
    return next((2 ** bits - 1 for bits in (10, 12, 14) if 255 < top <= (2 ** bits - 1) * (1 + slack)), 65535)


def _white_level(image: Image.Image) -> int | None:
    """The value of white in a 16- or 32-bit integer picture, from what its file declares:
    Pillow decodes 16-bit PGM/PPM (any maxval above 255, rescaled to 65535) and, in some
    versions, 16-bit PNG to "I"; an unsigned TIFF of up to 16 bits states its bits per
    sample (a 32-bit one's range is guessed from its values, as where nothing is declared).
    A 16-bit PNG's or TIFF's white is that of the 10, 12 or 14 bits its values use, where
    they use no more (:func:`_depth_white`). Without it a dark 16-bit picture (every value
    under 256) would pass for an 8-bit one and read bright."""
    sixteen = image.mode.startswith("I;16")
    if image.format == "PNG" and (image.mode == "I" or sixteen):
        top = int(np.asarray(image).max()) if image.width and image.height else 0
        return _depth_white(top)
    if image.format == "TIFF" and sixteen:  # Pillow's mode for an unsigned 16-bit TIFF: as a 16-bit PNG
        return _depth_white(int(np.asarray(image).max()) if image.width and image.height else 0)
    if image.mode != "I":
        return None
    if image.format == "PPM":
        return 65535
    if image.format == "TIFF":  # unsigned integers of up to 16 bits only: Pillow writes its
        # own "I" pictures as signed 32-bit TIFF, whatever range their values use
        tags = getattr(image, "tag_v2", {})
        bits, sample_format = tags.get(258), tags.get(339, 1)
        bits = bits[0] if isinstance(bits, tuple) and bits else bits
        sample_format = sample_format[0] if isinstance(sample_format, tuple) and sample_format else sample_format
        if isinstance(bits, int) and 8 < bits <= 16 and sample_format == 1:
            if bits == 16:
                return _depth_white(int(np.asarray(image).max()) if image.width and image.height else 0)
            return 2 ** bits - 1
    return None


OVERSHOOT = 0.01
OVERSHOOT_TOP = 16.0
"""A real-valued picture with at most :data:`OVERSHOOT` of its pixels above 1, and none above
:data:`OVERSHOOT_TOP`, is read as 0..1, those pixels as white (:func:`grey_levels`): a render's
highlights, up to 4 stops over white (a specular glint at 2.5 had made the rest black). One
with values past 16 is a 0..255 picture, however few its bright pixels (a thin light drawing,
under 1% of a dark ground of 0..1 noise); between, a 0..255 picture's drawing would be all but
black."""


def grey_levels(image: Image.Image) -> np.ndarray:
    """The brightness of a picture, 0 (black) to 255 (white), as floats, whatever its bit
    depth: 16-bit and 32-bit integer pictures are scaled from the white level their file
    declares (:data:`WHITE_LEVEL`) or, where it does not, from their range (the white of the
    10, 12, 14 or 16 bits their values use, :func:`_depth_white`, or their own maximum above
    65535; under 256, taken as 8-bit values), and real-valued ones so too, or from 0..1 when
    they lie in it, all but a few highlights (:data:`OVERSHOOT`). (Pillow's ``convert("L")``
    clips such pictures at 255 instead, so every grey above 255 became white.) A grey
    picture of whole numbers 0 and 1 only is a label mask: its 1s, the shape, read as black
    on white (a silhouette view's dark pixels are its hits)."""
    if image.mode not in ("L", "I", "F") and not image.mode.startswith("I;16"):
        return np.asarray(image.convert("L"), dtype=np.float64)
    values = np.asarray(image, dtype=np.float64)
    if image.mode != "F" and values.size and values.min() == 0 and values.max() == 1:
        # whole numbers 0 and 1 only: a label mask (a segmentation's, numpy's bool array
        # saved as is), 1 the shape; read as 0 and 1 of 255 it was refused as empty ("draw
        # darker"), or, as a silhouette view, all to hit
        return 255.0 - values * 255.0
    if image.mode == "L":
        return values
    finite = values[np.isfinite(values)]
    top = float(finite.max()) if finite.size else 0.0
    declared = image.info.get(WHITE_LEVEL)
    if isinstance(declared, int) and declared > 0:
        scale = 255.0 / declared
    elif image.mode.startswith("I;16"):
        scale = 255.0 / 65535.0
    elif image.mode == "F" and (top <= 1.0 + WHITE_SLACK or (
            top <= OVERSHOOT_TOP and float(np.mean(finite > 1.0)) <= OVERSHOOT)):
        # a 0..1 picture with a few highlights past 1 (a float render's or HDR export's
        # overshoot), or all of its paper a little past 1, is still a 0..1 picture: one pixel
        # at 1.02 had made the rest black and the mask empty ("draw the shape darker")
        scale = 255.0
    elif top <= 255.0 * (1 + WHITE_SLACK):
        scale = 1.0  # (a 0..255 picture resampled: its paper at 255.5 or 256 had read against 1023)
    else:
        # no white declared (a real-valued or 32-bit integer TIFF): that of the 10, 12, 14 or
        # 16 bits its values use, as a 16-bit PNG's; past 16 bits, its own maximum. Scaled
        # from 65535 always, a picture of 0..1000 (a scientific camera's, a float export's)
        # had read as black, its drawing refused as empty
        scale = 255.0 / (_depth_white(top, WHITE_SLACK) if top <= 65535.0 * (1 + WHITE_SLACK) else top)
    # an infinite pixel as the white level or black (nan_to_num's 1.8e308 overflowed the scaling)
    return np.clip(np.nan_to_num(values, nan=0.0, posinf=top, neginf=0.0) * scale, 0.0, 255.0)


INK_PERCENTILE = 0.1
"""The ink's colour is read at this percentile from the far end of all pixels' (robust to a
few stray pixels); where nothing that far differs enough from the paper, from the picture's
own extreme (a drawing smaller than this share of the picture)."""

NOISE_MARGIN = 6.0
"""Ink must differ from the paper by this many times the paper's pixel noise (from the
differences between neighbouring border pixels, :func:`_noise`) as well as by
:data:`MIN_CONTRAST`: a noisy blank page has no shape."""

_PERCENTILE_SAMPLES = 1_000_000  # percentiles are read from at most this many pixels

MIN_CONTRAST = 24.0
"""Grey levels (of 255) ink must differ from the paper by for a picture to hold a shape:
below it the differences are paper texture, sensor noise or JPEG artefacts."""

_LUMA = np.array([0.299, 0.587, 0.114])  # ITU-R 601, as Pillow's convert("L")


def opaque_part(image: Image.Image) -> np.ndarray | None:
    """Where a picture with real transparency is opaque (a layer at partial opacity is
    opaque where it is most), or None for a picture without any."""
    if image.mode not in ("RGBA", "LA", "PA") and "transparency" not in image.info:
        return None
    alpha = np.asarray(image.convert("RGBA"))[:, :, 3].astype(np.float64)
    if alpha.min() >= 0.5 * alpha.max():  # an alpha channel, but nothing see-through
        return None
    return alpha >= 0.5 * alpha.max()


TRANSLUCENT_NOTE = 0.1  # translucent strokes left out, as a share of the shape, that get a note
FAINT_LAYER = 0.9  # faint pixels over this share of what is not opaque are a faint layer over the canvas
FRINGE = 0.05  # how far (of the picture's larger side, at least 8 px) a soft edge, shadow or glow reaches


def translucent_left_out(image: Image.Image) -> float:
    """How much of a transparent picture's drawing :func:`opaque_part` leaves out, as a
    share of what it keeps: pixels under half the strongest opacity (but not nearly clear)
    farther from the opaque part than :data:`FRINGE`, which a soft brush's edge, a drop
    shadow or a glow is not (h68: those had the note, which told the user to export them
    opaque, into the shape). A brush whose opacity follows the pen's pressure (Procreate,
    Krita) draws so, and the light end of a stroke was lost without a word."""
    opaque = opaque_part(image)
    if opaque is None or not opaque.any():
        return 0.0
    alpha = np.asarray(image.convert("RGBA"))[:, :, 3].astype(np.float64)
    floor = 0.05 * alpha.max()
    faint = (alpha > floor) & ~opaque
    if faint.any() and faint.sum() >= FAINT_LAYER * (~opaque).sum():
        # faint nearly everywhere off the drawing: a faint layer over the canvas, which is no
        # strokes (its note had called it 3435% of the shape); strokes are what is more opaque
        # than it, as a pressure brush's over it are (h157)
        faint &= alpha > np.median(alpha[faint]) + floor
    if not faint.any():
        return 0.0
    from scipy import ndimage  # after the cheap checks: importing it costs ~0.13 s of start-up

    reach = max(8.0, FRINGE * max(opaque.shape))
    far = faint & (ndimage.distance_transform_edt(~opaque) > reach)
    return float(far.sum()) / float(opaque.sum())


def _fully_transparent(image: Image.Image) -> bool:
    """Whether every pixel of a picture with transparency is see-through."""
    if image.mode not in ("RGBA", "LA", "PA") and "transparency" not in image.info:
        return False
    if image.mode in ("I", "F") or image.mode.startswith("I;16"):
        # Pillow's RGBA of a 16-bit grey with a transparent value is clear everywhere, whatever
        # its pixels (h92): see-through are the pixels of that value
        clear = image.info["transparency"]
        return isinstance(clear, (int, float)) and bool((np.asarray(image) == clear).all())
    return not np.asarray(image.convert("RGBA"))[:, :, 3].any()


def _luma(colours: np.ndarray) -> np.ndarray:
    """The brightness of :func:`_colours`'s pixels, or of one colour (its last axis)."""
    if colours.shape[-1] == 1:
        return colours[..., 0]
    return colours @ (_LUMA if colours.ndim == 1 else _LUMA.astype(colours.dtype))  # one colour: in float64


def _colours(image: Image.Image) -> np.ndarray:
    """The picture as floats 0..255, ``(height, width, channels)``: one channel for grey
    pictures (of any bit depth, :func:`grey_levels`), three for everything else."""
    if image.mode in ("1", "L", "I", "F") or image.mode.startswith("I;16"):
        return grey_levels(image).astype(np.float32)[:, :, None]
    return np.asarray(image.convert("RGB"), dtype=np.float32)


def _far(values: np.ndarray, q: float) -> float:
    """The ``q`` percentile of ``values``, read from an even sample of at most
    :data:`_PERCENTILE_SAMPLES` of them (a 36-megapixel photo took seconds sorted whole)."""
    flat = values.ravel()
    return float(np.percentile(flat[::max(1, flat.size // _PERCENTILE_SAMPLES)], q))


def _beyond_half(values: np.ndarray, paper: float, seen: np.ndarray, noise: float,
                 light_paper: bool = True) -> np.ndarray | None:
    """Pixels past half way from ``paper`` to the far end of ``seen`` (the values looked
    at), on the side of the paper where that far end lies: ink darker than the paper, or
    lighter. Where both ends lie about as far (a white page on a mid-grey table, chalk on
    a board with dark smudges), the ink is dark on ``light_paper`` and light otherwise, as
    people draw. None when no pixel differs from the paper by :data:`MIN_CONTRAST` and
    :data:`NOISE_MARGIN` times the paper's ``noise``."""
    least = max(MIN_CONTRAST, NOISE_MARGIN * noise)
    dark = paper - _far(seen, INK_PERCENTILE)
    light = _far(seen, 100 - INK_PERCENTILE) - paper
    if max(dark, light) < least:  # a drawing too small for the percentile: its own extreme,
        # twice as far out, since half way to one stray pixel would let the noise through
        dark, light = paper - float(seen.min()), float(seen.max()) - paper
        if max(dark, light) < 2 * least:
            return None
    if min(dark, light) >= max(least, 0.8 * max(dark, light)):
        use_dark = light_paper
    else:
        use_dark = dark >= light
    return values < paper - 0.5 * dark if use_dark else values > paper + 0.5 * light


def _noise(values: np.ndarray, at: np.ndarray) -> float:
    """The pixel noise of ``values`` where ``at`` (paper): the robust spread of the
    differences between neighbours both in ``at``, which a smooth fall of light or a long
    run of ink (a shape reaching the border) hardly changes, over sqrt 2."""
    h, w = values.shape
    # along at most ~256 rows and columns, the first and last always (the border)
    rows = np.unique(np.append(np.arange(0, h, max(1, h // 256)), h - 1))
    cols = np.unique(np.append(np.arange(0, w, max(1, w // 256)), w - 1))
    across = values[rows], at[rows]
    down = values[:, cols].T, at[:, cols].T
    steps = np.concatenate([np.abs(np.diff(v, axis=1))[a[:, 1:] & a[:, :-1]] for v, a in (across, down)])
    if steps.size < 16:  # a picture too small to have paper apart from its ink
        return 0.0
    middle = float(np.median(steps))
    if np.array_equal(steps, np.round(steps)):
        # whole grey levels: the median of the grouped data (interpolated within its level),
        # or the estimate, and the 6x margin with it, would move in steps of a whole level
        below, level = int((steps < middle).sum()), int((steps == middle).sum())
        if level:
            low = max(middle - 0.5, 0.0)
            middle = low + (middle + 0.5 - low) * (0.5 * steps.size - below) / level
    return 1.4826 * middle / math.sqrt(2)


def _lighting(luma: np.ndarray) -> np.ndarray | None:
    """The paper's brightness across the picture when it falls off evenly (a photo lit from
    one side): a plane fitted to the border's brightness, outliers (ink reaching the
    border) dropped. None -- the paper is one brightness -- unless the plane fits the paper
    it kept closely (its pixels within a few grey levels), kept three quarters of each
    side of the border, and changes by more than :data:`MIN_CONTRAST` over the picture; a
    shape trimmed to its edges, a vignette or an even page all give None."""
    h, w = luma.shape
    if h < 8 or w < 8:
        return None
    rows = np.concatenate([np.zeros(w), np.full(w, h - 1), np.arange(h), np.arange(h)])
    cols = np.concatenate([np.arange(w), np.arange(w), np.zeros(h), np.full(h, w - 1)])
    values = luma[rows.astype(int), cols.astype(int)]
    design = np.column_stack([np.ones_like(rows), cols / w, rows / h])
    keep = np.ones(len(values), dtype=bool)
    for _ in range(4):
        coef = np.linalg.lstsq(design[keep], values[keep], rcond=None)[0]
        residual = values - design @ coef
        spread = 1.4826 * float(np.median(np.abs(residual[keep])))
        keep = np.abs(residual) <= max(3 * spread, 4.0)
    sides = np.split(keep, [w, 2 * w, 2 * w + h])  # top, bottom, left, right
    # every side mostly paper the plane explains: a shape reaching one side (a skyline on
    # the bottom edge) is not a fall of light, though a plane can run through it and the top
    if min(side.mean() for side in sides) < 0.75 or spread > 4.0 or (abs(coef[1]) + abs(coef[2])) < MIN_CONTRAST:
        return None
    across = (coef[1] * np.arange(w) / w).astype(np.float32)
    down = (coef[0] + coef[2] * np.arange(h) / h).astype(np.float32)
    return down[:, None] + across[None, :]


_VIGNETTE_CELLS = 64  # :func:`_vignette` fits the means of cells of a grid of at most this many a side
VIGNETTE_DEEPEST = 0.25  # the darkest a vignette leaves the paper, of its brightest


def _vignette(luma: np.ndarray) -> np.ndarray | None:
    """The paper's brightness across a photo whose light falls off towards its corners (a
    phone's vignetting), where no plane explains it (:func:`_lighting`): a radial surface,
    ``a + b x + c y + d r^2 + e r^4`` (r from the picture's middle, x in units of its half
    width, y of its half height; the plane terms move the centre a cropped photo's fall-off
    has), fitted to the
    picture's cells (:data:`_VIGNETTE_CELLS` a side) with the ink dropped as outliers.
    Corners darkened to the pencil's grey had been read as shape, or, darker, as the only
    shape (the drawing lost). Radial only: a surface of any shape (degree 4 in x and y) had
    bent through a light shape along a side (a shaded hill, a sea) and read it as light
    (h157). None -- the paper is one brightness -- unless the surface darkens outwards,
    fits the cells it kept closely (within a few grey levels), kept half the cells and three
    quarters of each side of the border, and changes by more than :data:`MIN_CONTRAST` over
    the picture and by half the ink's difference from it (less did not mislead the read): a
    clean scan, a page on a desk, a shape filling a side, dark ink on a page a little darker
    at its corners, all give None."""
    h, w = luma.shape
    step = max(1, math.ceil(max(h, w) / _VIGNETTE_CELLS))
    down, across = h // step, w // step
    if down < 8 or across < 8:
        return None
    cells = luma[:down * step, :across * step].reshape(down, step, across, step).mean(axis=(1, 3), dtype=np.float64)
    # r from the middle in units of the half width across and the half height down: a
    # fall-off elliptical as the frame (as photo apps' vignettes are), circular on a square

    def terms(ys: np.ndarray, xs: np.ndarray) -> list:  # the surface's terms on a grid, rows ys, columns xs
        r2 = ys[:, None] ** 2 + xs[None, :] ** 2
        return [np.ones_like(r2), np.broadcast_to(xs[None, :], r2.shape), np.broadcast_to(ys[:, None], r2.shape),
                r2, r2 * r2]

    ys = ((np.arange(down) + 0.5) * step - h / 2) / (h / 2)  # cell centres
    xs = ((np.arange(across) + 0.5) * step - w / 2) / (w / 2)
    design = np.stack([t.ravel() for t in terms(ys, xs)], axis=1)
    values = cells.ravel()
    keep = np.ones(len(values), dtype=bool)
    for _ in range(6):  # (the normal equations: lstsq's threaded SVD took ~30 ms a pass)
        if keep.sum() < 4 * design.shape[1]:
            return None
        used = design[keep]
        coef = np.linalg.solve(used.T @ used, used.T @ values[keep])
        residual = values - design @ coef
        spread = 1.4826 * float(np.median(np.abs(residual[keep])))
        keep = np.abs(residual) <= max(3 * spread, 4.0)
    kept = keep.reshape(down, across)
    sides = (kept[0], kept[-1], kept[:, 0], kept[:, -1])
    surface = (design @ coef).reshape(down, across)
    darkens = 2 * coef[3] + 4 * coef[4] < 0  # at the corners (r^2 = 2) against the middle
    fall = float(surface.max() - surface.min())
    # a lens dims the corners by a half, two thirds: a bright middle over a dark ground (a
    # glow, a sun, an orb) is a shape, though a radial surface fits it (h160)
    if (not darkens or spread > 4.0 or kept.mean() < 0.5 or min(side.mean() for side in sides) < 0.75
            or fall < MIN_CONTRAST or float(surface.min()) < VIGNETTE_DEEPEST * float(surface.max())):
        return None
    y = ((np.arange(h) + 0.5) - h / 2) / (h / 2)
    x = ((np.arange(w) + 0.5) - w / 2) / (w / 2)
    paper = sum(c * t for c, t in zip(coef, terms(y.astype(np.float32), x.astype(np.float32)))).astype(np.float32)
    paper = np.maximum(paper, np.float32(VIGNETTE_DEEPEST * float(surface.max())))  # (the corner pixels past the cells)
    # only where there is ink besides the paper's noise, and the fall of light reaches half way
    # to it, as the read would have been misled by it: bold ink on a scan lit a little
    # unevenly reads as before, bit for bit; ink as the lens dims it, over the paper's
    off = (luma / paper - 1) * float(paper.max())
    ink = max(-_far(off, INK_PERCENTILE), _far(off, 100 - INK_PERCENTILE))
    if ink < MIN_CONTRAST or fall < 0.5 * ink:
        return None
    return paper


def _ink(colours: np.ndarray, paper: np.ndarray, where: np.ndarray | None = None,
         lighting: bool = False, paper_at: np.ndarray | None = None) -> np.ndarray:
    """Pixels that differ from the ``paper`` colour as the picture's ink does.

    By brightness first: half way from the paper to the picture's darkest (or, for light
    ink on dark paper, lightest) pixels (:func:`_beyond_half`), so that pencil, pale ink
    and dim photos read as well as black on white, while the lighter-than-paper middle of a
    vignetted photo or a notebook's pale ruling does not. Where brightness barely differs
    (yellow on white) by colour: the largest channel difference from the paper, past half
    its far end. ``where`` limits the pixels looked at (the rest are not ink); ``paper_at``
    marks pixels known to be paper, whose spread is the noise ink must stand out of (the
    border; default ``where``). With ``lighting``, brightness is measured from the paper's
    own where it falls off evenly across the picture (:func:`_lighting`)."""
    where = np.ones(colours.shape[:2], dtype=bool) if where is None else where
    paper_at = where if paper_at is None else paper_at
    nothing = np.zeros(colours.shape[:2], dtype=bool)
    if not where.any():
        return nothing
    luma, paper_luma = _luma(colours), float(_luma(paper))
    light_paper = paper_luma >= 128
    plane = _lighting(luma) if lighting else None
    if plane is not None:
        luma, paper_luma = luma - plane, 0.0
    elif lighting and light_paper:  # (a glow over a dark ground falls off as a lens's light does, h160)
        plane = _vignette(luma)
        if plane is not None:  # a lens's fall of light dims ink and paper alike: divided out (h160)
            luma, paper_luma = (luma / plane - 1) * float(plane.max()), 0.0
    noise = _noise(luma, paper_at)
    ink = _beyond_half(luma, paper_luma, luma[where], noise, light_paper)
    if ink is None and colours.shape[2] > 1:
        distance = np.abs(colours - paper.astype(colours.dtype)).max(axis=2)
        # the noise of the noisiest channel: the largest of three noisy differences is
        # further from zero than any one
        noise = max(_noise(colours[:, :, c], paper_at) for c in range(colours.shape[2]))
        ink = _beyond_half(distance, 0.0, distance[where], noise)
    if ink is None:
        return nothing
    ink = _without_ruling(ink & where, colours, luma, where, paper, plane)
    return _filled_in(ink, colours, luma, where, noise)


RULING_SPAN = 0.8
"""The least share of a row (column) of the picture a coloured line must cross to be a
line of a ruled page's ruling (:func:`_without_ruling`)."""

RULING_LINES = 6  # the fewest lines, one way, evenly spaced, a ruled page shows
RULING_EVEN = 0.2  # how far (a share of their median) the spaces between its lines may differ
RULING_THIN = 0.004  # a ruling line's widest (a share of the picture's side; at least 3 pixels)
RULING_PARTLY = 0.3  # a coloured line of ink across this share of a row: faint marks are counted too
RULING_COVER = 0.7  # the least share of the picture's side from its first line to its last (hatching's is its shape's)


def _ruling_lines(counts: np.ndarray, across: np.ndarray, thin: int, ruled: bool = True,
                  covered: np.ndarray | None = None) -> np.ndarray | None:
    """Rows (or columns) that are a page's ruling, from ``counts`` of coloured ink along
    each and the pixels ``across`` each: :data:`RULING_LINES` or more thin runs of rows
    each crossed for :data:`RULING_SPAN` of its length, the spaces between them even
    within :data:`RULING_EVEN`, from first to last over :data:`RULING_COVER` of the
    picture; None otherwise. ``ruled=False`` (on a page ruled the other way): any such
    run, a margin line. ``covered``: rows all the ink crosses (a line the drawing covers
    for more than a fifth of its length, h124: a branch along a line); a space of two or
    more of the others counts as even where such rows fill in the lines it skips, not
    where nothing is drawn (a staff's gap between staves, h125)."""
    crossed = counts >= RULING_SPAN * np.maximum(across, 1)
    runs = [(start, stop) for start, stop in _runs(crossed) if stop - start <= thin]
    if not runs or (ruled and len(runs) < RULING_LINES):
        return None
    if ruled:
        centres = [0.5 * (start + stop) for start, stop in runs]
        spaces = np.diff(centres)
        step = float(np.median(spaces))
        skips = np.maximum(np.round(spaces / step), 1)
        if np.abs(spaces - step * skips).max() > RULING_EVEN * step or \
                centres[-1] - centres[0] < RULING_COVER * len(counts):
            return None  # not a page's ruling: a drawing's own lines (stripes, hatching, a staff, rails)
        for i in np.flatnonzero(skips > 1):
            for j in range(1, int(skips[i])):
                at = int(round(centres[i] + j * spaces[i] / skips[i]))
                if covered is None or not covered[max(0, at - thin):at + thin + 1].any():
                    return None
    lines = np.zeros_like(crossed)
    for start, stop in runs:
        lines[start:stop] = True
    return lines


def _as_lit_evenly(colours: np.ndarray, ys: np.ndarray, xs: np.ndarray, paper: np.ndarray,
                   plane: np.ndarray | None) -> np.ndarray:
    """Pixels' colours (float64) as they would be under the paper's light where the paper
    is its median colour: scaled by the paper's brightness over the fitted fall of light
    (:func:`_lighting`; ``plane``), so that one ruling reads one colour across a photo lit
    from one side (its lit end had been no blend of the ruling's colour, and stayed, h125)."""
    colours = colours.astype(np.float64)
    if plane is None or colours.shape[1] < 3:
        return colours
    scale = float(_luma(np.asarray(paper, dtype=np.float64).reshape(-1)[:colours.shape[1]])) / \
        np.maximum(plane[ys, xs].astype(np.float64), 1.0)
    return colours * scale[:, None]


def _runs(rows: np.ndarray) -> list:
    """``(start, stop)`` of each run of True in a boolean row (column) profile."""
    edges = np.flatnonzero(np.diff(np.concatenate([[0], rows.astype(np.int8), [0]])))
    return list(zip(edges[::2].tolist(), edges[1::2].tolist()))


def _thin_runs(rows: np.ndarray, thin: int) -> np.ndarray:
    """``rows`` less its runs of True longer than ``thin`` (a filled band is no line)."""
    out = np.zeros_like(rows)
    for start, stop in _runs(rows):
        if stop - start <= thin:
            out[start:stop] = True
    return out


def _middles(lines: np.ndarray) -> np.ndarray:
    """The middle row (two for an even run) of each run of True in ``lines``."""
    out = np.zeros_like(lines)
    for start, stop in _runs(lines):
        out[(start + stop - 1) // 2:(start + stop) // 2 + 1] = True
    return out


def _faint_marks(colours: np.ndarray, ink: np.ndarray, where: np.ndarray, paper: np.ndarray,
                 plane: np.ndarray | None, along: dict, least_chroma: float, widest: int) -> tuple:
    """``(y, x, colours)`` of a ruling's marks that fell short of the ink's half-way mark
    (pale lines near it, noise or a photo's light tipping each pixel either way, h125):
    pixels off the ink, visibly off the paper (:data:`MIN_CONTRAST`) under the fitted fall
    of light (a tinted page lit from one side was marks, h130) and as colourful as the
    ruling's ink (``least_chroma``). Looked for on the thin runs (up to ``widest``) of rows
    and columns that a sample of every ``step``-th pixel, with the coloured ink ``along``
    them, finds half marked: the whole picture cost ~1 s at 12 MP (h130)."""
    h, w = ink.shape
    step = max(1, max(h, w) // 128)
    paper = np.asarray(paper, dtype=np.float64).reshape(-1)[:colours.shape[2]]

    def marked(at_y, at_x) -> tuple:
        c = _as_lit_evenly(colours[at_y, at_x], at_y, at_x, paper, plane)
        return (np.abs(c - paper).max(axis=1) >= MIN_CONTRAST) & (c.max(axis=1) - c.min(axis=1) >= least_chroma), c

    partly = {}
    for way, sample in (("rows", (slice(None), slice(None, None, step))),
                        ("columns", (slice(None, None, step), slice(None)))):
        grid_y, grid_x = np.nonzero(np.ones(where[sample].shape, dtype=bool))
        at_y, at_x = np.arange(h)[sample[0]][grid_y], np.arange(w)[sample[1]][grid_x]
        seen = where[at_y, at_x] & ~ink[at_y, at_x]
        hit = np.zeros(len(at_y), dtype=bool)
        hit[seen] = marked(at_y[seen], at_x[seen])[0]
        at, size = (at_y, h) if way == "rows" else (at_x, w)
        _, counts, across = along[way]
        share = np.bincount(at[hit], minlength=size) / np.maximum(np.bincount(at[seen | ink[at_y, at_x]],
                                                                              minlength=size), 1)
        partly[way] = _thin_runs(share + counts / np.maximum(across, 1) >= 0.5, widest)
    faint_y, faint_x = np.nonzero(where & ~ink & (partly["rows"][:, None] | partly["columns"][None, :]))
    keep, faint = marked(faint_y, faint_x)
    return faint_y[keep], faint_x[keep], faint[keep]


def _without_ruling(ink: np.ndarray, colours: np.ndarray, luma: np.ndarray, where: np.ndarray,
                    paper: np.ndarray, plane: np.ndarray | None = None) -> np.ndarray:
    """``ink`` less a ruled page's coloured ruling, where the drawing is in a plainer colour:
    pencil (grey 125) on a notebook's blue lines (luma 176) put the lines past half way
    from the paper to the pencil, and every line was read as a stroke (h102: 69,062
    pixels read against 9,861 drawn). A ruling is :data:`RULING_LINES` or more evenly
    spaced thin lines one way (:func:`_ruling_lines`) of ink more colourful than the
    picture's darkest ink by :data:`MIN_CONTRAST`, each across :data:`RULING_SPAN` of the
    picture; with one, the pixels of such lines both ways (a margin line too) that are of
    the ruling's colour are dropped, but not where the drawing crosses them (darker than
    the ruling by :data:`MIN_CONTRAST`) or is of a colour of its own (a green leaf over a
    blue line). The drawing's colour is its darkest ink off ruling-like rows; pale lines
    read as ink in stretches only count their faint marks too (:func:`_faint_marks`); the
    ruling's colour is its lines' middle rows', colours read under the fitted fall of
    light (:func:`_as_lit_evenly`), and its blends with the paper go too (a blurred line's
    edges; beside the lines only what is lighter than the line). A drawing's own straight
    lines (a striped shirt, hatching, a fence's rails, a staff, stems: few, uneven, thick,
    or short of the picture's width) stay, and so does a drawing whose ink is as colourful
    as its ruling (blue pen on blue lines)."""
    if colours.shape[2] < 3 or not ink.any():
        return ink
    ys, xs = np.nonzero(ink)  # at the ink's pixels only: a 12-megapixel photo's whole chroma took ~1 s
    own = _as_lit_evenly(colours[ys, xs], ys, xs, paper, plane)
    chroma = own.max(axis=1) - own.min(axis=1)
    ink_luma = luma[ys, xs]
    h, w = ink.shape
    thin = max(3, round(RULING_THIN * max(h, w)))
    # the drawing's colour: its darkest ink off the rows and columns that look like a
    # ruling whatever their colour. Over all the ink, a ruling of one grey level (a
    # notebook's lines outnumbering a pencil sketch's pixels six to one, h124) filled the
    # darkest tenth, and the ruling was taken for the drawing's colour
    off = np.ones(len(ys), dtype=bool)
    shaped, covered = {}, {}  # way -> the rows (columns) that look like a ruling (or None); that all ink crosses
    for way, at, across in (("rows", ys, where.sum(axis=1)), ("columns", xs, where.sum(axis=0))):
        counts = np.bincount(at, minlength=len(across))
        covered[way] = counts >= RULING_SPAN * np.maximum(across, 1)
        shaped[way] = _ruling_lines(counts, across, thin)
        if shaped[way] is not None:
            off &= ~shaped[way][at]
    drawn = ink_luma[off] if off.any() else ink_luma
    darkest = (ink_luma <= _far(drawn, 10)) & (off if off.any() else True)
    least_chroma = float(np.median(chroma[darkest])) + MIN_CONTRAST
    coloured = chroma >= least_chroma
    if not coloured.any():
        return ink
    along = {"rows": (ys, np.bincount(ys[coloured], minlength=h), where.sum(axis=1)),
             "columns": (xs, np.bincount(xs[coloured], minlength=w), where.sum(axis=0))}
    lines = {way: _ruling_lines(counts, across, thin, covered=covered[way])
             for way, (_, counts, across) in along.items()}
    marks = None  # (colours, brightness, {way: positions}) of the lines' marks that are not ink
    halo = max(1, thin // 3)  # a blurred line's soft edge, beside the rows it fills
    if all(found is None for found in lines.values()) and any(
            (counts >= RULING_PARTLY * np.maximum(across, 1)).any() for _, counts, across in along.values()):
        # lines only partly read as ink, or not at all beside a margin line that is
        faint_y, faint_x, faint = _faint_marks(colours, ink, where, paper, plane, along, least_chroma,
                                               thin + 2 * halo)
        marks = (faint, luma[faint_y, faint_x], {"rows": faint_y, "columns": faint_x})
        for way, at, extra in (("rows", ys, faint_y), ("columns", xs, faint_x)):
            _, counts, across = along[way]
            along[way] = (at, counts + np.bincount(extra, minlength=len(counts)), across)
            covered[way] = covered[way] | (along[way][1] >= RULING_SPAN * np.maximum(across, 1))
        lines = {way: _ruling_lines(counts, across, thin, covered=covered[way])
                 for way, (_, counts, across) in along.items()}
    if all(found is None for found in lines.values()):
        return ink
    for way, found in lines.items():  # with the lines a drawing covers for over a fifth of their length
        if found is not None and shaped[way] is not None:
            lines[way] = found | shaped[way]
    for way, (_, counts, across) in along.items():  # a page ruled one way: its margin line the other way
        if lines[way] is None:
            lines[way] = _ruling_lines(counts, across, thin, ruled=False)
    dropped = np.zeros(len(ys), dtype=bool)
    paper = np.asarray(paper, dtype=np.float64).reshape(-1)[:3]
    for way, (at, _, _) in along.items():
        if lines[way] is None:
            continue
        ruled = coloured & lines[way][at]
        if not ruled.any():
            continue
        # the lines' own colour (a margin's pink is not the ruling's blue), not the
        # drawing's: that of their middle rows (a blurred or photographed line's edge rows
        # are most of it, h124; a darkest share was a green drawing's across graph paper),
        # and blends of it with the paper
        middle = _middles(lines[way])
        core = ruled & middle[at]
        if marks is not None:
            mark = middle[marks[2][way]]
            core_colours, core_luma = np.concatenate([own[core], marks[0][mark]]), \
                np.concatenate([ink_luma[core], marks[1][mark]])
        else:
            core_colours, core_luma = own[core], ink_luma[core]
        if not len(core_colours):
            continue
        ruling, ruling_luma = np.median(core_colours, axis=0), float(np.median(core_luma))
        span = ruling - paper
        share = np.clip((own - paper) @ span / max(float(span @ span), 1e-9), 0.0, 1.0)
        blend = np.abs(own - (paper + share[:, None] * span)).max(axis=1) < MIN_CONTRAST
        on = lines[way][at]
        # beside the lines only what is lighter than their full colour: a soft edge, not
        # a colouring-in of the ruling's blue (cut along the lines as before, no wider, h125)
        beside = (np.convolve(lines[way], np.ones(2 * halo + 1), mode="same") > 0)[at] & ~on
        dropped |= blend & ((on & (ink_luma > ruling_luma - MIN_CONTRAST)) | (beside & (ink_luma > ruling_luma)))
    out = ink.copy()
    out[ys[dropped], xs[dropped]] = False
    return out


FILL_CONTRAST = MIN_CONTRAST
"""A region the ink encloses is filled in (part of the shape) when nearly all of it
(:data:`FILL_SHARE`) differs from the paper around it by what ink must differ by, toward
the ink's side of brightness or in hue (:func:`_filled_in`)."""

FILL_SHARE = 0.9
"""The share of an enclosed region's cells that must differ from the paper around them for
it to be filled: a flat fill does everywhere; a shadow or a dim middle that falls on
part of it, with the paper beyond its outline lit, does not."""

_FILL_RIM = 2  # pixels of an enclosed region next to the ink left out of its colour: the strokes' soft edges
_HELD_INK, _HELD_SHARE = 16, 0.002  # ink inside a region, beyond specks: a drawing on it (pixels; share of it)
_FILL_CELLS = 256  # a region's colour is read as the means of cells on a grid of at most this many a side


def _filled_in(ink: np.ndarray, colours: np.ndarray, luma: np.ndarray, where: np.ndarray,
               noise: float) -> np.ndarray:
    """``ink`` with the regions it encloses that are coloured in, not paper: a shape
    outlined in black and filled with yellow, light blue, pink or grey (a colouring book,
    clip art, a highlighter) read as its outline alone, the fill being nearer the paper than
    half way to the black.

    The picture is read as the mean colours of cells (:data:`_FILL_CELLS` a side: a
    crayon's texture averages out, and the work does not grow with the megapixels). A
    region's cells are those wholly inside it, :data:`_FILL_RIM` pixels clear of the ink;
    each is compared with the paper around it: the nearest cell wholly of the paper
    beyond the ink (a shadow or a dim middle falls on both; a page's paper is not the desk
    it lies on). The region is filled when :data:`FILL_SHARE` of its cells differ from that
    by :data:`FILL_CONTRAST` (and :data:`NOISE_MARGIN` x the paper's ``noise``) toward the
    ink's side of brightness, or in hue (colour less brightness), and as many differ from
    the median paper cell of a band around the region (the nearest may lie in a blurred
    stroke's tinted halo). Only dark ink's regions are filled. A letter's counter, paper
    inside a drawn outline or frame, a region under a shadow that falls on part of it,
    and a region too small for a whole cell stay out, and so does a region with ink inside
    it (a drawing on a whiteboard in its frame: a surface, not a fill; an outline's fill
    around a drawn detail is lost with it). ``luma`` is the brightness the ink was read
    from (the fall of light taken out)."""
    if not ink.any() or ink.all() or float(luma[ink].mean()) >= float(luma[~ink].mean()):
        # light ink on a dark ground: a blackboard, or a light page read on a dark desk,
        # whose drawing is what it encloses (procmod.targets.image._drawing_on_a_page)
        return ink
    rest = ~ink & where
    least = max(FILL_CONTRAST, NOISE_MARGIN * noise)
    if rest.any():
        # subtracted in float64, as the cells' means are compared (float32's own rounding of
        # a range is ~2e-6: at the threshold it had decided otherwise, h86); the extremes
        # themselves are float32 values, read a channel at a time without a float64 copy of
        # the picture (a 24-megapixel photo spent 1.7 s here)
        def extent(values) -> np.ndarray:
            return values.max(axis=0).astype(np.float64) - values.min(axis=0).astype(np.float64)

        spread = float(extent(luma[rest]))
        if colours.shape[2] > 1:
            spread = max(spread, 2.0 * max(float(extent(colours[:, :, c][rest])) for c in range(colours.shape[2])))
        if spread + 1e-6 < least:  # (a margin for the cell means' rounding)
            return ink  # no cell can differ from another by ``least``: nothing is filled
    from scipy import ndimage  # after the cheap checks: importing it costs ~0.19 s of start-up
    # what the ink encloses: the regions of the rest that reach no edge of the picture (a
    # labelling, one pass: binary_fill_holes' flood took ~0.2 s on a page's photo)
    labels, count = ndimage.label(~ink)
    enclosed = np.ones(count + 1, dtype=bool)  # by label (a table: np.isin took 0.26 s on an A4 scan)
    enclosed[0] = False
    enclosed[np.concatenate([labels[0], labels[-1], labels[:, 0], labels[:, -1]])] = False
    inside = enclosed[labels] & where
    if not inside.any():
        return ink
    paper = ~ink & ~inside & where
    cell = max(1, math.ceil(max(ink.shape) / _FILL_CELLS))
    down, across = ink.shape[0] // cell, ink.shape[1] // cell  # whole cells (a ragged last row or column left out)

    def cell_mean(values):  # per cell, through a view of the picture split into cells
        return values[:down * cell, :across * cell].reshape(down, cell, across, cell).mean(axis=(1, 3),
                                                                                         dtype=np.float64)

    if cell > _FILL_RIM:  # the cells next to another kind hold the rims: left out, a cell at a time
        in_core = ndimage.binary_erosion(cell_mean(inside) == 1.0)
        in_paper = ndimage.binary_erosion(cell_mean(paper) == 1.0, border_value=1)
    else:
        in_core = cell_mean(ndimage.binary_erosion(inside, iterations=_FILL_RIM)) == 1.0
        in_paper = cell_mean(ndimage.binary_erosion(paper, iterations=_FILL_RIM, border_value=1)) == 1.0
    if not in_core.any() or not in_paper.any():
        return ink
    channels = [luma] + ([colours[:, :, c] for c in range(colours.shape[2])] if colours.shape[2] > 1 else [])
    means = np.stack([cell_mean(v) for v in channels], axis=-1)
    if colours.shape[2] > 1:  # hue: colour less its own brightness (from the colours, not ``luma``)
        means[..., 1:] -= (means[..., 1:] @ _LUMA)[..., None]
    least = max(FILL_CONTRAST, NOISE_MARGIN * noise)
    cell_region = labels[:down * cell:cell, :across * cell:cell]  # a whole cell lies in one region: its first pixel's
    region = cell_region[in_core]
    cells = np.bincount(region, minlength=count + 1)

    def differs(values, around):  # per cell: unlike the paper ``around`` it, darker (toward the ink) or in hue
        unlike = (around[..., 0] - values[..., 0]) >= least
        if colours.shape[2] > 1:
            unlike |= np.abs(values[..., 1:] - around[..., 1:]).max(axis=-1) >= least
        return unlike

    def coloured(paper_cells):  # by label: the regions whose cells differ from their nearest paper cell
        _, (iy, ix) = ndimage.distance_transform_edt(~paper_cells, return_indices=True)
        unlike = differs(means, means[iy, ix])[in_core]
        share = np.bincount(region, weights=unlike, minlength=count + 1) / np.maximum(cells, 1)
        return (cells > 0) & (share >= FILL_SHARE)

    chosen = coloured(in_paper)
    if not chosen.any():
        return ink
    # a region holding a drawing of its own is a surface it was drawn on, not a fill: a
    # whiteboard in its frame, a tablet in its bezel, a framed picture, a page on a
    # clipboard, photographed against a lighter wall or desk (a review found them filled solid)
    boxes = ndimage.find_objects(labels)
    for k in np.flatnonzero(chosen):
        box = boxes[k - 1]
        solid = ndimage.binary_fill_holes(labels[box] == k)
        if (solid & ink[box]).sum() >= max(_HELD_INK, _HELD_SHARE * solid.sum()):
            chosen[k] = False
    # the regions left out are paper too: one inside a surface (a house's window drawn on the
    # whiteboard) is judged again against that surface, not the wall beyond its frame
    paper_cells = in_paper | (in_core & ~chosen[cell_region])
    if chosen.any() and not np.array_equal(paper_cells, in_paper):
        chosen &= coloured(paper_cells)
    # and against the paper of a band around it, its median: the nearest paper cell may lie
    # in the soft halo of a blurred stroke (a yellow letter's, tinted 39 in hue 3 px out,
    # made its white counter a fill, a sweep found)
    cell_boxes = ndimage.find_objects(np.where(in_core, cell_region, 0), max_label=count)
    for k in np.flatnonzero(chosen):
        rows, cols = cell_boxes[k - 1]
        margin = max(3, (rows.stop - rows.start + cols.stop - cols.start) // 4)
        box = (slice(max(rows.start - margin, 0), rows.stop + margin),
               slice(max(cols.start - margin, 0), cols.stop + margin))
        band = means[box][paper_cells[box]]
        own = in_core[box] & (cell_region[box] == k)
        if len(band) and differs(means[box][own], np.median(band, axis=0)).mean() < FILL_SHARE:
            chosen[k] = False  # (no paper in the band, as on a page coloured all over: the nearest cells decide)
    return ink | chosen[labels]


def _fills_its_box(mask: np.ndarray, share: float) -> bool:
    """Whether ``mask`` covers at least ``share`` of its bounding box (a page, a frame's
    inside), as a drawn shape seldom does."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if not rows.size:
        return False
    box = (rows[-1] - rows[0] + 1) * (cols[-1] - cols[0] + 1)
    return mask.sum() >= share * box


PAGE_SHARE = 0.08
"""A light region read as the shape is taken for a page (with the drawing on it) when it
covers at least this share of the picture, as well as nearly all of its bounding box."""
CARD_TINT = 48  # the most a card's colour channels differ (paper, cream, a grey card; not a yellow sticker)


def card_read_as_shape(image: Image.Image, mask: np.ndarray) -> float | None:
    """The share of the canvas of a light grey rectangle, opaque on a transparent canvas,
    with darker marks on it, where that rectangle was read as the shape (under half the
    canvas it is, :func:`mask_from_image`); None otherwise. Such a picture is a card with
    a drawing placed on the canvas, or a sticker, button or label meant as the shape (h157:
    either reading misreads the other, pixel for pixel), so a note says which was taken."""
    opaque = opaque_part(image)
    if opaque is None or not PAGE_SHARE < opaque.mean() <= 0.5 or not _fills_its_box(opaque, 0.95):
        return None
    if not np.array_equal(mask, opaque):
        return None
    drawn, page = _drawing_on_opaque(image, opaque)
    if drawn is None or float(page @ _LUMA) < 160 or np.ptp(page) > CARD_TINT:
        return None
    return float(opaque.mean())


def _drawing_on_opaque(image: Image.Image, opaque: np.ndarray) -> tuple:
    """``(drawing, page colour)`` of the ``opaque`` part of a transparent picture taken as
    a page: its ink (:func:`_ink`, the page's median colour as the paper), or None where
    there is none darker than the page (a light detail on a dark badge, an icon's white
    dot, is part of the shape)."""
    rgb = np.asarray(image.convert("RGB"), dtype=np.float32)
    page = np.median(rgb[opaque], axis=0)
    drawn = _ink(rgb, page, where=opaque)
    if drawn.any() and float(np.mean(rgb[drawn] @ _LUMA)) < float(page @ _LUMA):
        return drawn, page
    return None, page

def _see_through_drawing(image: Image.Image, opaque: np.ndarray) -> np.ndarray:
    """The see-through strokes drawn on an opaque page, where the ``opaque`` part of a
    transparent picture is such a page, else ``opaque`` (the shape, as ever): a drawing
    whose ink is the file's transparent colour (a GIF or palette PNG whose tool made the
    ink's palette index the transparent one; a stencil), which had been read inverted, the
    page around it as the shape. The page is the opaque part with the see-through parts
    inside its bounding box filled in, but for those reaching past it (a margin, a notch
    from its edge) or into its corners (a rounded or turned page's): it must cover half the
    picture and 95% of its bounding box, be mostly paper (:data:`PAGE_PAPER`) of a
    paper's colour (light and untinted, as :func:`card_read_as_shape`'s card), have
    nothing drawn on it (:func:`_drawing_on_opaque`), and what it holds see-through must be
    strokes, thinned away by 2% of the picture as :func:`page_taken_for_shape`'s holes are
    and long (:func:`_strokes_drawn`): a window's panes, a ring's or a letter's hollow, a
    facade's small windows, a perforated plate's holes are no drawing. A see-through piece
    the thinning leaves is a stroke still where it is long and bends or branches
    (:func:`_bent_strokes`: a stencil cut with a fat brush), as no pane or hollow does."""
    from scipy import ndimage  # after the cheap checks: importing it costs ~0.13 s of start-up

    rows, cols = np.flatnonzero(opaque.any(axis=1)), np.flatnonzero(opaque.any(axis=0))
    labels, count = ndimage.label(~opaque, structure=np.ones((3, 3), dtype=bool))
    inside = np.zeros_like(opaque)
    inside[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] = True
    out = np.zeros(count + 1, dtype=bool)
    out[np.unique(labels[~inside])] = True
    out[[labels[r, c] for r in (rows[0], rows[-1]) for c in (cols[0], cols[-1])]] = True
    out[0] = True  # (the opaque pixels)
    holes = ~out[labels]
    page = opaque | holes
    if (not holes.any() or page.mean() <= 0.5 or not _fills_its_box(page, 0.95)
            or opaque.sum() < PAGE_PAPER * page.sum()):
        return opaque
    stroke = max(2, round(0.02 * max(opaque.shape)))
    wide = ndimage.binary_erosion(holes, iterations=stroke)
    if wide.sum() >= holes.sum() / 3:
        # a fat brush's strokes are wide too: only pieces that are no long, bent stroke count
        wide &= ~_bent_strokes(holes, labels, np.unique(labels[wide]))[labels]
    if wide.sum() >= holes.sum() / 3:
        return opaque  # wide: a window's panes, a hollow
    if not _strokes_drawn(holes, labels):
        return opaque  # small round or square holes: a facade's windows, a perforated plate, a calendar's days
    drawn, page_colour = _drawing_on_opaque(image, opaque)
    edge = drawn is not None and _edge_of(drawn, holes)
    if (drawn is not None and not edge) or float(page_colour @ _LUMA) < PAPER_LUMA or np.ptp(page_colour) > CARD_TINT:
        # a page is paper: a dark, grey or coloured opaque part (a building, a badge, a stencil's
        # plate, a brick wall) with see-through gaps is the shape, as before
        return opaque
    return holes | drawn if edge else holes


SOFT_EDGE = 3  # pixels: how far an anti-aliased edge reaches out from a see-through stroke


def _edge_of(drawn: np.ndarray, holes: np.ndarray) -> bool:
    """Whether what is drawn on a page (:func:`_drawing_on_opaque`) is the soft edge of its
    see-through ``holes``: nearly all of it within :data:`SOFT_EDGE` pixels of them (a
    float render's strokes of NaN, :func:`_non_finite_as_clear`, anti-aliased into the
    paper by a grey rim, which alone had been read as the drawing, its middle left out)."""
    from scipy import ndimage

    near = ndimage.binary_dilation(holes, structure=np.ones((3, 3), dtype=bool), iterations=SOFT_EDGE)
    return bool((drawn & near).sum() >= 0.9 * drawn.sum())


PAPER_LUMA = 160  # the least brightness of a page's paper (card_read_as_shape's light card)
STROKE_LENGTH = 4  # a stroke is at least this many times as long as it is wide (a square window is 2, a dash 4)


STROKE_BENT = 0.8  # the most of its convex hull a bent stroke fills (a pane, a hollow, a disc: nearly all)


def _piece_widths(holes: np.ndarray, labels: np.ndarray) -> tuple:
    """``(area, width, boxes)`` of each piece of ``holes`` (labelled by ``labels``; index 0
    none): its pixels, its width as :func:`stroke_width` measures it (twice the area over
    the boundary) and its bounding box (None for a label with no piece in ``holes``)."""
    from scipy import ndimage

    pieces = np.where(holes, labels, 0)
    area = np.bincount(pieces.ravel(), minlength=int(labels.max()) + 1)
    boundary = np.bincount(pieces[holes & ~ndimage.binary_erosion(holes)], minlength=len(area))
    width = 2.0 * area / np.maximum(boundary, 1)
    boxes = [None] + list(ndimage.find_objects(pieces, max_label=len(area) - 1))
    return area, width, boxes


def _bent_strokes(holes: np.ndarray, labels: np.ndarray, which) -> np.ndarray:
    """Which pieces of ``holes`` (by label, among the labels ``which``) are strokes however
    wide: at least :data:`STROKE_LENGTH` times as long as wide (:func:`_strokes_drawn`'s
    measure) and filling at most :data:`STROKE_BENT` of their convex hull, as a letter, a
    curve or a scribble drawn with a fat brush does. A window's pane, a hollow, a round
    or square hole is convex: it fills nearly all of its hull."""
    from scipy.spatial import ConvexHull, QhullError

    area, width, boxes = _piece_widths(holes, labels)
    bent = np.zeros(len(area), dtype=bool)
    for piece in which:
        box = boxes[piece] if 0 < piece < len(boxes) else None
        if box is None:
            continue
        extent = max(box[0].stop - box[0].start, box[1].stop - box[1].start)
        if extent < STROKE_LENGTH * width[piece]:
            continue
        corners = _row_end_corners(labels[box] == piece)
        try:
            hull = ConvexHull(np.unique(corners, axis=0)).volume  # (in 2D, its area)
        except (QhullError, ValueError):  # all in a line: a straight stroke, no bend
            continue
        bent[piece] = area[piece] <= STROKE_BENT * hull
    return bent


def _row_end_corners(piece: np.ndarray) -> np.ndarray:
    """``(row, column)`` corners of the first and last pixel of each row of ``piece``, whose
    convex hull is that of all its pixels whole (a row's pixels lie between its two ends;
    their centres' hull misses half of each edge pixel). Every pixel's corners had been
    hulled: a 6000-pixel picture's wide slot (5 million pixels) took over a minute."""
    rows = np.flatnonzero(piece.any(axis=1))
    first = piece[rows].argmax(axis=1)
    last = piece.shape[1] - piece[rows, ::-1].argmax(axis=1)  # (one past the last pixel: its right corners)
    return np.concatenate([np.stack([rows + dr, ends], axis=1) for dr in (0, 1) for ends in (first, last)])


def _strokes_drawn(holes: np.ndarray, labels: np.ndarray) -> bool:
    """Whether most of ``holes`` (labelled by ``labels``) lies in pieces drawn as strokes:
    pieces at least :data:`STROKE_LENGTH` times as long (their bounding box's longer side)
    as wide (:func:`stroke_width`'s measure, twice the area over the boundary). A pen's
    lines are; the small square or round holes of a facade's windows, a perforated plate
    or a calendar's day cells, which the 2% thinning also removes, are not."""
    area, width, boxes = _piece_widths(holes, labels)
    long = 0
    for piece, box in enumerate(boxes):
        if box is not None:
            extent = max(box[0].stop - box[0].start, box[1].stop - box[1].start)
            if extent >= STROKE_LENGTH * width[piece]:
                long += int(area[piece])
    return long >= 0.5 * int(holes.sum())


PAGE_BOX_FILL = 0.8  # a page turned up to ~7 degrees in the photo still fills this much of its box


def _spans(region: np.ndarray) -> np.ndarray:
    """``region`` with each row and each column filled between its first and last pixel:
    a convex page with the drawing's strokes as notches in it (a stroke that meets the
    page's edge is no hole) filled whole, and nothing outside its convex hull."""
    def along_rows(r):
        any_ = r.any(axis=1)
        first = np.where(any_, r.argmax(axis=1), r.shape[1])
        last = np.where(any_, r.shape[1] - 1 - r[:, ::-1].argmax(axis=1), -1)
        cols = np.arange(r.shape[1])
        return (cols[None, :] >= first[:, None]) & (cols[None, :] <= last[:, None])
    return along_rows(region) | along_rows(region.T).T


_PAGE_GRID = 512  # the page is found on a copy of at most this many pixels a side


def _drawing_on_a_page(colours: np.ndarray, mask: np.ndarray, surround: np.ndarray) -> np.ndarray | None:
    """The drawing on a page photographed on a darker surface (a desk), or None.

    The picture's border is then the desk, and the page, lighter than it, was read as the
    shape with the drawing as holes and notches in it. A page is the largest region of
    that mask, filled (:func:`_spans`), when it is lighter than the border, covers
    :data:`PAGE_SHARE` of the picture and :data:`PAGE_BOX_FILL` of its bounding box; what
    is drawn on its inside (its edge, where the desk's shadow falls, left out) is read as
    a picture on that page's paper. A light shape on a dark ground with nothing drawn on
    it (a white silhouette, a mask exported inverted) stays the shape, and so does one whose
    holes and notches are the ground's colour (a white letter, a silhouette with a hole): a
    drawing must differ from the ground by :data:`MIN_CONTRAST` (its strokes' cores, not
    their blurred rims). A page in a near-black frame drawn in black is therefore not told
    from them (the "covers" note of :func:`procmod.targets.placement.picture_note` says
    what to crop)."""
    if not mask.any():
        return None
    luma, surround_luma = _luma(colours), float(_luma(surround))
    # the region read as the shape is the light page itself, not dark ink on paper whose
    # middle is a little lighter than its edges (a drawn frame, which spans fill as well)
    if float(np.median(luma[mask])) < surround_luma + MIN_CONTRAST:
        return None
    from scipy import ndimage  # after the cheap checks: importing it costs ~0.19 s of start-up

    h, w = mask.shape
    step = max(1, math.ceil(max(h, w) / _PAGE_GRID))
    small = mask[::step, ::step]
    if not small.any():  # thin strokes the coarse copy steps over: no page
        return None
    # with every light piece within its bounding box: strokes that meet the page's edges cut
    # pockets of it off (a trunk and a branch from the edges, the corner between them)
    rows, cols = np.nonzero(_largest_part(small))
    boxed = np.zeros_like(small)
    boxed[rows.min():rows.max() + 1, cols.min():cols.max() + 1] = \
        small[rows.min():rows.max() + 1, cols.min():cols.max() + 1]
    page = ndimage.binary_fill_holes(_spans(boxed))  # where strokes cross, both spans miss
    if page.mean() < PAGE_SHARE or not _fills_its_box(page, PAGE_BOX_FILL):
        return None
    inside = ndimage.binary_erosion(page, iterations=max(1, round(0.015 * max(page.shape))))
    inside = np.repeat(np.repeat(inside, step, axis=0), step, axis=1)[:h, :w]  # back to the picture's pixels
    if inside.sum() < 64 or float(np.median(luma[inside])) <= surround_luma:
        return None
    paper = np.median(colours[inside], axis=0)
    drawn = _ink(colours, paper, where=inside)
    paper_luma = float(_luma(paper))
    # a drawing: darker than its page, and a small part of it (not the page's own texture)
    if not drawn.any() or float(np.mean(luma[drawn])) >= paper_luma or drawn.sum() > 0.5 * inside.sum():
        return None
    # and unlike the border: the holes and notches of a light shape on a dark ground (a
    # white silhouette with a hole, a bold letter, an inverted mask) are the ground's own
    # colour, and that light shape is the shape. Measured on the strokes' cores: their
    # rims, blurred into the paper by a phone photo and its JPEG, had brought black ink on
    # a page on a dark desk under the contrast asked (the page read as the shape, the
    # drawing as its holes)
    core = ndimage.binary_erosion(drawn)
    measured = core if core.any() else drawn
    if float(np.abs(np.median(colours[measured], axis=0) - surround).max()) < MIN_CONTRAST:
        return None
    return drawn


def _border_colour(colours: np.ndarray) -> tuple:
    """``(the picture's border pixels as a mask, their median colour)``: the paper's colour
    when nothing says otherwise (:func:`mask_from_image`)."""
    on_border = np.zeros(colours.shape[:2], dtype=bool)
    on_border[0] = on_border[-1] = on_border[:, 0] = on_border[:, -1] = True
    return on_border, np.median(colours[on_border], axis=0)


def mask_from_image(image: Image.Image) -> np.ndarray:
    """Binary mask of a picture: foreground = pixels unlike the paper.

    The paper is the median colour of the picture's border; a pixel is foreground when its
    colour is nearer the far end of the picture's colours than the paper (:func:`_ink`):
    dark ink on light paper or light on dark, pencil grey or a pale colour on white, a
    dim photo. (A fixed grey threshold of 128 lost pencil, yellow and light-blue ink and
    underexposed photos.) With transparency the opaque part is the shape, unless it is a
    page (most of the picture, and nearly all of its own bounding box: a window with a
    transparent margin) with something drawn on it: then that is, read as above with the
    page's median colour as the paper. So is an opaque picture of a page lying on a darker
    surface (:func:`_drawing_on_a_page`). Non-square
    pictures are padded with background to a square, centred, because the built-in models'
    viewport is square.
    """
    opaque = opaque_part(image)
    colours = _colours(image)
    if opaque is not None:
        mask = opaque
        if opaque.mean() > 0.5 and _fills_its_box(opaque, 0.95):  # a page: read what is drawn on it
            drawn, _ = _drawing_on_opaque(image, opaque)
            # nothing drawn on it, or only a soft edge around see-through strokes: the drawing may be see-through
            seen = _see_through_drawing(image, opaque) if drawn is None or _edge_of(drawn, ~opaque) else opaque
            mask = drawn if drawn is not None and seen is opaque else seen
        elif opaque.mean() > 0.5 * PAGE_PAPER:  # a page whose see-through drawing leaves under 95% of it opaque
            mask = _see_through_drawing(image, opaque)
    else:
        on_border, surround = _border_colour(colours)
        mask = _ink(colours, surround, lighting=True, paper_at=on_border)
        drawn = _drawing_on_a_page(colours, mask, surround)
        if drawn is not None:
            mask = drawn
    h, w = mask.shape
    top, left, _, _ = picture_in_square(h, w)
    square = np.zeros((max(h, w), max(h, w)), dtype=bool)
    square[top:top + h, left:left + w] = mask
    return square


def picture_in_square(height: int, width: int) -> tuple:
    """``(top, left, height, width)`` of a ``height x width`` picture in the square frame
    :func:`mask_from_image` pads it to (centred)."""
    side = max(height, width)
    return (side - height) // 2, (side - width) // 2, height, width


def point_in_square(point, height: int, width: int) -> tuple:
    """A point in a ``height x width`` picture's normalised coordinates, in those of the
    square :func:`mask_from_image` pads it to."""
    top, left, _, _ = picture_in_square(height, width)
    side = max(height, width)
    x, y = point
    return (x * width + left) / side, (y * height + top) / side


SIDECAR_KEYS = ("start", "direction")



def typo_of(key, known) -> str | None:
    """The key of ``known`` that ``key`` is meant to be, or None: one typing slip from it
    (a letter added, dropped, changed, or two swapped: ``"strat"``, ``"directon"``,
    ``"Start"``), or it with a word that says the same (``"start_point"``, ``"startPos"``,
    ``"direction_vector"``). Tight on purpose, for files whose other keys are a tool's
    own: a similarity ratio took ``"description"`` for ``"direction"`` and ``"state"`` for
    ``"start"``, and ``"startTime"`` is no start."""
    word = re.sub(r"[\s_\-]", "", str(key)).lower()
    for candidate in known:
        if word.startswith(candidate) and word[len(candidate):] in _SAME_THING:
            return candidate
        if _slips(word, candidate) <= 1:
            return candidate
    return None


# what a key may add to start or direction and still mean it
_SAME_THING = {"", "s", "ing", "point", "pt", "pos", "position", "xy", "coord", "coords", "vector", "vec"}


def _slips(a: str, b: str) -> int:
    """Edit distance with swaps of neighbours (optimal string alignment)."""
    previous2, previous = None, list(range(len(b) + 1))
    for i in range(1, len(a) + 1):
        row = [i] + [0] * len(b)
        for j in range(1, len(b) + 1):
            row[j] = min(previous[j] + 1, row[j - 1] + 1, previous[j - 1] + (a[i - 1] != b[j - 1]))
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                row[j] = min(row[j], previous2[j - 2] + 1)
        previous2, previous = previous, row
    return previous[len(b)]


def meant_key(key, known, cutoff: float) -> str | None:
    """The key of ``known`` a file's unknown ``key`` is a near miss of (``"strat"``,
    ``"look-at"``), or None: a file's near misses are refused, its other keys (a tool's
    own notes) left alone."""
    found = difflib.get_close_matches(str(key).lower().replace("-", "_"), known, n=1, cutoff=cutoff)
    return found[0] if found else None


def sidecar_files(path: Path) -> list:
    """The files beside a picture that may be its sidecar: ``NAME.json`` and
    ``NAME.png.json``, their suffix in lower or upper case (``NAME.JSON``, as Windows
    tools write it: these had been passed over without a word, and the start taken from
    the picture). Each file once (a file system that ignores case finds one under both
    spellings)."""
    found, seen = [], set()
    for stem in (path.with_suffix(""), path):
        for suffix in (".json", ".JSON"):
            candidate = stem.with_name(stem.name + suffix)
            try:
                info = candidate.stat()
            except (OSError, ValueError):
                continue
            if (info.st_dev, info.st_ino) not in seen:
                seen.add((info.st_dev, info.st_ino))
                found.append(candidate)
    return found


def _read_sidecar(path: Path, shape_padding) -> dict | None:
    """The placement a picture's sidecar ``NAME.json`` gives, as ``{"start": (x, y),
    "direction": (dx, dy)}`` with either key absent when the file leaves it out (the
    picture then decides it); None without a sidecar. A JSON file with a ``"format"`` is
    not a sidecar but one of procmod's own files (``best.json`` beside ``best.png``, a run
    used as a target) and is passed over; two sidecars of the user's
    (:func:`sidecar_files`) are refused; a key close to ``start`` or ``direction`` is
    refused as a typo (it would otherwise be ignored); keys unlike both are a tool's own
    and left alone."""
    own = []  # the sidecars that are no file of procmod's own
    for candidate in sidecar_files(path):
        data = read_json(candidate, TargetFileError, "sidecar JSON")
        if not isinstance(data, dict):
            raise TargetFileError(f"{candidate}: expected an object like "
                                  '{"start": [0.5, 0.9166], "direction": [0, -1]}')
        if "format" not in data:
            own.append((candidate, data))
    if len(own) > 1:
        raise TargetFileError(f"{path} has two sidecars, {own[0][0].name} and {own[1][0].name}: keep the one that "
                              "says where to start")
    if not own:
        return None
    sidecar, data = own[0]
    for key in sorted(set(data) - set(SIDECAR_KEYS)):
        # a misspelt key would silently leave the start to the picture; other keys (a
        # tool's own notes: "name", "source") are not ours and are left alone
        meant = typo_of(key, SIDECAR_KEYS)
        if meant:
            raise TargetFileError(f"{sidecar}: unknown key {cut_text(repr(key), 40)}; did you mean {meant!r}? A "
                                  "sidecar gives \"start\" and/or \"direction\" (normalised image coordinates, y down)")
    placement = {}
    for key, value in ((k, v) for k, v in data.items() if k in SIDECAR_KEYS):
        if (not isinstance(value, (list, tuple)) or len(value) != 2
                # (JSON's true is no coordinate: Python's bool is an int, and it was read as 1)
                or not all(isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)
                           for v in value)):
            raise TargetFileError(f"{sidecar}: {key!r} must be two finite numbers, got {cut_text(repr(value), 60)}")
        placement[key] = (float(value[0]), float(value[1]))
    if "start" in placement:
        if not all(0.0 <= v <= 1.0 for v in placement["start"]):
            raise TargetFileError(f"{sidecar}: 'start' is in normalised image coordinates and must lie in [0, 1]")
        # The sidecar refers to the original picture; map it into the padded square.
        placement["start"] = point_in_square(placement["start"], *shape_padding)
    if placement.get("direction") == (0.0, 0.0):
        raise TargetFileError(f"{sidecar}: 'direction' must be a non-zero vector")
    return placement


FRAME_LINE = 0.9  # a row or column of a drawn frame's side covers this much of the shape's extent
FRAME_RIM = 0.3  # ... and its anti-aliased rim rows at least this much
FRAME_SIDE = 0.08  # a frame's side is at most this thick, of the shape's smaller extent
FRAME_SPAN = 0.85  # and the frame spans this much of the picture's width and height
FRAME_GAP = 2  # pixels between a frame and the drawing inside it


def drawn_frame(mask: np.ndarray, picture: tuple | None = None) -> np.ndarray | None:
    """The pixels of a rectangular frame drawn around a picture (a border line on all
    four sides of the shape, near the picture's edges, apart from the drawing inside), or
    None. ``picture``: where the picture lies in the mask (:func:`picture_in_square`).

    A frame is read as part of the shape; its bottom line, the lowest ink, then takes the
    start, and a vine grows along the frame (h51: best similarity -0.002 where the same
    drawing without it reaches 0.8). Found as runs of rows (columns) at the top, bottom,
    left and right of the shape's bounding box that each cover :data:`FRAME_LINE` of its
    width (height), with their anti-aliased rims, each side at most :data:`FRAME_SIDE` of
    the box thick, spanning :data:`FRAME_SPAN` of the picture both ways, with a drawing
    inside that keeps :data:`FRAME_GAP` pixels from it. A rectangle that is part of the
    drawing is left alone: alone in the picture, smaller than the picture (a door with its
    knob), or touched by what is inside it (a window's cross). A frame turned in a photo
    covers no row whole and is not found."""
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    if len(rows) < 8 or len(cols) < 8:
        return None
    height, width = mask.shape if picture is None else picture[2:]
    if rows[-1] - rows[0] + 1 < FRAME_SPAN * height or cols[-1] - cols[0] + 1 < FRAME_SPAN * width:
        return None
    box = mask[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    limit = max(1, int(FRAME_SIDE * min(box.shape)))

    def side(cover: np.ndarray) -> int:  # rows of a side from the box's edge inwards (0: none)
        end = min(limit, len(cover))
        n = 0
        while n < min(end, FRAME_GAP + 1) and cover[n] < FRAME_LINE:  # a blurred line's sparse outer rim
            n += 1
        if n >= end or cover[n] < FRAME_LINE:
            return 0
        while n < end and cover[n] >= FRAME_LINE:
            n += 1
        while n < end and cover[n] >= FRAME_RIM:  # its anti-aliased inner rim
            n += 1
        return n if n < limit else 0  # as thick as the limit: a filled block (a page), not a line

    across, down = box.mean(axis=1), box.mean(axis=0)
    top, bottom, left, right = side(across), side(across[::-1]), side(down), side(down[::-1])
    if not (top and bottom and left and right):
        return None
    frame = np.zeros_like(box)
    frame[:top] = frame[box.shape[0] - bottom:] = True
    frame[:, :left] = frame[:, box.shape[1] - right:] = True
    inside = box & ~frame
    if inside.sum() < 0.02 * box.sum() or inside.sum() < 16:  # nothing drawn inside: the rectangle is the shape
        return None
    # the drawing meets it (a window's cross): ink next to the frame, away from its corners,
    # where a blurred or rounded frame's inner fillet lies. (scipy.ndimage is imported only
    # here: importing it costs ~0.13 s of every run's start-up, and most pictures have no frame.)
    from scipy import ndimage

    meets = inside & ndimage.binary_dilation(box & frame, iterations=FRAME_GAP)
    corner = 2 * max(top, bottom, left, right) + FRAME_GAP + 1
    meets[:corner, :corner] = meets[:corner, -corner:] = meets[-corner:, :corner] = meets[-corner:, -corner:] = False
    if meets.any():
        return None
    out = np.zeros_like(mask)
    out[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1] = box & frame
    return out


PAGE_RECTANGLE = 0.95  # a shape filling this much of its bounding box is a rectangle (a page), not a letter
PAGE_NOTE = "the shape read is one light rectangle"  # how load_target_image's page note begins


def page_taken_for_shape(image: Image.Image, mask: np.ndarray) -> float | None:
    """The share of the picture a page read as the shape covers, or None.

    A page photographed on a desk about as dark as its ink stays the shape, its drawing
    holes in it (:func:`_drawing_on_a_page` cannot tell that drawing from the ground's
    colour showing through a light shape). Named when the shape read is lighter than the
    picture's border by :data:`MIN_CONTRAST`, its largest part with its holes filled
    covers :data:`PAGE_SHARE` of the picture and :data:`PAGE_BOX_FILL` of its bounding
    box, and its holes are strokes (under a third of them is left after thinning by 2% of
    the picture), not a letter's counters or a silhouette's gaps, unless it is a rectangle
    (:data:`PAGE_RECTANGLE` of its box: a filled or bold drawing on a page).

    A stroke that reaches the page's edge is a notch in it, not a hole, and one across it
    cuts the page in two: failing the above, the page is the light shape with gaps of a
    stroke's width closed, taken only when the light covers :data:`PAGE_PAPER` of it
    (white strokes close together on dark ground, chalk writing or hatching, close into a
    block as well, one about as dark as light). ``mask``: the picture's own, unpadded
    (:func:`mask_from_image`'s before its square)."""
    if opaque_part(image) is not None or not mask.any():
        return None
    colours = _colours(image)
    surround = float(_luma(_border_colour(colours)[1]))
    if float(_luma(colours[mask]).max()) < surround + MIN_CONTRAST:  # dark ink on light paper, whatever ``part``
        return None
    from scipy import ndimage  # after the cheap checks: importing it costs ~0.13 s of start-up

    stroke = max(2, round(0.02 * max(mask.shape)))  # the widest stroke taken for the drawing's
    part = _largest_part(mask)
    page = _page_of(ndimage.binary_fill_holes(part), part, stroke)
    if page is None:
        closed = ndimage.binary_closing(np.pad(mask, stroke), iterations=stroke)[stroke:-stroke, stroke:-stroke]
        filled = ndimage.binary_fill_holes(_largest_part(closed | mask))
        part = filled & mask
        if part.sum() < PAGE_PAPER * filled.sum():
            return None
        page = _page_of(filled, part, stroke)
    if page is None:
        return None
    if float(np.median(_luma(colours[part]))) < surround + MIN_CONTRAST:  # dark ink on light paper
        return None
    return float(page.mean())


PAGE_PAPER = 0.75  # a page is mostly paper: its drawing's strokes cover under a quarter of it


def _largest_part(mask: np.ndarray) -> np.ndarray:
    """The largest 8-connected part of a non-empty mask."""
    from scipy import ndimage

    labels, _ = ndimage.label(mask, structure=np.ones((3, 3)))
    return labels == 1 + int(np.argmax(np.bincount(labels.ravel())[1:]))


def _page_of(filled: np.ndarray, part: np.ndarray, stroke: int) -> np.ndarray | None:
    """``filled`` when it is a page (:func:`page_taken_for_shape`) whose light is ``part``
    and whose drawing is ``filled & ~part``, else None."""
    from scipy import ndimage

    holes = filled & ~part
    if not holes.any() or filled.mean() < PAGE_SHARE or not _fills_its_box(filled, PAGE_BOX_FILL):
        return None
    thinned = ndimage.binary_erosion(holes, iterations=stroke)
    if thinned.sum() >= holes.sum() / 3 and not _fills_its_box(filled, PAGE_RECTANGLE):
        return None  # wide holes in a shape that is no rectangle: a letter's counters, a silhouette's gaps
    return filled


def load_target_image(path: str | os.PathLike) -> TargetImage:
    """Read a target picture (any format Pillow reads) and its optional sidecar JSON."""
    path = Path(path)
    try:
        exists = path.exists()
    except (OSError, ValueError):  # a name too long to look up
        exists = False
    if not exists:
        if is_link_quietly(path):  # exists() follows links: a dangling link or a loop reads as missing
            raise TargetFileError(f"target file {cut_text(str(path))} is a symbolic link to nothing (its target is "
                                  "missing, or the links lead round in a loop); point it at the picture") from None
        raise TargetFileError(f"target file {cut_text(str(path))} does not exist") from None
    image = open_image(path, square=True)
    shape = (image.height, image.width)
    frames = image.info.get(FRAMES, 1)
    try:
        mask = check_mask(mask_from_image(image), cut_text(str(path)))
    except TargetFileError as exc:
        if image.mode == "F" and not np.isfinite(np.asarray(image)).any():  # (read as black: "draw darker")
            raise TargetFileError(f"{cut_text(str(path))}: the picture's pixels are all NaN or infinite, so nothing "
                                  "is drawn; export the render with the drawing's values") from None
        if _fully_transparent(image):  # (its colours, read instead, were blank too)
            raise TargetFileError(f"{cut_text(str(path))}: the picture is fully transparent (every pixel's alpha is "
                                  "0), so nothing is drawn; export it with the drawing's layer visible") from None
        if frames > 1:  # say which frame was read: the drawing may be on another
            raise TargetFileError(f"{exc} (the file holds {frames} frames or pages; procmod reads the first: "
                                  "save the one with the drawing on its own)") from None
        raise
    notes = []
    top, left, height, width = picture_in_square(*shape)
    frame = drawn_frame(mask, (top, left, height, width))
    # a light frame around a light drawing on dark ground was read as a page with the
    # drawing as holes too, and said so beside the frame's note: the frame is the light rectangle (h68)
    page = None if frame is not None else page_taken_for_shape(image, mask[top:top + height, left:left + width])
    if page is not None:
        notes.append(f"{PAGE_NOTE} covering {page:.0%} of the picture with the drawing as "
                     "holes in it: a page photographed on a desk about as dark as its ink? Crop the photo to the "
                     "page (or photograph it on a lighter surface)")
    if frame is not None:
        mask = mask & ~frame
        notes.append("a rectangular frame drawn around the picture was left out of the shape (its lowest line had "
                     "taken the start); crop inside it to say so yourself")
    card = card_read_as_shape(image, mask[top:top + height, left:left + width]) if frame is None else None
    if card is not None:
        notes.append(f"the opaque part, a light rectangle covering {card:.0%} of the canvas with marks on it, was read "
                     "as the shape; if it is a card or page with the drawing on it, crop the picture to the card (or "
                     "flatten it onto white) to read the drawing")
    faint = translucent_left_out(image)
    if faint > TRANSLUCENT_NOTE:
        notes.append(f"translucent strokes (under half the drawing's strongest opacity), {faint:.0%} as many pixels as "
                     "the shape read, were left out of it: a brush whose opacity follows the pen's pressure? "
                     "Export the drawing at full opacity to keep them")
    if frames > 1:  # the drawing may be on another
        notes.append(f"the file holds {frames} frames or pages and procmod read the first; save the one with the "
                     "drawing on its own if it is another")
    placement = _read_sidecar(path, shape) or {}
    if "start" not in placement:  # the picture decides what the sidecar leaves out
        start, direction = lowest_point_start(mask)
        placement = {"start": start, "direction": direction, **placement}
    elif "direction" not in placement:  # a start of the user's own: grow up the picture from it
        placement["direction"] = (0.0, -1.0)
    return TargetImage(_picture_name(path), mask, tuple(placement["start"]), tuple(placement["direction"]),
                       picture=picture_in_square(*shape), notes=tuple(notes))


def _picture_name(path: Path) -> str:
    """A picture's name in reports and ``settings.json``: its file name, written as a
    path (``./circuit``) where the bare name is a built-in target's spec (a picture file
    named ``circuit`` or ``glyph:a`` had been recorded as the built-in target)."""
    name = path.name
    if name == "circuit" or name.startswith(("circuit:", "glyph:", "scribble:")):
        return f"./{name}"
    return name


def place_model(model, image: TargetImage):
    """``model`` configured to start where the target says, if it takes start/direction as
    the built-in models do: a ``start`` whose default is a point in normalised image
    coordinates (two numbers in [0, 1]), and then a ``direction`` whose default is a 2D
    vector. A
    user's model may name its own parameters so (a start point in world units, a heading
    in radians): those are its own, and the picture's placement would have been written
    over them, silently or refused as a value of the wrong kind the user never gave."""
    placed = picture_placed(model.params)
    values = {"start": image.start, "direction": image.direction}
    return model.configure(**{name: [float(v) for v in values[name]] for name in placed}) if placed else model


def out_of_bounds_penalty(canvas, oob_sigma: float | None) -> float:
    """vines.md's penalty ``(ex^2 + ey^2) / oob_sigma^2`` for geometry beyond the viewport."""
    if oob_sigma is None:
        return 0.0
    ex, ey = canvas.out_of_bounds()
    if ex == 0.0 and ey == 0.0:  # the usual case, cheaply
        return 0.0
    return (ex * ex + ey * ey) / (oob_sigma * oob_sigma)


def check_canvas(output, what: str):
    """The scoring canvas of a 2D model (an output of dimension 2: a raster
    :class:`procmod.geometry.Canvas`), or a clear error for other models."""
    if output.dimension != 2:
        raise InvalidArgumentError(f"{what} needs a 2D model that draws into a raster canvas")
    return output
