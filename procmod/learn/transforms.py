"""Transform parameterisation of seed 000 section 5, and symmetry parameters.

A node's world transform ``W = [Rot diag(s) | t]`` is decomposed canonically: ``|s_i|`` is
the length of column i, ``Rot`` the normalised columns, and when ``Rot`` is improper the
x scale and column are negated (so a reflection shows up as a negative x scale).

A child is described relative to its nearest part ancestor's *frame*: the ancestor's
rotation ``Rp``, translation ``tp`` and bounding-box extents ``E`` (its part's local box
scaled by ``|s|``). The 9 continuous components, in the Gaussian NADE's category order:

* ``ls0..2`` — log ``|s|`` (absolute scale of the child),
* ``r0..2`` — xyz Euler angles (scipy's extrinsic "xyz") of ``Rp^T Rot``,
* ``t0..2`` — ``Rp^T (t - tp) / E`` (translation as a fraction of the parent's box),

plus three sign bits (``s_i < 0``). Symmetry maps are handled in the same frame.

**Units.** The learned densities must not depend on the units the examples were modelled
in (metres, or centimetres as Maya and FBX exports carry them, often as a root scale of
100 or 0.01). Two lengths are therefore measured against the example set itself
(:class:`Units`, found by :func:`procmod.learn.preprocessing.preprocess` and stored with
the program): a child's log-scale is taken relative to its part's reference log-scale
(the mean of ``log |s|`` over the part's placements in the examples), and the roots are
placed in a world frame whose extent is the examples' size (the geometric mean of their
bounding-box diagonals) instead of one unit. Before, a set exported at 100x learned 45
abstractions against 11 (the NADEs' hidden units saw log-scales shifted by log 100, and
the roots' translations met the absolute sigma cap). With both, a set and its copy at
any scale have the same components, so they learn the same program. A flat part's frame
is measured in its size (:func:`frame_of`), and a symmetry's direction is a polar and an
azimuth angle about the body diagonal (:data:`DIAGONAL_POLE`), where coordinate axes are
well-conditioned; programs learned before all this keep their ``LEGACY`` conventions.
"""

from __future__ import annotations

import math
import warnings
from typing import NamedTuple

import numpy as np
from scipy.spatial.transform import Rotation

COMPONENTS = ("ls0", "ls1", "ls2", "r0", "r1", "r2", "t0", "t1", "t2")
CATEGORY = (0, 0, 0, 1, 1, 1, 2, 2, 2)  # 0 log-scale, 1 rotation, 2 translation
# Phase-2 fixed standard deviations (seed 000 section 6.2): log-scale, rotation, translation.
FIXED_SIGMA = (math.log(1.1), math.pi / 8, 0.2)
# Floors on learned standard deviations (the final pass frees them): keeps densities finite
# for variables that are constant across the examples, which seed 000's final pass lets
# reach "no variation, if sigma ~ 0". A floor is what such a variable is sampled with, so
# it must be below what an eye sees: at the legacy 0.01 every part the examples hold level
# was sampled tilted by a median 1.2 degrees (0.01 rad a rotation component; a castle's
# walls all leaned, a wide floor's box grew 5% taller) and shifted by 1% of its parent's
# box. At 3e-3 the median lean is 0.4 degrees. 1e-3 gave 0.13, but a longer tail: a
# rarely used copy of an abstraction, fitted by Adam's steps on densities that sharp,
# leaned walls on walls by up to 17-20 degrees (0.8-2.7% of castles' sampled parts over 5
# degrees, against 0-0.24% at 3e-3; the examples hold every part level). Each program
# stores the floor it was learned with (Program.sigma_floor); files written before that
# were learned with LEGACY_SIGMA_FLOOR and keep it, so their samples are unchanged.
SIGMA_FLOOR = (3e-3, 3e-3, 3e-3)
LEGACY_SIGMA_FLOOR = (0.01, 0.01, 0.01)
# Caps on learned standard deviations: a NADE's sigma output can explode for inputs
# unlike its (few) training values, and a sample then lands kilometres away.
SIGMA_MAX = (0.5, math.pi / 2, 1.0)


class Frame(NamedTuple):
    """A part node's frame: proper rotation, translation, bounding-box extents; and, handed
    to a symmetry by the symmetry holding it, the frame its parameters are measured in
    (``measure``: that frame turned, :func:`turned_frame`; None: this frame). ``part`` is
    the part type placed in it and ``box`` its bounding box in the frame's axes (``(centre,
    half extents)``, the centre from the frame's origin): a child's translation may be
    measured from a face of that box (:data:`Units.anchors`); the world frame has neither."""

    rot: np.ndarray
    t: np.ndarray
    extent: np.ndarray
    measure: "Frame | None" = None
    part: "str | None" = None
    box: "tuple | None" = None

    def for_symmetry(self) -> "Frame":
        """The frame a symmetry node handed this frame measures its parameters in."""
        return self if self.measure is None else self.measure

    def matrix(self) -> np.ndarray:
        m = np.eye(4)
        m[:3, :3] = self.rot
        m[:3, 3] = self.t
        return m


WORLD_FRAME = Frame(np.eye(3), np.zeros(3), np.ones(3))


def turn_about_up(angle: float) -> np.ndarray:
    """The 3x3 turn by ``angle`` radians about the up axis y (the identity for 0)."""
    if not angle:
        return np.eye(3)
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
NO_LOG_SCALE = (0.0, 0.0, 0.0)


# How components are measured (Units.conventions): LEGACY as programs learned before
# units were (z pole, an absolute floor for flat parts), CURRENT as preprocess now does.
LEGACY, CURRENT = 1, 2


class Units(NamedTuple):
    """The lengths an example set's transform components are measured against (see the
    module docstring): the world frame's extent; per part name, the reference log-scale
    of its placements (three floats; a part missing from it has reference 0: scale 1);
    and the ``conventions`` the components follow (flat parts' frames, :func:`frame_of`;
    the pole of directions' angles, :data:`DIAGONAL_POLE`). A program written before
    units existed has ``Units()``: extent 1, no references, :data:`LEGACY` conventions,
    so it samples as it was learned. Not to be changed once made (it is shared by copies
    of a program); comparable with ``==``."""

    world_extent: float = 1.0
    part_log_scales: dict = {}
    conventions: int = LEGACY
    # per symmetry type, the pole its directions' angles are taken about when they are
    # spread over a circle (:func:`spread_pole`), as a 3x3 tuple of rows; other types
    # take :meth:`pole`'s
    sym_poles: dict = {}
    # per symmetry type whose directions vary and that holds another symmetry (a table's
    # mirrored pair of leg pairs), the reference direction (three floats) from which a
    # node of it turns the frame it hands that symmetry (:func:`turned_frame`)
    sym_turns: dict = {}
    # translation symmetry types whose parameters are the row's span (first to last member,
    # step x (count - 1)), not its step: the count and the step are drawn independently,
    # and where the span is what the examples hold (posts along a rail, shelves up a unit)
    # the step follows from it (see procmod.learn.preprocessing.span_types)
    trans_spans: tuple = ()
    # per parent part type, per child part type: the child's translation along each of the
    # parent frame's axes measured between points of the two boxes instead of between their
    # origins (None: origins; (a_p, a_c): the parent box's low side, middle or high side for
    # a_p = -1, 0, 1, to the child box's alike; (a_p, a_c, 1): measured in the child's
    # extent, not the parent's), where that is what the examples hold fixed (see
    # anchor_terms, procmod.learn.preprocessing.choose_anchors)
    anchors: dict = {}
    # the height every example's lowest point is at, where they share one (None: they do
    # not); a forward sample is set on it (see procmod.learn.ground)
    ground: float | None = None
    # the way the examples' roots face (radians about the up axis y; see
    # procmod.learn.examples.reference_facing): the roots' frame is turned so, and their
    # turns are measured from it. Measured from the world's axes, a set facing 97 degrees
    # held the roots' hand tilts near Euler angles' gimbal lock, and 7 of 60 sampled tables
    # leaned over 10 degrees (none facing 0; h138)
    facing: float = 0.0

    def frame_of(self, world, local_lo, local_hi, part: str | None = None) -> "Frame":
        """:func:`frame_of` with these conventions for flat parts (of a ``part`` placed by ``world``)."""
        return frame_of(world, local_lo, local_hi, self.conventions >= CURRENT, part)

    def anchor(self, parent: str | None, child: str) -> tuple | None:
        """The anchors of ``child``'s translation in a ``parent``'s frame (None: origins)."""
        return self.anchors.get(parent, {}).get(child) if parent is not None else None

    def pole(self, sym_type: str | None = None) -> np.ndarray:
        """The basis directions' polar and azimuth angles are taken in (its third column is
        the pole): that of symmetry type ``sym_type``."""
        own = self.sym_poles.get(sym_type)
        if own is not None:
            return np.array(own, dtype=np.float64)
        return DIAGONAL_POLE if self.conventions >= CURRENT else Z_POLE

    def world_frame(self) -> Frame:
        """The frame the roots are placed in: turned by :attr:`facing` about the up axis."""
        return Frame(turn_about_up(self.facing), np.zeros(3), np.full(3, float(self.world_extent)))

    def log_scale(self, part: str) -> tuple:
        """The reference log-scale of ``part``'s placements."""
        return self.part_log_scales.get(part, NO_LOG_SCALE)


def turned_frame(frame: Frame, reference, direction) -> Frame:
    """``frame`` turned by the least rotation that takes ``reference`` to ``direction``
    (unit directions in ``frame``'s coordinates; a direction opposite the reference is
    taken as its negative, as a mirror's normal is either): the frame a symmetry node has
    the symmetry it holds measure its parameters in (``Frame.measure``), so that the inner
    one's direction is measured from the outer's.

    Seed 000 draws a symmetry's parameters independently of its parent's. A table's four
    legs are a mirror pair of mirror pairs; turned by hand about the vertical, both
    mirrors turn together, and independent draws of the two directions sampled pairs of
    mirrors a degree or two from square, the legs' centre off the top's. Measured in the
    outer mirror's turned frame, the inner's direction hardly varies. (Only the held
    symmetry's parameters: the parts below keep their part ancestor's frame.)"""
    reference, direction = np.asarray(reference, dtype=np.float64), np.asarray(direction, dtype=np.float64)
    if float(reference @ direction) < 0:
        direction = -direction
    axis = np.cross(reference, direction)
    sine, cosine = float(np.linalg.norm(axis)), float(reference @ direction)
    if sine < 1e-12:
        return frame
    turn = Rotation.from_rotvec(axis / sine * math.atan2(sine, cosine)).as_matrix()
    return Frame(frame.rot @ turn, frame.t, frame.extent)


def symmetry_direction(sym, pole: np.ndarray) -> np.ndarray:
    """A mirror's normal or a rotation's axis from its parameters (angles about ``pole``)."""
    return angles_direction(float(sym[0]), float(sym[1]), pole)


def decompose(m) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Canonical (proper rotation, signed scales, translation) of an affine 4x4 without shear."""
    m = np.asarray(m, dtype=np.float64)
    linear = m[:3, :3]
    s = np.linalg.norm(linear, axis=0)
    rot = linear / s
    if np.linalg.det(rot) < 0:
        s = s.copy()
        s[0] = -s[0]
        rot = rot.copy()
        rot[:, 0] = -rot[:, 0]
    # re-orthonormalise against rounding
    u, _, vt = np.linalg.svd(rot)
    rot = u @ vt
    return rot, s, m[:3, 3].copy()


# A part thinner than this fraction of its size along an axis is flat along it (a quad,
# a decal, a pane: no thickness at all, or the rounding of one).
FLAT = 1e-3
LEGACY_FLOOR = 1e-6  # the absolute floor (world units) of programs learned before Units


def frame_of(world, local_lo, local_hi, flat_by_size: bool = True, part: str | None = None) -> Frame:
    """The frame of a part placed by ``world`` whose local box is [lo, hi].

    Along an axis where the part is flat (under :data:`FLAT` of its largest extent) the
    extent is its largest: the children's offsets off a pane's plane are measured in the
    pane's size. The old floor of 1e-6 world units (``flat_by_size=False``, kept for
    programs learned with it) put a knob 0.5 above a pane at 500,000 extents in metres and
    100x that in centimetres, far past the translation cap, and the learner split
    abstractions to make up for it; a floor of 1e-3 of the size still gave 200 extents.
    Thin parts that are not flat (a wing 3% of its span) keep their own extent."""
    rot, s, t = decompose(world)
    lo, hi = np.asarray(local_lo, dtype=np.float64), np.asarray(local_hi, dtype=np.float64)
    extent = np.abs(s) * (hi - lo)
    box = (s * (lo + hi) / 2.0, extent / 2.0)  # in the frame's axes: rot diag(s) is the placement
    if not flat_by_size:
        return Frame(rot, t, np.maximum(extent, LEGACY_FLOOR), part=part, box=box)
    largest = float(extent.max())
    if not largest > 0:
        return Frame(rot, t, np.ones(3), part=part, box=box)
    return Frame(rot, t, np.where(extent < FLAT * largest, largest, extent), part=part, box=box)


def euler_of(rot: np.ndarray) -> np.ndarray:
    with warnings.catch_warnings():  # gimbal lock: scipy zeroes the third angle, still exact
        warnings.simplefilter("ignore", UserWarning)
        return Rotation.from_matrix(rot).as_euler("xyz")


def rot_of(angles) -> np.ndarray:
    return Rotation.from_euler("xyz", np.asarray(angles, dtype=np.float64)).as_matrix()


ANCHOR_SIDES = (-1, 0, 1)  # a box's low side, middle, high side along an axis


def anchor_terms(turn: np.ndarray, s: np.ndarray, child_box, frame: Frame, anchor) -> tuple[np.ndarray, np.ndarray]:
    """``(shift, measure)`` per axis of ``frame``: how far a child's anchor point lies
    from its origin less how far the parent's lies from the frame's origin (the child's
    translation between the anchors is its translation between the origins plus this),
    and the length that translation is measured in. Along an axis whose anchor is None:
    0 and the parent's extent, as seed 000 measures. An anchor ``(a_p, a_c)`` names the
    parent box's and the child box's sides (-1, 0, 1: low, middle, high), measured in the
    parent's extent; ``(a_p, a_c, 1)`` the same, measured in the child's own extent along
    that axis (a window a metre in from the edge of facades of any width).

    ``turn`` is the child's rotation in the frame (``frame.rot.T @ rot``), ``s`` its
    signed scales and ``child_box`` its part's local ``(lo, hi)``; its box in the frame's
    axes is taken axis-aligned (a turned child's bounding box there). A leg hanging from a
    table top by its top face, a stem standing on a base: from example to example the
    offset between the faces is zero, where the offset between the origins follows both
    parts' sizes, which seed 000's independent draws do not tie (sampled stems floated over
    their bases, legs hung off robots' torsos)."""
    shift, measure = np.zeros(3), np.array(frame.extent, dtype=np.float64)
    if anchor is None or frame.box is None:
        return shift, measure
    lo, hi = (np.asarray(v, dtype=np.float64) for v in child_box)
    centre = turn @ (s * (lo + hi) / 2.0)
    half = np.abs(turn) @ (np.abs(s) * (hi - lo) / 2.0)
    # the child's extent as a length to measure in: a flat axis takes its largest (frame_of)
    own = 2.0 * half
    own = np.where(own < FLAT * max(float(own.max()), 1e-300), max(float(own.max()), 1e-300), own)
    parent_centre, parent_half = frame.box
    for axis, sides in enumerate(anchor):
        if sides is not None:
            a_parent, a_child = sides[0], sides[1]
            shift[axis] = (centre[axis] + a_child * half[axis]) - (parent_centre[axis] + a_parent * parent_half[axis])
            if len(sides) > 2 and sides[2]:
                measure[axis] = own[axis]
    return shift, measure


def xform_params(world, frame: Frame, child_box=None, anchor=None) -> tuple[np.ndarray, np.ndarray]:
    """The 9 continuous components and 3 sign bits of ``world`` relative to ``frame``
    (absolute log-scales: ``preprocess`` takes the parts' references off once it has them);
    translations between the boxes' ``anchor`` points where it names them
    (:func:`anchor_terms`; ``child_box``: the child part's local ``(lo, hi)``)."""
    rot, s, t = decompose(world)
    x = np.empty(9)
    x[0:3] = np.log(np.abs(s))
    turn = frame.rot.T @ rot
    x[3:6] = euler_of(turn)
    shift, measure = anchor_terms(turn, s, child_box, frame, anchor)
    x[6:9] = (frame.rot.T @ (t - frame.t) + shift) / measure
    return x, s < 0


def xform_matrix(x, signs, frame: Frame, log_scale=NO_LOG_SCALE, child_box=None, anchor=None) -> np.ndarray:
    """Inverse of :func:`xform_params`: the world 4x4 of a child."""
    x = np.asarray(x, dtype=np.float64)
    s = np.exp(x[0:3] + log_scale) * np.where(np.asarray(signs, dtype=bool), -1.0, 1.0)
    turn = rot_of(x[3:6])
    rot = frame.rot @ turn
    m = np.eye(4)
    m[:3, :3] = rot * s
    shift, measure = anchor_terms(turn, s, child_box, frame, anchor)
    m[:3, 3] = frame.t + frame.rot @ (x[6:9] * measure - shift)
    return m


# ---- symmetry maps -------------------------------------------------------------------

SYM_KINDS = ("refl", "trans", "rot")


def node_kind(type_: str) -> str:
    """The kind of a node type: a symmetry's (``"refl"``, ``"trans"``, ``"rot"``: its type
    is ``KIND(INNER)``) or ``"part"``. A part's type is the user's part name, which may
    hold parentheses: ``Leg (1)``, as Unity, Maya and SketchUp name copies, was taken for
    a symmetry of kind ``"Leg "`` (a KeyError deep in the learner); :func:`reserved_name`
    says which part names cannot be told from a symmetry's type."""
    head, bracket, _ = type_.partition("(")
    return head if bracket and head in SYM_KINDS and type_.endswith(")") else "part"


def reserved_name(name: str) -> bool:
    """Whether a part name reads as a symmetry's node type (``rot(leg)``)."""
    return node_kind(name) != "part"
# Parameter names and categories (1 angle, 2 translation fraction) of each symmetry kind.
SYM_PARAMS = {
    "refl": (("polar", 1), ("azimuth", 1), ("offset", 2)),
    "trans": (("d0", 2), ("d1", 2), ("d2", 2)),
    "rot": (("polar", 1), ("azimuth", 1), ("c0", 2), ("c1", 2), ("c2", 2), ("angle", 1)),
}


def canonical_direction(v: np.ndarray) -> tuple[np.ndarray, float]:
    """``v`` flipped so that its largest-magnitude component is positive, and the sign used."""
    v = np.asarray(v, dtype=np.float64)
    sign = 1.0 if v[int(np.argmax(np.abs(v)))] >= 0 else -1.0
    return sign * v, sign


# Below this distance of a unit direction from the pole its azimuth is 0: at the pole
# the azimuth is undefined, and atan2 of two rounding errors gave anything in (-pi, pi]
# (with the legacy z pole the ornaments' flowers, turned about z, had azimuths that
# changed with the units the set was exported in, and so did the program learned). Well
# above float32 rounding, as transforms that went through a tool's float32 or a file's 7
# digits carry (1e-9 let those through: 10 abstractions for 8).
POLE = 1e-4


# The pole of a direction's (polar, azimuth) angles. Mirror normals and rotation axes of
# real objects lie along the coordinate axes far more often than anywhere else, and the
# azimuth is ill-conditioned near the pole: a flower turned about z with its placements
# 1e-3 off (hand-placed parts) had an azimuth the noise set anywhere in (-pi, pi], which
# the search split abstractions over. About the body diagonal (1, 1, 1), every coordinate
# axis is 54.7 degrees from the pole (x, y, z at azimuths 30, 150 and -90 degrees).
Z_POLE = np.eye(3)  # the legacy convention (Units.conventions LEGACY)
DIAGONAL_POLE = np.column_stack([np.array([1.0, -1.0, 0.0]) / math.sqrt(2), np.array([1.0, 1.0, -2.0]) / math.sqrt(6),
                                 np.array([1.0, 1.0, 1.0]) / math.sqrt(3)])


# Directions of one symmetry type whose scatter has a second eigenvalue under this (an
# RMS spread of ~0.006 degrees: float32 rounding of a tool's transforms) are one
# direction: its scatter's other eigenvectors are the noise's, and the default pole serves.
SPREAD = 1e-8


def spread_pole(directions: np.ndarray) -> np.ndarray | None:
    """A pole for directions that vary from example to example, or None for directions
    that are one (to rounding: the default pole serves those).

    The polar and azimuth angles are drawn independently (seed 000), so the directions a
    program samples lie where those two Gaussians put them, and those are aligned with
    the directions' own spread only about a pole the directions are perpendicular to.
    Mirror normals of towers on a ring are horizontal at every azimuth: about the default
    diagonal pole, a circle of directions is a curve along which polar and azimuth vary
    together, and independent draws left it, sampling mirrors tilted and towers leaning
    up to 65 degrees. So did a few degrees' spread: the legs of tables whose tops were
    turned by hand were mirrored across planes turned a few degrees about the vertical,
    and the program sampled mirrors tilted out of it too, legs leaning 9 degrees and
    sunk 10 cm through the top where no example leans one over 3 (h64). About the axis
    the directions are most nearly perpendicular to (the scatter's least eigenvector),
    a circle, or an arc, is a constant polar angle of 90 degrees at varying azimuths, and
    the spread across it, the polar's. The pole's basis: the pole third (largest
    component positive), the first the coordinate axis least along it made perpendicular
    to it, the second their cross product."""
    d = np.asarray(directions, dtype=np.float64).reshape(-1, 3)
    if len(d) < 2:
        return None
    w, v = np.linalg.eigh(d.T @ d / len(d))
    if w[1] < SPREAD:
        return None
    u, _ = canonical_direction(v[:, 0])
    a = np.eye(3)[int(np.argmin(np.abs(u)))]
    e1 = a - (a @ u) * u
    e1 /= np.linalg.norm(e1)
    return np.column_stack([e1, np.cross(u, e1), u])


def direction_angles(n: np.ndarray, pole: np.ndarray = DIAGONAL_POLE) -> tuple[float, float]:
    """(polar, azimuth) of direction ``n`` in the basis ``pole`` (third column the pole)."""
    n = pole.T @ (n / np.linalg.norm(n))
    polar = math.acos(max(-1.0, min(1.0, n[2])))
    return polar, (math.atan2(n[1], n[0]) if math.hypot(n[0], n[1]) > POLE else 0.0)


def angles_direction(polar: float, azimuth: float, pole: np.ndarray = DIAGONAL_POLE) -> np.ndarray:
    """Inverse of :func:`direction_angles`."""
    return pole @ np.array([math.sin(polar) * math.cos(azimuth), math.sin(polar) * math.sin(azimuth),
                            math.cos(polar)])


def in_frame(g_world: np.ndarray, frame: Frame) -> np.ndarray:
    """A world map expressed in the frame's (rigid, unnormalised) coordinates."""
    f = frame.matrix()
    return np.linalg.inv(f) @ g_world @ f


def to_world(g_frame: np.ndarray, frame: Frame) -> np.ndarray:
    f = frame.matrix()
    return f @ g_frame @ np.linalg.inv(f)


def reflection_params(g_world: np.ndarray, frame: Frame, pole: np.ndarray = DIAGONAL_POLE,
                      towards: np.ndarray | None = None) -> np.ndarray:
    """(polar, azimuth, offset fraction) of the mirror plane n.x = d in the frame: n
    canonical (:func:`canonical_direction`), or on the side of ``towards`` (a world
    direction: the normal the mirror pairs of its type agree on, symmetry.align_mirror_sides)."""
    g = in_frame(g_world, frame)
    w, v = np.linalg.eigh(0.5 * (g[:3, :3] + g[:3, :3].T))
    n, sign = canonical_direction(v[:, int(np.argmin(w))])
    if towards is not None and float((frame.rot @ n) @ towards) < 0:
        n = -n
    d = 0.5 * float(n @ g[:3, 3])  # translation of the reflection is 2 d n
    polar, azimuth = direction_angles(n, pole)
    return np.array([polar, azimuth, d / float(np.abs(n) @ frame.extent)])


def reflection_map(p, frame: Frame, pole: np.ndarray = DIAGONAL_POLE) -> np.ndarray:
    n = angles_direction(p[0], p[1], pole)
    d = p[2] * float(np.abs(n) @ frame.extent)
    g = np.eye(4)
    g[:3, :3] -= 2 * np.outer(n, n)
    g[:3, 3] = 2 * d * n
    return to_world(g, frame)


def translation_params(g_world: np.ndarray, frame: Frame) -> np.ndarray:
    g = in_frame(g_world, frame)
    return g[:3, 3] / frame.extent


def translation_map(p, frame: Frame) -> np.ndarray:
    g = np.eye(4)
    g[:3, 3] = np.asarray(p[:3]) * frame.extent
    return to_world(g, frame)


def rotation_axis_angle(g_frame: np.ndarray) -> tuple[np.ndarray, float]:
    """Canonical axis (largest component positive) and signed angle of a rotation map."""
    rotvec = Rotation.from_matrix(g_frame[:3, :3]).as_rotvec()
    angle = float(np.linalg.norm(rotvec))
    if angle < 1e-12:
        return np.array([0.0, 0.0, 1.0]), 0.0
    axis, sign = canonical_direction(rotvec / angle)
    return axis, sign * angle


def rotation_params(g_world: np.ndarray, frame: Frame, pole: np.ndarray = DIAGONAL_POLE) -> np.ndarray:
    """(polar, azimuth, centre fractions x3, angle) of a rotation map about an axis."""
    g = in_frame(g_world, frame)
    axis, angle = rotation_axis_angle(g)
    centre, *_ = np.linalg.lstsq(np.eye(3) - g[:3, :3], g[:3, 3], rcond=None)
    centre = centre - (centre @ axis) * axis  # the axis point nearest the frame origin
    polar, azimuth = direction_angles(axis, pole)
    return np.array([polar, azimuth, *(centre / frame.extent), angle])


def rotation_map(p, frame: Frame, pole: np.ndarray = DIAGONAL_POLE) -> np.ndarray:
    axis = angles_direction(p[0], p[1], pole)
    centre = np.asarray(p[2:5]) * frame.extent
    rot = Rotation.from_rotvec(axis * p[5]).as_matrix()
    g = np.eye(4)
    g[:3, :3] = rot
    g[:3, 3] = centre - rot @ centre
    return to_world(g, frame)


def sym_params(kind: str, g_world: np.ndarray, frame: Frame, pole: np.ndarray = DIAGONAL_POLE,
               towards: np.ndarray | None = None) -> np.ndarray:
    """A symmetry map's parameters (:data:`SYM_PARAMS`); directions' angles about ``pole``
    (a mirror's normal on the side of ``towards``, where given: :func:`reflection_params`)."""
    if kind == "trans":
        return translation_params(g_world, frame)
    if kind == "refl":
        return reflection_params(g_world, frame, pole, towards)
    return rotation_params(g_world, frame, pole)


def sym_maps(kind: str, params, count: int, frame: Frame, pole: np.ndarray = DIAGONAL_POLE) -> list[np.ndarray]:
    """World maps of the members: identity first, then the group's generator powers."""
    if kind == "refl":
        return [np.eye(4), reflection_map(params, frame, pole)]
    g = translation_map(params, frame) if kind == "trans" else rotation_map(params, frame, pole)
    maps = [np.eye(4)]
    for _ in range(count - 1):
        maps.append(g @ maps[-1])
    return maps
