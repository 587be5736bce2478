"""Layers for the 3D viewer: parts, volume targets and silhouette targets as GLB meshes.

A volume target is shown as what the score rewards: the surface of the voxels whose
covering gains score (blue) and of those whose covering costs score (red; hidden at first
when it fills most of the grid, as a fill/avoid target's outside does), on the target's
grid, whose box is drawn as lines. A silhouette target is shown in the scene where its
camera sees it: each view's pixels to hit (blue) and to avoid (yellow) as a flat cut-out
in the plane through the camera's ``look_at``, facing the camera, at the size the camera
sees there; the view can be set to each target camera.
"""

from __future__ import annotations

import numpy as np

from . import Layer, View

GAIN_COLOUR, COST_COLOUR, AVOID_COLOUR = "#2f6fdb", "#d9473b", "#d8b21c"
TARGET_OPACITY = 0.28
MAX_TRIANGLES = 400_000  # per layer: a larger voxel surface is shown on coarser voxels


def mesh_glb(vertices, faces) -> bytes:
    """A GLB file of one uncoloured triangle mesh (no faces: a GLB of an empty scene)."""
    import trimesh

    from ..geometry.mesh_export import check_storable, empty_glb_bytes, set_view_targets

    vertices, faces = np.asarray(vertices, dtype=np.float64), np.asarray(faces, dtype=np.int64)
    if faces.size == 0:
        # trimesh wrote an empty node and a zero-length BIN chunk, which strict readers refuse
        return empty_glb_bytes()
    check_storable(vertices, "a viewer layer's mesh")
    return trimesh.Trimesh(vertices=vertices, faces=faces, process=False).export(file_type="glb",
                                                                          tree_postprocessor=set_view_targets)


def parts_glb(parts) -> bytes:
    """A GLB file of 3D parts, one colour per part tag (as ``best.glb`` and ``sample_*.glb``)."""
    from ..geometry.export import colour_of
    from ..geometry.mesh_export import glb_bytes

    return glb_bytes(parts, colour_of)


def voxel_surface(mask, origin, size: float):
    """The boundary of a voxel set: ``(vertices, faces)``, quads between an inside and an
    outside voxel split into two triangles each, facing out, vertices shared."""
    mask = np.asarray(mask, dtype=bool)
    padded = np.pad(mask, 1)
    corners, keeps = [], []
    for axis in range(3):
        a = np.moveaxis(padded, axis, 0)
        change = (a[1:] != a[:-1])[:, 1:-1, 1:-1]  # plane k lies between voxels k - 1 and k
        plane, u, v = np.nonzero(change)
        outward = a[:-1, 1:-1, 1:-1][plane, u, v]  # inside below the plane: the face looks +axis
        quad = np.stack([np.stack([plane, u, v], -1), np.stack([plane, u + 1, v], -1),
                         np.stack([plane, u + 1, v + 1], -1), np.stack([plane, u, v + 1], -1)], 1)
        order = [axis] + [b for b in range(3) if b != axis]  # (plane, u, v) -> (x, y, z)
        xyz = np.empty_like(quad)
        for k, b in enumerate(order):
            xyz[..., b] = quad[..., k]
        corners.append(xyz)
        # (u, v) run along (y, z), (x, z), (x, y): the corner order faces +axis except for axis 1
        keeps.append(outward != (axis == 1))
    if not corners or sum(len(c) for c in corners) == 0:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64)
    corners = np.concatenate(corners)
    keep = np.concatenate(keeps)
    lattice, index = np.unique(corners.reshape(-1, 3), axis=0, return_inverse=True)
    index = index.reshape(-1, 4)
    tri = np.concatenate([index[:, [0, 1, 2]], index[:, [0, 2, 3]]])
    keep2 = np.concatenate([keep, keep])
    tri[~keep2] = tri[~keep2][:, ::-1]
    vertices = np.asarray(origin, dtype=np.float64) + float(size) * lattice
    return vertices, tri


def _coarser(mask):
    """A voxel set on voxels twice as large (a large voxel is in when any of its eight is)."""
    nx, ny, nz = mask.shape
    padded = np.pad(mask, ((0, nx % 2), (0, ny % 2), (0, nz % 2)))
    a = padded.reshape(padded.shape[0] // 2, 2, padded.shape[1] // 2, 2, padded.shape[2] // 2, 2)
    return a.any(axis=(1, 3, 5))


def voxel_layer(name: str, mask, origin, size: float, colour: str, visible: bool = True) -> Layer | None:
    """A translucent layer of a voxel set's surface (None for an empty set)."""
    mask = np.asarray(mask, dtype=bool)
    if not mask.any():
        return None
    factor = 1
    vertices, faces = voxel_surface(mask, origin, size)
    while len(faces) > MAX_TRIANGLES and min(mask.shape) > 1:
        mask, factor = _coarser(mask), 2 * factor
        vertices, faces = voxel_surface(mask, origin, size * factor)
    if factor > 1:
        name = f"{name} (shown on {factor}x coarser voxels)"
    return Layer(name, mesh_glb(vertices, faces), TARGET_OPACITY, colour, visible, frame=visible)


def _pixel_runs(image):
    """``(row, first column, last column + 1)`` of every horizontal run of True pixels."""
    image = np.asarray(image, dtype=bool)
    padded = np.pad(image, ((0, 0), (1, 1)))
    step = np.diff(padded.astype(np.int8), axis=1)
    rows, starts = np.nonzero(step == 1)
    _, ends = np.nonzero(step == -1)
    return rows, starts, ends


def silhouette_layer(name: str, image, camera, colour: str, visible: bool = True) -> Layer | None:
    """The True pixels of one view's image as a flat cut-out where ``camera`` sees them at
    its ``look_at`` (None when no pixel is set)."""
    rows, starts, ends = _pixel_runs(image)
    if len(rows) == 0:
        return None
    eye, right, up, forward = camera.basis()
    depth = float(np.dot(np.asarray(camera.look_at, dtype=np.float64) - eye, forward))
    height, width = np.asarray(image).shape
    if camera.projection == "perspective":
        pixel = 2 * depth * np.tan(np.radians(camera.fov) / 2) / height
    else:
        pixel = camera.fov / height
    centre = eye + depth * forward

    def point(px, py):
        return centre + np.multiply.outer(px - width / 2, right * pixel) + np.multiply.outer(height / 2 - py, up * pixel)

    top, bottom = rows.astype(np.float64), rows + 1.0
    quads = np.stack([point(starts, top), point(ends, top), point(ends, bottom), point(starts, bottom)], 1)
    n = len(quads)
    vertices = quads.reshape(-1, 3)
    base = 4 * np.arange(n)[:, None]
    faces = np.concatenate([base + [0, 2, 1], base + [0, 3, 2]])  # facing the camera
    return Layer(name, mesh_glb(vertices, faces), TARGET_OPACITY + 0.12, colour, visible, frame=False)


def camera_json(camera, shape=None) -> dict:
    """A camera as ``procmod-silhouette/1`` writes it (for the viewer's target-camera
    buttons), with ``aspect``, the width over the height of its picture of ``shape``
    (rows, columns), so that the view shows all of a wide picture."""
    out = {"eye": [float(v) for v in camera.eye], "look_at": [float(v) for v in camera.look_at],
           "up": [float(v) for v in camera.up], "projection": camera.projection, "fov": float(camera.fov)}
    if shape is not None:
        out["aspect"] = float(shape[1]) / float(shape[0])
    return out


def target_view_parts(target) -> tuple:
    """``(layers, bounds, cameras)`` showing a 3D target (nothing for other targets)."""
    from ..targets import ProxyVolume, Silhouette, Volume

    if isinstance(target, Volume):
        grid, gain = target.grid, np.asarray(target.combined)
        costs = gain < 0
        layers = [voxel_layer("target: covering gains", gain > 0, grid.origin, grid.size, GAIN_COLOUR),
                  voxel_layer("target: covering costs", costs, grid.origin, grid.size, COST_COLOUR,
                              visible=bool(costs.mean() <= 0.5))]
        return [x for x in layers if x is not None], (grid.origin, grid.upper), ()
    if isinstance(target, ProxyVolume):
        grid = target.grid
        layer = voxel_layer("target volume", target.mask, grid.origin, grid.size, GAIN_COLOUR)
        return [layer] if layer is not None else [], (grid.origin, grid.upper), ()
    if isinstance(target, Silhouette):
        layers = []
        for i, (weights, camera) in enumerate(zip(target.weights, target.cameras)):
            layers.append(silhouette_layer(f"target view {i + 1}: hit", weights > 0, camera, GAIN_COLOUR))
            layers.append(silhouette_layer(f"target view {i + 1}: avoid", weights < 0, camera, AVOID_COLOUR,
                                           visible=False))
        return ([x for x in layers if x is not None], None,
                tuple(camera_json(c, np.shape(w)) for w, c in zip(target.weights, target.cameras)))
    return [], None, ()


def run_view(best_glb: bytes, target, label: str = "") -> View:
    """The report's view: the best result and the target."""
    layers, bounds, cameras = target_view_parts(target)
    return View((Layer("best result", best_glb), *layers), label, bounds, cameras)


__all__ = ["mesh_glb", "parts_glb", "run_view", "silhouette_layer", "target_view_parts", "voxel_layer",
           "voxel_surface"]
