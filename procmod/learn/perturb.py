"""Placement noise on example hierarchies: what hand-made models look like.

:func:`perturb_examples` moves every node of every example independently, as a modeller
placing parts by eye would: with ``D`` the example's world bounding-box diagonal and
``sigma = relative * D``,

* translation + N(0, sigma^2) per axis,
* rotation by a random rotation vector, N(0, relative^2) radians per axis (a point at
  distance ``D`` moves by about ``sigma``), applied about the part's own origin,
* each axis scale times (1 + N(0, relative^2)).

The result is still rotation x scale x translation (no shear), so it reads back as
``procmod-examples/1``. The bench's noisy sets use ``relative = 1e-3``.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np
from scipy.spatial.transform import Rotation

from ..geometry.part_library import world_bounds
from .examples import ExampleNode, ExampleSet


def example_diagonal(node: ExampleNode, parts: dict) -> float:
    """The diagonal of an example's world bounding box."""
    boxes = [world_bounds(parts[n.part], n.transform) for n in node.walk()]
    lo = np.min([b[0] for b in boxes], axis=0)
    hi = np.max([b[1] for b in boxes], axis=0)
    return float(np.linalg.norm(hi - lo))


def _perturb(node: ExampleNode, sigma: float, relative: float, rng: np.random.Generator) -> ExampleNode:
    m = np.array(node.transform, dtype=np.float64)
    rot = Rotation.from_rotvec(rng.normal(0.0, relative, 3)).as_matrix()
    scale = 1.0 + rng.normal(0.0, relative, 3)
    out = np.eye(4)
    out[:3, :3] = rot @ m[:3, :3] * scale  # scales the columns: still rotation x axis scaling
    out[:3, 3] = m[:3, 3] + rng.normal(0.0, sigma, 3)
    return ExampleNode(node.part, out, [_perturb(c, sigma, relative, rng) for c in node.children])


def perturb_examples(example_set: ExampleSet, relative: float, rng: np.random.Generator) -> ExampleSet:
    """A copy of ``example_set`` with Gaussian placement noise of ``relative`` x each
    example's bounding-box diagonal on every transform (see the module docstring)."""
    examples = [_perturb(e, relative * example_diagonal(e, example_set.parts), relative, rng)
                for e in example_set.examples]
    return replace(example_set, examples=examples)
