"""``vines``: recursive vine growth, the program of seeds 003/004 (see shared/seeds/vines.md).

Random choices per call of rule ``branch`` (one segment):

* ``angle ~ Normal(parent angle, pi/8)``; for the first segment
  ``Normal(atan2(direction), pi/6)``.
* with leaves and flowers (parameter ``leaves``, default on):

  * ``leaf ~ Categorical(none, left, right)`` uniform; for left / right
    ``leaf_angle ~ Normal(angle +/- pi/4, pi/12)`` and an elliptical leaf of width
    1.3 x 0.75 and length 2.0986 x that width is emitted with its base at the segment's
    midpoint, pointing along ``leaf_angle``;
  * ``flower ~ Bernoulli(0.5)``: a disc of radius 0.75 at the segment's end point.

* ``terminate ~ Bernoulli(0.5)``: if true, the *whole* derivation stops (``ctx.stop``).
* otherwise, if the child width ``0.975 x width`` is above ``0.15 x 0.75``:
  ``branch1 ~ Bernoulli(0.66)``, a ``maybe`` site that continues from the end point; only
  if branch1 is true, a call of rule ``second_branch`` (spawn site ``then``) follows it.

Rule ``second_branch`` (no geometry) runs once ``branch1``'s subtree has run, unless that
subtree stopped the vine, and draws ``branch2 ~ Bernoulli(0.5)``, a second continuation
from the same point: no, one or two further branches, each with probability about 1/3,
as in the original program (vines.md).

Segments have length 2 and start with width 0.75; the width bound limits depth to 75.

Why ``branch2`` is a call of its own: the original program draws its coin after
``branch1``'s subtree has run, and for SMC *when* a coin is drawn matters, not only its
distribution. Drawn at the end of the parent's call (an earlier procmod did that), the
coin is fixed before the particle is resampled at the subtree's emits, so every copy of a
particle inherits it; drawn when the subtree is done, each copy draws its own, so copies
whose tip has left the target resume from different points of the stem. Same model,
same outputs; on the bench's glyphs, SMC-200's median similarity went from 0.30 to 0.79
(bench/vs_webppl.py; docs/vines_smc.md).
"""

from __future__ import annotations

import math

from ..core import Bernoulli, Categorical, Model, Normal
from ..geometry import Disc, Segment, leaf
from .frame import FRAME_RANGES, heading, new_canvas, to_world

LENGTH = 2.0
INITIAL_WIDTH = 0.75
WIDTH_DECAY = 0.975
MIN_WIDTH = 0.15 * INITIAL_WIDTH
TURN_SD = math.pi / 8
START_SD = math.pi / 6
LEAF_WIDTH = 1.3 * 0.75
LEAF_LENGTH = 2.0986 * LEAF_WIDTH
LEAF_ANGLE_SD = math.pi / 12
FLOWER_RADIUS = 0.75

_LEAF_SIDE = Categorical([1, 1, 1], labels=("none", "left", "right"))
_COIN = Bernoulli(0.5)


def branch(ctx, x, y, parent_angle, spread, width, leaves):
    """One vine segment, its leaf and flower, then termination or continuations."""
    ctx.at((x, y, parent_angle))  # position and heading: where guides look
    angle = ctx.sample("angle", Normal(parent_angle, spread))
    x1 = x + LENGTH * math.cos(angle)
    y1 = y + LENGTH * math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, width, "stem"))
    ctx.at((x1, y1, angle))
    if leaves:
        side = ctx.sample("leaf", _LEAF_SIDE)
        if side != "none":
            offset = math.pi / 4 if side == "left" else -math.pi / 4
            leaf_angle = ctx.sample("leaf_angle", Normal(angle + offset, LEAF_ANGLE_SD))
            ctx.emit(leaf(0.5 * (x + x1), 0.5 * (y + y1), leaf_angle, LEAF_LENGTH, LEAF_WIDTH))
        if ctx.sample("flower", _COIN):
            ctx.emit(Disc(x1, y1, FLOWER_RADIUS, "flower"))
    if ctx.sample("terminate", _COIN):
        ctx.stop()
        return
    child_width = width * WIDTH_DECAY
    if child_width > MIN_WIDTH:
        if ctx.maybe("branch1", 0.66, branch, x1, y1, angle, TURN_SD, child_width, leaves):
            ctx.spawn("then", second_branch, x1, y1, angle, child_width, leaves)


def second_branch(ctx, x, y, angle, width, leaves):
    """``branch2``: drawn once ``branch1``'s subtree has run, if the vine still grows."""
    ctx.maybe("branch2", 0.5, branch, x, y, angle, TURN_SD, width, leaves)


def _root_args(params):
    x, y = to_world(params["start"])
    return (x, y, heading(params["direction"]), START_SD, INITIAL_WIDTH, bool(params["leaves"]))


MODEL = Model(
    name="vines",
    description="vines that grow, fork, taper and stop at random, with leaves and flowers (seeds 003/004)",
    root=branch,
    root_args=_root_args,
    new_output_from=new_canvas,
    params={"start": [0.5, 0.9166], "direction": [0.0, -1.0], "size": 50, "leaves": True, "min_radius_px": 0.0},
    param_ranges=FRAME_RANGES,
    rules=(branch, second_branch),
    choices_doc=__doc__,
    # x, y, parent_angle, spread, width, leaves: for the local-state features of guides
    arg_ranges={"branch": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, START_SD),
                           (0.0, INITIAL_WIDTH), (0.0, 1.0)),
                # x, y, angle, width, leaves
                "second_branch": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, INITIAL_WIDTH), (0.0, 1.0))},
    heading_rules=("branch",),
)
