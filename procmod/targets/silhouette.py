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
The camera's resolution is the image's.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np
from PIL import Image, UnidentifiedImageError

from ..core import InvalidArgumentError
from ..geometry.camera import Camera, Silhouettes
from .image import TargetFileError


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


def _camera(spec, where) -> Camera:
    if not isinstance(spec, dict):
        raise TargetFileError(f"{where}: \"camera\" must be an object with eye, look_at, ...")
    try:
        camera = Camera(tuple(float(v) for v in spec["eye"]), tuple(float(v) for v in spec["look_at"]),
                        tuple(float(v) for v in spec.get("up", (0, 1, 0))), spec.get("projection", "perspective"),
                        float(spec.get("fov", 40.0)))
    except (KeyError, TypeError, ValueError) as exc:
        raise TargetFileError(f"{where}: bad camera ({exc}); it needs eye and look_at as three numbers") from None
    if camera.projection not in ("perspective", "orthographic"):
        raise TargetFileError(f"{where}: projection must be perspective or orthographic")
    if np.allclose(camera.eye, camera.look_at):
        raise TargetFileError(f"{where}: the camera's eye and look_at coincide")
    return camera


def load_silhouette_target(path: str | os.PathLike) -> Silhouette:
    """Read a ``procmod-silhouette/1`` target (see the module docstring)."""
    from .volume import read_target_json

    path = Path(path)
    spec = read_target_json(path)
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
            try:
                weights = np.load(path.parent / view["weights"], allow_pickle=False).astype(np.float64)
            except (OSError, ValueError, TypeError) as exc:
                raise TargetFileError(f"{where}: cannot read the weights ({exc})") from None
            if weights.ndim != 2:
                raise TargetFileError(f"{where}: weights must be a 2D array")
        elif "image" in view:
            try:
                with Image.open(path.parent / view["image"]) as image:
                    grey = np.asarray(image.convert("L"), dtype=np.float64)
            except (OSError, UnidentifiedImageError) as exc:
                raise TargetFileError(f"{where}: cannot read the image ({exc})") from None
            weights = np.where(grey < 85, float(view.get("hit", 1.0)),
                               np.where(grey > 170, float(view.get("avoid", -1.0)), 0.0))
        else:
            raise TargetFileError(f"{where} needs \"image\" or \"weights\"")
        if not (weights > 0).any():
            raise TargetFileError(f"{where}: nothing to hit (no positive weight)")
        out.append((weights, camera))
    name = path.parent.name if path.name == "target.json" else path.stem
    return Silhouette(out, name=name)
