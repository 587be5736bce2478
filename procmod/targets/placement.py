"""Whether a 3D target and a model meet: same place, similar size.

A model builds at its own origin in its own units; a target mesh keeps the frame of the
tool that exported it (Maya writes centimetres by default, a CAD file millimetres, a
scene may sit far from its origin). Against such a target every derivation scores about
nothing and the engines run to the end without saying why. :func:`placement_note`
compares where the model's prior samples lie with where the target asks for shape and
says, in one line, what is off and how to put it right. It is advice (the caller prints
it), not a refusal: a target may deliberately be much larger than one sample (a city
block for a growing city) or lie beside the origin.

For a picture (a 2D shape target) the same function says when what procmod read is
probably not what the user drew: a mask covering most of the picture (a dark frame, a
table or the paper itself taken for the shape), a band along one edge beside the drawing
(a scanner lid's shadow), or strokes too thin to survive the model's canvas.
"""

from __future__ import annotations

import math
import time

import numpy as np

from ..core.runtime import run_forward
from .files import span_text, up_rotation
from .shape import ShapeMatch
from .silhouette import Silhouette
from .volume import ProxyVolume, Volume

SAMPLES = 16
"""Prior samples whose median bounding box stands for the model's size and place."""

SCALE_FACTOR = 10.0
"""Sizes differing by more than this factor either way are worth a note."""


def model_box(model, rng: np.random.Generator, samples: int = SAMPLES, seconds: float = 1.0):
    """The median (over ``samples`` prior derivations with parts, or those drawn within
    ``seconds``) of each corner coordinate of their world bounding boxes, as ``(lo, hi)``,
    or None when no sample drew a part. The median, not the union: one sample flung far
    must not stand for all."""
    boxes = []
    start = time.perf_counter()
    for _ in range(samples):
        if boxes and time.perf_counter() - start > seconds:
            break
        extent = getattr(run_forward(model, rng).output, "extent", None)
        if extent is not None:
            boxes.append(extent)
    if not boxes:
        return None
    return (np.median([b[0] for b in boxes], axis=0), np.median([b[1] for b in boxes], axis=0))


def _corners(lo, hi) -> np.ndarray:
    return np.array([[(lo, hi)[i >> a & 1][a] for a in range(3)] for i in range(8)], dtype=np.float64)


def _fill(target) -> np.ndarray:
    """The voxels where a volume target gains (a proxy target: its mask)."""
    gain = getattr(target, "combined", None)
    return gain > 0 if gain is not None else np.asarray(target.mask)


def _volume_box(target):
    """The box of the voxels where the target gains (its fill), in world units."""
    inside = _fill(target)
    if not inside.any():
        return None
    index = np.argwhere(inside)
    grid = target.grid
    origin = np.asarray(grid.origin, dtype=np.float64)
    return origin + grid.size * index.min(axis=0), origin + grid.size * (index.max(axis=0) + 1)


STRAY_SHARE = 0.02
"""Far pieces of a volume target's fill (:func:`_stray_fill`) are called stray only when
they hold at most this share of its voxels."""


def _stray_fill(target):
    """``(lo, hi, voxels, near)`` when small pieces of a volume target's fill lie far from
    its largest piece (:data:`procmod.targets.files.STRAY_DISTANCE` times that piece's
    size): the largest piece's box in world units, the strays' voxel count and a point
    near them; else None. A helper object or a stray face left far off in the exported
    scene stretches the fill's box, which a note must not take for other units."""
    from scipy import ndimage

    from .files import STRAY_DISTANCE

    labels, count = ndimage.label(_fill(target))
    if count < 2:
        return None
    sizes = np.bincount(labels.ravel())[1:]
    main = int(np.argmax(sizes))
    boxes = [(np.array([s.start for s in box]), np.array([s.stop for s in box]))
             for box in ndimage.find_objects(labels)]
    m_lo, m_hi = boxes[main]
    reach = STRAY_DISTANCE * float(np.linalg.norm(m_hi - m_lo))
    strays = [k for k, (lo, hi) in enumerate(boxes) if k != main and sizes[k] < sizes[main]
              and float(np.linalg.norm(np.maximum(np.maximum(m_lo - hi, lo - m_hi), 0))) > reach]
    # small beside the rest: separate buildings of a sparse settlement are not strays
    if not strays or sizes[strays].sum() > STRAY_SHARE * sizes.sum():
        return None
    grid = target.grid
    origin = np.asarray(grid.origin, dtype=np.float64)
    near = origin + grid.size * 0.5 * (boxes[strays[0]][0] + boxes[strays[0]][1])
    return origin + grid.size * m_lo, origin + grid.size * m_hi, int(sizes[strays].sum()), near


def _size(lo, hi) -> float:
    return float(np.linalg.norm(np.asarray(hi) - np.asarray(lo)))


def _digits(v: float, resolution: float | None, least: int) -> str:
    """``v`` with ``least`` significant digits, or as many as keep it within ``resolution``:
    a mesh 123456.7 from the origin written as 1.235e+05 was 43 units off, several times
    the model's size, and the note then repeated the value the user had already given."""
    v = float(v)
    digits = least
    if resolution and resolution > 0 and v != 0 and math.isfinite(v):
        digits = min(17, max(least, math.ceil(math.log10(abs(v) / resolution)) + 1))
    return f"{v:.{digits}g}"


def _shown(vector, resolution: float | None = None) -> str:
    return "(" + ", ".join(_digits(v, resolution, 3) for v in vector) + ")"


def _listed(vector, resolution: float | None = None) -> str:
    return "[" + ", ".join(_digits(v, resolution, 4) for v in vector) + "]"


def _rescale_advice(target, factor: float, resolution: float) -> str:
    """What to write in the target file to scale its shape by ``factor``, from what it holds
    now (:attr:`placed_by`, set when the file was read); positions to ``resolution``."""
    placed = getattr(target, "placed_by", None)
    if placed is None:  # built in Python: no file to edit
        return f"scale the target by about {factor:g}"
    kind, scale, offset = placed
    if kind == "grid":  # .npy layers lie on the file's grid: scale the grid itself
        grid = target.grid
        return (f"give grid.voxel_size {grid.size * factor:.4g} and grid.origin "
                f"{_listed(np.asarray(grid.origin) * factor, resolution)} in the target file")
    advice = f"give \"mesh_scale\": {scale * factor:.4g}"
    if np.any(offset):
        advice += f" and \"mesh_offset\": {_listed(np.asarray(offset) * factor, resolution)}"
    grid = getattr(target, "grid", None)
    if getattr(target, "grid_from_voxel_size", False) \
            and not VOXELS_ACROSS[0] <= max(grid.shape) * factor <= VOXELS_ACROSS[1]:
        # a voxel_size chosen for the mesh as it was read: scaled with it, the grid keeps its
        # voxels (kept as it is, a mesh 100x smaller fell within two voxels and was refused)
        advice += f" and \"voxel_size\": {grid.size * factor:.4g}"
    return advice + " in the target file"


# Voxels along a volume target's longest side, after the scale a note advises, outside
# which the note advises scaling the voxel size too.
VOXELS_ACROSS = (8, 1000)


def _move_advice(target, delta, resolution: float) -> str:
    """What to write in the target file to move its shape by ``delta`` (to ``resolution``)."""
    placed = getattr(target, "placed_by", None)
    if placed is None:
        return f"move the target by about {_listed(delta, resolution)}"
    kind, _, offset = placed
    if kind == "grid":
        return f"give grid.origin {_listed(np.asarray(target.grid.origin) + delta, resolution)} in the target file"
    return f"give \"mesh_offset\": {_listed(np.asarray(offset) + delta, resolution)} in the target file"


def _volume_note(target, lo, hi) -> str | None:
    box = _volume_box(target)
    if box is None:
        return None
    t_lo, t_hi = box
    t_size, m_size = _size(t_lo, t_hi), _size(lo, hi)
    if m_size <= 0:
        return None
    ratio = t_size / m_size
    if not 0 < ratio < math.inf:
        return None  # a fill of no size (or beyond float range): nothing to compare
    what = "the target's fill"
    where = f"spans {_shown(t_lo, 0.01 * t_size)} to {_shown(t_hi, 0.01 * t_size)}"
    model = f"about {_shown(lo)} to {_shown(hi)}"
    resolution = 1e-3 * m_size  # advice to a thousandth of the model's size
    if ratio > SCALE_FACTOR or ratio < 1 / SCALE_FACTOR:
        stray = _stray_fill(target)
        also = ""
        if stray is not None:
            s_lo, s_hi, voxels, near = stray
            gone = (f"{voxels} voxel{'s' if voxels > 1 else ''} of the target's fill {'lie' if voxels > 1 else 'lies'} "
                    f"far from the rest (near {_shown(near, 0.01 * t_size)})")
            rest = _size(s_lo, s_hi) / m_size
            if 1 / SCALE_FACTOR <= rest <= SCALE_FACTOR:
                # the rest alone is the model's size: the stray, not the units, stretched the box
                return (f"{gone}, while the rest spans {span_text(s_lo, s_hi)}: delete that stray geometry (a "
                        "helper object, a stray face) in a modelling tool; the fill's box, stretched by it, is not "
                        "the shape's")
            ratio, also = rest, f"; and {gone}: delete that stray geometry"  # the units from the rest alone
            where = f"spans {_shown(s_lo, 0.01 * t_size)} to {_shown(s_hi, 0.01 * t_size)} (less a stray piece)"
        factor = 10 ** round(math.log10(1 / ratio))
        return (f"{what} {where}, {ratio:.3g}x the size of the model's samples ({model}): if it was made in "
                f"other units (Maya's default is centimetres), {_rescale_advice(target, factor, resolution)}{also}")
    turned = _up_note(target, what, t_lo, t_hi, lo, hi, resolution)
    if turned is not None:  # before the place: a lying target moved onto the model still lies
        return turned
    if np.any(t_lo > hi) or np.any(t_hi < lo):
        delta = 0.5 * (np.asarray(lo) + np.asarray(hi)) - 0.5 * (t_lo + t_hi)
        return (f"{what} {where} and does not meet the model's samples, which build at its origin ({model}): "
                f"to move it onto them, {_move_advice(target, delta, resolution)}")
    return None


def _up_note(target, what: str, t_lo, t_hi, lo, hi, resolution: float) -> str | None:
    """The note for a mesh target (its box ``t_lo``..``t_hi``) lying on its side next to the
    model's samples (``lo``..``hi``): turned over by its file's ``"mesh_up"``, or a z-up
    tool's mesh read y-up; None when it stands."""
    up = getattr(target, "mesh_up", "y")
    if up != "y" and _turned_onto_its_side(target, np.asarray(t_hi) - np.asarray(t_lo), np.asarray(hi) - np.asarray(lo)):
        return (f"{what} is {span_text(t_lo, t_hi)} (x, y, z), shaped like the model's samples "
                f"({span_text(lo, hi)}) laid on their side, and stands as the file has it: the target file's "
                f"\"mesh_up\": \"{up}\" turned it over; leave \"mesh_up\" out if the mesh is y-up (glTF is, "
                "and so are OBJ files exported with a tool's defaults)")
    if _lying(target, np.asarray(t_hi) - np.asarray(t_lo), np.asarray(hi) - np.asarray(lo)):
        return (f"{what} is {span_text(t_lo, t_hi)} (x, y, z), shaped like the model's "
                f"samples ({span_text(lo, hi)}) laid on their side: if the mesh comes "
                "from a z-up tool (3ds Max, a CAD file, an OBJ or STL exported \"Z up\"), give \"mesh_up\": "
                f"\"z\"{_offset_once_stood(target, t_lo, t_hi, lo, hi, resolution)} in the target file "
                "(procmod's models are y-up)")
    return None


# A mesh target lying on its side (a z-up tool's file read y-up): its box's shape, its size
# set aside, is unlike the model's samples' (some side's proportion off by more than LYING)
# and, stood up from z, like it (every side within STANDING). Advice only, for volume
# targets' meshes read with the default y up.
LYING, STANDING = 2.0, 1.5


def _lies_but_stands(t_ext, m_ext, stood_ext) -> bool:
    """Whether a target's box (extents ``t_ext``) is unlike the model's samples' (``m_ext``)
    in its proportions, whatever its size (some side off by more than :data:`LYING`), and
    like them turned (``stood_ext``, every side within :data:`STANDING`)."""
    floor = 1e-9 * float(max(np.max(t_ext), np.max(m_ext)))

    def shape(e):  # proportions: the extents over their geometric mean
        logs = np.log(np.maximum(np.asarray(e, dtype=np.float64), floor))
        return logs - logs.mean()

    model = shape(m_ext)
    return float(np.abs(shape(t_ext) - model).max()) > math.log(LYING) and \
        float(np.abs(shape(stood_ext) - model).max()) <= math.log(STANDING)


def _placed_by_meshes(target) -> bool:
    placed = getattr(target, "placed_by", None)
    return placed is not None and placed[0] == "meshes"


def _lying(target, t_ext, m_ext) -> bool:
    """Whether a mesh target's box is the model's samples' shape laid on its side (y and z
    swapped), whatever its size: a z-up tool's file read y-up."""
    if not _placed_by_meshes(target) or getattr(target, "mesh_up", "y") != "y":
        return False
    return _lies_but_stands(t_ext, m_ext, t_ext[[0, 2, 1]])  # "z" turns (x, y, z) to (x, z, -y)


def _turned_onto_its_side(target, t_ext, m_ext) -> bool:
    """Whether a mesh target read with a ``"mesh_up"`` other than y lies on its side next to
    the model's samples and stood as its file has it (the turn undone): a y-up file given
    ``"mesh_up": "z"``. The note for the default up said nothing here."""
    if not _placed_by_meshes(target):
        return False
    return _lies_but_stands(t_ext, m_ext, np.abs(up_rotation(target.mesh_up)).T @ t_ext)  # before the turn


def _offset_once_stood(target, t_lo, t_hi, lo, hi, resolution: float) -> str:
    """The mesh_offset (added after the turn) that puts the stood-up target's centre on the
    model's: with a file that gives one (the old one would move it off), or when the target
    stood up would not meet the model (a centimetre z-up mesh far from the origin took a
    run for each piece of advice, h79)."""
    _, scale, offset = target.placed_by
    centre = (0.5 * (np.asarray(t_lo) + np.asarray(t_hi)) - offset) / scale  # in the mesh's own frame
    new = 0.5 * (np.asarray(lo) + np.asarray(hi)) - up_rotation("z") @ centre * scale
    if not np.any(offset):
        half = 0.5 * np.abs(up_rotation("z")) @ (np.asarray(t_hi) - np.asarray(t_lo))
        stood = up_rotation("z") @ centre * scale  # the stood-up target's centre, not moved
        if np.all(stood + half >= lo) and np.all(stood - half <= hi):
            return ""  # stood up, it meets the model: no offset to give
    return f" and \"mesh_offset\": {_listed(new, resolution)}"


MOST_OF_THE_VIEW = 0.95
"""A silhouette view whose shape to hit covers more than this share of it, its whole border
included (so that no outline is left in view; a close-up may fill most of it), gets a note."""


def _silhouette_note(target, lo, hi) -> str | None:
    return _view_note(target, lo, hi) or _mesh_view_note(target, lo, hi)


def _mesh_view_note(target, lo, hi) -> str | None:
    """For a view of a mesh that the views' own notes said nothing of: the mesh in other
    units (a camera inside a centimetre mesh sees no outline to compare), or lying on its
    side, as a volume's mesh may (h79: a z-up STL seen from the side, without a word)."""
    for i, box in enumerate(getattr(target, "mesh_boxes", ()) or ()):
        if box is None:
            continue
        ratio = _size(*box) / max(_size(lo, hi), 1e-300)
        if ratio > SCALE_FACTOR or ratio < 1 / SCALE_FACTOR:
            factor = 10 ** round(math.log10(1 / ratio))
            return (f"views[{i}]: the mesh spans {span_text(*box)}, {ratio:.3g}x the size of the model's samples "
                    f"(about {_shown(lo)} to {_shown(hi)}): if it was made in other units (Maya's default is "
                    f"centimetres), {_rescale_advice(target, factor, 1e-3 * _size(lo, hi))}")
        turned = _up_note(target, f"views[{i}]: the mesh", *box, lo, hi, 1e-3 * _size(lo, hi))
        if turned is not None:
            return turned
    return None


def _view_note(target, lo, hi) -> str | None:
    """What each view shows against the model's samples seen by its camera."""
    grounded = getattr(target, "grounded_views", set())
    corners = _corners(lo, hi)
    kinds = getattr(target, "view_kinds", None) or ["mesh"] * len(target.cameras)  # a file's: what each view gave
    for i, (camera, weights) in enumerate(zip(target.cameras, target.weights)):
        hit = np.argwhere(weights > 0)
        if not hit.size:
            continue
        covered = len(hit) / weights.size
        border = np.concatenate([weights[0], weights[-1], weights[:, 0], weights[:, -1]])
        if covered > MOST_OF_THE_VIEW and (border > 0).all():  # no outline in view: every derivation alike
            if kinds[i] != "mesh":  # a painted mask or a picture: no units to give
                return (f"views[{i}]: the shape to hit covers {100 * covered:.0f}% of the view, so it has no outline "
                        "to match: mark only the shape to hit (black) and leave the rest white")
            if i in grounded:  # the floor named above fills it, not the units (h81)
                return (f"views[{i}]: the shape to hit covers {100 * covered:.0f}% of the view, so it has no outline "
                        "to match: the flat piece named above fills it")
            return (f"views[{i}]: the shape to hit covers {100 * covered:.0f}% of the view, so it has no outline "
                    "to match: if it is a mesh made in other units than the model (Maya writes centimetres), "
                    "give \"mesh_scale\" (0.01 for centimetres to metres); else move the camera back")
        if covered > MOST_OF_THE_PICTURE and (border > 0).all() and (weights < 0).any():
            return (f"views[{i}]: the shape to hit surrounds the rest of the view ({100 * covered:.0f}% of it, its "
                    "whole border): a picture's dark pixels are the ones to hit; if its shape is the light part (a "
                    "white-on-black mask, an alpha pass), invert the picture")
        projected = camera.project(corners)
        behind = projected[:, 2] <= 0
        if behind.all():
            return (f"views[{i}]: the model's samples (at its origin, about {_shown(lo)} to {_shown(hi)}) lie "
                    "behind the camera: point the camera's look_at at the model")
        if behind.any():
            continue  # the camera is inside the model's box: sizes on screen mean nothing
        p_lo, p_hi = projected[:, :2].min(axis=0), projected[:, :2].max(axis=0)
        t_lo, t_hi = hit.min(axis=0)[::-1], hit.max(axis=0)[::-1] + 1  # (x, y) pixels
        t_size, m_size = _size(t_lo, t_hi), _size(p_lo, p_hi)
        view = f"views[{i}]"
        if m_size > 0 and not 1 / SCALE_FACTOR <= t_size / m_size <= SCALE_FACTOR:
            return (f"{view}: the shape to hit spans {t_size:.0f} pixels on screen, the model's samples about "
                    f"{m_size:.3g} ({t_size / m_size:.3g}x): move the camera so the model (which builds at its "
                    f"origin, about {_shown(lo)} to {_shown(hi)}) fills the view as the target should"
                    + (" (a mesh in other units: \"mesh_scale\", with the camera in the model's units)"
                       if kinds[i] == "mesh" else ""))
        if np.all(p_hi < 0) or np.all(p_lo > (camera.width, camera.height)) or np.any(p_hi < t_lo) \
                or np.any(p_lo > t_hi):
            return (f"{view}: the model's samples (at its origin, about {_shown(lo)} to {_shown(hi)}) fall "
                    "beside the shape to hit in the view: point the camera's look_at at the model")
    return None


MOST_OF_THE_PICTURE = 0.5
"""A shape read as covering more than this share of its picture gets a note."""

VANISHED = 0.25
"""A note when more than this share of a picture's shape is lost at the model's canvas
(after :func:`procmod.targets.image.stroke_preserving_mask` widened thin strokes)."""

EDGE_BAND_LENGTH = 0.6
EDGE_BAND_DEPTH = 0.25
"""A part of a picture's shape that runs along one edge of the picture for more than
:data:`EDGE_BAND_LENGTH` of it and reaches no further in than :data:`EDGE_BAND_DEPTH` of
the picture, beside another part of the shape, gets a note (a scanner lid's shadow)."""


def _edge_band(mask: np.ndarray, picture: tuple | None = None) -> tuple[str, float] | None:
    """``(side, share of the shape)`` of a thin band of the mask along one edge of the
    picture, separate from the rest of the shape, or None (:data:`EDGE_BAND_LENGTH`).
    ``picture``: where the picture lies in the mask (:attr:`TargetImage.picture`; a
    portrait scan is padded to a square, and its edges are inside the frame). A shape
    cut tight to the picture touches its edges too, but is all one part, or reaches far in."""
    if picture is not None:
        top, left, height, width = picture
        mask = mask[top:top + height, left:left + width]
    height, width = mask.shape
    if mask.size == 0 or not any(line.sum() > EDGE_BAND_LENGTH * length for line, length in
               ((mask[:, 0], height), (mask[:, -1], height), (mask[0], width), (mask[-1], width))):
        return None  # no side has a band's length of shape (importing scipy.ndimage costs ~0.13 s)
    from scipy import ndimage

    labels, count = ndimage.label(mask, structure=np.ones((3, 3)))
    if count < 2:
        return None
    sizes = np.bincount(labels.ravel())[1:]
    # each side: its pixels, its length, and the picture's extent across it
    sides = {"left": (labels[:, 0], height, width), "right": (labels[:, -1], height, width),
             "top": (labels[0], width, height), "bottom": (labels[-1], width, height)}
    for side, (line, length, across) in sides.items():
        found = np.bincount(line, minlength=count + 1)[1:]
        part = int(np.argmax(found)) + 1
        if found[part - 1] <= EDGE_BAND_LENGTH * length:
            continue
        rows, cols = np.nonzero(labels == part)
        depth = {"left": cols.max() + 1, "right": width - cols.min(), "top": rows.max() + 1,
                 "bottom": height - rows.min()}[side]
        others = np.delete(sizes, part - 1)
        if depth <= EDGE_BAND_DEPTH * across and others.max() >= 0.02 * sizes[part - 1]:  # beside a drawing, not dust
            return side, float(sizes[part - 1]) / float(sizes.sum())
    return None


SMALL_DRAWING = 0.3
"""A drawing whose thin strokes were widened and which spans less than this share of the
model's canvas is advised to be cropped closer (:func:`_picture_advice`)."""

EDGE_SCRAP_SHARE = 0.25
"""A start on a part of the shape that touches the picture's edge and holds less than
this share of the shape, beside a larger part, gets a note (a photo's shadow in a corner,
h124: the lowest point of the shape lay on it, and the model grew there)."""


def _start_on_edge_scrap(mask: np.ndarray, picture: tuple | None, start) -> tuple[str, float] | None:
    """``(side, share of the shape)`` of the part of the mask the start lies on, where that
    part touches an edge of the picture and is small beside another (:data:`EDGE_SCRAP_SHARE`),
    or None."""
    if start is None or not mask.any():
        return None
    height, width = mask.shape
    col = min(width - 1, int(float(start[0]) * width))
    row = min(height - 1, int(float(start[1]) * height))
    if not mask[row, col]:
        return None
    top, left, h, w = picture if picture is not None else (0, 0, height, width)
    edges = {"left": (slice(top, top + h), left), "right": (slice(top, top + h), left + w - 1),
             "top": (top, slice(left, left + w)), "bottom": (top + h - 1, slice(left, left + w))}
    if not any(mask[at].any() for at in edges.values()):
        return None  # nothing touches an edge (importing scipy.ndimage costs ~0.13 s)
    from scipy import ndimage

    labels, count = ndimage.label(mask, structure=np.ones((3, 3)))
    if count < 2:
        return None
    sizes = np.bincount(labels.ravel())[1:]
    part = labels[row, col]
    share = float(sizes[part - 1]) / float(sizes.sum())
    if share >= EDGE_SCRAP_SHARE or sizes[part - 1] >= sizes.max():
        return None
    for side, at in edges.items():
        if (labels[at] == part).any():
            return side, share
    return None


def picture_note(target: ShapeMatch, model) -> str | None:
    """One line when a picture target's mask is probably not the drawing (see the module
    docstring), or reading it guessed (:attr:`TargetImage.notes`), else None."""
    advice = _picture_advice(target, model)
    start = _start_off_drawing(target)
    said = [*target.image.notes, *([advice] if advice else []), *([start] if start else [])]
    return "; ".join(said) if said else None


OFF_DRAWING = 0.1
"""A picture target's start farther than this (of the picture's side) from every pixel of
its shape gets a note: a sidecar's or ``--param start``'s start off the drawing grows the
model across the paper before it can reach the shape."""


def _start_off_drawing(target: ShapeMatch) -> str | None:
    """A note when the start lies :data:`OFF_DRAWING` or farther from the shape (the start
    the picture's drawing gives lies on it: only a sidecar's or the user's can be off)."""
    image = target.image
    mask = image.mask
    if not mask.any() or image.start is None:
        return None
    side = max(mask.shape)
    x, y = float(image.start[0]) * mask.shape[1], float(image.start[1]) * mask.shape[0]
    # the shape in blocks of ~1/200 of the picture (a block holding any of it counts: a
    # stride passed over a 1-pixel line, h87), each at its centre: a distance, not a fit
    step = max(1, side // 200)
    h, w = -(-mask.shape[0] // step) * step, -(-mask.shape[1] // step) * step
    blocks = np.pad(mask, ((0, h - mask.shape[0]), (0, w - mask.shape[1])))
    blocks = blocks.reshape(h // step, step, w // step, step).any(axis=(1, 3))
    rows, cols = np.nonzero(blocks)
    centre = 0.5 * step
    nearest = float(np.sqrt(((rows * step + centre - y) ** 2 + (cols * step + centre - x) ** 2).min()))
    nearest = max(0.0, nearest - 0.71 * step) / side  # a block's centre is up to 0.71 of its side from its pixels
    if nearest < OFF_DRAWING:
        return None
    return (f"the start lies {nearest:.0%} of the picture from the nearest of its shape: the "
            "model grows from there across the paper before it reaches the shape; give a start on the drawing "
            "(a sidecar's or --param start's, in the picture's coordinates, 0-1, y down), or none for its lowest "
            "point")


def _picture_advice(target: ShapeMatch, model) -> str | None:
    """:func:`picture_note`'s advice of its own."""
    from .image import PAGE_NOTE, _fills_its_box

    mask = target.image.mask
    picture = target.image.picture
    if picture is not None:  # the picture's own area, not the square it was padded to
        top, left, height, width = picture
        fill = float(mask[top:top + height, left:left + width].mean())
    else:
        fill = float(mask.mean())
    # a page read as the shape is a near rectangle; a filled silhouette (a mountain, a disc)
    # covering as much is not
    # a built-in target (glyph:, scribble:) is drawn by procmod, with no paper or border
    # of a user's to crop: its advice is for pictures
    built_in = target.name.startswith(("glyph:", "scribble:"))
    page_named = any(note.startswith(PAGE_NOTE) for note in target.image.notes)  # the same advice, said once
    if fill > MOST_OF_THE_PICTURE and _fills_its_box(mask, 0.85) and not built_in and not page_named:
        return (f"the shape read from {target.name} covers {fill:.0%} of the picture: the border's colour was "
                "taken for the paper, so if the paper is inside a dark frame or on a table, crop that away; "
                "a shape trimmed to its own edges needs some paper around it")
    band = None if built_in else _edge_band(mask, picture)
    if band is not None:
        return (f"a band along the {band[0]} edge of {target.name} ({band[1]:.0%} of the shape read) is taken as "
                "part of the shape: if it is a scanner lid's shadow or a frame, crop it away or paint it the "
                "paper's colour")
    scrap = None if built_in else _start_on_edge_scrap(mask, picture, target.image.start)
    if scrap is not None:
        return (f"the start lies on a small part of {target.name}'s shape at the picture's {scrap[0]} edge "
                f"({scrap[1]:.0%} of the shape read), apart from the drawing: if it is a shadow or the paper's "
                "edge, crop it away or paint it the paper's colour, or give a start on the drawing (a sidecar's "
                "or --param start's)")
    canvas = model.new_output()
    width, height = getattr(canvas, "width", None), getattr(canvas, "height", None)
    if not width or not height or mask.shape == (height, width):
        return None
    from .image import THIN_STROKE, lost_share, widened_share
    widened = widened_share(mask, width, height)
    lost = lost_share(mask, target.image.at_size(width, height))
    if lost > VANISHED:
        return (f"{lost:.0%} of the shape read from {target.name} (thin strokes, small marks) vanishes at the model's "
                f"{width}x{height} canvas, which scores against what is left: draw those strokes thicker, "
                "or crop the picture closer to the shape")
    rows, cols = np.flatnonzero(mask.any(axis=1)), np.flatnonzero(mask.any(axis=0))
    side = max(mask.shape)  # the square the picture was padded to: the canvas's
    across = (max(rows[-1] - rows[0] + 1, cols[-1] - cols[0] + 1) / side * max(width, height)) if len(rows) else 0.0
    if widened is not None and not built_in and len(rows) and across < SMALL_DRAWING * max(width, height):
        # a doodle on a full page: drawing thicker would not help, the page around it is
        # what makes it small (h151: a 12-pixel blob, and the advice was to draw thicker)
        return (f"the shape read from {target.name} spans about {across:.0f} pixels of the model's "
                f"{width}x{height} canvas, the rest of the picture being paper, so its strokes merge there: crop "
                "the picture closer to the drawing")
    if widened is not None:
        return (f"the strokes of {target.name} are under {THIN_STROKE:g} pixels of the model's {width}x{height} "
                f"canvas wide "
                f"({widened:.0%} of the shape would break up there), so its thin strokes were widened by half a "
                "canvas pixel on each side, where they were drawn; draw them thicker to set their width yourself")
    return None


def placement_note(model, target, rng: np.random.Generator, samples: int = SAMPLES) -> str | None:
    """One line of advice when the 3D ``target`` and ``model``'s prior samples differ in
    size by more than :data:`SCALE_FACTOR` or do not meet at all; None when they do meet,
    or for targets this does not apply to (style scores). A picture target gets
    :func:`picture_note`'s advice."""
    if isinstance(target, ShapeMatch):
        return picture_note(target, model)
    if not isinstance(target, (Volume, ProxyVolume, Silhouette)):
        return None
    notes = list(getattr(target, "file_notes", ()))  # what reading the file found (targets.files)
    box = model_box(model, rng, samples)
    if box is not None:
        notes.append(_silhouette_note(target, *box) if isinstance(target, Silhouette) else _volume_note(target, *box))
    notes = [n for n in notes if n]
    return "; ".join(notes) if notes else None
