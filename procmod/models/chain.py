"""``chain``: the linear chain of seed 003, Figure 2a.

::

    function chain(pos, ang) {
      var newang = ang + gaussian(0, PI/8);
      var newpos = pos + polarToRect(LENGTH, newang);
      genSegment(pos, newpos);
      if (flip(0.5)) chain(newpos, newang);
    }

Random choices per call (rule ``chain``):

* ``angle ~ Normal(parent angle, pi/8)`` — the new segment's direction (the first call's
  parent angle is the start direction);
* ``next ~ Bernoulli(0.5)`` — a ``maybe`` site: continue the chain from the end point.

Constants: segment length 2, stroke width 0.6 (world units); a hard bound of
``MAX_SEGMENTS`` = 100 segments (reached with probability 2^-99) keeps runs finite.
"""

from __future__ import annotations

import math

from ..core import Model, Normal
from ..geometry import Segment
from .frame import FRAME_RANGES, heading, new_canvas, to_world

LENGTH = 2.0
WIDTH = 0.6
TURN_SD = math.pi / 8
MAX_SEGMENTS = 100


def chain(ctx, x, y, angle, count):
    """One segment, then maybe the rest of the chain."""
    ctx.at((x, y))
    new_angle = ctx.sample("angle", Normal(angle, TURN_SD))
    x1 = x + LENGTH * math.cos(new_angle)
    y1 = y + LENGTH * math.sin(new_angle)
    ctx.emit(Segment(x, y, x1, y1, WIDTH, "chain"))
    ctx.at((x1, y1))
    if count + 1 < MAX_SEGMENTS:
        ctx.maybe("next", 0.5, chain, x1, y1, new_angle, count + 1)


def _root_args(params):
    x, y = to_world(params["start"])
    return (x, y, heading(params["direction"]), 0)


MODEL = Model(
    name="chain",
    description="a random-walk chain of segments that stops with probability 1/2 (seed 003, Fig. 2a)",
    root=chain,
    root_args=_root_args,
    new_output_from=new_canvas,
    params={"start": [0.5, 0.9166], "direction": [0.0, -1.0], "size": 50},
    param_ranges=FRAME_RANGES,
    rules=(chain,),
    choices_doc=__doc__,
    arg_ranges={"chain": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, MAX_SEGMENTS))},
)
