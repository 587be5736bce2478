"""``Silhouette``: seed 002's image score s_img for 3D models.

Given weighted images ``I_i`` (positive = should be hit, negative = should be avoided,
zero = don't care) and cameras ``C_i``,

    s_img(M) = sum_i sum_p project_{C_i}(M)(p) I_i(p)

i.e. every pixel the model's silhouette covers adds that pixel's weight, kept
incrementally by :class:`procmod.geometry.camera.Silhouettes`. The score is s_img; the
log-likelihood is ``s_img / temperature`` (default: 1% of the best attainable s_img).

Files (``procmod-silhouette/1`` JSON, paths relative to it)::

    {"format": "procmod-silhouette/1",
     "views": [{"image": "sketch.png", "hit": 1.0, "avoid": -1.0,
                "camera": {"eye": [0, 4, 20], "look_at": [0, 4, 0], "up": [0, 1, 0],
                           "projection": "orthographic", "fov": 10}}]}

A view gives either ``"weights"`` (an .npy float image) or ``"image"``, a picture read
as: dark (< 85) = hit weight, light (> 170) = avoid weight, mid grey = don't care.
The camera's resolution is the image's (at most :data:`~procmod.targets.image.MAX_IMAGE_PIXELS`
pixels). Every field is checked when the file is read, and a bad one is refused in one
line naming the file and the field: ``eye``, ``look_at`` and ``up`` are three finite
numbers (``up`` not zero and not along the view direction), ``fov`` a finite positive
number (perspective: degrees below 180), ``hit`` and ``avoid`` finite numbers.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np
from PIL import Image

from ..core import InvalidArgumentError
from ..core.paths import UnsafePathError, named_file
from ..core.serialize import read_json
from ..geometry.camera import Camera, Silhouettes
from .image import MAX_IMAGE_PIXELS, TargetFileError, open_image


class Silhouette:
    """Weighted silhouette images under given cameras (seed 002's s_img).

    ``exact_removal``: the score is the silhouettes' ``gain_total``, which
    :meth:`Silhouettes.remove` restores exactly (see :class:`procmod.targets.Volume`).
    """

    exact_removal = True

    def __init__(self, views, temperature: float | None = None, name: str = "silhouette"):
        if not views:
            raise InvalidArgumentError("a silhouette target needs at least one view")
        self.cameras, self.weights = [], []
        for weights, camera in views:
            weights = np.asarray(weights, dtype=np.float64)
            if weights.shape != (camera.height, camera.width):
                camera = camera._replace(width=weights.shape[1], height=weights.shape[0])
            self.cameras.append(camera)
            self.weights.append(weights)
        self.name = name
        self.best_attainable = float(sum(np.clip(w, 0, None).sum() for w in self.weights))
        self.temperature = float(temperature if temperature is not None else max(0.01 * self.best_attainable, 1e-9))

    def configure(self, model):
        if hasattr(model.new_output(), "viewport"):
            raise InvalidArgumentError(f"a silhouette target needs a 3D model; {model.name!r} is 2D")
        return model

    def new_output(self, model) -> Silhouettes:
        self.configure(model)
        return Silhouettes(self.cameras, [w.ravel() for w in self.weights])

    def score(self, output: Silhouettes) -> float:
        return output.gain_total

    def log_likelihood(self, output: Silhouettes) -> float:
        return output.gain_total / self.temperature

    def display_mask(self, width: int):
        return None

    def overlay_image(self, output: Silhouettes, index: int = 0, width: int = 256) -> Image.Image:
        """The model's silhouette (green) over view ``index``'s weights (blue = hit,
        yellow = avoid, white = don't care), for reports."""
        w = self.weights[index]
        rgb = np.full(w.shape + (3,), 255, dtype=np.uint8)
        rgb[w > 0] = (200, 205, 245)
        rgb[w < 0] = (250, 246, 220)
        rgb[output.image(index)] = (40, 120, 40)
        height = max(1, round(width * w.shape[0] / w.shape[1]))
        return Image.fromarray(rgb).resize((width, height), Image.NEAREST)


def _shown(value, limit: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= limit else text[:limit - 3] + "..."


def _number(value, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise TargetFileError(f"{where} must be a finite number, got {_shown(value)}")
    return float(value)


def _vector(value, where: str) -> tuple:
    if not isinstance(value, (list, tuple)) or len(value) != 3:
        raise TargetFileError(f"{where} must be three numbers, got {_shown(value)}")
    return tuple(_number(v, f"{where}[{i}]") for i, v in enumerate(value))


def _camera(spec, where) -> Camera:
    if not isinstance(spec, dict):
        raise TargetFileError(f"{where}: \"camera\" must be an object with eye, look_at, ...")
    where = f"{where}.camera"
    for key in ("eye", "look_at"):
        if key not in spec:
            raise TargetFileError(f"{where} needs {key!r} (three numbers)")
    eye, look_at = _vector(spec["eye"], f"{where}.eye"), _vector(spec["look_at"], f"{where}.look_at")
    up = _vector(spec.get("up", (0, 1, 0)), f"{where}.up")
    projection = spec.get("projection", "perspective")
    if projection not in ("perspective", "orthographic"):
        raise TargetFileError(f"{where}.projection must be perspective or orthographic, got {_shown(projection)}")
    fov = _number(spec.get("fov", 40.0), f"{where}.fov")
    if projection == "perspective" and not 0 < fov < 180:
        raise TargetFileError(f"{where}.fov is the vertical field of view in degrees and must lie strictly "
                              f"between 0 and 180, got {fov:g}")
    if projection == "orthographic" and not fov > 0:
        raise TargetFileError(f"{where}.fov is the height of the view in world units and must be positive, "
                              f"got {fov:g}")
    forward = np.subtract(look_at, eye)
    if np.allclose(eye, look_at):
        raise TargetFileError(f"{where}: the camera's eye and look_at coincide")
    length = np.linalg.norm(up)
    if length == 0 or np.linalg.norm(np.cross(forward / np.linalg.norm(forward), np.divide(up, length))) < 1e-9:
        raise TargetFileError(f"{where}.up must be a non-zero vector not along the view direction "
                              f"(look_at - eye), got {list(up)}")
    return Camera(eye, look_at, up, projection, fov)


def _view_file(path: Path, view: dict, key: str, where: str, suffixes, kind: str) -> Path:
    try:
        return named_file(path.parent, view[key], f"{where}.{key}", suffixes, kind)
    except UnsafePathError as exc:
        raise TargetFileError(f"cannot read the {kind}: {exc}") from None


def _load_weights(file: Path, where: str) -> np.ndarray:
    """A 2D float array from an .npy file, its size checked from the header before it is read."""
    try:
        with open(file, "rb") as handle:
            version = np.lib.format.read_magic(handle)
            read_header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                           else np.lib.format.read_array_header_2_0)
            shape, _, dtype = read_header(handle)
    except (OSError, ValueError, TypeError, SyntaxError) as exc:
        raise TargetFileError(f"{where}: cannot read the weights ({_shown(str(exc), 120)})") from None
    if len(shape) != 2:
        raise TargetFileError(f"{where}: weights must be a 2D array, got shape {shape}")
    if shape[0] * shape[1] > MAX_IMAGE_PIXELS:
        raise TargetFileError(f"{where}: the weights are {shape[1]}x{shape[0]} pixels; procmod reads views up to "
                              f"{MAX_IMAGE_PIXELS / 1e6:.0f} megapixels: scale them down")
    if dtype.kind not in "biuf":
        raise TargetFileError(f"{where}: weights must be numbers, got dtype {dtype}")
    try:
        weights = np.load(file, allow_pickle=False).astype(np.float64)
    except (OSError, ValueError, TypeError) as exc:
        raise TargetFileError(f"{where}: cannot read the weights ({_shown(str(exc), 120)})") from None
    if not np.isfinite(weights).all():
        raise TargetFileError(f"{where}: weights must be finite numbers (the file holds NaN or infinity)")
    return weights


def load_silhouette_target(path: str | os.PathLike) -> Silhouette:
    """Read a ``procmod-silhouette/1`` target (see the module docstring)."""
    path = Path(path)
    spec = read_json(path, TargetFileError, "target file")
    views = spec.get("views") if isinstance(spec, dict) else None
    if not isinstance(views, list) or not views:
        raise TargetFileError(f"{path}: \"views\" must be a non-empty list")
    out = []
    for i, view in enumerate(views):
        where = f"{path}: views[{i}]"
        if not isinstance(view, dict):
            raise TargetFileError(f"{where} must be an object")
        camera = _camera(view.get("camera"), where)
        if "weights" in view:
            weights = _load_weights(_view_file(path, view, "weights", where, {".npy"}, "weights"), f"{where}.weights")
        elif "image" in view:
            hit = _number(view.get("hit", 1.0), f"{where}.hit")
            avoid = _number(view.get("avoid", -1.0), f"{where}.avoid")
            image = open_image(_view_file(path, view, "image", where, None, "image"), f"{where}.image")
            grey = np.asarray(image.convert("L"), dtype=np.float64)
            weights = np.where(grey < 85, hit, np.where(grey > 170, avoid, 0.0))
        else:
            raise TargetFileError(f"{where} needs \"image\" or \"weights\"")
        if not (weights > 0).any():
            raise TargetFileError(f"{where}: nothing to hit (no positive weight)")
        out.append((weights, camera))
    name = path.parent.name if path.name == "target.json" else path.stem
    return Silhouette(out, name=name)
