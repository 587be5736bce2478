"""``tree``: the tree generator of seed 002 (Figure 8a), y up.

Rule ``trunk``: ``radius ~ U(0.15, 0.35)``, ``length ~ U(2, 4)``; a cylinder up the y axis
from the origin, then up to three sub-branches (maybe sites ``b0``, ``b1``, ``b2`` with
probabilities 0.95, 0.8, 0.6).

Rule ``branch`` (depth d), the figure's (phi, psi, s, l, o):

* ``phi ~ U(0, 2 pi)`` — normal angle: the azimuth around the parent's axis;
* ``psi ~ U(0.25, 1.1)`` — inclination from the parent's axis (radians);
* ``s ~ U(0.55, 0.85)`` — radial scaling relative to the parent;
* ``l ~ U(0.55, 0.9)`` — length relative to the parent;
* ``o ~ U(0.45, 1.0)`` — offset: where along the parent it starts (fraction of its length);
* sub-branches ``b0``, ``b1``, ``b2`` (maybe sites, probabilities 0.9, 0.7, 0.45 times
  0.85^d) while d < ``MAX_DEPTH`` = 4.

A branch with no sub-branch ends in foliage (seed 002: "the foliage is always added as
extension of a final branch"): rule ``foliage`` draws ``size ~ U(0.5, 1.1)`` and extends the
branch by a cone of that length and radius 0.6 x size. The constants are ours (the paper
gives none); they make plausible broad-leaved trees about 6 units tall.
"""

from __future__ import annotations

import math

from ..core import Model, Uniform
from ..geometry.solid import Cylinder, new_part_bounds

MAX_DEPTH = 4
TRUNK_CHILDREN = (0.95, 0.8, 0.6)
BRANCH_CHILDREN = (0.9, 0.7, 0.45)


def _cross(a, b) -> tuple:
    return (a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0])


def _unit(v) -> tuple:
    n = math.sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2])
    return (v[0] / n, v[1] / n, v[2] / n)


def _axes(axis) -> tuple:
    """Two unit vectors x, y completing the unit ``axis`` to a right-handed frame (x, y, axis)."""
    helper = (1.0, 0.0, 0.0) if abs(axis[0]) < 0.9 else (0.0, 1.0, 0.0)
    x = _unit(_cross(helper, axis))
    return x, _cross(axis, x)


def _frame(origin, axis) -> tuple:
    """Transform (row-major 4x4 tuple) whose local +z is ``axis`` (unit) at ``origin``.

    Plain-Python vector maths: this runs once per branch call, where numpy's per-call
    overhead would cost more than the arithmetic.
    """
    x, y = _axes(axis)
    return (x[0], y[0], axis[0], origin[0], x[1], y[1], axis[1], origin[1],
            x[2], y[2], axis[2], origin[2], 0.0, 0.0, 0.0, 1.0)


def _spawn_children(ctx, probabilities, scale, base, axis, radius, length, depth) -> bool:
    any_on = False
    if depth < MAX_DEPTH:
        for k, p in enumerate(probabilities):
            any_on |= ctx.maybe(f"b{k}", p * scale, branch, base, axis, radius, length, depth + 1)
    return any_on


def trunk(ctx):
    """The trunk and its first branches."""
    radius = ctx.sample("radius", Uniform(0.15, 0.35))
    length = ctx.sample("length", Uniform(2.0, 4.0))
    axis = (0.0, 1.0, 0.0)
    ctx.emit(Cylinder(radius, length, _frame((0.0, 0.0, 0.0), axis), "trunk", 0.85 * radius))
    ctx.at((0.0, length, 0.0))
    _spawn_children(ctx, TRUNK_CHILDREN, 1.0, (0.0, 0.0, 0.0), axis, radius, length, 0)


def branch(ctx, parent_base, parent_axis, parent_radius, parent_length, depth):
    """A branch off its parent, then sub-branches or foliage."""
    phi = ctx.sample("phi", Uniform(0.0, 2 * math.pi))
    psi = ctx.sample("psi", Uniform(0.25, 1.1))
    s = ctx.sample("s", Uniform(0.55, 0.85))
    l = ctx.sample("l", Uniform(0.55, 0.9))
    o = ctx.sample("o", Uniform(0.45, 1.0))
    px, py = _axes(parent_axis)
    cphi, sphi, cpsi, spsi = math.cos(phi), math.sin(phi), math.cos(psi), math.sin(psi)
    axis = _unit(tuple(cpsi * a + spsi * (cphi * u + sphi * v) for a, u, v in zip(parent_axis, px, py)))
    base = tuple(b + o * parent_length * a for b, a in zip(parent_base, parent_axis))
    radius, length = s * parent_radius, l * parent_length
    ctx.emit(Cylinder(radius, length, _frame(base, axis), "branch", 0.8 * radius))
    tip = tuple(float(b + length * a) for b, a in zip(base, axis))
    ctx.at(tip)
    if not _spawn_children(ctx, BRANCH_CHILDREN, 0.85 ** depth, base, axis, radius, length, depth):
        ctx.spawn("foliage", foliage, tip, axis)


def foliage(ctx, tip, axis):
    """A cone of leaves extending a final branch."""
    size = ctx.sample("size", Uniform(0.5, 1.1))
    back = tuple(t - 0.3 * size * a for t, a in zip(tip, axis))
    ctx.emit(Cylinder(0.6 * size, size, _frame(back, axis), "foliage", 0.05))


def _root_args(params) -> tuple:
    return ()


MODEL = Model(
    name="tree",
    description="trees of tapering branches ending in foliage (seed 002, Fig. 8a)",
    root=trunk,
    root_args=_root_args,
    new_output_from=new_part_bounds,
    params={},
    rules=(trunk, branch, foliage),
    choices_doc=__doc__,
)
