"""Write your own model: a chain of segments, sampled and rendered (the README's example).

Run: python examples/custom_model.py OUT.png
"""

import math
import sys

import numpy

from procmod import Model, Normal, run_forward
from procmod.geometry import Canvas, Segment, render_image


def chain(ctx, x, y, angle):
    angle = ctx.sample("angle", Normal(angle, math.pi / 8))     # a named random choice
    x1, y1 = x + 2 * math.cos(angle), y + 2 * math.sin(angle)
    ctx.emit(Segment(x, y, x1, y1, 0.6))                         # draw; SMC may resample here
    ctx.at((x1, y1))                                             # where neural guides look
    ctx.maybe("next", 0.5, chain, x1, y1, angle)                 # spawn with probability 1/2


model = Model("my-chain", "a chain", chain, root_args=lambda p: (0.0, 0.0, -math.pi / 2),
              new_output_from=lambda p: Canvas((-12, 12, -22, 2), 50))

if __name__ == "__main__":
    derivation = run_forward(model, numpy.random.default_rng(0))
    print(derivation)
    render_image(derivation.geometry(), derivation.output.viewport, 256).save(sys.argv[1] if len(sys.argv) > 1 else "chain.png")
