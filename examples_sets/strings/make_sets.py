"""Make the example shape sets of procmod.strings (seed 001's castles, moon bases, colonnades).

    python examples_sets/strings/make_sets.py        # writes castle.json, moonbase.json, colonnade.json

Every set is a ``procmod-shapes/1`` file with two input shapes laid out on a grid: part
instances sit on grid cells, links between neighbouring cells are separate parts, and the
layouts close into rings, so the shape graphs have cycles. Parts touch face to face
exactly (the contact test's tolerance only absorbs rounding).
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


SETS = {"castle": castle, "moonbase": moonbase, "colonnade": colonnade}


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
        (out / f"{name}.json").write_text(json.dumps(rounded(make()), indent=1) + "\n")
        print(f"wrote {out / (name + '.json')}")


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else HERE)
