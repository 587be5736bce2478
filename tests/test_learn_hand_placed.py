"""Learning from parts placed by hand: symmetries read as the modeller meant them, so
that upright parts are sampled upright."""

import math

import numpy as np
import trimesh

from procmod.core import run_forward
from procmod.geometry.solid import matrix, rotation, translation
from procmod.learn import examples_from_dict
from procmod.learn.examples import read_example_inputs
from procmod.learn.preprocessing import preprocess
from procmod.learn.program import derivation_hierarchies, program_model
from procmod.learn.search import SearchOptions, run_search
from procmod.parallel import InlineExecutor

QUICK = dict(init_iterations=80, split_iterations=40, warm_iterations=10, final_iterations=300)


def T(x, y, z):
    return matrix(translation(x, y, z))


def turn_y(a):
    return matrix(rotation("y", a))


def lean(transform) -> float:
    """Degrees between a node's local y axis and the world's."""
    linear = np.asarray(transform, dtype=float)[:3, :3]
    y = linear[:, 1] / np.linalg.norm(linear[:, 1])
    return math.degrees(math.acos(min(1.0, abs(y[1]))))


def sampled_leans(program, part: str, count: int, seed: int) -> list:
    model = program_model(program, "hand_placed")
    out = []
    for i in range(count):
        stack = derivation_hierarchies(run_forward(model, np.random.default_rng([seed, i])))
        while stack:
            node = stack.pop()
            stack.extend(node["children"])
            if node["part"] == part:
                out.append(lean(node["transform"]))
    return out


def castle_folder(folder):
    """Five GLB castles: a keep with 4-6 round towers on a ring (each turned about the
    vertical to face out, the ring's start differing per castle), a cone roof on each.
    Every part is upright."""
    folder.mkdir()
    tower = trimesh.creation.cylinder(radius=0.5, height=4, sections=16)
    roof = trimesh.creation.cone(radius=0.7, height=1.2, sections=16)
    for mesh in (tower, roof):
        mesh.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [1, 0, 0]))  # along y
    for i, n in enumerate((4, 5, 4, 6, 5)):
        scene = trimesh.Scene()
        height = 3 + 0.3 * i
        scene.add_geometry(trimesh.creation.box((4, 3, 4)), node_name="Keep", geom_name="keep",
                           transform=T(0, height / 2, 0) @ np.diag([1, height / 3, 1, 1]))
        keep = scene.graph.get("Keep")[0]
        for k in range(n):
            a = 2 * math.pi * k / n + 0.3 * i
            world = T(2.6 * math.cos(a), 2, 2.6 * math.sin(a)) @ turn_y(-a)
            scene.add_geometry(tower, node_name=f"Tower{k}", geom_name="tower", parent_node_name="Keep",
                               transform=np.linalg.inv(keep) @ world)
            scene.add_geometry(roof, node_name=f"Roof{k}", geom_name="roof", parent_node_name=f"Tower{k}",
                               transform=T(0, 2.6, 0))
        scene.export(str(folder / f"castle_{i}.glb"))
    return folder


def test_towers_on_a_ring_are_sampled_upright(tmp_path):
    """Mirror normals of towers on a ring are horizontal at every azimuth. Their polar and
    azimuth angles are drawn independently (seed 000); about the default diagonal pole a
    circle of directions is a curve along which both vary together, and samples left it:
    83 of 300 sampled towers leaned over 3 degrees, up to 65. About the axis the normals
    are perpendicular to, the circle is one polar angle."""
    example_set, _ = read_example_inputs([castle_folder(tmp_path / "castles")])
    data = preprocess(example_set)
    spread = [t for t in data.units.sym_poles]
    assert spread, "the towers' mirror normals are spread over a circle"
    pole = data.units.pole(spread[0])
    assert abs(abs(pole[1, 2]) - 1.0) < 1e-6  # about the vertical
    polar = [n.sym[0] for n in data.nodes if n.type in data.units.sym_poles]
    assert np.allclose(polar, math.pi / 2, atol=1e-6)
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    leans = sampled_leans(result.program, "tower", 40, seed=1)
    assert len(leans) > 120
    # before: ~28% of towers over 3 degrees; with the polar at its floor of 3e-3 rad a
    # mirror tilts a tower by under a degree
    assert max(leans) < 3.0, sorted(leans)[-5:]


def test_legs_placed_a_centimetre_off_are_sampled_upright():
    """Five tables whose legs were placed by hand, each 1 cm off in every direction,
    none turned. The mirrors between legs were fitted a degree or so off the top's axes,
    differently in every table, and the program sampled legs leaning by up to 7 degrees
    (76 of 400 over 3). Snapped to the top's axes (they still fit within the symmetry
    tolerance), the mirrors are upright and so are the legs."""
    rng = np.random.default_rng(7)
    examples = []
    for k in range(5):
        w, d = 1.2 + 0.1 * k, 0.7 + 0.05 * (k % 3)
        legs = [{"part": "leg", "children": [],
                 "transform": (T(sx * (w / 2 - 0.05), 0.38, sz * (d / 2 - 0.05)) @ T(*rng.normal(0, 0.01, 3))
                               @ np.diag([1, 1.05, 1, 1])).tolist()}
                for sx in (-1, 1) for sz in (-1, 1)]
        examples.append({"part": "top", "transform": (T(0, 0.78, 0) @ np.diag([w, 1, d, 1])).tolist(),
                         "children": legs})
    example_set = examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                      "parts": {"top": {"box": [1.0, 0.05, 1.0]}, "leg": {"box": [0.06, 0.7, 0.06]}}})
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    leans = sampled_leans(result.program, "leg", 50, seed=2)
    assert len(leans) == 200
    assert max(leans) < 3.0, sorted(leans)[-5:]


def sampled_tables(program, count: int, seed: int) -> list:
    """The legs' world transforms of ``count`` sampled tables."""
    model = program_model(program, "hand_placed")
    tables = []
    for i in range(count):
        stack, legs = derivation_hierarchies(run_forward(model, np.random.default_rng([seed, i]))), []
        while stack:
            node = stack.pop()
            stack.extend(node["children"])
            if node["part"] == "leg":
                legs.append(np.asarray(node["transform"], dtype=float))
        tables.append(legs)
    return tables


def turned_tables(count: int = 30, seed: int = 1) -> tuple:
    """``count`` tables placed by hand: each top turned a degree or two about the vertical,
    the legs placed square in the room, each 1 cm off and leaning up to 3 degrees.
    (examples as dicts, their example set)."""
    rng = np.random.default_rng(seed)
    examples = []
    for _ in range(count):
        w, d, h = rng.uniform(1.0, 1.6), rng.uniform(0.6, 0.9), rng.uniform(0.7, 0.8)
        top = T(0, h, 0) @ turn_y(math.radians(rng.normal(0, 2.0))) @ np.diag([w / 1.2, 1, d / 0.8, 1])
        legs = []
        for sx, sz in ((1, 1), (1, -1), (-1, 1), (-1, -1)):
            place = T(sx * (w / 2 - 0.06) + rng.normal(0, 0.01), (h - 0.025) / 2 + rng.normal(0, 0.005),
                      sz * (d / 2 - 0.06) + rng.normal(0, 0.01))
            turn = turn_y(math.radians(rng.normal(0, 2.0))) @ matrix(rotation("x", math.radians(rng.normal(0, 1.0))))
            scale = np.diag([1, (h - 0.025) / 0.72 * (1 + rng.normal(0, 0.03)), 1, 1])
            legs.append({"part": "leg", "children": [], "transform": (place @ turn @ scale).tolist()})
        examples.append({"part": "top", "transform": top.tolist(), "children": legs})
    return examples, examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                         "parts": {"top": {"box": [1.2, 0.05, 0.8]},
                                                   "leg": {"box": [0.06, 0.72, 0.06]}}})


def test_the_mirrors_of_a_tables_four_legs_pass_through_the_legs_centre():
    """The mirror between one pair of legs, which the program samples for both pairs, was
    fitted to that pair alone: snapped square to a top turned from the legs, it passed
    through their midpoint, up to 7 cm from the top's centre, and the program sampled
    legs off-centre (44% of 300 tables 3 cm or more, where no example is 1.5 cm off).
    Fitted square to the other mirror and through all four legs' centre, it is where the
    legs' centre is in every example."""
    examples, example_set = turned_tables()
    data = preprocess(example_set)
    centres = [np.mean([np.asarray(leg["transform"])[[0, 2], 3] for leg in e["children"]], axis=0)
               for e in examples]
    assert max(np.hypot(*c) for c in centres) < 0.015  # the examples' legs are about the top's centre
    inner = [n for n in data.nodes if n.type == "refl(leg)"]
    outer = [n for n in data.nodes if n.type == "refl(refl(leg))"]
    assert len(inner) == len(outer) == 30
    # offsets as fractions of the top's extent along the normal (about 0.8 m or 1.3 m):
    # 1.5 cm is under 0.02. Before: up to 0.07 (5.6 cm), a spread of 0.026
    for nodes in (inner, outer):
        offsets = np.array([n.sym[2] for n in nodes])
        assert np.abs(offsets).max() < 0.02, sorted(np.abs(offsets))[-3:]


def test_legs_of_tables_whose_tops_were_turned_by_hand_stay_upright_and_level():
    """30 tables placed by hand: each top turned a degree or two about the vertical, each
    leg 1 cm off and leaning up to 3 degrees. In the top's frame the legs' mirrors turn
    with it, a few degrees about the vertical only; their angles, taken about the
    diagonal pole, varied together, and independent draws tilted the mirrors out of the
    vertical too: 3.5% of sampled legs leaned over 5 degrees (up to 9) and 28% of tables
    had legs 3 cm or more higher than others, sunk through the top (h64)."""
    examples, example_set = turned_tables()
    given = [max(lean(leg["transform"]) for leg in e["children"]) for e in examples]
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    tables = [legs for legs in sampled_tables(result.program, 100, seed=2) if len(legs) == 4]
    assert len(tables) >= 90
    leans = [lean(leg) for legs in tables for leg in legs]
    heights = [np.ptp([leg[1, 3] for leg in legs]) for legs in tables]
    assert max(given) < 3.5 and max(leans) < 5.0, sorted(leans)[-5:]
    assert max(heights) < 0.03, sorted(heights)[-5:]
    # and centred under the top. The two mirrors' directions were drawn independently
    # (seed 000), a degree or two from square, and 29% of tables had their legs' centre 3
    # cm or more off the top's (44% before the inner mirror went through all four legs'
    # centre); measured from the outer mirror's turned frame, under 1% (no example is
    # 1.5 cm off). Fewer than 5 of 100 over 3 cm: about 29 expected before, 0.7 after
    offsets = []
    model = program_model(result.program, "hand_placed")
    for i in range(100):
        (top,) = derivation_hierarchies(run_forward(model, np.random.default_rng([3, i])))
        legs = [np.asarray(c["transform"], dtype=float) for c in _descendants(top) if c["part"] == "leg"]
        if len(legs) == 4:
            centre = np.mean([leg[:3, 3] for leg in legs], axis=0) - np.asarray(top["transform"], dtype=float)[:3, 3]
            offsets.append(math.hypot(centre[0], centre[2]))
    assert len(offsets) >= 90 and sum(o > 0.03 for o in offsets) < 5, sorted(offsets)[-8:]
    # the turn is the program's: written and read back, it samples the same
    from procmod.learn.program import program_from_json, program_to_json

    data = program_to_json(result.program, "t.npz")
    assert set(data["units"]["sym_turns"]) == {"refl(refl(leg))"}
    again = program_from_json(data, result.program.parts)
    assert again.units == result.program.units


def _descendants(node: dict) -> list:
    out, stack = [], list(node["children"])
    while stack:
        child = stack.pop()
        out.append(child)
        stack.extend(child["children"])
    return out


def test_a_part_named_with_parentheses_is_learned_and_a_symmetrys_name_is_refused():
    """Unity, Maya and SketchUp name copies "Leg (1)": its type was taken for a symmetry
    of kind "Leg " and the learner failed deep inside (KeyError '0.s1.xf.W', h66)."""
    import pytest

    from procmod.learn.examples import ExamplesError

    def tables(leg: str) -> dict:
        examples = [{"part": "top", "transform": (T(0, 0.78, 0) @ np.diag([w, 1, 0.8, 1])).tolist(),
                     "children": [{"part": leg, "children": [],
                                   "transform": T(sx * (w / 2 - 0.05), 0.38, sz * 0.35).tolist()}
                                  for sx in (-1, 1) for sz in (-1, 1)]}
                    for w in (1.2, 1.3, 1.4)]
        return {"format": "procmod-examples/1", "examples": examples,
                "parts": {"top": {"box": [1.0, 0.05, 1.0]}, leg: {"box": [0.06, 0.7, 0.06]}}}

    result = run_search(examples_from_dict(tables("Leg (1)")), SearchOptions(particles=1, **QUICK), InlineExecutor())
    assert {a.type for a in result.program.abstractions.values()} >= {"Leg (1)", "refl(Leg (1))"}
    assert len(sampled_leans(result.program, "Leg (1)", 5, seed=1)) == 20
    with pytest.raises(ExamplesError, match="part name 'rot\\(leg\\)' reads as the name procmod gives a learned"):
        preprocess(examples_from_dict(tables("rot(leg)")))


def test_two_mirrors_at_an_angle_keep_the_inner_mirror_where_it_is():
    """Exact tables whose inner mirror is 7 degrees off square to the outer one: their
    four legs' centre lies on the outer mirror only, and moving the inner mirror through
    it put every sampled table's legs 3 cm from where every example has them (h76)."""
    def reflect(n):
        n = np.asarray(n, float) / np.linalg.norm(n)
        m = np.eye(4)
        m[:3, :3] -= 2 * np.outer(n, n)
        return m

    rng, examples = np.random.default_rng(1), []
    inner, outer = reflect([math.cos(math.radians(7)), 0, math.sin(math.radians(7))]), reflect([0, 0, 1])
    for _ in range(6):
        w, d = rng.uniform(1.0, 1.6), rng.uniform(0.6, 0.9)
        a1 = T(w / 2 - 0.06, 0.37, d / 2 - 0.06)
        legs = []
        for m in (a1, inner @ a1, outer @ a1, outer @ inner @ a1):
            m = m.copy()
            if np.linalg.det(m[:3, :3]) < 0:
                m[:3, 0] *= -1  # a proper placement of the (symmetric) leg
            legs.append({"part": "leg", "children": [], "transform": m.tolist()})
        examples.append({"part": "top", "transform": (T(0, 0.75, 0) @ np.diag([w / 1.2, 1, d / 0.8, 1])).tolist(),
                         "children": legs})
    data = preprocess(examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                          "parts": {"top": {"box": [1.2, 0.05, 0.8]},
                                                    "leg": {"box": [0.06, 0.72, 0.06]}}}))
    offsets = [n.sym[2] for n in data.nodes if n.type == "refl(leg)"]
    assert len(offsets) == 6 and np.abs(offsets).max() < 1e-6, offsets  # through the top's centre, as placed


def test_a_programs_turns_are_checked_when_read():
    """A hand-edited sym_turns that is no unit direction is refused, not sampled from."""
    import pytest

    from procmod.learn.program import _units_from_json

    units = {"world_extent": 1.0, "part_log_scales": {}, "conventions": 2}
    assert _units_from_json({**units, "sym_turns": {"refl(refl(leg))": [0.6, 0.0, 0.8]}}).sym_turns == \
        {"refl(refl(leg))": (0.6, 0.0, 0.8)}
    assert _units_from_json(units).sym_turns == {}  # a program learned before: no turns
    for bad in ([1, 2, 3], [0.6, 0.8], ["x", 0, 1], "up"):
        with pytest.raises(ValueError, match="sym_turns"):
            _units_from_json({**units, "sym_turns": {"refl(refl(leg))": bad}})


def test_a_turn_is_kept_only_where_the_held_symmetry_follows_it():
    """Eight posts at a box's corners (three mirrors deep), each 1 cm off: the middle
    mirror's direction varies by placement noise alone, and the inner one's does not
    follow it. Measured from its turn, the inner direction spread more, and independent
    draws of the two added up: posts leaned twice as far (h77: 28-44 of 2,400 over 7
    degrees, 0-4 before). No turn is kept there; the turned tables keep theirs."""
    rng, examples = np.random.default_rng(11), []
    for _ in range(12):
        w, d, h = rng.uniform(1, 1.4), rng.uniform(0.6, 0.9), rng.uniform(0.5, 0.8)
        posts = [{"part": "post", "children": [],
                  "transform": T(sx * w / 2 + rng.normal(0, 0.01), 0.5 + sy * h / 2 + rng.normal(0, 0.01),
                                 sz * d / 2 + rng.normal(0, 0.01)).tolist()}
                 for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]
        examples.append({"part": "base", "transform": (turn_y(math.radians(rng.normal(0, 2)))
                                                       @ np.diag([w, 1, d, 1])).tolist(), "children": posts})
    data = preprocess(examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                          "parts": {"base": {"box": [1, 0.05, 1]}, "post": {"box": [0.05] * 3}}}))
    assert "refl(refl(refl(post)))" in {n.type for n in data.nodes}
    assert data.units.sym_turns == {}
    assert set(preprocess(turned_tables()[1]).units.sym_turns) == {"refl(refl(leg))"}


def test_parts_resting_on_parts_of_varying_size_stay_on_them():
    """A stem on a base and a plate on the stem, each of its own height in each example:
    between the origins the offsets follow both heights, which seed 000 draws apart, and
    sampled stems floated above or sank into their bases (h98: 87 of 200 candelabras
    off by 1 cm or more, roofs sunk into floors). Measured from the base's top face to
    the stem's bottom face (transforms.anchor_terms), the offset is zero in every example."""
    rng = np.random.default_rng(3)
    examples = []
    for _ in range(6):
        base_h, stem_h, width = rng.uniform(0.08, 0.3), rng.uniform(0.3, 0.7), rng.uniform(0.25, 0.4)
        plate = {"part": "plate", "children": [],
                 "transform": (T(0, base_h + stem_h + 0.01, 0) @ np.diag([width / 0.3, 1, width / 0.3, 1])).tolist()}
        stem = {"part": "stem", "children": [plate],
                "transform": (T(0, base_h + stem_h / 2, 0) @ np.diag([1, stem_h / 0.5, 1, 1])).tolist()}
        examples.append({"part": "base", "children": [stem],
                         "transform": (T(0, base_h / 2, 0) @ np.diag([1, base_h / 0.2, 1, 1])).tolist()})
    example_set = examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                      "parts": {"base": {"box": [0.4, 0.2, 0.4]}, "stem": {"box": [0.05, 0.5, 0.05]},
                                                "plate": {"box": [0.3, 0.02, 0.3]}}})
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    # to the stem's bottom face (from the base's middle: half its height is half its extent in every example)
    assert result.program.units.anchors["base"]["stem"][1][1] == -1
    model = program_model(result.program, "stacked")
    gaps = []
    for i in range(60):
        stack, top = derivation_hierarchies(run_forward(model, np.random.default_rng([5, i]))), {}
        while stack:
            node = stack.pop()
            stack.extend(node["children"])
            m = np.asarray(node["transform"], dtype=float)
            half = {"base": 0.1, "stem": 0.25, "plate": 0.01}[node["part"]] * np.linalg.norm(m[:3, 1])
            top[node["part"]] = (m[1, 3] - half, m[1, 3] + half)  # (bottom, top) of its (upright) box
        if "stem" in top:
            gaps.append(top["stem"][0] - top["base"][1])
    assert len(gaps) >= 50
    assert max(abs(g) for g in gaps) < 0.01, sorted(gaps, key=abs)[-5:]


def test_windows_a_metre_above_the_bottom_of_facades_of_any_height_stay_there():
    """Windows 1.5 m tall with their sills 1 m above the bottom of facades 3-6 m high (a
    reviewer's set): as a fraction of the facade's height, or from its bottom face in its
    height, the sill's height varies; in the window's own height it is fixed, and the
    samples keep it (a reviewer's run: median sill error 0.36 m before, 739 of 855 windows off by
    0.1 m; 0.014 m and 3 of 855 with the default search)."""
    rng = np.random.default_rng(4)
    examples = []
    for _ in range(8):
        width, height, count = rng.uniform(8, 16), rng.uniform(3, 6), int(rng.integers(3, 6))
        windows = [{"part": "window", "children": [],
                    "transform": (T(x, 1.75, 0.15) @ np.diag([1.2, 1.5, 0.1, 1])).tolist()}
                   for x in np.linspace(-width / 2 + 1.6, width / 2 - 1.6, count)]
        examples.append({"part": "facade", "children": windows,
                         "transform": (T(0, height / 2, 0) @ np.diag([width, height, 0.2, 1])).tolist()})
    example_set = examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                      "parts": {"facade": {"box": [1, 1, 1]}, "window": {"box": [1, 1, 1]}}})
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    assert result.program.units.anchors["facade"]["window"][1][2:] == (1,)  # measured in the window's height
    model = program_model(result.program, "facades")
    sills = []
    for i in range(40):
        stack = derivation_hierarchies(run_forward(model, np.random.default_rng([6, i])))
        while stack:
            node = stack.pop()
            stack.extend(node["children"])
            if node["part"] == "window":
                m = np.asarray(node["transform"], dtype=float)
                sills.append(m[1, 3] - 0.5 * np.linalg.norm(m[:3, 1]))
    assert len(sills) >= 80
    # (a row's step is drawn with a little rise, which the sills further along show)
    errors = np.abs(np.array(sills) - 1.0)
    assert np.median(errors) < 0.1 and (errors > 0.1).mean() < 0.3, (np.median(errors), (errors > 0.1).mean())


def test_a_ring_of_arms_placed_by_eye_closes_in_every_lamp():
    """Arms turned about a lamp's pole by eye (each within 3 degrees of 360 / n): one lamp's
    ring of four fitted its chain within the symmetry tolerance but the closed ring only at
    1.2x it, so it stayed open at 92.6 degrees, and since a ring closes in the program only
    if it closes in every example, every sampled lamp drew its arms bunched to one side
    (54 of 60; h136). The closed ring is taken within 1.5x the tolerance where the chain's
    own fit is as noisy."""
    from procmod.learn.structure import full_rings

    rng = np.random.default_rng(3)
    parts = {"pole": {"box": [0.06, 1.2, 0.06]}, "arm": {"box": [0.3, 0.04, 0.04]}}
    examples = []
    for count in (3, 4, 5, 3, 4, 5, 4, 3):
        arms = []
        for k in range(count):
            angle = 2 * math.pi * k / count + math.radians(rng.uniform(-3.0, 3.0))
            arms.append({"part": "arm", "children": [],
                         "transform": (T(0, 0.5, 0) @ turn_y(angle) @ T(0.18, 0, 0)).tolist()})
        examples.append({"part": "pole", "transform": T(0, 0.6, 0).tolist(), "children": arms})
    data = preprocess(examples_from_dict({"format": "procmod-examples/1", "parts": parts, "examples": examples}))
    angles = sorted({round(math.degrees(float(n.sym[-1])), 6) for n in data.nodes if n.kind == "rot"})
    assert angles == [72.0, 90.0, 120.0], angles  # every ring snapped closed
    assert full_rings(data) == ["rot(arm)"]
    # an arc made open on purpose (five paddles at 75 degrees, a fan: exact in every
    # example) fits its chain exactly, and stays an arc (1.5x alone had closed it; h138)
    parts = {"pole": {"box": [0.06, 1.2, 0.06]}, "paddle": {"box": [0.2, 0.02, 0.2]}}
    paddles = [{"part": "paddle", "children": [], "transform": (T(0, 0.5, 0) @ turn_y(math.radians(75.0 * k))
                                                                @ T(0.12, 0, 0)).tolist()} for k in range(5)]
    fans = [{"part": "pole", "transform": T(0, 0.6, 0).tolist(), "children": paddles} for _ in range(3)]
    data = preprocess(examples_from_dict({"format": "procmod-examples/1", "parts": parts, "examples": fans}))
    angles = sorted({round(math.degrees(float(n.sym[-1])), 6) for n in data.nodes if n.kind == "rot"})
    assert angles == [75.0] and full_rings(data) == [], angles


def test_tables_facing_one_way_off_the_axes_sample_upright_and_facing_that_way():
    """Twelve tables turned as one by 97 degrees about the vertical, each top tilted a
    degree or so by hand. Measured from the world's axes, the tops' turns sat near Euler
    angles' gimbal lock (a turn of 90 degrees about y), and tables were sampled leaning
    over 10 degrees (7 of 60 in h136's set); spun to face the world's axes instead, they
    stood but faced another way than the examples (h138). The roots' frame now faces the
    way the examples face."""
    from procmod.learn.examples import centred_examples, facing_angle, reference_facing

    examples, _ = turned_tables(count=12, seed=4)
    rng = np.random.default_rng(5)
    for example in examples:
        tilt = matrix(rotation("x", math.radians(rng.normal(0, 1.0)))) @ matrix(
            rotation("z", math.radians(rng.normal(0, 1.0))))
        whole = turn_y(math.radians(97.0 + rng.normal(0, 3.0)))

        def place(node, m):
            node["transform"] = (m @ np.asarray(node["transform"], dtype=float)).tolist()
            for child in node["children"]:
                place(child, m)

        top = np.asarray(example["transform"], dtype=float)
        place(example, whole @ T(*top[:3, 3]) @ tilt @ np.linalg.inv(T(*top[:3, 3])))
    given = examples_from_dict({"format": "procmod-examples/1", "examples": examples,
                                "parts": {"top": {"box": [1.2, 0.05, 0.8]}, "leg": {"box": [0.06, 0.72, 0.06]}}})
    facing = math.degrees(reference_facing([facing_angle(e.transform) for e in given.examples]))
    assert 90.0 < facing < 104.0
    example_set = centred_examples(given)
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    model = program_model(result.program, "hand_placed")
    leans, turns = [], []
    for i in range(60):
        (top,) = derivation_hierarchies(run_forward(model, np.random.default_rng([6, i])))
        leans.append(lean(top["transform"]))
        turns.append(math.degrees(facing_angle(np.asarray(top["transform"], dtype=float))))
    assert max(leans) < 6.0, sorted(leans)[-5:]  # the examples' tops lean up to ~3 degrees
    assert all(abs(t - facing) < 8.0 for t in turns), (facing, sorted(turns)[:3], sorted(turns)[-3:])
