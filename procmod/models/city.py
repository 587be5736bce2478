"""``city``: the city generator of seed 002 (Figure 8b), on the ground plane y = 0.

Lots are unit cells (i, j) of the xz grid. Only ``building`` makes geometry; the lot
iterators recurse over the ground without any:

* ``center`` (at lot (0, 0)): ``building ~ Bernoulli(0.7)``; always spawns four straight
  iterators (+x, -x, +z, -z) and four diagonal ones (the quadrants).
* ``straight`` (walks along one axis): ``building ~ Bernoulli(0.65)``; ``next ~ Bernoulli(0.85)``
  continues one lot further (at most ``MAX_STEPS`` = 10 lots from the centre).
* ``diagonal`` (walks along a quadrant's diagonal): ``building ~ Bernoulli(0.65)``;
  ``row ~ Bernoulli(0.75)`` and ``col ~ Bernoulli(0.75)`` start straight iterators along x
  and z from the next lots, and ``next ~ Bernoulli(0.8)`` continues along the diagonal.
  Together they reach every lot at most once.
* ``building``: ``rotation ~ U(-0.35, 0.35)`` (radians about y), ``sx ~ U(0.35, 0.9)``,
  ``sy ~ U(0.35, 0.9)`` (footprint, lot = 1), ``height ~ U(0.4, 4)``; one box.

The constants are ours (the paper gives none).
"""

from __future__ import annotations

from ..core import Model, Uniform
from ..geometry.solid import Box, compose, new_part_bounds, rotation, translation

MAX_STEPS = 10


def center(ctx):
    """The centre lot and the eight iterators leaving it."""
    ctx.maybe("building", 0.7, building, 0, 0)
    for name, di, dj in (("east", 1, 0), ("west", -1, 0), ("north", 0, 1), ("south", 0, -1)):
        ctx.spawn(name, straight, di, dj, di, dj, 1)
    for name, di, dj in (("ne", 1, 1), ("nw", -1, 1), ("se", 1, -1), ("sw", -1, -1)):
        ctx.spawn(name, diagonal, di, dj, di, dj, 1)


def straight(ctx, i, j, di, dj, steps):
    """A lot on a straight street, maybe a building, maybe the next lot."""
    ctx.maybe("building", 0.65, building, i, j)
    if steps < MAX_STEPS:
        ctx.maybe("next", 0.85, straight, i + di, j + dj, di, dj, steps + 1)


def diagonal(ctx, i, j, di, dj, steps):
    """A lot on a quadrant's diagonal, branching into a row and a column."""
    ctx.maybe("building", 0.65, building, i, j)
    if steps < MAX_STEPS:
        ctx.maybe("row", 0.75, straight, i + di, j, di, 0, steps + 1)
        ctx.maybe("col", 0.75, straight, i, j + dj, 0, dj, steps + 1)
        ctx.maybe("next", 0.8, diagonal, i + di, j + dj, di, dj, steps + 1)


def building(ctx, i, j):
    """One building on lot (i, j)."""
    phi = ctx.sample("rotation", Uniform(-0.35, 0.35))
    sx = ctx.sample("sx", Uniform(0.35, 0.9))
    sy = ctx.sample("sy", Uniform(0.35, 0.9))
    height = ctx.sample("height", Uniform(0.4, 4.0))
    ctx.emit(Box((sx, height, sy), compose(translation(float(i), 0.5 * height, float(j)), rotation("y", phi)),
                 "building"))


def _root_args(params) -> tuple:
    return ()


MODEL = Model(
    name="city",
    description="a city of buildings on lots reached by street iterators (seed 002, Fig. 8b)",
    root=center,
    root_args=_root_args,
    new_output_from=new_part_bounds,
    params={},
    rules=(center, straight, diagonal, building),
    choices_doc=__doc__,
)
