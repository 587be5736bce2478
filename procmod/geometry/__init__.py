"""Geometry: 2D primitives, a raster canvas with incremental drawing, exporters.

The primitives are imported eagerly; the raster canvas (numba kernels) and the image
exporters (Pillow) on first use, so that a command which only lists models or prints
help does not pay for them (``procmod models`` starts in a fraction of a second).
"""

from ..core.lazy import lazy_getattr
from .primitives import Disc, Ellipse, Polygon, Segment, Viewport, bounds, leaf, leaf_polygon

_LAZY = {
    "Canvas": "raster", "rasterize": "raster",
    "PALETTE": "export", "canvas_height": "export", "colour_of": "export", "contact_sheet": "export",
    "render_image": "export", "render_svg": "export", "save_figure_atomic": "export",
    "save_image_atomic": "export", "shaded_preview": "export",
}


__getattr__ = lazy_getattr(__name__, _LAZY, globals())


__all__ = ["Disc", "Ellipse", "Polygon", "Segment", "Viewport", "bounds", "leaf", "leaf_polygon", *_LAZY]
