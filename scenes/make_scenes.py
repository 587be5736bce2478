"""Make the 3D target scenes stored in this folder (small files; rerun to regenerate).

    python scenes/make_scenes.py

* ``spaceship_volume``: seed 002 Figure 3b — a spaceship filling a volume: an
  arrow-shaped proxy (a long hull with swept wings and a fin), voxelized on the
  spaceship program's grid (cell 0.25, margin 0.1). Fill weight 1 inside, avoid weight
  -1 outside (seed 002's s_vol); ``spaceship_proxy`` is the same volume under the
  original program's score (spaceship.md).
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from procmod.geometry.solid import Box, compose, rotation, translation
from procmod.geometry.voxel import VoxelGrid, voxelize

HERE = Path(__file__).resolve().parent


def spaceship_proxy_parts():
    """The arrow-shaped volume a spaceship should fill (ship frame: +z forward, y up)."""
    return [
        Box((2.5, 1.5, 12.0), translation(0.0, 0.0, 1.0)),                        # hull
        Box((7.0, 0.6, 3.0), compose(translation(3.0, 0.0, -1.5), rotation("y", -0.35))),   # right wing
        Box((7.0, 0.6, 3.0), compose(translation(-3.0, 0.0, -1.5), rotation("y", 0.35))),   # left wing
        Box((0.6, 1.6, 3.0), translation(0.0, 1.4, -2.5)),                         # fin
    ]


def write_volume_scene(name: str, parts, score: str, voxel_size=0.25, margin=0.1):
    folder = HERE / name
    folder.mkdir(exist_ok=True)
    lo = np.min([np.min([p for p in _corners(part)], axis=0) for part in parts], axis=0)
    hi = np.max([np.max([p for p in _corners(part)], axis=0) for part in parts], axis=0)
    grid = VoxelGrid.around(lo, hi, voxel_size, margin)
    mask = voxelize(parts, grid)
    np.save(folder / "volume.npy", mask)
    spec = {"format": "procmod-volume/1", "score": score,
            "grid": {"origin": list(grid.origin), "voxel_size": grid.size},
            "layers": [{"file": "volume.npy", "w_fill": 1.0, "w_avoid": -1.0}], "w_self": 0.0}
    (folder / "target.json").write_text(json.dumps(spec, indent=1) + "\n")
    print(f"wrote {folder} ({mask.sum()} of {mask.size} voxels filled)")


def _corners(part):
    from procmod.geometry.solid import part_bounds
    return part_bounds(part)


if __name__ == "__main__":
    write_volume_scene("spaceship_volume", spaceship_proxy_parts(), "svol")
    write_volume_scene("spaceship_proxy", spaceship_proxy_parts(), "proxy")
