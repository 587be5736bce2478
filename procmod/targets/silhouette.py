"""``Silhouette``: seed 002's image score s_img for 3D models.

Given weighted images ``I_i`` (positive = should be hit, negative = should be avoided,
zero = don't care) and cameras ``C_i``,

    s_img(M) = sum_i sum_p project_{C_i}(M)(p) I_i(p)

i.e. every pixel the model's silhouette covers adds that pixel's weight, kept
incrementally by :class:`procmod.geometry.camera.Silhouettes`. The score is s_img; the
log-likelihood is ``s_img / temperature`` (default: 1% of the best attainable s_img).

Files (``procmod-silhouette/1`` JSON, paths relative to it; read by
:mod:`procmod.targets.files`)::

    {"format": "procmod-silhouette/1",
     "views": [{"image": "sketch.png", "hit": 1.0, "avoid": -1.0,
                "camera": {"eye": [0, 4, 20], "look_at": [0, 4, 0], "up": [0, 1, 0],
                           "projection": "orthographic", "fov": 10}}]}

A view gives one of ``"image"``, a picture read as: dark (< 85) = hit weight, light (> 170)
= avoid weight, mid grey = don't care; ``"weights"``, an .npy float image; or ``"mesh"``, a
mesh file (OBJ, GLB/glTF, PLY, STL, OFF) seen through the camera: the pixels whose centres
its triangles cover get the hit weight, the others the avoid weight, on a ``width`` x
``height`` image given in the camera (default 128 x 128). A picture's or weights'
resolution is its own (at most :data:`~procmod.targets.image.MAX_IMAGE_PIXELS` pixels).
Every field is checked when the file is read, and a bad one is refused in one line naming
the file and the field: ``eye``, ``look_at`` and ``up`` are three finite numbers (``up``
not zero and not along the view direction), ``fov`` a finite positive number
(perspective: degrees below 180), ``hit`` and ``avoid`` finite numbers.
"""

from __future__ import annotations

import numpy as np
from PIL import Image

from ..core import InvalidArgumentError
from ..geometry.camera import Silhouettes
from .volume import check_3d


class Silhouette:
    """Weighted silhouette images under given cameras (seed 002's s_img).

    ``exact_removal``: the score is the silhouettes' ``gain_total``, which
    :meth:`Silhouettes.remove` restores exactly (see :class:`procmod.targets.Volume`).
    """

    # capabilities (procmod.core.protocols.Target)
    exact_removal = True
    has_mask = False
    has_overlay = True  # overlay_image: a result's silhouette over a view

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
        check_3d(model, "silhouette")
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
