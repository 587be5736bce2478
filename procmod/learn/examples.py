"""The ``procmod-examples/1`` format: part-based example hierarchies; and example sets from
asset files (glTF, GLB, URDF: :func:`read_example_inputs`, :func:`examples_from_assets`).

::

    {"format": "procmod-examples/1",
     "parts": {"body": {"box": [2.0, 0.5, 4.0]}, "wing": {"mesh": "parts/wing.obj"}},
     "examples": [{"part": "body", "transform": [[...4 rows of 4...]],
                   "children": [{"part": "wing", "transform": ..., "children": []}]}]}

Samples of a learned program (:func:`procmod.learn.write_examples`) also say which program
they were sampled from: ``"sampled_from": "../runs/castles/program.json"`` (relative to the
file's folder), which ``procmod sample`` reads to replace its own earlier file, never a set
of the user's, without ``--overwrite``.

A part is a box (full extents, centred at its local origin) or a triangle mesh (a path
relative to the JSON file's folder; see :mod:`procmod.core.paths`) in its own local
frame. ``transform`` is the node's world-space 4x4 affine matrix (row-major). Children
nest to any depth.

Reading checks everything a learner relies on and names the JSON path of the first
problem (``examples[3].children[1].transform``): wrong format tag, unknown part,
non-affine or singular matrix, a transform with shear (the learner models rotation x
scale x translation only), missing mesh file, a node that contains itself (a cycle,
possible when a Python object is passed in) and nesting deeper than :data:`MAX_DEPTH`.
"""

from __future__ import annotations

import json
import math
import os
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

from ..core.errors import ProcmodError, shown_value
from ..core.io import check_format, read_json, write_text_atomic
from ..core.limits import MAX_COORDINATE
from ..geometry.assets import MAX_DEPTH  # one depth limit for example files and asset files
from ..geometry.units import mixed_sizes_note
from ..geometry.part_library import (PartLibraryError, PartShape, is_singular, read_part_library, read_transform,
                                     transform_to_json)
from .transforms import decompose, turn_about_up

FORMAT = "procmod-examples/1"
# The cosine between two columns of a transform's 3x3 part above which it shears: 2e-3 is
# about 0.1 degree, what matrices written at 3-5 decimals leave (rounded spaceship
# transforms were refused at 1e-6); decompose() re-orthonormalises what is accepted.
SHEAR_TOLERANCE = 2e-3


class ExamplesError(ProcmodError):
    """An examples file (or object) that cannot be read; the message names where."""


@dataclass
class ExampleNode:
    """One part of an example hierarchy: its part name, world transform and children."""

    part: str
    transform: np.ndarray
    children: list = field(default_factory=list)

    def walk(self):
        """This node and all its descendants, depth first."""
        yield self
        for child in self.children:
            yield from child.walk()

    def size(self) -> int:
        return sum(1 for _ in self.walk())


@dataclass
class ExampleSet:
    """A part library and the example hierarchies built from it."""

    parts: dict  # name -> PartShape
    examples: list  # of ExampleNode
    base_dir: Path = Path(".")
    # parts moved down to the part they touch (procmod.learn.hanging): (example, type, from, to)
    rehung: tuple = ()
    # the way the examples faced (radians about the up axis y) before :func:`centred_examples`
    # turned each to face the world's axes: a learned program's roots face it (Units.facing)
    facing: float = 0.0


def shear_degrees(m: np.ndarray) -> float:
    """How far from square (degrees) the most skewed pair of columns of ``m``'s 3x3 part is."""
    linear = np.asarray(m, dtype=np.float64)[:3, :3]
    gram = linear.T @ linear  # diagonal exactly when the columns are orthogonal
    diag = np.sqrt(np.outer(np.diag(gram), np.diag(gram)))
    off = np.abs(gram - np.diag(np.diag(gram))) / np.maximum(diag, 1e-300)
    return math.degrees(math.asin(min(float(off.max()), 1.0)))


def has_shear(m: np.ndarray) -> bool:
    """True when the 3x3 part of ``m`` is not a rotation times a (signed) axis scaling, up
    to :data:`SHEAR_TOLERANCE`."""
    return shear_degrees(m) > math.degrees(math.asin(SHEAR_TOLERANCE))


def _read_node(value, parts: dict, where: str, depth: int, seen: set) -> ExampleNode:
    if not isinstance(value, dict):
        raise ExamplesError(f"{where}: expected a node object with 'part' and 'transform', "
                            f"got {shown_value(value, 60)}")
    if id(value) in seen:
        raise ExamplesError(f"{where}: this node contains itself (a cycle); example hierarchies must be trees")
    if depth > MAX_DEPTH:
        raise ExamplesError(f"{where}: hierarchy deeper than {MAX_DEPTH} levels; is it cyclic?")
    unknown = sorted(set(value) - {"part", "transform", "children"})
    if unknown:
        raise ExamplesError(f"{where}: unknown field {unknown[0]!r} (a node has 'part', 'transform', 'children')")
    part = value.get("part")
    if not isinstance(part, str):
        raise ExamplesError(f"{where}.part: expected a part name (a string), got {shown_value(part, 60)}")
    if part not in parts:
        raise ExamplesError(f"{where}.part: unknown part {part!r}; the file's parts are: "
                            f"{', '.join(sorted(parts))}")
    if "transform" not in value:
        raise ExamplesError(f"{where}: missing 'transform' (a 4x4 world matrix, row-major)")
    transform = read_transform(value["transform"], f"{where}.transform")
    if has_shear(transform):
        raise ExamplesError(f"{where}.transform: the matrix shears (its 3x3 part is not a rotation times "
                            f"an axis scaling: columns {shear_degrees(transform):.2g} degrees off square); procmod "
                            "learn models rotation, scale and translation only")
    children_value = value.get("children", [])
    if not isinstance(children_value, list):
        raise ExamplesError(f"{where}.children: expected a list of nodes, got {shown_value(children_value, 60)}")
    seen.add(id(value))
    children = [_read_node(c, parts, f"{where}.children[{i}]", depth + 1, seen)
                for i, c in enumerate(children_value)]
    seen.discard(id(value))
    return ExampleNode(part, transform, children)


def examples_from_dict(data, base_dir: str | os.PathLike = ".", source: str = "examples") -> ExampleSet:
    """Check and read a parsed ``procmod-examples/1`` object.

    Raises
    ------
    ExamplesError
        Naming ``source`` and the JSON path of the first problem.
    """
    check_format(data, FORMAT, source, ExamplesError)
    unknown = sorted(map(str, set(data) - {"format", "parts", "examples", "sampled_from"}))
    if unknown:
        raise ExamplesError(f"{source}: unknown field {unknown[0]!r} (the file has 'format', 'parts', 'examples', "
                            "and, written by procmod sample, 'sampled_from')")
    if "sampled_from" in data and not isinstance(data["sampled_from"], str):
        raise ExamplesError(f"{source}: 'sampled_from' must be the path of the program the examples were sampled "
                            "from (procmod sample writes it)")
    examples = data.get("examples")
    if not isinstance(examples, list) or not examples:
        raise ExamplesError(f"{source}: 'examples' must be a non-empty list of hierarchies")
    try:  # the messages name the field; the file is named here
        parts = read_part_library(data.get("parts"), base_dir)
        nodes = [_read_node(e, parts, f"examples[{i}]", 0, set()) for i, e in enumerate(examples)]
    except (ExamplesError, PartLibraryError) as exc:
        raise ExamplesError(f"{source}: {exc}") from None
    return ExampleSet(parts, nodes, Path(base_dir))


def read_examples(path: str | os.PathLike) -> ExampleSet:
    """Read and check a ``procmod-examples/1`` file (mesh paths relative to it)."""
    path = Path(path)
    return examples_from_dict(read_json(path, ExamplesError, "examples file"), path.parent, str(path))


def _asset_node(node, path: Path, depth: int, up: np.ndarray) -> ExampleNode:
    if depth > MAX_DEPTH:
        raise ExamplesError(f"{path}: hierarchy deeper than {MAX_DEPTH} levels")
    with np.errstate(all="ignore"):
        m = up @ np.asarray(node.transform, dtype=np.float64)
    where = f"{path}: node {node.name!r}"
    if not np.isfinite(m).all() or np.abs(m).max() > MAX_COORDINATE:
        # squares of such numbers overflow: the learner's SVDs spun on NaN matrices, deaf to SIGTERM
        raise ExamplesError(f"{where}: its world transform holds a number beyond {MAX_COORDINATE:g} (or not finite); "
                            "placements and scales must be ordinary lengths: check the file's units")
    if is_singular(m[:3, :3]):
        raise ExamplesError(f"{where}: its world transform is singular (a scale of zero, or a parent's); procmod "
                            "learn needs every part to have a volume's worth of placement: delete the part (a "
                            "hidden helper) or give it and its parents non-zero scales")
    if has_shear(m):
        # a guard: the asset reader puts a shearing node's map into its geometry
        raise ExamplesError(f"{where}: its world transform shears (a non-uniform scale applied to a rotated part, "
                            "or under a rotated parent); procmod learn models rotation, scale and translation only: "
                            "apply the scale in the modelling tool (Blender: Object > Apply > Scale) and export again")
    return ExampleNode(node.part, np.array(m, dtype=np.float64),
                       [_asset_node(c, path, depth + 1, up) for c in node.children])


def examples_from_assets(asset_set) -> ExampleSet:

    """An example set from asset files read by :func:`procmod.geometry.assets.read_assets`:
    its part library, and one example per file (the file's single top-level part). A URDF
    robot (z-up) is turned up the y axis, procmod's up and glTF's, so robots stand upright
    in contact sheets and in Blender, and agree with glTF examples in one set.

    Raises
    ------
    ExamplesError
        For a file with no or several top-level parts, or a transform the learner cannot
        model (singular, or shearing).
    """
    from ..geometry.assets import Y_UP_TO_Z_UP

    examples = []
    for asset in asset_set.assets:
        if len(asset.roots) != 1:
            names = ", ".join(repr(r.name) for r in asset.roots[:5]) + (", ..." if len(asset.roots) > 5 else "")
            # (a mesh object without faces is read as an empty too: "the empty" named it wrongly, h91)
            under = (f"; they are under {asset.groups[0]!r}, which draws no faces (an empty, or a mesh without "
                     "faces) and so is no part" if len(asset.groups) == 1 else "")
            raise ExamplesError(f"{asset.path}: {len(asset.roots)} top-level parts ({names}){under}; an example is "
                                "one hierarchy: parent them under one part (the body), or, if they are several "
                                "examples side by side, give each a file (in Blender, a root) of its own")
        up = Y_UP_TO_Z_UP.T if asset.path.suffix.lower() == ".urdf" else np.eye(4)
        examples.append(_asset_node(asset.roots[0], asset.path, 0, up))
    base = asset_set.assets[0].path.parent if asset_set.assets else Path(".")
    return ExampleSet(dict(asset_set.parts), examples, base)


FACING_CONDITION = 0.2
"""A root turned so far from standing (near upside down: its turn's part about the up axis
under this, as a quaternion's length) that which way it faces is not well defined; such
an example keeps its spin (:func:`centred_examples`)."""


def facing_angle(world) -> float | None:
    """The spin about the up axis (y; radians in (-pi, pi]) of a node's world transform:
    the twist about world y of its rotation (the rotation is ``Ry(angle) @ swing``, the
    swing turning about no vertical axis). Examples that stand alike but face other ways
    differ by it alone. None for a root standing near upside down
    (:data:`FACING_CONDITION`)."""
    rot = decompose(world)[0]
    x, y, z, w = Rotation.from_matrix(rot).as_quat()
    if w < 0:  # q and -q are one rotation: the one with w >= 0 gives an angle within +-pi
        y, w = -y, -w
    if math.hypot(y, w) < FACING_CONDITION:
        return None
    angle = 2.0 * math.atan2(y, w)
    return 0.0 if abs(angle) < 1e-12 else angle


def _turn_between(a: float, b: float) -> float:
    """The turn from angle ``b`` to angle ``a``, within +-pi."""
    return math.remainder(a - b, 2.0 * math.pi)


def reference_facing(angles: list) -> float | None:
    """The way most examples face: of their facings (:func:`facing_angle`; None left out),
    the one nearest all the others (the least summed turn to them; the first on a tie),
    set to the nearest quarter turn when within :data:`FACING_SQUARE` of it."""
    known = [a for a in angles if a is not None]
    if not known:
        return None
    facing = min(known, key=lambda a: sum(abs(_turn_between(b, a)) for b in known))
    square = round(facing / (0.5 * math.pi)) * 0.5 * math.pi
    return math.remainder(square, 2.0 * math.pi) if abs(facing - square) <= FACING_SQUARE else facing


FACING_SQUARE = math.radians(3.0)
"""A set facing within this of a quarter turn faces the quarter turn (a hand's yaw of a
degree: samples had faced 0.9 degrees off the axes; h140); as parts' turns are squared
(procmod.learn.preprocessing.SQUARE_TURN)."""


def centred_examples(example_set: ExampleSet) -> ExampleSet:
    """The example set with each example moved, rigidly, so that its root part stands over
    the origin facing the world's axes: the root's x and z (procmod is y-up) become 0, its
    height is kept, and it is spun about the vertical through it by its root's
    :func:`facing_angle`. The way most examples faced (:func:`reference_facing`) is kept as
    :attr:`ExampleSet.facing`: the learned program's roots face it.

    Where an example stands in the world is not part of its shape. Examples modelled side
    by side in one scene (the only way to see them all at once; Blender's "Learn from
    selection" and glTF exports keep world positions) otherwise made the root's placement
    a wide Gaussian the learner had to explain: on the castles spread 25 units apart the
    search ran 10x longer and kept 39 abstractions, one per example, against 11. Nor is
    which way one faces: fences turned every way in the scene had their roots' turns
    learned as a Gaussian spanning 0 to 180 degrees about the vertical, and 54 of 60
    sampled fences leaned over 10 degrees (median 42; h136), against none for the same
    fences facing one way. Learned facing the world's axes, a hand's tilt is read near
    Euler angle 0, squared where it is within a few degrees, and the set's size is its
    own, not its bounding box's as it stands turned (h140: a set facing 90 degrees, learned
    so, sampled tables leaning 2 degrees); a set turned as one samples as it stood (h138)."""
    def moved(node: ExampleNode, turn: np.ndarray) -> ExampleNode:
        return ExampleNode(node.part, turn @ np.asarray(node.transform, dtype=np.float64),
                           [moved(c, turn) for c in node.children])

    facings = [facing_angle(np.asarray(root.transform, dtype=np.float64)) for root in example_set.examples]
    examples = []
    for root, facing in zip(example_set.examples, facings):
        world = np.asarray(root.transform, dtype=np.float64)
        angle = facing or 0.0
        if world[0, 3] == 0.0 and world[2, 3] == 0.0 and angle == 0.0:
            examples.append(root)
            continue
        # the root's x and z to 0, then the example spun back about the vertical through it
        shift = np.eye(4)
        shift[0, 3], shift[2, 3] = -world[0, 3], -world[2, 3]
        spin = np.eye(4)
        spin[:3, :3] = turn_about_up(-angle)
        examples.append(moved(root, spin @ shift))
    return replace(example_set, examples=examples, facing=reference_facing(facings) or 0.0)


def size_note(example_set: ExampleSet, labels: list | None = None) -> str | None:
    """One line when the largest example is over :data:`~procmod.geometry.units.MIXED_SIZES`
    times the size (world bounding-box diagonal) of the smallest: likely some exported in
    other units (cm and m), which the program would learn as variation and sample at both
    scales (:func:`procmod.geometry.units.mixed_sizes_note`). ``labels`` name the examples
    (default ``examples[i]``). None otherwise."""
    if len(example_set.examples) < 2:
        return None
    from .perturb import example_diagonal  # (perturb imports this module)

    sizes = [example_diagonal(root, example_set.parts) for root in example_set.examples]
    return mixed_sizes_note(sizes, labels or [f"examples[{i}]" for i in range(len(sizes))], "examples",
                            "the program learns sizes from all of them")


TURNED = 45.0
"""Degrees an example's root may stand turned from most of the others before it gets a
note (:func:`orientation_note`)."""


def orientation_note(example_set: ExampleSet, labels: list | None = None) -> str | None:
    """One line when some examples stand turned (tilted, not merely spun about the up
    axis) by more than :data:`TURNED` degrees from the way most examples with the same
    root part stand: one example left lying down, or exported from a z-up tool. The
    program would learn tilts anywhere between (an adversarial pass's tables, one of five
    lying down: samples leaned by 1 to 83 degrees). None otherwise; examples whose root
    parts differ are not compared (their frames are unrelated). ``labels`` name them."""
    labels = labels or [f"examples[{i}]" for i in range(len(example_set.examples))]
    by_root = {}
    for i, root in enumerate(example_set.examples):
        by_root.setdefault(root.part, []).append(i)
    turned, worst = [], 0.0
    for members in by_root.values():
        if len(members) < 3:
            continue
        # world up (y) in each root part's own frame: the same for examples that stand
        # alike, however each is spun about the up axis
        ups = np.array([np.linalg.solve(np.asarray(example_set.examples[i].transform, dtype=np.float64)[:3, :3],
                                        [0.0, 1.0, 0.0]) for i in members])
        ups /= np.linalg.norm(ups, axis=1)[:, None]
        angles = np.degrees(np.arccos(np.clip(ups @ ups.T, -1.0, 1.0)))
        alike = (angles <= 20.0).sum(axis=1)
        most = int(np.argmax(alike))
        if alike[most] * 2 <= len(members):  # no majority stands one way: none is the odd one
            continue
        for k, i in enumerate(members):
            if angles[most, k] > TURNED:
                turned.append(i)
                worst = max(worst, float(angles[most, k]))
    if not turned:
        return None
    turned.sort()
    named = ", ".join(labels[i] for i in turned[:4]) + (f" and {len(turned) - 4} more" if len(turned) > 4 else "")
    return (f"{named} ({len(turned)} of {len(labels)} examples) {'stands' if len(turned) == 1 else 'stand'} turned "
            f"up to {worst:.0f} degrees from how the others stand (lying down, or from a z-up tool?): the program "
            "learns tilts anywhere between; stand it as the others stand, or leave it out")


def _first_three(phrases: list) -> str:
    """Up to three phrases joined by "; ", and how many more there are: a note's list."""
    return "; ".join(phrases[:3]) + (f" (and {len(phrases) - 3} more)" if len(phrases) > 3 else "")


SAME_PLACE = 0.01
"""Two nodes of one part whose bounding-box corners all lie within this fraction of the
part's diagonal of each other are at the same place (:func:`duplicate_note`)."""


def duplicate_note(example_set: ExampleSet, labels: list | None = None) -> str | None:
    """One line when an example holds a part twice at the same place (a copy left where
    it was made: Blender's Shift+D then a right click, a paste in place). The program
    learns such a copy as a part of its own and samples draw it: a table of four legs
    with one leg doubled in one example of six gave a fifth leg, inside another, in 6 of
    20 samples (an adversarial pass). None otherwise; ``labels`` name the examples."""
    from scipy.spatial import cKDTree

    from .symmetry import box_corners  # (symmetry imports this module)

    labels = labels or [f"examples[{i}]" for i in range(len(example_set.examples))]
    found = []  # (example, part, copies)
    for i, root in enumerate(example_set.examples):
        by_part = {}
        for node in root.walk():
            by_part.setdefault(node.part, []).append(np.asarray(node.transform, dtype=np.float64))
        for part, transforms in by_part.items():
            if len(transforms) < 2:
                continue
            corners = box_corners(*example_set.parts[part].local_bounds())
            placed = np.array([corners @ t[:3, :3].T + t[:3, 3] for t in transforms])  # (nodes, 8, 3)
            sizes = np.linalg.norm(placed[:, 0] - placed[:, -1], axis=1)  # each node's diagonal
            # candidates by centre (a corner's distance bounds the centres'), then each pair
            # by its own corners against the smaller of its two sizes
            near = cKDTree(placed.mean(axis=1)).query_pairs(SAME_PLACE * float(sizes.max()))
            copies = len({max(a, b) for a, b in near
                          if np.linalg.norm(placed[a] - placed[b], axis=1).max() <= SAME_PLACE * min(sizes[a], sizes[b])})
            if copies:
                found.append((i, part, copies))
    if not found:
        return None
    shown = _first_three([f"{labels[i]} has {n} more {part!r} at the same place as another" for i, part, n in found])
    return (f"{shown}: a copy left where it was made? the program learns it as a part of its own and samples "
            "draw it; delete the copy")


NEAR_TWIN = 0.05
"""A part whose mesh is another's (the same triangles) resized by at most this share along
any axis, and edited by at most this share of its size, gets a note (:func:`near_twin_note`)."""


def near_twin_note(example_set: ExampleSet, labels: list | None = None) -> str | None:
    """One line naming parts that are another part's mesh a little resized or edited (a
    copy made with Ctrl+D, then scaled 2% with the scale applied and a vertex moved): the
    asset reader makes one part of two meshes only within 0.5% of their size, so such a
    copy is a part type of its own, which the program samples where the examples have it
    and elsewhere in place of the original (a table of eight with one such leg: 10 of 60
    samples drew it, one with three legs; h136). None otherwise."""
    labels = labels or [f"examples[{i}]" for i in range(len(example_set.examples))]
    uses = {}
    for i, root in enumerate(example_set.examples):
        for node in root.walk():
            uses.setdefault(node.part, []).append(i)
    meshes = [(name, shape) for name, shape in example_set.parts.items() if shape.kind == "mesh" and name in uses]
    found = []
    for k, (name_a, a) in enumerate(meshes):
        for name_b, b in meshes[k + 1:]:
            if len(a.vertices) != len(b.vertices) or tuple(a.faces) != tuple(b.faces):
                continue
            va, vb = np.asarray(a.vertices, dtype=np.float64), np.asarray(b.vertices, dtype=np.float64)
            size = float(np.linalg.norm(np.ptp(va, axis=0)))
            if not size > 0:
                continue
            homogeneous = np.hstack([va, np.ones((len(va), 1))])
            solution, *_ = np.linalg.lstsq(homogeneous, vb, rcond=None)  # vb ~ va @ m + t
            stretch = np.linalg.svd(solution[:3], compute_uv=False)
            edit = float(np.abs(homogeneous @ solution - vb).max())
            if np.abs(stretch - 1.0).max() <= NEAR_TWIN and edit <= NEAR_TWIN * size:
                # the one the examples use less is the copy
                copy, original = (name_b, name_a) if len(uses[name_b]) <= len(uses[name_a]) else (name_a, name_b)
                found.append((copy, original, float(np.abs(stretch - 1.0).max()), uses[copy][0]))
    if not found:
        return None
    shown = _first_three([f"{copy!r} (in {labels[i]}) is {original!r} resized by {100 * d:.2g}% or edited a little"
                          for copy, original, d, i in found])
    return (f"{shown}: a copy made and changed by hand? it is learned as a part type of its own, which "
            "samples may draw in place of the other; give it the other's mesh if it is meant as one")


STRAY = 1.0
"""A node whose bounding box lies farther than this many diagonals of the rest of its
example from every other node's gets a note (:func:`stray_note`)."""


def stray_note(example_set: ExampleSet, labels: list | None = None) -> str | None:
    """One line when an example holds a part far from all the rest (a leftover copy moved
    out of the way, a part exported with the wrong scene): a part holding no others, other
    than the root, further from every other part than :data:`STRAY` times the size of the
    rest of the example (a sun whose planets circle far off is no leftover). The program learns it as
    a placement like any other and samples draw it: one table of five with a spare leg
    4.5 m off gave a leg floating 5 m away in 30 of 100 samples (an adversarial pass).
    None otherwise; ``labels`` name the examples."""
    from .symmetry import box_corners  # (symmetry imports this module)

    labels = labels or [f"examples[{i}]" for i in range(len(example_set.examples))]
    found = []  # (example, part, distance, size of the rest)
    for i, root in enumerate(example_set.examples):
        nodes = list(root.walk())
        if len(nodes) < 3:
            continue
        boxes = []
        for node in nodes:
            t = np.asarray(node.transform, dtype=np.float64)
            placed = box_corners(*example_set.parts[node.part].local_bounds()) @ t[:3, :3].T + t[:3, 3]
            boxes.append((placed.min(axis=0), placed.max(axis=0)))
        lo, hi = np.array([b[0] for b in boxes]), np.array([b[1] for b in boxes])
        for k, node in enumerate(nodes):
            if k == 0 or node.children:  # the root, or a part holding others, is no leftover
                continue
            rest = np.arange(len(nodes)) != k
            # the gap between boxes: how far apart they are along the axes where they do not overlap
            gaps = np.linalg.norm(np.maximum(0.0, np.maximum(lo[rest] - hi[k], lo[k] - hi[rest])), axis=1)
            size = float(np.linalg.norm(hi[rest].max(axis=0) - lo[rest].min(axis=0)))
            if size > 0 and gaps.min() > STRAY * size:
                found.append((i, node.part, float(gaps.min()), size))
    if not found:
        return None
    shown = _first_three([f"{labels[i]} has a {part!r} {gap:.3g} from every other part (the rest is {size:.3g} "
                          "across)" for i, part, gap, size in found])
    return (f"{shown}: a leftover moved out of the way? the program learns it as a placement like any other "
            "and samples draw it; delete it if it is not part of the model")


def read_example_inputs(paths) -> tuple[ExampleSet, str]:
    """The example set of ``procmod learn``'s inputs, and a digest of what was read.

    ``paths``: one ``procmod-examples/1`` JSON file, or asset files and folders of them
    (glTF, GLB, URDF: one example per file; see :mod:`procmod.geometry.assets`). Each
    example is then moved over the origin (:func:`centred_examples`), and a part hung
    higher up than other examples hang its kind is moved down to the part it touches
    (:func:`procmod.learn.hanging.consistent_hanging`; the moves are the set's ``rehung``).
    The digest covers the file (JSON) or the part library and every transform and
    hierarchy (assets), so a checkpoint made from other inputs is refused.
    """
    from ..core.serialize import fingerprint
    from ..geometry.assets import AssetError, asset_files, json_or_assets, read_assets

    try:
        json_file, assets = json_or_assets(paths, "examples", "procmod-examples/1")
    except AssetError as exc:
        raise ExamplesError(str(exc)) from None
    from .hanging import consistent_hanging

    if json_file is not None:
        read = read_examples(json_file)
        example_set = centred_examples(read)
        moved = any(a is not b for a, b in zip(read.examples, example_set.examples))
        example_set, rehung = consistent_hanging(example_set)
        # a checkpoint of a run from before examples were centred (or parts rehung) learned
        # them as they stood: changed examples must not resume it
        # (and one from before they were turned to face one way: "faced")
        mark = (b"centred\0faced\0" + repr(example_set.facing).encode() + b"\0" if moved else b"") \
            + (b"rehung\0" if rehung else b"")
        return replace(example_set, rehung=tuple(rehung)), fingerprint(mark + json_file.read_bytes())
    try:
        example_set = centred_examples(examples_from_assets(read_assets(asset_files(assets))))
    except AssetError as exc:
        raise ExamplesError(str(exc)) from None
    example_set, rehung = consistent_hanging(example_set)
    return replace(example_set, rehung=tuple(rehung)), example_set_digest(example_set)


def example_set_digest(example_set: ExampleSet) -> str:
    """A digest of an example set's parts (shapes) and hierarchies (parts, transforms)."""
    import hashlib
    h = hashlib.sha256()
    for name in sorted(example_set.parts):
        shape = example_set.parts[name]
        h.update(f"{name}\0{shape.kind}\0".encode())
        if shape.kind == "box":
            h.update(np.asarray(shape.size, dtype=np.float64).tobytes())
        else:
            h.update(np.asarray(shape.vertices, dtype=np.float64).tobytes())
            h.update(np.asarray(shape.faces, dtype=np.int64).tobytes())

    def visit(node):
        h.update(f"({node.part}\0".encode())
        h.update(np.asarray(node.transform, dtype=np.float64).tobytes())
        for c in node.children:
            visit(c)
        h.update(b")")

    for e in example_set.examples:
        visit(e)
    if example_set.facing:  # (a set facing the axes digests as before facing was kept)
        h.update(f"facing\0{example_set.facing!r}".encode())
    return h.hexdigest()[:16]


def node_to_json(node: ExampleNode) -> dict:
    return {"part": node.part, "transform": transform_to_json(node.transform),
            "children": [node_to_json(c) for c in node.children]}


def parts_json_relative(parts: dict, base_dir: Path, out_dir: Path) -> dict:
    """The "parts" object with mesh paths rewritten relative to ``out_dir``."""
    out = {}
    for name, shape in parts.items():
        if shape.kind == "box":
            out[name] = {"box": list(shape.size)}
        elif shape.source is None:
            raise ExamplesError(f"part {name!r} is a mesh read from an asset file and has no mesh file of its own; "
                                "it cannot be written as procmod-examples/1")
        else:
            mesh = (Path(base_dir) / shape.source).resolve()
            out[name] = {"mesh": os.path.relpath(mesh, Path(out_dir).resolve())}
    return out


def examples_to_dict(example_set: ExampleSet, out_dir: str | os.PathLike | None = None) -> dict:
    """The JSON object of an example set (mesh paths relative to ``out_dir``)."""
    out_dir = example_set.base_dir if out_dir is None else Path(out_dir)
    return {"format": FORMAT,
            "parts": parts_json_relative(example_set.parts, example_set.base_dir, out_dir),
            "examples": [node_to_json(e) for e in example_set.examples]}


def write_examples_file(example_set: ExampleSet, path: str | os.PathLike) -> None:
    """Write an example set as ``procmod-examples/1`` JSON, atomically."""
    path = Path(path)
    if path.exists() and path.is_dir():
        raise ExamplesError(f"{path} is a folder; give a file name ending in .json")
    if not path.parent.exists():
        path.parent.mkdir(parents=True, exist_ok=True)
    write_text_atomic(path, json.dumps(examples_to_dict(example_set, path.parent)) + "\n")


def example_parts(node: ExampleNode, parts: dict) -> list:
    """World-space parts (Box / Mesh) of a hierarchy, tagged by part name."""
    return [parts[n.part].part(n.transform) for n in node.walk()]


def facing_examples(example_set: ExampleSet) -> list:
    """The examples turned to face the way the set faced (:attr:`ExampleSet.facing`), as a
    learned program's samples stand: read (:func:`centred_examples`), they face the world's
    axes. For pictures and measures that set examples beside samples (h141: a report's
    rows of examples and samples had stood 42 degrees apart)."""
    if not example_set.facing:
        return list(example_set.examples)
    turn = np.eye(4)
    turn[:3, :3] = turn_about_up(example_set.facing)

    def turned(node: ExampleNode) -> ExampleNode:
        return ExampleNode(node.part, turn @ np.asarray(node.transform, dtype=np.float64),
                           [turned(c) for c in node.children])

    return [turned(e) for e in example_set.examples]


__all__ = ["FORMAT", "ExamplesError", "ExampleNode", "ExampleSet", "PartShape", "read_examples",
           "read_example_inputs", "centred_examples", "size_note", "orientation_note", "duplicate_note",
           "near_twin_note", "examples_from_assets", "example_set_digest",
           "examples_from_dict", "examples_to_dict", "write_examples_file", "example_parts", "facing_examples",
           "has_shear"]
