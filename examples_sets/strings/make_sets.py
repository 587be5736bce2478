"""Make the example shape sets of procmod.strings (seed 001's castles, moon bases, colonnades,
and a pavilion off the grid).

    python examples_sets/strings/make_sets.py        # writes castle.json, moonbase.json, colonnade.json,
                                                     # pavilion/*.glb, pavilion.json, parts/{post,beam}.obj

Every set is a ``procmod-shapes/1`` file with two input shapes. Castle, moon base and
colonnade are laid out on a square grid: part instances sit on grid cells, links between
neighbouring cells are separate parts, turned by quarter turns. The pavilion is not: its
posts stand on a triangular lattice, its beams run at 60-degree steps, each input is
turned by an angle no quarter turn makes, and it is built as glTF scenes of real meshes
that procmod reads back (``pavilion()``). The layouts close into rings, so the shape
graphs have cycles. Parts touch face to face exactly (the contact test's tolerance only
absorbs rounding).
"""

from __future__ import annotations

import json
import math
import sys
from pathlib import Path

import numpy as np
import trimesh

HERE = Path(__file__).resolve().parent


def placed(x, y, z, yaw_quarters=0):
    """A 4x4 transform: rotate by quarter turns about z, then translate."""
    c, s = [(1, 0), (0, 1), (-1, 0), (0, -1)][yaw_quarters % 4]
    return [[c, -s, 0, x], [s, c, 0, y], [0, 0, 1, z], [0, 0, 0, 1]]


def node(part, transform):
    return {"part": part, "transform": [[float(v) for v in row] for row in transform]}


def ring(w, h):
    """Cells on the border of a w x h rectangle of cells."""
    return [(i, j) for i in range(w) for j in range(h) if i in (0, w - 1) or j in (0, h - 1)]


def grid_links(cells):
    """Links between 4-neighbouring cells."""
    cs = set(cells)
    return sorted(((i, j), (i + 1, j)) for i, j in cs if (i + 1, j) in cs) + \
        sorted(((i, j), (i, j + 1)) for i, j in cs if (i, j + 1) in cs)


def link_transform(a, b, spacing, z):
    (i0, j0), (i1, j1) = a, b
    x, y = spacing * (i0 + i1) / 2, spacing * (j0 + j1) / 2
    return placed(x, y, z, 0 if j0 == j1 else 1)


# --------------------------------------------------------------------------------------------
# castle: octagonal towers (a mesh) at cells, walls / gates between them

def octagon_tower(path: Path, apothem=0.5, height=3.0):
    r = apothem / math.cos(math.pi / 8)
    angles = [math.pi / 8 + k * math.pi / 4 for k in range(8)]
    polygon = [(r * math.cos(a), r * math.sin(a)) for a in angles]
    # A closed prism written by hand (shapely is not a dependency).
    v = [(x, y, -height / 2) for x, y in polygon] + [(x, y, height / 2) for x, y in polygon]
    f = []
    for k in range(8):
        n = (k + 1) % 8
        f += [(k, n, 8 + n), (k, 8 + n, 8 + k)]
    for k in range(1, 7):
        f += [(0, k + 1, k), (8, 8 + k, 8 + k + 1)]
    mesh = trimesh.Trimesh(vertices=v, faces=f, process=False)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(trimesh.exchange.obj.export_obj(mesh, include_normals=False, include_texture=False))


def castle_shape(cells, links, gates):
    """Towers at cells (a corner tower where the walls turn), walls or gates on links."""
    spacing = 2.0
    linked = {c: set() for c in cells}
    for a, b in links:
        linked[a].add((b[0] - a[0], b[1] - a[1]))
        linked[b].add((a[0] - b[0], a[1] - b[1]))
    nodes = []
    for i, j in cells:
        dirs = linked[(i, j)]
        corner = \
            len(dirs) == 2 and (sum(d[0] for d in dirs), sum(d[1] for d in dirs)) != (0, 0)
        nodes.append(node("corner" if corner else "tower", placed(spacing * i, spacing * j, 1.5)))
    for a, b in links:
        part = "gate" if (a, b) in gates else "wall"
        z = 1.1 if part == "gate" else 0.8
        nodes.append(node(part, link_transform(a, b, spacing, z)))
    return {"nodes": nodes}


def castle():
    octagon_tower(HERE / "parts" / "tower.obj")
    s1_cells = ring(5, 4)
    s1_links = [l for l in grid_links(s1_cells)]
    s1 = castle_shape(s1_cells, s1_links, {((2, 0), (3, 0))})
    # a 6 x 3 ring split by a cross wall: T-junction towers
    s2_cells = ring(6, 3) + [(2, 1)]
    s2_links = grid_links(s2_cells)
    s2 = castle_shape(s2_cells, s2_links, {((0, 1), (0, 2)), ((4, 2), (5, 2))})
    return {"format": "procmod-shapes/1",
            "parts": {"tower": {"mesh": "parts/tower.obj"}, "corner": {"box": [1.0, 1.0, 3.4]}, "wall": {"box": [1.0, 0.4, 1.6]},
                      "gate": {"box": [1.0, 0.7, 2.2]}},
            "shapes": [s1, s2]}


# --------------------------------------------------------------------------------------------
# moonbase: modules at cells, corridors between, domes on some modules, antennas on some domes

def moonbase_shape(cells, links, domes, antennas):
    spacing = 4.0
    nodes = [node("module", placed(spacing * i, spacing * j, 0.5)) for i, j in cells]
    nodes += [node("corridor", link_transform(a, b, spacing, 0.4)) for a, b in links]
    nodes += [node("dome", placed(spacing * i, spacing * j, 1.3)) for i, j in domes]
    nodes += [node("antenna", placed(spacing * i + 0.3, spacing * j, 2.1)) for i, j in antennas]
    return {"nodes": nodes}


def moonbase():
    c1 = [(i, j) for i in range(3) for j in range(3)]
    l1 = [l for l in grid_links(c1) if l != ((1, 1), (2, 1))]
    s1 = moonbase_shape(c1, l1, [(0, 0), (1, 1), (2, 2), (0, 2)], [(1, 1), (2, 2)])
    c2 = [(i, j) for i in range(4) for j in range(2)] + [(4, 0)]
    l2 = grid_links(c2)
    s2 = moonbase_shape(c2, l2, [(0, 0), (1, 1), (3, 0), (4, 0), (2, 1)], [(1, 1), (4, 0), (3, 0)])
    return {"format": "procmod-shapes/1",
            "parts": {"module": {"box": [2.0, 2.0, 1.0]}, "corridor": {"box": [2.0, 0.6, 0.5]},
                      "dome": {"box": [1.2, 1.2, 0.6]}, "antenna": {"box": [0.1, 0.1, 1.0]}},
            "shapes": [s1, s2]}


# --------------------------------------------------------------------------------------------
# colonnade: floor tiles at cells, a column on each, beams from column top to column top

def colonnade_shape(cells):
    spacing = 2.0
    nodes = [node("floor", placed(spacing * i, spacing * j, 0.15)) for i, j in cells]
    nodes += [node("column", placed(spacing * i, spacing * j, 0.3 + 1.25)) for i, j in cells]
    nodes += [node("beam", link_transform(a, b, spacing, 2.8 + 0.15)) for a, b in grid_links(cells)]
    return {"nodes": nodes}


def colonnade():
    s1 = colonnade_shape(ring(5, 4))
    s2 = colonnade_shape(ring(3, 3) + [(3, 1), (4, 1), (5, 1)])
    return {"format": "procmod-shapes/1",
            "parts": {"floor": {"box": [1.9, 1.9, 0.3]}, "column": {"box": [0.5, 0.5, 2.5]},
                      "beam": {"box": [1.7, 0.24, 0.3]}},
            "shapes": [s1, s2]}


# --------------------------------------------------------------------------------------------
# pavilion (off the grid): posts at the points of a triangular lattice, beams between
# neighbours (0, 60 and 120 degrees apart), each input turned by an angle no quarter turn
# makes; real meshes (a 12-sided post with plinth and capital, an octagonal beam) in a
# y-up glTF scene per input, which procmod reads like any user's asset (procmod.strings.assets)

PAVILION_SPACING = 2.0  # lattice step (post centre to post centre)
POST_APOTHEM = 0.2  # the shaft's 12 faces are this far from its axis
POST_HEIGHT = 2.6
BEAM_APOTHEM = 0.08
BEAM_RISE = 0.45  # the beams' axis above the post's centre
# the inputs' turns about the vertical: drawn once (numpy's generator, seed 1) from
# (0, 30) degrees; the second input is turned 150 degrees more, so its lattice runs 30
# degrees off the first's (a triangular lattice repeats every 60) while its 12-sided posts
# show the same faces to the world (they repeat every 30)
PAVILION_YAW = float(np.round(np.random.default_rng(1).uniform(0.0, 30.0), 3))
PAVILION_YAWS = (PAVILION_YAW, PAVILION_YAW + 150.0)


def lathe(profile, sides: int, phase: float):
    """A closed surface of revolution about y (glTF's up): ``profile`` (apothem, y) pairs,
    ``sides`` flat faces round (vertices at ``phase + 360 k / sides`` degrees in the
    world's x, y after the y-up to z-up turn), both ends capped."""
    step = 2 * math.pi / sides
    angles = np.radians(phase) + step * np.arange(sides)
    v = []
    for apothem, y in profile:
        r = apothem / math.cos(step / 2)
        v += [(r * math.cos(a), y, -r * math.sin(a)) for a in angles]  # world (x, -z) -> z-up (x, y)
    f = []
    for ring in range(len(profile) - 1):
        a0, b0 = ring * sides, (ring + 1) * sides
        for k in range(sides):
            n = (k + 1) % sides
            f += [(a0 + k, a0 + n, b0 + n), (a0 + k, b0 + n, b0 + k)]
    bottom, top = len(v), len(v) + 1
    v += [(0.0, profile[0][1], 0.0), (0.0, profile[-1][1], 0.0)]
    last = (len(profile) - 1) * sides
    for k in range(sides):
        n = (k + 1) % sides
        f += [(bottom, n, k), (top, last + k, last + n)]
    return trimesh.Trimesh(vertices=v, faces=f, process=False)


def post_mesh():
    """A 12-sided post standing along y: plinth, a shaft of 40 rings (the detail a modeller's
    mesh has), capital; faces of the shaft at 0, 30, ... degrees (beams meet them flush)."""
    h = POST_HEIGHT / 2
    shaft = [(POST_APOTHEM, -h + 0.2 + (2 * h - 0.4) * k / 40) for k in range(41)]
    return lathe([(0.3, -h), (0.3, -h + 0.2)] + shaft + [(0.3, h - 0.2), (0.3, h)], 12, 15.0)


def beam_mesh():
    """An octagonal beam along x, from face to face of two posts one lattice step apart."""
    half = PAVILION_SPACING / 2 - POST_APOTHEM
    m = lathe([(BEAM_APOTHEM, -half + 2 * half * k / 8) for k in range(9)], 8, 22.5)
    # stood along y by lathe: lay it along x (a quarter turn about z in y-up terms)
    m.apply_transform(trimesh.transformations.rotation_matrix(-math.pi / 2, [0, 0, 1]))
    return m


Y_UP = np.array([[1.0, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]])  # y-up -> z-up


def lattice_point(i, j):
    return PAVILION_SPACING * (i + j / 2), PAVILION_SPACING * j * math.sqrt(3) / 2


def pavilion_scene(points, yaw_degrees, offset):
    """A trimesh scene (y-up, as glTF is): an empty root, a post at each lattice point and a
    beam between every two neighbouring points, the whole turned by ``yaw_degrees``."""
    scene = trimesh.Scene()
    scene.graph.update(frame_to="pavilion", frame_from=scene.graph.base_frame, matrix=np.eye(4))
    turn = np.array(placed(offset[0], offset[1], 0.0))
    turn[:3, :3] = trimesh.transformations.rotation_matrix(math.radians(yaw_degrees), [0, 0, 1])[:3, :3]
    post, beam = post_mesh(), beam_mesh()
    pts = sorted(points)
    for k, (i, j) in enumerate(pts):
        x, y = lattice_point(i, j)
        m = turn @ np.array(placed(x, y, POST_HEIGHT / 2))
        scene.add_geometry(post, geom_name="post", node_name=f"post_{k:02d}", parent_node_name="pavilion",
                           transform=np.linalg.inv(Y_UP) @ m @ Y_UP)
    have = set(pts)
    k = 0
    for i, j in pts:
        for di, dj, angle in ((1, 0, 0.0), (0, 1, 60.0), (-1, 1, 120.0)):
            if (i + di, j + dj) in have:
                (x0, y0), (x1, y1) = lattice_point(i, j), lattice_point(i + di, j + dj)
                m = turn @ np.array(placed((x0 + x1) / 2, (y0 + y1) / 2, POST_HEIGHT / 2 + BEAM_RISE))
                m[:3, :3] = m[:3, :3] @ trimesh.transformations.rotation_matrix(math.radians(angle), [0, 0, 1])[:3, :3]
                scene.add_geometry(beam, geom_name="beam", node_name=f"beam_{k:02d}", parent_node_name="pavilion",
                                   transform=np.linalg.inv(Y_UP) @ m @ Y_UP)
                k += 1
    return scene


def pavilion_files(folder: Path) -> list[Path]:
    """The two input scenes as GLB files: a hexagon of six triangles round a centre post
    with one more post off a corner, and a strip of five triangles with a tail of two."""
    hexagon = [(0, 0), (1, 0), (0, 1), (-1, 1), (-1, 0), (0, -1), (1, -1), (2, 0)]
    strip = [(0, 0), (1, 0), (2, 0), (3, 0), (0, 1), (1, 1), (2, 1), (4, 0), (5, 0)]
    folder.mkdir(parents=True, exist_ok=True)
    out = []
    for name, points, yaw, offset in (("a_hexagon", hexagon, PAVILION_YAWS[0], (0.0, 0.0)),
                                      ("b_strip", strip, PAVILION_YAWS[1], (14.0, 3.0))):
        path = folder / f"{name}.glb"
        path.write_bytes(pavilion_scene(points, yaw, offset).export(file_type="glb"))
        out.append(path)
    return out


def pavilion(out: Path) -> dict:
    """The pavilion set, read from its glTF files by procmod (the parts' meshes go to
    ``out/parts``; the shapes file's JSON is returned)."""
    sys.path.insert(0, str(HERE.parents[1]))
    from procmod.strings.assets import read_shape_inputs
    from procmod.strings.shapes import shapes_to_dict, write_shapes

    shape_set = read_shape_inputs(pavilion_files(out / "pavilion"))
    write_shapes(shape_set, out / "pavilion.json")  # writes parts/post.obj, parts/beam.obj
    return shapes_to_dict(shape_set)


SETS = {"castle": castle, "moonbase": moonbase, "colonnade": colonnade, "pavilion": pavilion}


# Floats are written with 12 significant digits, so the stored sets are what this script
# makes on any machine (another CPU's libm or BLAS may change a double's last digits).
SIGNIFICANT_DIGITS = 12


def rounded(data):
    """``data`` with every float rounded to ``SIGNIFICANT_DIGITS`` significant digits."""
    if isinstance(data, float):
        return float(f"{data:.{SIGNIFICANT_DIGITS}g}") + 0.0  # + 0.0: no negative zeros
    if isinstance(data, dict):
        return {k: rounded(v) for k, v in data.items()}
    if isinstance(data, (list, tuple)):
        return [rounded(v) for v in data]
    return data


def main(out: Path = HERE) -> None:
    for name, make in SETS.items():
        data = make(out) if name == "pavilion" else make()
        (out / f"{name}.json").write_text(json.dumps(rounded(data), indent=1) + "\n")
        print(f"wrote {out / (name + '.json')}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
