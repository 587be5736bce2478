"""Vines targets unlike the guides' training scribbles: silhouettes of real 3D assets.

The objects and robots the ``pybullet`` wheel ships in ``pybullet_data`` (``pip install
pybullet``; read where pip put them, nothing copied here), each seen from its broadest
side with an orthographic camera and drawn as a 50x50 mask: blobs (the Stanford bunny, a
duck, a teddy) and articulated robots whose legs and arms are strokes of their own width.
Neither procmod nor the guides' training data made them.

The view: along the axis of the object's smallest bounding-box extent (its broadest
silhouette), with the image's up along +z unless that is the view axis (+y then); the
silhouette is cropped to its bounding box and fitted into the square with a margin,
aspect kept. The start is the lowest foreground point, as for any target picture
(``procmod.targets.lowest_point_start``).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

# (label, path inside pybullet_data); the first ``count`` are used, in this order
ASSETS = (
    ("bunny", "bunny.obj"),
    ("r2d2", "r2d2.urdf"),
    ("duck", "duck.obj"),
    ("a1", "a1/a1.urdf"),
    ("teddy", "teddy2_VHACD_CHs.obj"),
    ("laikago", "laikago/laikago.urdf"),
    ("kuka", "kuka_iiwa/model.urdf"),
    ("racecar", "racecar/racecar.urdf"),
    ("panda", "franka_panda/panda.urdf"),
    ("minitaur", "quadruped/minitaur.urdf"),
    ("samurai", "samurai_monastry.obj"),
    ("mini-cheetah", "mini_cheetah/mini_cheetah.urdf"),
    ("spirit40", "quadruped/spirit40.urdf"),
)
# (the humanoid, husky and bicycle URDFs are not standard URDF: xacro arguments,
#  capsules, trailing content; procmod's reader refuses them with a one-line error)
RENDER = 200  # pixels of the silhouette before it is fitted into the target square
MARGIN = 0.08  # of the target square, left empty on each side


def data_path() -> Path | None:
    """pybullet_data's folder, or None when pybullet is not installed."""
    try:
        import pybullet_data
    except ImportError:
        return None
    return Path(pybullet_data.getDataPath())


def _solids(path: Path) -> tuple[list, np.ndarray]:
    """The asset's solids posed in the world (a URDF's links at their zero configuration,
    read by procmod's own asset reader) and points spanning their extent."""
    from procmod.geometry.assets import read_assets
    from procmod.geometry.solid import Mesh

    if path.suffix.lower() == ".urdf":
        assets = read_assets([path])
        solids, points = [], []
        for node in assets.assets[0].nodes():
            shape = assets.parts[node.part]
            solids.append(shape.part(node.transform))
            # a mesh's own vertices (geometry.part_library.world_bounds would take its local
            # box's corners, a looser frame when the part is turned)
            local = (np.asarray(shape.vertices, dtype=np.float64) if shape.kind == "mesh" else
                     0.5 * np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
                     * np.asarray(shape.size, dtype=np.float64))
            t = np.asarray(node.transform, dtype=np.float64)
            points.append(local @ t[:3, :3].T + t[:3, 3])
        return solids, np.concatenate(points)
    import trimesh

    mesh = trimesh.load(str(path), force="mesh", process=False)
    vertices, faces = np.asarray(mesh.vertices, dtype=np.float64), np.asarray(mesh.faces, dtype=np.int64)
    return [Mesh(vertices, faces)], vertices


def silhouette_mask(solids: list, points: np.ndarray, size: int) -> np.ndarray:
    """The ``size`` x ``size`` boolean silhouette of ``solids`` from their broadest side
    (``points`` span their extent)."""
    from procmod.geometry.camera import Camera, Silhouettes
    from procmod.targets.image import resample_mask

    low, high = points.min(axis=0), points.max(axis=0)
    centre, extent = 0.5 * (low + high), high - low
    view = int(np.argmin(extent))
    up = np.zeros(3)
    up[2 if view != 2 else 1] = 1.0
    eye = centre.copy()
    eye[view] -= 2.0 * float(extent.max()) + 1.0
    camera = Camera(tuple(eye), tuple(centre), tuple(up), "orthographic", 1.2 * float(extent.max()), RENDER, RENDER)
    views = Silhouettes([camera])
    for solid in solids:
        views.add(solid)
    big = views.image(0)
    rows, cols = np.flatnonzero(big.any(axis=1)), np.flatnonzero(big.any(axis=0))
    crop = big[rows[0]:rows[-1] + 1, cols[0]:cols[-1] + 1]
    scale = size * (1.0 - 2.0 * MARGIN) / max(crop.shape)
    h, w = max(1, round(crop.shape[0] * scale)), max(1, round(crop.shape[1] * scale))
    out = np.zeros((size, size), dtype=bool)
    top, left = (size - h) // 2, (size - w) // 2
    out[top:top + h, left:left + w] = resample_mask(crop, w, h)
    return out


def silhouette_targets(count: int, size: int = 50) -> list:
    """The first ``count`` assets' silhouettes as ``TargetImage``; [] without pybullet."""
    from procmod.targets import TargetImage, lowest_point_start

    root = data_path()
    if root is None:
        return []
    out = []
    for label, relative in ASSETS[:count]:
        mask = silhouette_mask(*_solids(root / relative), size)
        start, direction = lowest_point_start(mask)
        out.append(TargetImage(f"silhouette:{label}", mask, start, direction))
    return out
