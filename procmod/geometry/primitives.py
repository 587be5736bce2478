"""2D geometry primitives that rules emit, in world coordinates.

Each carries a ``tag`` ("stem", "leaf", ...) that display renderers map to a colour;
rasterisation for scoring ignores it.
"""

from __future__ import annotations

import math
from typing import NamedTuple


class Viewport(NamedTuple):
    """The world-space rectangle a canvas shows; pixel row 0 is at ``ymin``."""

    xmin: float
    xmax: float
    ymin: float
    ymax: float


class Segment(NamedTuple):
    """A thick line from (x0, y0) to (x1, y1) with round caps; ``width`` is its full width."""

    x0: float
    y0: float
    x1: float
    y1: float
    width: float
    tag: str = "stroke"


class Disc(NamedTuple):
    """A filled circle."""

    x: float
    y: float
    radius: float
    tag: str = "disc"


class Ellipse(NamedTuple):
    """A filled ellipse centred at (x, y) whose ``length`` axis points along ``angle``."""

    x: float
    y: float
    angle: float
    length: float
    width: float
    tag: str = "ellipse"

    def points(self, n: int = 24) -> tuple:
        """Vertices of an inscribed polygon (for SVG and other vector outputs)."""
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        a, b = 0.5 * self.length, 0.5 * self.width
        out = []
        for i in range(n):
            t = 2 * math.pi * i / n
            u, v = a * math.cos(t), b * math.sin(t)
            out.append((self.x + u * ca - v * sa, self.y + u * sa + v * ca))
        return tuple(out)


class Polygon(NamedTuple):
    """A filled simple polygon given by its vertices ((x, y), ...), even-odd rule."""

    points: tuple
    tag: str = "polygon"


def leaf(x: float, y: float, angle: float, length: float, width: float, tag: str = "leaf") -> Ellipse:
    """An elliptical leaf whose base is at (x, y), pointing along ``angle``."""
    half = 0.5 * length
    return Ellipse(x + half * math.cos(angle), y + half * math.sin(angle), angle, length, width, tag)


def leaf_polygon(x: float, y: float, angle: float, length: float, width: float,
                 tag: str = "leaf", n: int = 10) -> Polygon:
    """A pointed leaf (two circular arcs) whose base is at (x, y), pointing along ``angle``."""
    ca, sa = math.cos(angle), math.sin(angle)
    points = []
    for i in range(n + 1):  # one side from base to tip, then back along the other side
        t = i / n
        points.append((t * length, 0.5 * width * math.sin(math.pi * t)))
    for i in range(n - 1, 0, -1):
        t = i / n
        points.append((t * length, -0.5 * width * math.sin(math.pi * t)))
    return Polygon(tuple((x + u * ca - v * sa, y + u * sa + v * ca) for u, v in points), tag)


def bounds(geometry) -> tuple:
    """World-space bounding box (xmin, xmax, ymin, ymax) of one primitive."""
    if isinstance(geometry, Segment):
        r = 0.5 * geometry.width
        return (min(geometry.x0, geometry.x1) - r, max(geometry.x0, geometry.x1) + r,
                min(geometry.y0, geometry.y1) - r, max(geometry.y0, geometry.y1) + r)
    if isinstance(geometry, Disc):
        r = geometry.radius
        return geometry.x - r, geometry.x + r, geometry.y - r, geometry.y + r
    if isinstance(geometry, Ellipse):
        ca, sa = math.cos(geometry.angle), math.sin(geometry.angle)
        a, b = 0.5 * geometry.length, 0.5 * geometry.width
        hx, hy = math.hypot(a * ca, b * sa), math.hypot(a * sa, b * ca)
        return geometry.x - hx, geometry.x + hx, geometry.y - hy, geometry.y + hy
    if isinstance(geometry, Polygon):
        xs = [p[0] for p in geometry.points]
        ys = [p[1] for p in geometry.points]
        return min(xs), max(xs), min(ys), max(ys)
    raise TypeError(f"not a 2D primitive: {geometry!r}")
