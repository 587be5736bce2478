"""Volume targets for 3D models.

``Volume`` is seed 002's s_vol. Given target volumes ``V_i`` with fill weights ``w_i``
and avoid weights ``w~_i`` (all voxelized on one grid),

    s_vol(M) = sum_i ( sum_{v in V_i} w_i V_M(v) + sum_{v in V_M} w~_i (1 - V_i(v)) )

so each voxel the model covers adds the combined weight ``sum_i w_i V_i(v) + w~_i (1 -
V_i(v))``; covered lattice cells outside the grid add ``sum_i w~_i`` each, and every
extra hit of an already covered voxel (self-intersection) subtracts ``w_self``. All of it
is kept incrementally by :class:`procmod.geometry.voxel.VoxelScene`. The score is s_vol
itself (seed 002's fitness); the log-likelihood probabilistic engines use is
``s_vol / temperature``, with the temperature 1% of the best attainable s_vol by default
(a change of 1% of the attainable fitness changes the log-likelihood by 1).

``ProxyVolume`` is the score of the original spaceship program (spaceship.md): fraction
of grid cells where ship and target agree, ``log N(same; 1, 0.005) + log N(outside; 0,
0.005)`` with ``outside`` how far the ship's bounding box pokes out of the grid (summed
over the six sides as fractions of the grid's extent), and -inf for any part that
intersects an earlier one. Intersection is the exact part-part test of
:mod:`procmod.geometry.collide` (bounding boxes first, then the parts, as spaceship.md
says the original does), not shared voxels: two parts that overlap between voxel centres
intersect, and parts that only touch (the spaceship's stacked segments, wings and fins) do
not. :class:`ProxyScene` keeps that count incrementally beside the voxels.
"""

from __future__ import annotations

import math

import numpy as np

from ..core import InvalidArgumentError
from ..geometry.collide import PartIntersections
from ..geometry.voxel import VoxelGrid, VoxelScene


def check_3d(model, what: str = "volume"):
    """Refuse a model that does not draw 3D parts (InvalidArgumentError): a ``what``
    target (volume, silhouette) needs one."""
    dimension = model.new_output().dimension
    if dimension != 3:
        raise InvalidArgumentError(f"a {what} target needs a 3D model; {model.name!r} "
                                   + ("is 2D" if dimension == 2 else "draws no 3D parts"))


class Volume:
    """Seed 002's weighted volume fill/avoid score.

    The score reads only what :meth:`VoxelScene.remove` restores exactly (gain, outside
    and overlap counts), so ``exact_removal`` is True: the GA may derive an offspring's
    scene from its parent's by removing and adding parts.

    Parameters
    ----------
    grid : VoxelGrid
    layers : list of (mask, w_fill, w_avoid)
        Boolean masks of shape ``grid.shape`` with their fill and avoid weights.
    w_self : float
        Penalty per extra hit of a covered voxel (0 disables it).
    temperature : float, optional
        Divides s_vol to give the log-likelihood (default: 1% of the best attainable s_vol).
    """

    def __init__(self, grid: VoxelGrid, layers, w_self: float = 0.0, temperature: float | None = None,
                 name: str = "volume"):
        self.grid = grid
        self.name = name
        self.w_self = float(w_self)
        if not layers:
            raise InvalidArgumentError("a volume target needs at least one target volume")
        combined = np.zeros(grid.shape)
        self.outside_weight = 0.0
        for mask, w_fill, w_avoid in layers:
            mask = np.asarray(mask, dtype=bool)
            if mask.shape != tuple(grid.shape):
                raise InvalidArgumentError(f"target volume has shape {mask.shape}, the grid {tuple(grid.shape)}")
            combined += np.where(mask, float(w_fill), float(w_avoid))
            self.outside_weight += float(w_avoid)
        self.combined = combined
        self._gain = combined.ravel().copy()
        self.best_attainable = float(np.clip(self._gain, 0, None).sum())
        if temperature is None:
            temperature = max(0.01 * self.best_attainable, 1e-9)
        if not temperature > 0:
            raise InvalidArgumentError(f"temperature must be positive, got {temperature!r}")
        self.temperature = float(temperature)

    # capabilities (procmod.core.protocols.Target)
    exact_removal = True
    has_mask = False
    has_overlay = False

    def configure(self, model):
        check_3d(model)
        return model

    def new_output(self, model) -> VoxelScene:
        check_3d(model)
        return VoxelScene(self.grid, self._gain)

    def score(self, scene: VoxelScene) -> float:
        """s_vol of the model so far."""
        return scene.gain_total + scene.outside * self.outside_weight - self.w_self * scene.overlaps

    def log_likelihood(self, scene: VoxelScene) -> float:
        return self.score(scene) / self.temperature

    def display_mask(self, width: int):
        return None


class ProxyScene(VoxelScene):
    """A :class:`VoxelScene` that also counts the pairs of its parts that intersect
    exactly (``intersections``, a :class:`procmod.geometry.collide.PartIntersections`):
    each part added is tested against the earlier ones whose bounding boxes overlap it."""

    def __init__(self, grid: VoxelGrid, gain=None):
        super().__init__(grid, gain)
        self.intersections = PartIntersections()

    def copy(self) -> "ProxyScene":
        other = VoxelScene.copy(self)  # the voxel state (VoxelScene's slots)
        other.intersections = self.intersections.copy()
        return other

    def add(self, part) -> int:
        self.intersections.add(part)
        return super().add(part)

    def remove(self, part) -> int:
        n = super().remove(part)
        self.intersections.remove(part)
        return n


class ProxyVolume:
    """The original spaceship program's volume score (see the module docstring)."""

    # capabilities (procmod.core.protocols.Target): ``outside`` reads the scene's extent,
    # which ``remove`` does not shrink, so removal is not exact for this score
    exact_removal = False
    has_mask = False
    has_overlay = False

    def __init__(self, grid: VoxelGrid, mask, sigma: float = 0.005, name: str = "proxy"):
        mask = np.asarray(mask, dtype=bool)
        if mask.shape != tuple(grid.shape):
            raise InvalidArgumentError(f"target volume has shape {mask.shape}, the grid {tuple(grid.shape)}")
        self.grid, self.mask, self.sigma, self.name = grid, mask, float(sigma), name
        self._gain = np.where(mask, 1.0, -1.0).ravel()
        self._empty_agree = float((~mask).sum())

    configure = Volume.configure

    def new_output(self, model) -> ProxyScene:
        check_3d(model)
        return ProxyScene(self.grid, self._gain)

    def score(self, scene: VoxelScene) -> float:
        """Fraction of grid cells where the ship and the target agree."""
        return (self._empty_agree + scene.gain_total) / self.mask.size

    def outside(self, scene: VoxelScene) -> float:
        if scene.extent is None:
            return 0.0
        lo, hi = scene.extent
        g_lo, g_hi = np.asarray(self.grid.origin), self.grid.upper
        span = g_hi - g_lo
        return float(np.sum(np.maximum(g_lo - lo, 0) / span) + np.sum(np.maximum(hi - g_hi, 0) / span))

    def log_likelihood(self, scene: ProxyScene) -> float:
        if scene.intersections.count > 0:  # some part intersects an earlier one
            return -math.inf
        norm = -math.log(self.sigma * math.sqrt(2 * math.pi))
        same, out = self.score(scene), self.outside(scene)
        return 2 * norm - 0.5 * ((same - 1) / self.sigma) ** 2 - 0.5 * (out / self.sigma) ** 2

    def display_mask(self, width: int):
        return None
