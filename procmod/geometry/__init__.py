"""Geometry: 2D primitives, a raster canvas with incremental drawing, exporters.

The primitives are imported eagerly; the raster canvas (numba kernels) and the image
exporters (Pillow) on first use, so that a command which only lists models or prints
help does not pay for them (``procmod models`` starts in a fraction of a second).
"""

import importlib

from .primitives import Disc, Ellipse, Polygon, Segment, Viewport, bounds, leaf, leaf_polygon

_LAZY = {
    "Canvas": "raster", "rasterize": "raster",
    "PALETTE": "export", "canvas_height": "export", "colour_of": "export", "contact_sheet": "export",
    "render_image": "export", "render_svg": "export", "save_figure_atomic": "export",
    "save_image_atomic": "export",
}


def __getattr__(name):
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    value = getattr(importlib.import_module(f".{module}", __name__), name)
    globals()[name] = value  # later lookups skip this hook
    return value


__all__ = ["Disc", "Ellipse", "Polygon", "Segment", "Viewport", "bounds", "leaf", "leaf_polygon", *_LAZY]
