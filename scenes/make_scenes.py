"""Make the 3D target scenes stored in this folder (small files; rerun to regenerate).

    python scenes/make_scenes.py

* ``spaceship_volume``: seed 002 Figure 3b — a spaceship filling a volume: an
  arrow-shaped proxy (a long hull with swept wings and a fin), voxelized on the
  spaceship program's grid (cell 0.25, margin 0.1). Fill weight 1 inside, avoid weight
  -1 outside (seed 002's s_vol); ``spaceship_proxy`` is the same volume under the
  original program's score (spaceship.md).
* ``tree_heart``: seed 002 Figure 1 — a tree matching a sketched silhouette: a heart,
  drawn procedurally, seen by an orthographic front camera; hit +1 inside, avoid -0.5
  outside, don't care on a corridor for the trunk.
* ``trees_avoid_cylinder``: Figure 9a — fill a crown-shaped ellipsoid (+1) while
  avoiding (-2) a tube around the trunk's axis that has four windows cut in it.
* ``city_skyline``: Figures 9b-c — a city's front silhouette matching a skyline (two
  towers over stepped blocks): hit +1 below the skyline, avoid -1 above it.
* ``city_volume``: Figure 9d — fill a plus-shaped block of lots 3 units high (+1);
  every voxel built outside it costs 4 (wrongly placed buildings punished severely).
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


def write_weighted_volume(name: str, grid: VoxelGrid, layers, w_self=0.0):
    """A volume scene from boolean masks on ``grid``: layers = [(mask, w_fill, w_avoid)]."""
    folder = HERE / name
    folder.mkdir(exist_ok=True)
    entries = []
    for k, (mask, w_fill, w_avoid) in enumerate(layers):
        np.save(folder / f"layer{k}.npy", mask)
        entries.append({"file": f"layer{k}.npy", "w_fill": w_fill, "w_avoid": w_avoid})
    spec = {"format": "procmod-volume/1", "score": "svol",
            "grid": {"origin": list(grid.origin), "voxel_size": grid.size}, "layers": entries, "w_self": w_self}
    (folder / "target.json").write_text(json.dumps(spec, indent=1) + "\n")
    print(f"wrote {folder} ({', '.join(str(int(m.sum())) for m, _, _ in layers)} voxels per layer)")


def write_silhouette_scene(name: str, weights: np.ndarray, camera: dict, hit: float, avoid: float):
    """A silhouette scene: a picture (dark = hit, light = avoid, grey = don't care) + camera."""
    from PIL import Image
    folder = HERE / name
    folder.mkdir(exist_ok=True)
    grey = np.where(weights > 0, 0, np.where(weights < 0, 255, 128)).astype(np.uint8)
    Image.fromarray(grey).save(folder / "sketch.png")
    spec = {"format": "procmod-silhouette/1",
            "views": [{"image": "sketch.png", "hit": hit, "avoid": avoid, "camera": camera}]}
    (folder / "target.json").write_text(json.dumps(spec, indent=1) + "\n")
    print(f"wrote {folder} ({int((weights > 0).sum())} hit pixels)")


def heart_weights(size=64, view_height=10.0, centre_y=4.0):
    """+1 inside a heart, -1 outside, 0 on a corridor for the trunk (pixels: row 0 at top)."""
    scale = view_height / size
    cols = (np.arange(size) + 0.5 - size / 2) * scale
    rows = centre_y + view_height / 2 - (np.arange(size) + 0.5) * scale
    x, y = np.meshgrid(cols, rows)
    u, v = x / 3.6, (y - 5.2) / 3.6
    inside = (u * u + v * v - 1) ** 3 - u * u * v ** 3 <= 0
    weights = np.where(inside, 1.0, -1.0)
    weights[(np.abs(x) < 0.6) & (y < 2.5) & ~inside] = 0.0
    return weights


def skyline_weights(width=128, height=48, pixel=0.25, bottom=-1.0):
    """+1 below a skyline profile, -1 above it, 0 below the ground."""
    x = (np.arange(width) + 0.5 - width / 2) * pixel
    profile = np.where(np.abs(x) < 2.0, 3.6, np.where(np.abs(x) < 5.0, 2.2, np.where(np.abs(x) < 8.5, 1.2, 0.0)))
    profile[(np.abs(x + 3.5) < 0.8)] = 3.0
    y = bottom + height * pixel - (np.arange(height) + 0.5) * pixel
    X, Y = np.meshgrid(profile, y)
    weights = np.where(Y <= X, 1.0, -1.0)
    weights[Y < 0] = 0.0
    weights[(X == 0.0) & (Y >= 0)] = -1.0
    return weights


def tree_avoid_layers():
    grid = VoxelGrid((-5.0, 0.0, -5.0), 0.25, (40, 40, 40))
    c = grid.centres()
    x, y, z = c[..., 0], c[..., 1], c[..., 2]
    crown = ((x / 4.0) ** 2 + ((y - 5.5) / 3.0) ** 2 + (z / 4.0) ** 2) <= 1.0
    r = np.hypot(x, z)
    angle = np.degrees(np.arctan2(z, x)) % 90.0
    windows = (np.minimum(angle, 90.0 - angle) < 20.0) & (y > 4.5) & (y < 6.5)
    tube = (r >= 2.0) & (r <= 2.5) & (y >= 3.0) & (y <= 8.0) & ~windows
    return grid, [(crown, 1.0, 0.0), (tube, -2.0, 0.0)]


def city_volume_layers():
    grid = VoxelGrid((-10.5, 0.0, -10.5), 0.5, (42, 8, 42))
    c = grid.centres()
    x, y, z = c[..., 0], c[..., 1], c[..., 2]
    plus = ((np.abs(x) <= 1.5) | (np.abs(z) <= 1.5)) & (np.maximum(np.abs(x), np.abs(z)) <= 7.5) & (y <= 3.0)
    return grid, [(plus, 1.0, -4.0)]


if __name__ == "__main__":
    write_volume_scene("spaceship_volume", spaceship_proxy_parts(), "svol")
    write_volume_scene("spaceship_proxy", spaceship_proxy_parts(), "proxy")
    write_silhouette_scene("tree_heart", heart_weights(), {"eye": [0, 4, 30], "look_at": [0, 4, 0],
                                                          "projection": "orthographic", "fov": 10.0},
                           hit=1.0, avoid=-0.5)
    write_weighted_volume("trees_avoid_cylinder", *tree_avoid_layers())
    write_silhouette_scene("city_skyline", skyline_weights(), {"eye": [0, 5, 40], "look_at": [0, 5, 0],
                                                               "projection": "orthographic", "fov": 12.0},
                           hit=1.0, avoid=-1.0)
    write_weighted_volume("city_volume", *city_volume_layers())
