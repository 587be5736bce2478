"""The 2D frame shared by the built-in 2D models: the vines viewport of seeds 003/004.

World x in [-12, 12], y in [-22, 2]; image row 0 is world y = -22, so y grows towards
the bottom of the image. Models take their start point in *normalised image
coordinates* (what a target's sidecar JSON holds) and a direction vector.
"""

from __future__ import annotations

import math

from ..core import InvalidArgumentError
from ..geometry import Viewport

VIEWPORT = Viewport(-12.0, 12.0, -22.0, 2.0)
DEFAULT_SIZE = 50
# Bounds Model.configure checks (a 10^9-pixel canvas is refused, not allocated).
# the picture-frame models' parameters: a canvas's pixels a machine holds; a start in the
# picture's normalised coordinates, allowed a few frames outside it (a vine growing in from
# off the picture) but not so far that the world coordinates overflow (start 1e308 had been
# blamed on the rule's arithmetic, as an infinite segment)
FRAME_RANGES = {"size": (1, 4096), "min_radius_px": (0.0, 10.0), "start": (-10.0, 10.0)}


def to_world(point) -> tuple:
    """Normalised image coordinates (0..1, 0..1) to world coordinates."""
    u, v = _pair(point, "start")
    return (VIEWPORT.xmin + u * (VIEWPORT.xmax - VIEWPORT.xmin),
            VIEWPORT.ymin + v * (VIEWPORT.ymax - VIEWPORT.ymin))


def heading(direction) -> float:
    """Angle (radians, y down) of a direction vector."""
    dx, dy = _pair(direction, "direction")
    if dx == 0 and dy == 0:
        raise InvalidArgumentError("direction must be a non-zero vector, e.g. [0, -1] for up")
    return math.atan2(dy, dx)


def _pair(value, what) -> tuple:
    try:
        a, b = (float(v) for v in value)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"{what} must be two numbers, got {value!r}") from None
    if not (math.isfinite(a) and math.isfinite(b)):
        raise InvalidArgumentError(f"{what} must be finite, got {value!r}")
    return a, b


def new_canvas(params):
    """The scoring canvas of a 2D model: ``params['size']`` pixels square.

    ``params['min_radius_px']`` (default 0.5) is the smallest radius, in pixels, a stroke,
    disc or ellipse is drawn with, so thin branches stay visible; 0 covers a pixel only
    when its centre lies inside the primitive, as the original vines program does.
    """
    from ..geometry.raster import MIN_RADIUS_PX, Canvas  # numba kernels: imported on first use

    size = params.get("size", DEFAULT_SIZE)
    if not isinstance(size, int) or isinstance(size, bool) or size < 1:
        raise InvalidArgumentError(f"size must be a positive number of pixels, got {size!r}")
    least = params.get("min_radius_px", MIN_RADIUS_PX)
    if isinstance(least, bool) or not isinstance(least, (int, float)) or not 0 <= least <= 10:
        raise InvalidArgumentError(f"min_radius_px must be a number of pixels in [0, 10], got {least!r}")
    return Canvas(VIEWPORT, size, size, min_radius_px=least)
