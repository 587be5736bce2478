"""Exact part-part intersection (procmod.geometry.collide): overlapping, touching, rotated
boxes, cylinders, frusta and meshes, and the incremental pair count."""

import math
import pickle

import numpy as np
import pytest

from procmod.core import run_forward
from procmod.geometry.collide import PartIntersections, parts_intersect
from procmod.geometry.solid import Box, Cylinder, Mesh, compose, rotation, scaling, translation
from procmod.models import get_model


def test_boxes_overlapping_by_a_tenth_intersect_and_touching_ones_do_not():
    a = Box((1, 1, 1))
    assert parts_intersect(a, Box((1, 1, 1), translation(0.9, 0, 0)))  # 0.1 deep
    assert parts_intersect(a, Box((1, 1, 1), translation(0.9, 0.95, -0.9)))  # 0.1 x 0.05 x 0.1 corner
    assert not parts_intersect(a, Box((1, 1, 1), translation(1.0, 0, 0)))  # face on face
    assert not parts_intersect(a, Box((1, 1, 1), translation(1.0, 1.0, 0)))  # edge on edge
    assert not parts_intersect(a, Box((1, 1, 1), translation(1.2, 0, 0)))
    # a face computed as another's position plus a length, with rounding: still touching
    rear = 0.1 + 0.2
    assert not parts_intersect(Box((1, 1, 0.3), translation(0, 0, 0.15)), Box((1, 1, 2), translation(0, 0, rear + 1.0)))


def test_rotated_boxes_use_their_true_shape_not_their_bounding_boxes():
    # A unit cube turned 45 degrees about z reaches sqrt(1/2) = 0.707 along x, its
    # bounding box 0.707 too, but only at the corner edge; along the diagonal it is thin.
    turned = Box((1, 1, 1), rotation("z", math.pi / 4))
    half_diag = math.sqrt(0.5)
    assert parts_intersect(turned, Box((1, 1, 1), translation(half_diag + 0.45, 0, 0)))  # 0.05 deep at the edge
    assert not parts_intersect(turned, Box((1, 1, 1), translation(half_diag + 0.5, 0, 0)))  # edge on face
    # bounding boxes overlap (corner regions), the solids do not: SAT on an edge-edge axis
    a = Box((1, 1, 1), rotation("z", math.pi / 4))
    b = Box((1, 1, 1), compose(translation(0.75, 0.75, 0), rotation("z", math.pi / 4)))
    assert not parts_intersect(a, b)
    b_in = Box((1, 1, 1), compose(translation(0.65, 0.65, 0), rotation("z", math.pi / 4)))
    assert parts_intersect(a, b_in)
    # rotated about two axes, cross-product axes decide (two long bars crossing at a skew)
    bar_x = Box((4, 0.2, 0.2))
    bar_skew = Box((4, 0.2, 0.2), compose(translation(0, 0, 0.25), rotation("y", 0.3), rotation("z", 1.0)))
    bar_skew_low = Box((4, 0.2, 0.2), compose(translation(0, 0, 0.15), rotation("y", 0.3), rotation("z", 1.0)))
    assert not parts_intersect(bar_x, bar_skew) and parts_intersect(bar_x, bar_skew_low)
    # a scaled and sheared placement is a parallelepiped
    sheared = Box((1, 1, 1), (1.0, 0.5, 0.0, 1.2, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 1.0))
    # its faces x = +-0.5 + 0.5 y (+ 1.2): at y = -0.5 the left face is at x = 0.45
    assert parts_intersect(sheared, Box((1, 1, 1), translation(0, -0.4, 0)))  # 0.05 + deep near y = -0.5
    assert not parts_intersect(sheared, Box((0.2, 0.2, 0.2), translation(0.3, 0.3, 0)))  # left of the face


def test_cylinders_and_boxes():
    cyl = Cylinder(0.5, 2.0)  # z from 0 to 2
    assert parts_intersect(cyl, Box((1, 1, 1), translation(0.9, 0, 1)))  # 0.1 into the side
    assert not parts_intersect(cyl, Box((1, 1, 1), translation(1.0, 0, 1)))  # tangent to a face
    assert not parts_intersect(cyl, Box((2, 2, 1), translation(0, 0, -0.5)))  # cap on a face
    assert parts_intersect(cyl, Box((2, 2, 1), translation(0, 0, -0.4)))
    # the box's corner region beside the round side: bounding boxes overlap, solids do not
    assert not parts_intersect(cyl, Box((0.3, 0.3, 1), translation(0.55, 0.55, 1)))  # corner 0.566 from the axis
    assert parts_intersect(cyl, Box((0.3, 0.3, 1), translation(0.45, 0.45, 1)))  # corner 0.424 from it
    # the spaceship's cluster: four cylinders tangent to their neighbours
    r = 0.4
    cluster = [Cylinder(r, 3.0, translation(sx * r, sy * r, 0)) for sx in (-1, 1) for sy in (-1, 1)]
    assert not any(parts_intersect(p, q) for i, p in enumerate(cluster) for q in cluster[i + 1:])
    assert parts_intersect(cluster[0], Cylinder(r, 3.0, translation(-r + 0.05, -r + 2 * r - 0.05, 0)))
    # an oriented cylinder (the tree's frames) against a rotated box
    tilted = Cylinder(0.3, 2.0, rotation("x", -math.pi / 2))  # along +y
    assert parts_intersect(tilted, Box((1, 1, 1), compose(translation(0.75, 1, 0), rotation("y", 0.4))))
    assert not parts_intersect(tilted, Box((1, 1, 1), translation(0.8, 1, 0)))


def _l_prism() -> Mesh:
    """An L-shaped prism (not convex): the union of [-0.5, 1.5] x [-0.5, 0.5] and
    [-0.5, 0.5] x [-0.5, 1.5], z in [-0.5, 0.5]; its notch is x, y > 0.5."""
    outline = [(-0.5, -0.5), (1.5, -0.5), (1.5, 0.5), (0.5, 0.5), (0.5, 1.5), (-0.5, 1.5)]
    vertices = tuple((x, y, -0.5) for x, y in outline) + tuple((x, y, 0.5) for x, y in outline)
    fan = [(3, 4, 5), (3, 5, 0), (3, 0, 1), (3, 1, 2)]  # from the reflex corner
    faces = [(a, c, b) for a, b, c in fan] + [(a + 6, b + 6, c + 6) for a, b, c in fan]
    for i in range(6):
        j = (i + 1) % 6
        faces += [(i, j, j + 6), (i, j + 6, i + 6)]
    return Mesh(vertices, tuple(faces))


def test_frusta_cones_and_meshes():
    nose = Cylinder(1.0, 2.0, translation(0, 0, 0), "nose", 0.5)  # radius 1 at z = 0, 0.5 at z = 2
    # at z = 1 the radius is 0.75
    assert parts_intersect(nose, Box((1, 1, 0.2), translation(0.7 + 0.5, 0, 1)))
    assert not parts_intersect(nose, Box((1, 1, 0.2), translation(0.8 + 0.5, 0, 1)))
    assert not parts_intersect(nose, Box((2, 2, 1), translation(0, 0, -0.5)))  # base on the body's face
    tip = Cylinder(0.15, 0.3, translation(0, 0, 1.0), "gun", 0.0)  # a cone
    assert not parts_intersect(tip, Cylinder(0.15, 1.0))  # base on the gun's cap
    assert parts_intersect(tip, Cylinder(0.15, 1.05))
    # a scaled cylinder (an ellipse in x) stands as its inscribed prism
    wide = Cylinder(0.5, 1.0, scaling(2.0, 1.0, 1.0))
    assert parts_intersect(wide, Box((1, 1, 1), translation(1.4, 0, 0.5)))  # reaches x = 1
    assert not parts_intersect(wide, Box((1, 1, 1), translation(1.5, 0, 0.5)))
    # a convex mesh: a unit cube given as triangles
    import trimesh
    cube = trimesh.creation.box((1, 1, 1))
    mesh = Mesh(tuple(map(tuple, cube.vertices)), tuple(map(tuple, cube.faces)))
    assert parts_intersect(mesh, Box((1, 1, 1), translation(0.9, 0, 0)))
    assert not parts_intersect(mesh, Box((1, 1, 1), translation(1.0, 0, 0)))
    # a non-convex mesh (an L of two cubes): its notch is empty, a part inside it is caught
    ell = _l_prism()
    assert trimesh.Trimesh(ell.vertices, ell.faces).is_watertight
    lmesh = ell
    assert not parts_intersect(lmesh, Box((0.8, 0.8, 0.8), translation(1.0, 1.0, 0)))  # in the notch
    assert parts_intersect(lmesh, Box((0.2, 0.2, 0.2), translation(0.0, 0.0, 0)))  # wholly inside
    assert parts_intersect(lmesh, Box((0.8, 0.8, 0.8), translation(0.8, 0.8, 0)))  # into both arms


def test_part_intersections_count_pairs_incrementally():
    pairs = PartIntersections()
    a, b, c = Box((1, 1, 1)), Box((1, 1, 1), translation(0.9, 0, 0)), Box((1, 1, 1), translation(1.8, 0, 0))
    assert pairs.add(a) == 0 and pairs.add(b) == 1 and pairs.add(c) == 1 and pairs.count == 2
    copy = pairs.copy()
    assert pairs.remove(b) == 2 and pairs.count == 0  # a and c are 0.8 apart
    assert copy.count == 2 and len(copy.parts) == 3
    assert pickle.loads(pickle.dumps(copy)).count == 2
    with pytest.raises(ValueError):
        pairs.remove(b)


def test_brute_force_count_on_forward_spaceships():
    # The incremental count equals the pairwise count over all parts (no broad-phase miss),
    # and the spaceship's prior ships do not all intersect: its parts are placed touching.
    model = get_model("spaceship")
    counts = []
    for seed in range(12):
        parts = run_forward(model, np.random.default_rng(seed)).geometry()
        pairs = PartIntersections()
        for p in parts:
            pairs.add(p)
        brute = sum(parts_intersect(p, q) for i, p in enumerate(parts) for q in parts[i + 1:])
        assert pairs.count == brute
        counts.append(brute)
    assert 0 in counts and any(counts)
