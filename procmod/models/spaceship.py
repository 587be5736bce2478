"""``spaceship``: the spaceship generator of the SOSMC paper, as seed 002 (Figure 4a) uses
it; the program is restated in shared/seeds/spaceship.md and these are its defaults.

Ships are built along +z from the rear of the first body segment at z = -5; y is up;
wings are mirrored across x = 0. ``U(a, b)`` is uniform and ``w(i, k) = exp(-k i)`` the
continuation probability at recursion depth i.

Rule ``body`` (depth i), choices:

* ``kind ~ Categorical(box, cylinder, cluster)`` uniform;
* box: ``xsize ~ U(1, 3)``, ``yfrac ~ U(0.5, 1)`` (y-size = yfrac x xsize),
  ``length ~ U(2, 5)``; after a non-box segment, x and y sizes are at least the
  previous ones;
* cylinder along z: ``radius ~ U(0.4 r, r)`` with r = half the smaller previous box size
  after a box, else ``U(0.3, 1.25)``; ``length ~ U(2, 5)``;
* cluster: four cylinders at (+-radius, +-radius), ``radius`` from the quarter-size range
  ([0.4 r', r'] with r' = a quarter of the smaller previous box size, else [0.15, 0.625]);
  ``length ~ U(2, 5)``;
* ``wings ~ Bernoulli(w(i + 1, 0.5))``, ``fin ~ Bernoulli(0.7)``, ``next ~ Bernoulli(w(i, 0.4))``
  and, when ``next`` is off, ``nose ~ Bernoulli(0.75)`` — maybe sites.

Rule ``nose``: ``length ~ U(1, 3)``, ``tip ~ U(0.25, 0.75)`` (tip radius over base radius; the
base radius is half the segment's smaller size).

Rule ``wing`` (depth j): ``kind ~ Categorical(box, cylinder)``, ``z ~ U(zmin, zmax)``; box:
``xsize ~ U(0.25, 2)``, ``ysize ~ U(0.25, 1.25)``, ``length ~ U(0.5, 4)``, ``guns ~ Bernoulli(0.5)``
with ``gun_length ~ U(1, 1.2)`` (x the wing's length; radius 0.15, a short cone tip),
above and below; cylinder: ``radius ~ U(0.15, 0.7)``, ``length ~ U(1, 5)``. Maybe site
``next ~ Bernoulli(w(j, 0.6))`` continues outward.

Rule ``fin`` (depth j): ``width ~ U(0.5, 1)`` (x the allowed width), ``height ~ U(0.1, 0.5)``,
``depth ~ U(0.5, 1)`` (x the allowed z range), centred; maybe site ``next ~ Bernoulli(w(j, 0.2))``
stacks another on top.

Cylinders are exact (the original used 8-sided prisms). The depth bound ``MAX_DEPTH`` =
12 (probabilities below 1e-2 by then) keeps runs finite.
"""

from __future__ import annotations

import math

from ..core import Bernoulli, Categorical, Model, Uniform
from ..geometry.solid import Box, Cylinder, new_part_bounds, translation

REAR_Z = -5.0
MAX_DEPTH = 12
_BODY_KIND = Categorical([1, 1, 1], labels=("box", "cylinder", "cluster"))
_WING_KIND = Categorical([1, 1], labels=("box", "cylinder"))
_COIN = Bernoulli(0.5)


def w(i: int, k: float) -> float:
    """Continuation probability at depth i."""
    return math.exp(-k * i)


def body(ctx, i, rear, prev_kind, prev_x, prev_y):
    """One body segment and its futures (wings, fin, next segment or nose)."""
    kind = ctx.sample("kind", _BODY_KIND)
    length = ctx.sample("length", Uniform(2.0, 5.0))
    after_box = prev_kind == "box"
    if kind == "box":
        xs = ctx.sample("xsize", Uniform(1.0, 3.0))
        ys = ctx.sample("yfrac", Uniform(0.5, 1.0)) * xs
        if prev_kind is not None and not after_box:
            xs, ys = max(xs, prev_x), max(ys, prev_y)
        ctx.emit(Box((xs, ys, length), translation(0.0, 0.0, rear + 0.5 * length), "hull"))
    else:
        quarter = kind == "cluster"
        if after_box:
            r = 0.5 * min(prev_x, prev_y) * (0.5 if quarter else 1.0)
            radius = ctx.sample("radius", Uniform(0.4 * r, r))
        else:
            radius = ctx.sample("radius", Uniform(0.15, 0.625) if quarter else Uniform(0.3, 1.25))
        if quarter:
            for sx in (-1, 1):
                for sy in (-1, 1):
                    ctx.emit(Cylinder(radius, length, translation(sx * radius, sy * radius, rear), "hull"))
            xs = ys = 4.0 * radius
        else:
            ctx.emit(Cylinder(radius, length, translation(0.0, 0.0, rear), "hull"))
            xs = ys = 2.0 * radius
    front = rear + length
    ctx.at((0.0, 0.0, front))
    ctx.maybe("wings", w(i + 1, 0.5), wing, 0, 0.5 * xs, rear + 0.5, front - 0.5)
    ctx.maybe("fin", 0.7, fin, 0, 0.5 * ys, rear, front, 0.6 * xs)
    if i + 1 < MAX_DEPTH and ctx.maybe("next", w(i, 0.4), body, i + 1, front, kind, xs, ys):
        return
    ctx.maybe("nose", 0.75, nose, front, 0.5 * min(xs, ys))


def nose(ctx, front, base_radius):
    """A tapered cylinder closing the hull."""
    length = ctx.sample("length", Uniform(1.0, 3.0))
    tip = ctx.sample("tip", Uniform(0.25, 0.75)) * base_radius
    ctx.emit(Cylinder(base_radius, length, translation(0.0, 0.0, front), "nose", tip))


def wing(ctx, j, x_start, zmin, zmax):
    """One wing segment, mirrored across x = 0, maybe continued outward."""
    kind = ctx.sample("kind", _WING_KIND)
    z = ctx.sample("z", Uniform(min(zmin, zmax), max(zmin, zmax) + 1e-9))
    if kind == "box":
        xs = ctx.sample("xsize", Uniform(0.25, 2.0))
        ys = ctx.sample("ysize", Uniform(0.25, 1.25))
        length = ctx.sample("length", Uniform(0.5, 4.0))
        guns = ctx.sample("guns", _COIN)
        gun_length = ctx.sample("gun_length", Uniform(1.0, 1.2)) * length if guns else 0.0
        for side in (-1, 1):
            cx = side * (x_start + 0.5 * xs)
            ctx.emit(Box((xs, ys, length), translation(cx, 0.0, z), "wing"))
            if guns:
                for up in (-1, 1):
                    y = up * (0.5 * ys + 0.15)
                    z0 = z - 0.5 * gun_length
                    ctx.emit(Cylinder(0.15, gun_length, translation(cx, y, z0), "gun"))
                    ctx.emit(Cylinder(0.15, 0.3, translation(cx, y, z0 + gun_length), "gun", 0.02))
        extent = (z - 0.5 * length, z + 0.5 * length)
    else:
        radius = ctx.sample("radius", Uniform(0.15, 0.7))
        length = ctx.sample("length", Uniform(1.0, 5.0))
        xs = 2.0 * radius
        for side in (-1, 1):
            ctx.emit(Cylinder(radius, length, translation(side * (x_start + radius), 0.0, z - 0.5 * length), "wing"))
        extent = (z - 0.5 * length, z + 0.5 * length)
    if j + 1 < MAX_DEPTH:
        ctx.maybe("next", w(j, 0.6), wing, j + 1, x_start + xs, extent[0], extent[1])


def fin(ctx, j, y_start, zmin, zmax, max_width):
    """A fin on top of the hull, maybe with another stacked on it."""
    width = ctx.sample("width", Uniform(0.5, 1.0)) * max_width
    height = ctx.sample("height", Uniform(0.1, 0.5))
    depth = ctx.sample("depth", Uniform(0.5, 1.0)) * (zmax - zmin)
    zc = 0.5 * (zmin + zmax)
    ctx.emit(Box((width, height, depth), translation(0.0, y_start + 0.5 * height, zc), "fin"))
    if j + 1 < MAX_DEPTH:
        ctx.maybe("next", w(j, 0.2), fin, j + 1, y_start + height, zc - 0.5 * depth, zc + 0.5 * depth, width)




def _root_args(params) -> tuple:
    return (0, REAR_Z, None, 0.0, 0.0)


MODEL = Model(
    name="spaceship",
    description="spaceships of body segments, wings and fins (SOSMC paper / seed 002 Fig. 4a)",
    root=body,
    root_args=_root_args,
    new_output_from=new_part_bounds,
    params={},
    rules=(body, nose, wing, fin),
    choices_doc=__doc__,
)
