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
  ``branch1 ~ Bernoulli(0.66)``, a ``maybe`` site that continues from the end point, and
  **only if branch1 is true** ``branch2 ~ Bernoulli(0.5)``, a second continuation from
  the same point: no, one or two further branches, each with probability about 1/3, as
  in the original program (vines.md).

Segments have length 2 and start with width 0.75; the width bound limits depth to 75.

The original draws ``branch2`` after ``branch1``'s subtree has run, and only if that
subtree did not terminate the vine. Here spawned calls are futures run in program order,
so ``branch2``'s coin is drawn with ``branch1``'s and its call runs after ``branch1``'s
subtree, or never if that subtree called ``ctx.stop``. The coin is independent of
everything in between, so derivations and outputs are distributed as in the original; a
derivation whose ``branch1`` subtree terminated carries one coin more (its log-prior
counts it; the output is the same).
"""

from __future__ import annotations

import math

from ..core import Bernoulli, Categorical, Model, Normal
from ..geometry import Disc, Segment, leaf
from .frame import heading, new_canvas, to_world

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
            ctx.maybe("branch2", 0.5, branch, x1, y1, angle, TURN_SD, child_width, leaves)


def _root_args(params):
    x, y = to_world(params["start"])
    return (x, y, heading(params["direction"]), START_SD, INITIAL_WIDTH, bool(params["leaves"]))


MODEL = Model(
    name="vines",
    description="vines that grow, fork, taper and stop at random, with leaves and flowers (seeds 003/004)",
    root=branch,
    root_args=_root_args,
    new_output_from=new_canvas,
    params={"start": [0.5, 0.9166], "direction": [0.0, -1.0], "size": 50, "leaves": True},
    rules=(branch,),
    choices_doc=__doc__,
    # x, y, parent_angle, spread, width, leaves: for the local-state features of guides
    arg_ranges={"branch": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, START_SD),
                           (0.0, INITIAL_WIDTH), (0.0, 1.0))},
    heading_rules=("branch",),
)
