"""``lightning``: branching lightning bolts (in the spirit of seed 003's lightning example).

A bolt is a zig-zag of segments around a slowly drifting heading, thinning as it goes;
at each joint it may fork a thinner side bolt.

Random choices per call of rule ``bolt`` (one segment):

* ``angle ~ Normal(heading, pi/6)`` — the zig-zag around the bolt's heading;
* ``length ~ TruncatedNormal(1.4, 0.5, 0.6, 2.6)`` — segment length;
* ``fork ~ Bernoulli(0.22)`` — ``maybe`` site: start a side bolt (rule ``fork``);
* ``next ~ Bernoulli(0.96 if width >= 0.4 else 0.8)`` — ``maybe`` site: continue.

Rule ``fork`` makes one choice, ``spread ~ GaussianMixture(1/2 at +pi/4, 1/2 at -pi/4,
sd pi/12)`` — which side and how far the side bolt turns — then spawns a bolt of 0.6 x
the width. The heading drifts a quarter of the way towards each segment's angle. Widths
decay by 0.97 per segment; a bolt stops below width 0.12 or after 60 segments.
"""

from __future__ import annotations

import math

from ..core import GaussianMixture, Model, Normal, TruncatedNormal
from ..geometry import Segment
from .frame import FRAME_RANGES, heading, new_canvas, to_world

INITIAL_WIDTH = 0.6
WIDTH_DECAY = 0.97
FORK_WIDTH = 0.6
MIN_WIDTH = 0.12
MAX_SEGMENTS = 60
FORK_P = 0.22
DRIFT = 0.25

_LENGTH = TruncatedNormal(1.4, 0.5, 0.6, 2.6)
_SPREAD = GaussianMixture([0.5, 0.5], [math.pi / 4, -math.pi / 4], [math.pi / 12, math.pi / 12])


def bolt(ctx, x, y, bolt_heading, width, remaining):
    """One segment of a bolt, then maybe a fork and maybe the next segment."""
    ctx.at((x, y))
    angle = ctx.sample("angle", Normal(bolt_heading, math.pi / 6))
    length = ctx.sample("length", _LENGTH)
    x1 = x + length * math.cos(angle)
    y1 = y + length * math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, width, "bolt"))
    ctx.at((x1, y1))
    child_width = width * WIDTH_DECAY
    if remaining <= 1 or child_width < MIN_WIDTH:
        return
    new_heading = bolt_heading + DRIFT * (angle - bolt_heading)
    if child_width * FORK_WIDTH >= MIN_WIDTH:
        ctx.maybe("fork", FORK_P, fork, x1, y1, new_heading, child_width * FORK_WIDTH, remaining - 1)
    ctx.maybe("next", 0.96 if width >= 0.4 else 0.8, bolt, x1, y1, new_heading, child_width, remaining - 1)


def fork(ctx, x, y, parent_heading, width, remaining):
    """Turn a side bolt off the main one."""
    spread = ctx.sample("spread", _SPREAD)
    ctx.spawn("bolt", bolt, x, y, parent_heading + spread, width, remaining)


def _root_args(params):
    x, y = to_world(params["start"])
    return (x, y, heading(params["direction"]), INITIAL_WIDTH, MAX_SEGMENTS)


MODEL = Model(
    name="lightning",
    description="a zig-zag lightning bolt that forks thinner side bolts",
    root=bolt,
    root_args=_root_args,
    new_output_from=new_canvas,
    params={"start": [0.5, 0.04], "direction": [0.0, 1.0], "size": 50},
    param_ranges=FRAME_RANGES,
    rules=(bolt, fork),
    choices_doc=__doc__,
    arg_ranges={"bolt": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, INITIAL_WIDTH),
                         (0.0, MAX_SEGMENTS)),
                "fork": ((-12.0, 12.0), (-22.0, 2.0), "angle", (0.0, INITIAL_WIDTH),
                         (0.0, MAX_SEGMENTS))},
)
