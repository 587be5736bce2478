"""Geometry: 2D primitives, a raster canvas with incremental drawing, exporters."""

from .export import (PALETTE, canvas_height, colour_of, contact_sheet, render_image,
                     render_svg, save_figure_atomic, save_image_atomic)
from .primitives import Disc, Ellipse, Polygon, Segment, bounds, leaf, leaf_polygon
from .raster import Canvas, Viewport, rasterize

__all__ = [name for name in dir() if not name.startswith("_")]
