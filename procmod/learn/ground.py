"""The ground a learned program's examples stand on, and its forward samples set on it.

A learned program places its root part (a table's top) at a height drawn from the
examples' and sizes its descendants (the legs) by draws of their own: nothing ties the two
together, so the lowest point of a sample lands wherever the draws put it. On a helper's
eight tables modelled in Blender, every one standing on the floor, the feet of 84 of 199
samples floated or sank by more than 2 cm (up to 8 cm): the top's height and the legs'
length were drawn apart (correlation 0.08). Seed 000 has no ground; a user of a table
generator expects the tables to stand.

So where the examples share a ground (every example's lowest point at one height, within
:data:`GROUND_TOLERANCE` of their size), the program keeps it (``units.ground``), and a
forward sample is set on it when it is complete: its root part's height choice is moved
so that the sample's lowest point is at the ground, and the derivation replayed with it
(:func:`settle_on_ground`). The result is a derivation of the program like any other (its
saved choices replay to the same parts; its log-prior is that of its choices); only the
root's height is no longer drawn independently of the rest. Inference against a target
is unchanged: the target places the result, and an engine's particles are never moved.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.runtime import replay
from ..geometry.solid import scene_bounds
from .examples import ExampleSet, example_parts

GROUND_TOLERANCE = 0.01
"""The most the examples' lowest points may differ in height, as a fraction of their
median bounding-box diagonal, for them to share a ground: parts placed by eye on a floor
are a few millimetres off it (a helper's tables: +-3 mm on 1.2 m), a set with no ground
(spaceships of several sizes, centred on their body) differs by a sizeable fraction."""

ROOT_HEIGHT = "x.t1"  # the choice a part's translation along its frame's y axis is drawn as
SETTLE_STEPS = 3  # the most replays that move a sample (each corrects the last one's miss)


def examples_ground(example_set: ExampleSet) -> float | None:
    """The height every example's lowest point is at (the median of them), when they
    differ by at most :data:`GROUND_TOLERANCE` of the examples' median diagonal; None for
    fewer than two examples with parts, or lowest points further apart."""
    lows, diagonals = [], []
    for root in example_set.examples:
        parts = example_parts(root, example_set.parts)
        if not parts:
            continue
        lo, hi = scene_bounds(parts)
        lows.append(float(lo[1]))
        diagonals.append(float(np.linalg.norm(hi - lo)))
    if len(lows) < 2:
        return None
    size = float(np.median(diagonals))
    if not size > 0 or max(lows) - min(lows) > GROUND_TOLERANCE * size:
        return None
    return float(np.median(lows))


def _bounds(derivation) -> tuple | None:
    """``(lowest height, extent along each axis)`` of a derivation's parts' bounding box;
    None without parts."""
    geometry = derivation.geometry()
    if not geometry:
        return None
    lo, hi = scene_bounds(geometry)
    return float(lo[1]), hi - lo


def settle_on_ground(ground: float, derivation, slope: float | None = None):
    """``derivation`` (a complete forward sample of a learned program) with its root part's
    height choice moved so that its lowest point is at ``ground``, replayed; the derivation
    itself where it already is (to 1e-9 of its size), has no parts, or where moving that
    choice does not move the whole sample up and down (then it is left as drawn).

    The root part's placement is the shallowest call that draws a height (a root that is a
    symmetry of parts has it in its member's call); every other part is placed from it, so
    the lowest point moves with that choice in a straight line: by ``slope`` (world units
    per unit of the choice: a root part's is the program's world extent) when given, else
    measured by a replay. A move that does not land within 1e-6 of the sample's size (far
    from the origin, rounding: a floor at 1e8 times the examples' size) is corrected from
    the two points it gives, up to :data:`SETTLE_STEPS` replays in all; the closest rigid
    move is kept, and none that changes the sample's extent.
    """
    if not derivation.done or derivation.stopped:
        return derivation
    measured = _bounds(derivation)
    if measured is None:
        return derivation
    low, extent = measured
    size = float(np.linalg.norm(extent))
    # there to 1e-9 of its size, or to what floats resolve that far from the origin
    if abs(low - ground) <= max(1e-9 * size, 8 * np.finfo(float).eps * abs(ground)):
        return derivation
    placing = [node for node in derivation.nodes() if ROOT_HEIGHT in node.choices]
    if not placing:
        return derivation
    key = (min(placing, key=lambda node: len(node.address)).address, ROOT_HEIGHT)
    choices = dict(derivation.choice_map())
    order = derivation.order()
    model = derivation.model
    rng = np.random.default_rng(0)  # every choice is in the map: nothing is drawn

    def replayed(height: float):
        """(the derivation with the root's height choice at ``height``, its lowest point),
        or None where it is not the sample moved whole (other calls, or another extent)."""
        run = replay(model, {**choices, key: height}, rng, order)
        moved = _bounds(run.derivation) if not run.unused else None
        if moved is None or np.abs(moved[1] - extent).max() > 1e-6 * size:
            return None
        return run.derivation, moved[0]

    height, at = float(choices[key]), low
    if slope is None:
        probe = replayed(height + 1.0)
        if probe is None:
            return derivation
        slope = probe[1] - low
    best, best_error = derivation, abs(low - ground)
    for _ in range(SETTLE_STEPS):
        if not (math.isfinite(slope) and abs(slope) > 1e-12 * max(size, 1.0)):
            break
        moved_to = height + (ground - at) / slope
        moved = replayed(moved_to)
        if moved is None:
            break
        settled, lands = moved
        if abs(lands - ground) < best_error:
            best, best_error = settled, abs(lands - ground)
        if best_error <= 1e-6 * max(size, 1e-12) or moved_to == height:
            break
        slope, height, at = (lands - at) / (moved_to - height), moved_to, lands
    return best
