"""Hand-placed example sets the learn tests share (parts placed by eye, with noise)."""

from __future__ import annotations

import math

import numpy as np

from procmod.learn import examples_from_dict


def stools(count=8, noise=0.02, seed=0, leg_counts=(4,)):
    """Stools placed by eye: lengths, radii and angles off by about ``noise``. Stool i has
    ``leg_counts[i % len(leg_counts)]`` legs spread evenly about the seat's centre (four:
    on the seat's axes, mirrored across its diagonals; three: one leg plus a mirrored pair)."""
    rng = np.random.default_rng(seed)
    examples = []
    for i in range(count):
        legs_n = leg_counts[i % len(leg_counts)]
        h, r = 0.45 * (1 + rng.normal(0, noise)), 0.18 * (1 + rng.normal(0, noise))
        legs = []
        for k in range(legs_n):
            a = 2 * math.pi * k / legs_n + rng.normal(0, noise)
            m = np.diag([1.0, h / 0.45, 1.0, 1.0])
            m[:3, 3] = (r * math.cos(a) * (1 + rng.normal(0, noise)), h / 2, r * math.sin(a))
            legs.append({"part": "leg", "transform": m.tolist(), "children": []})
        seat = np.eye(4)
        seat[1, 3] = h + 0.02
        examples.append({"part": "seat", "transform": seat.tolist(), "children": legs})
    return examples_from_dict({"format": "procmod-examples/1",
                               "parts": {"seat": {"box": [0.5, 0.04, 0.5]}, "leg": {"box": [0.04, 0.45, 0.04]}},
                               "examples": examples})
