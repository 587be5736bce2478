"""Containment of mesh parts in messages, and the first part's turn in instantiation."""
import json

import numpy as np
import pytest

from procmod.cli import main
from procmod.strings.categories import EdgeCategories
from procmod.strings.contacts import part_points, shape_graph
from procmod.strings.instantiate import instantiate_graph
from procmod.strings.shapes import first_poses, shapes_from_dict


def _rolled(x, roll=0.0, size=(1.0, 1.0, 1.0)):
    """A part turned by ``roll`` about x, at ``x``, standing on the ground (z = 0)."""
    c, s = np.cos(roll), np.sin(roll)
    z = 0.5 * (abs(s) * size[1] + abs(c) * size[2])
    return [[1, 0, 0, x], [0, c, -s, 0], [0, s, c, z], [0, 0, 0, 1]]


def _placements(shape_set, shape):
    """Per part: its type and its vertices about their mean, rounded (its turn, up to its symmetry)."""
    out = []
    for p, t in zip(shape.parts, shape.transforms):
        q = part_points(shape_set.library, p, t)
        out.append((p, tuple(sorted(map(tuple, np.round(q - q.mean(0), 6) + 0.0)))))
    return out


@pytest.mark.parametrize("tilted_first", [True, False])
def test_a_flat_shape_instantiates_flat_when_its_part_type_is_also_seen_turned(tmp_path, tilted_first):
    """A slab seen square in one row and turned 45 degrees about x in another: each row is
    rebuilt with its own slabs' turn, whichever row holds the slab's first instance (the
    first part placed took that instance's turn, tilting the flat row by 45 degrees)."""
    slab = (1.0, 0.4, 1.6)
    flat = [("cube", _rolled(0)), ("slab", _rolled(1, size=slab)), ("cube", _rolled(2)),
            ("slab", _rolled(3, size=slab)), ("cube", _rolled(4))]
    tilted = [("cube", _rolled(0)), ("slab", _rolled(1, np.pi / 4, slab)), ("cube", _rolled(2))]
    rows = [tilted, flat] if tilted_first else [flat, tilted]
    data = {"format": "procmod-shapes/1", "parts": {"cube": {"box": [1, 1, 1]}, "slab": {"box": list(slab)}},
            "shapes": [{"nodes": [{"part": p, "transform": t} for p, t in row]} for row in rows]}
    ss = shapes_from_dict(data, tmp_path)
    graphs = [shape_graph(ss, s) for s in ss.shapes]
    cats = EdgeCategories.fit(ss, ss.shapes, graphs)
    start = first_poses(ss)
    for shape, g in zip(ss.shapes, graphs):
        want = set(_placements(ss, shape))
        truth = cats.edge_categories(ss, shape, g)
        for seed in range(6):  # start edges at a cube and at a slab
            result = instantiate_graph(g, truth, cats, ss, np.random.default_rng(seed), start)
            assert result.success and result.fallbacks == 0
            assert set(_placements(ss, result.shape)) == want
            built = min(part_points(ss.library, p, t)[:, 2].min()
                        for p, t in zip(result.shape.parts, result.shape.transforms))
            assert built == pytest.approx(0.0, abs=1e-6)  # on the ground the inputs stand on


_CUBE_FACES = [(0, 1, 3), (0, 3, 2), (4, 6, 7), (4, 7, 5), (0, 4, 5), (0, 5, 1), (2, 3, 7), (2, 7, 6), (0, 2, 6),
               (0, 6, 4), (1, 5, 7), (1, 7, 3)]


def _box_obj(path, size):
    corners = [(x, y, z) for x in (-0.5, 0.5) for y in (-0.5, 0.5) for z in (-0.5, 0.5)]
    lines = [f"v {x * size[0]} {y * size[1]} {z * size[2]}" for x, y, z in corners]
    path.write_text("\n".join(lines + [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in _CUBE_FACES]) + "\n")


def _inside_set(tmp_path, nodes):
    """Two 2-unit mesh cubes side by side, and ``nodes`` more (part, x) at y = z = 0."""
    _box_obj(tmp_path / "big.obj", (2, 2, 2))
    _box_obj(tmp_path / "small.obj", (0.4, 0.4, 0.4))
    at = lambda x: [[1, 0, 0, x], [0, 1, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1]]  # noqa: E731
    data = {"format": "procmod-shapes/1",
            "parts": {"big": {"mesh": "big.obj"}, "small": {"mesh": "small.obj"}, "brick": {"box": [0.4, 0.4, 0.4]}},
            "shapes": [{"nodes": [{"part": p, "transform": at(x)} for p, x in [("big", 0), ("big", 2)] + nodes]}]}
    (tmp_path / "set.json").write_text(json.dumps(data))
    return tmp_path / "set.json"


@pytest.mark.parametrize("part", ["small", "brick"])
def test_a_part_inside_a_mesh_part_is_said_to_lie_inside_it_not_apart(tmp_path, capsys, part):
    """A mesh cube (or a box) wholly inside a mesh cube touches none of its surface, so it is
    no neighbour (mesh parts touch by surfaces): the note and the error say it lies inside
    the other and to move it out, not that the two are apart and a tolerance could join them."""
    path = _inside_set(tmp_path, [(part, 0.0)])
    assert main(["strings", "graph", str(path), "--out", str(tmp_path / "g")]) == 0
    err = capsys.readouterr().err
    assert f"{part} #2 lies inside big #0, touching none of its surface" in err, err
    assert "move a part that lies inside another out until their surfaces meet" in err, err
    assert "apart" not in err.replace("side by side", "") and "--tolerance" not in err, err
    code = main(["strings", "augment", str(path), "--count", "2", "--out", str(tmp_path / "a")])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and f"{part} #2 lies inside big #0" in err, err
    assert "they are apart" not in err and "give --tolerance" not in err, err


def test_a_part_apart_and_one_inside_are_told_apart(tmp_path, capsys):
    """A part far off keeps the tolerance advice; the one inside is named as lying inside."""
    path = _inside_set(tmp_path, [("small", 0.0), ("small", 9.0)])
    assert main(["strings", "graph", str(path), "--out", str(tmp_path / "g")]) == 0
    err = capsys.readouterr().err
    assert "in 3 pieces: small, small touch no other part" in err and "small #2 lies inside big #0" in err, err
    assert "no tolerance up to 25% of a part's size joins them" in err, err


def test_a_part_inside_near_the_wall_keeps_the_tolerance_that_joins_it(tmp_path, capsys):
    """A part inside a mesh part 0.05 from its wall is joined by a contact tolerance of 0.06,
    as any gap is: the advice names that tolerance, not that none would do (h159)."""
    path = _inside_set(tmp_path, [("small", 0.75)])
    assert main(["strings", "graph", str(path), "--out", str(tmp_path / "g")]) == 0
    err = capsys.readouterr().err
    assert "small #2 lies inside big #0" in err and "--tolerance 0.051 joins them" in err, err
    assert main(["strings", "graph", str(path), "--out", str(tmp_path / "g2"), "--tolerance", "0.06"]) == 0
    assert "pieces" not in capsys.readouterr().err


def test_a_part_inside_a_part_that_is_itself_apart_is_apart(tmp_path, capsys):
    """A mesh part far off with a part inside it: both are apart from the shape, and moving
    the inner one to its holder's surface would not join them (h159: only the inner part
    was named, as lying inside)."""
    path = _inside_set(tmp_path, [("big", 4.0), ("big", 20.0), ("small", 20.0)])
    assert main(["strings", "graph", str(path), "--out", str(tmp_path / "g")]) == 0
    err = capsys.readouterr().err
    assert "in 3 pieces: big, small touch no other part" in err and "lies inside" not in err, err
    assert "no tolerance up to 25% of a part's size joins them" in err, err
