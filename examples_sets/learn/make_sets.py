"""Author the procmod-examples/1 example sets used to test and benchmark ``procmod learn``.

Run ``python examples_sets/learn/make_sets.py`` (from the repository root). It writes,
for each set, ``examples_sets/learn/<set>/examples.json`` plus the part meshes in
``examples_sets/learn/<set>/parts/*.obj``. Each set holds ten examples made by a small
hand-written generator with a fixed seed; it is independent of the learner (it imports
nothing of procmod) and writes the format directly.

Sets (world y is up):

* ``spaceships`` — a body with one wide reflected pair of wings or two thin pairs (each
  pair with no tip weapon, reflected guns above or below the tips, or reflected
  missiles under them), a rear hull built recursively from 0-2 tapering segments, on
  the last of which (or on the body) sit a rear engine, a reflected pair of side engines
  or a row of three small ones (they overlap: co-occurrence conflict), an optional
  tilted fin on top or keel below, optional reflected tail fins and belly guns, an
  optional sensor dish, a cockpit with an optional antenna. The structural choices are
  independent draws (``SPACESHIP_CHOICES``), made before the continuous ones.
* ``castles`` — a keep with 4-6 towers around it (a rotational group) with optional
  roofs and flags, an outer wall built recursively from 2-5 segments bent left or right
  by a per-wall angle, an optional second wall behind, an optional gate.
* ``ornaments`` — a centre disc with a rotational group of 3-6 stems; each stem is a
  recursive chain of 1-4 segments curling left or right, with optional reflected leaf
  pairs, ending in a flower (a rotational group of five petals) or a bud.
* ``stations`` — a hub with a ring of 3-6 spokes (rotational group), each carrying a
  module and optionally a translated row of 3-4 reflected solar-panel pairs tilted one
  way or the other (nested symmetry), an optional translated row of antennas, an optional dock, and recursively
  an optional smaller hub on top with its own ring.
"""

from __future__ import annotations

import json
import math
import os
import tempfile
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
N_EXAMPLES = 10


# ---- matrices ---------------------------------------------------------------------

def T(x, y, z):
    m = np.eye(4)
    m[:3, 3] = (x, y, z)
    return m


def S(x, y, z):
    return np.diag([x, y, z, 1.0])


def R(axis, a):
    c, s = math.cos(a), math.sin(a)
    m = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    m[i, i], m[i, j], m[j, i], m[j, j] = c, -s, s, c
    return m


def mirror(normal, point=(0, 0, 0)):
    """Reflection across the plane through ``point`` with ``normal``."""
    n = np.asarray(normal, dtype=float)
    n /= np.linalg.norm(n)
    m = np.eye(4)
    m[:3, :3] -= 2 * np.outer(n, n)
    m[:3, 3] = 2 * np.dot(n, point) * n
    return m


def about(point, rot):
    """``rot`` (a 4x4 rotation) applied about ``point``."""
    return T(*point) @ rot @ T(*(-np.asarray(point)))


def node(part, m, children=()):
    return {"part": part, "transform": [[float(v) for v in row] for row in m], "children": list(children)}


def mapped(g, n):
    """A deep copy of node ``n`` with the world map ``g`` applied to every transform."""
    return {"part": n["part"], "transform": [[float(v) for v in row] for row in g @ np.array(n["transform"])],
            "children": [mapped(g, c) for c in n["children"]]}


# ---- meshes (closed, in the part's local frame) ------------------------------------

def prism(n, radius, lo, hi, axis):
    """An n-gon prism along ``axis`` from ``lo`` to ``hi``."""
    verts, faces = [], []
    for h in (lo, hi):
        for k in range(n):
            a = 2 * math.pi * k / n
            u, v = radius * math.cos(a), radius * math.sin(a)
            verts.append({"y": (u, h, v), "z": (u, v, h), "x": (h, u, v)}[axis])
    for k in range(n):
        j = (k + 1) % n
        faces += [(k, j, n + j), (k, n + j, n + k)]
    for k in range(1, n - 1):
        faces += [(0, k + 1, k), (n, n + k, n + k + 1)]
    return verts, faces


def extrude(outline, thick, axis="y"):
    """A convex outline (list of 2D points, counter-clockwise) extruded symmetrically."""
    n = len(outline)
    verts = []
    for h in (-thick / 2, thick / 2):
        for u, v in outline:
            verts.append({"y": (u, h, v), "z": (u, v, h)}[axis])
    faces = []
    for k in range(n):
        j = (k + 1) % n
        faces += [(k, j, n + j), (k, n + j, n + k)]
    for k in range(1, n - 1):
        faces += [(0, k + 1, k), (n, n + k, n + k + 1)]
    return verts, faces


def pyramid(base, height, axis="y"):
    h = base / 2
    pts = [(-h, -h), (h, -h), (h, h), (-h, h)]
    if axis == "y":
        verts = [(u, 0.0, v) for u, v in pts] + [(0.0, height, 0.0)]
    else:  # along +z
        verts = [(u, v, 0.0) for u, v in pts] + [(0.0, 0.0, height)]
    faces = [(0, 2, 1), (0, 3, 2), (0, 1, 4), (1, 2, 4), (2, 3, 4), (3, 0, 4)]
    return verts, faces


def write_obj(path: Path, mesh) -> None:
    verts, faces = mesh
    lines = [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in verts]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in faces]
    path.write_text("\n".join(lines) + "\n")


# ---- sets ----------------------------------------------------------------------------

MX = mirror((1, 0, 0))


# The spaceship generator's independent structural choices and their probabilities
# (``novelty_bound.py`` reads them: an ideal learner fits exactly these).
SPACESHIP_CHOICES = {
    "two_pairs": 0.5,                  # one wide wing pair, or two thin pairs
    "tip": (1 / 3, 1 / 3, 1 / 3),      # per wing pair: no tip weapon, reflected guns, reflected missiles
    "engines": (1 / 3, 1 / 3, 1 / 3),  # one rear engine, a reflected pair, a row of three
    "segments": (1 / 3, 1 / 3, 1 / 3),  # 0, 1 or 2 rear hull segments (recursive chain)
    "fin": 0.6,                        # a fin on top or a keel below
    "belly": 0.5,                      # reflected guns under the body
    "tail": 0.5,                       # reflected tail fins
    "dish": 0.5,                       # a sensor dish on the body's back
    "antenna": 0.5,                    # an antenna on the cockpit
}


def spaceship_choices(rng, p=SPACESHIP_CHOICES) -> dict:
    """Draw a spaceship's structural choices (independent; probabilities ``p``)."""
    two = bool(rng.random() < p["two_pairs"])
    return {"two_pairs": two,
            "tips": [int(rng.choice(3, p=p["tip"])) for _ in range(2 if two else 1)],
            "engines": int(rng.choice(3, p=p["engines"])),
            "segments": int(rng.choice(3, p=p["segments"])),
            **{k: bool(rng.random() < p[k]) for k in ("fin", "belly", "tail", "dish", "antenna")}}


def spaceship_from(c: dict, rng):
    """A spaceship with structural choices ``c``; continuous variety drawn from ``rng``."""
    L = rng.uniform(0.8, 1.3)
    half = 2.0 * L
    children = []
    if c["two_pairs"]:  # two thin pairs, front and back
        pairs = [(half * rng.uniform(0.15, 0.4), rng.uniform(1.2, 1.8), 0.8),
                 (-half * rng.uniform(0.25, 0.5), rng.uniform(1.2, 1.8), 0.8)]
    else:  # one wide pair
        pairs = [(rng.uniform(-0.3, 0.3) * L, rng.uniform(2.2, 3.0), 1.5)]
    gun_side = 1.0 if rng.random() < 0.5 else -1.0  # guns above or below the wing tips
    for (z, span, chord), tip in zip(pairs, c["tips"]):
        theta = rng.uniform(-0.35, 0.35)
        frame = T(0.55, 0.0, z) @ R("z", theta)
        kids = []
        if tip == 1:
            kids.append(node("gun", frame @ T(0.8 * span, 0.12 * gun_side, 0.2)))
        elif tip == 2:  # a missile hung under the wing tip, pointing forward
            kids.append(node("missile", frame @ T(span * rng.uniform(0.85, 1.0), -0.15, 0.1)))
        wing = node("wing", frame @ S(span, 1.0, chord), kids)
        children += [wing, mapped(MX, wing)]
    # rear hull: a recursive chain of 0-2 tapering segments; the engines sit on the last
    taper = rng.uniform(0.8, 0.95)
    rear, width, frames = -half, 1.0, []
    for _ in range(c["segments"]):
        width *= taper
        frames.append(T(0, 0, rear - 0.8) @ S(width, width, 1.0))
        rear -= 1.6
    back = T(0, 0, rear) @ S(width, width, 1.0)
    if c["engines"] == 0:  # one big rear engine
        engines = [node("engine", back @ T(0, 0, -0.3) @ S(1.4, 1.4, 1.0))]
    elif c["engines"] == 1:  # a reflected pair of side engines
        engine = node("engine", back @ T(0.45, 0, -0.2) @ S(0.8, 0.8, 1.2))
        engines = [engine, mapped(MX, engine)]
    else:  # a row of three small engines
        engines = [node("engine", back @ T(-0.4 + 0.4 * j, 0, -0.25) @ S(0.45, 0.45, 0.8)) for j in range(3)]
    tail = engines
    for m in reversed(frames):
        tail = [node("segment", m, tail)]
    children += tail
    if c["fin"]:
        side = 1.0 if rng.random() < 0.5 else -1.0  # a fin on top or a keel below
        children.append(node("fin", T(0, 0.7 * side, -half * rng.uniform(0.35, 0.7)) @ R("x", side * rng.uniform(-0.4, 0.0))))
    if c["belly"]:  # a reflected pair of guns under the body
        belly = node("gun", T(0.35, -0.5, half * rng.uniform(0.0, 0.4)))
        children += [belly, mapped(MX, belly)]
    if c["tail"]:  # a reflected pair of tail fins
        fin = node("fin", T(0.45, 0.55, -half + 1.0) @ R("z", -0.5))  # clear of the engines and rear hull
        children += [fin, mapped(MX, fin)]
    if c["dish"]:  # a sensor dish on the back, tilted forward or back
        children.append(node("dish", T(0, 0.5, half * rng.uniform(0.3, 0.45)) @ R("x", rng.uniform(-0.5, 0.5))))
    cz = rng.uniform(0.8, 1.4)
    antenna = [node("antenna", T(0, 0.6, half - 0.3 + 0.3 * cz))] if c["antenna"] else []
    children.append(node("cockpit", T(0, 0.15, half - 0.3) @ S(0.7, 0.5, cz), antenna))
    order = rng.permutation(len(children))
    return node("body", S(1.0, 1.0, L), [children[i] for i in order])


def spaceship(rng):
    """A spaceship: structural choices first (``spaceship_choices``), then its shape."""
    return spaceship_from(spaceship_choices(rng), rng)


def wall_chain(start, n_walls, bend):
    """A recursive wall: each segment's child is the next one, turned by ``bend``."""
    segments, frame = [], start
    for i in range(n_walls):
        segments.append(frame @ T(1.0, 0, 0))
        frame = frame @ T(2.0, 0, 0) @ R("y", -bend)
    wall = None
    for m in reversed(segments):
        wall = node("wall", m, [wall] if wall else [])
    return wall


def castle(rng):
    kx, ky = rng.uniform(0.9, 1.2), rng.uniform(0.9, 1.3)
    children = []
    h = rng.uniform(3.5, 5.0)
    roof = rng.random() < 0.7
    flag = rng.random() < 0.5
    roof_h = rng.uniform(1.0, 1.8)
    c = 2.0 * kx
    kids = [node("roof", T(c, h, c) @ S(1.6, roof_h, 1.6))] if roof else []
    if flag:
        kids.append(node("flag", T(c, h + (roof_h if roof else 0.0) + 0.3, c)))
    tower = node("tower", T(c, h / 2, c) @ S(1.2, h, 1.2), kids)
    n_towers = int(rng.integers(4, 7))
    for j in range(n_towers):
        children.append(mapped(R("y", j * 2 * math.pi / n_towers), tower))
    sign = lambda: 1 if rng.random() < 0.5 else -1  # noqa: E731 - walls curve one way or the other
    children.append(wall_chain(T(-c - 1.0, 0.6, c + 2.5) @ R("y", 0.3), int(rng.integers(2, 6)),
                               rng.uniform(0.4, 0.6) * sign()))
    if rng.random() < 0.5:  # a second wall behind the keep
        children.append(wall_chain(T(c + 1.0, 0.6, -c - 2.5) @ R("y", math.pi + 0.3), int(rng.integers(2, 5)),
                                   rng.uniform(0.4, 0.6) * sign()))
    if rng.random() < 0.5:
        children.append(node("gate", T(rng.uniform(-0.5, 0.5), 0.75, c + 0.1)))
    order = rng.permutation(len(children))
    return node("keep", T(0, 1.5 * ky, 0) @ S(kx, ky, kx), [children[i] for i in order])


def ornament(rng):
    s = rng.uniform(1.2, 1.6)
    k = int(rng.integers(3, 7))
    n_seg = int(rng.integers(1, 5))
    bend = rng.uniform(0.5, 0.7) * (1 if rng.random() < 0.5 else -1)  # curling left or right
    leaves = [rng.random() < 0.5 for _ in range(n_seg)]
    flower = rng.random() < 0.6
    phi = rng.uniform(0, 2 * math.pi / k)
    r0 = 0.5 * s
    pos, ang = np.array([r0 * math.cos(phi), r0 * math.sin(phi), 0.0]), phi
    frames = []
    for i in range(n_seg):
        frames.append(T(*pos) @ R("z", ang))
        pos = pos + np.array([math.cos(ang), math.sin(ang), 0.0])
        ang += bend
    tip = pos
    stem = None
    for i in reversed(range(n_seg)):
        f = frames[i]
        kids = [stem] if stem else []
        if i == n_seg - 1:
            if flower:
                petal = node("petal", T(*tip) @ R("z", ang - bend) @ S(0.6, 1.0, 1.0))
                kids += [mapped(about(tip, R("z", j * 2 * math.pi / 5)), petal) for j in range(5)]
            else:
                kids.append(node("bud", T(*tip) @ R("z", ang - bend)))
        if leaves[i]:
            leaf = node("leaf", f @ T(0.45, 0.06, 0) @ R("z", 0.6))
            normal = f[:3, :3] @ np.array([0.0, 1.0, 0.0])
            kids += [leaf, mapped(mirror(normal, f[:3, 3]), leaf)]
        stem = node("stem", f @ T(0.5, 0, 0), kids)
    children = [mapped(R("z", j * 2 * math.pi / k), stem) for j in range(k)]
    return node("disc", S(s, s, 1.0), children)


def station(rng, depth=0, base=np.eye(4)):
    hy = rng.uniform(1.0, 1.5)
    hub_m = base @ S(2.0, hy, 2.0)
    children = []
    if depth == 0 or rng.random() < 0.5:
        k = int(rng.integers(3, 7))
        length = rng.uniform(1.5, 3.0)
        phi = rng.uniform(0, 2 * math.pi / k)
        arm = base @ R("y", phi)
        m_panels = int(rng.choice([0, 3, 4]))
        kids = [node("module", arm @ T(0, 0, 1.0 + length + 0.5))]
        if m_panels:
            step = length / (m_panels + 0.5)
            tilt = 0.6 if rng.random() < 0.5 else -0.6
            right = node("panel", arm @ T(0.75, 0, 1.3) @ R("z", tilt))
            pair = [right, mapped(mirror(arm[:3, :3] @ np.array([1.0, 0, 0]), arm[:3, 3]), right)]
            for j in range(m_panels):
                g = T(*(arm[:3, :3] @ np.array([0, 0, j * step])))
                kids += [mapped(g, p) for p in pair]
        spoke = node("spoke", arm @ T(0, 0, 1.0 + length / 2) @ S(1, 1, length), kids)
        for j in range(k):
            g = about(base[:3, 3], R("y", j * 2 * math.pi / k))
            children.append(mapped(g, spoke))
    if rng.random() < 0.6:
        count = int(rng.integers(3, 6))
        delta = rng.uniform(0.3, 0.5)
        for j in range(count):
            children.append(node("antenna", base @ T(-0.8 + j * delta, hy / 2 + 0.5, 0.3)))
    if depth == 0 and rng.random() < 0.5:
        children.append(node("dock", base @ T(0, -hy / 2, 0) @ R("x", math.pi) @ S(1.0, 0.8, 1.0)))
    if depth < 2 and rng.random() < 0.5:
        top = base @ T(0, hy / 2 + 0.6, 0) @ S(0.7, 0.7, 0.7) @ T(0, 0.6, 0)
        children.append(station(rng, depth + 1, top))
    order = rng.permutation(len(children))
    return node("hub", hub_m, [children[i] for i in order])


SETS = {
    "spaceships": (spaceship, {
        "body": {"box": [1.2, 0.8, 4.0]},
        "wing": {"mesh": "parts/wing.obj"},
        "engine": {"mesh": "parts/engine.obj"},
        "fin": {"box": [0.1, 0.8, 1.0]},
        "gun": {"box": [0.12, 0.12, 1.2]},
        "cockpit": {"mesh": "parts/cockpit.obj"},
        "antenna": {"box": [0.05, 0.6, 0.05]},
        "missile": {"mesh": "parts/missile.obj"},
        "segment": {"box": [1.0, 0.7, 1.6]},
        "dish": {"mesh": "parts/dish.obj"},
    }, {
        "wing": extrude([(0, -0.5), (1, -0.1), (1, 0.2), (0, 0.5)], 0.1, "y"),
        "engine": prism(6, 0.5, -0.5, 0.5, "z"),
        "cockpit": pyramid(1.0, 1.0, "z"),
        "missile": prism(6, 0.07, -0.6, 0.6, "z"),
        "dish": prism(10, 0.4, -0.04, 0.04, "y"),
    }),
    "castles": (castle, {
        "keep": {"box": [4.0, 3.0, 4.0]},
        "tower": {"mesh": "parts/tower.obj"},
        "roof": {"mesh": "parts/roof.obj"},
        "wall": {"box": [2.0, 1.2, 0.3]},
        "gate": {"box": [1.2, 1.5, 0.3]},
        "flag": {"box": [0.05, 0.6, 0.4]},
    }, {
        "tower": prism(8, 0.5, -0.5, 0.5, "y"),
        "roof": pyramid(1.0, 1.0, "y"),
    }),
    "ornaments": (ornament, {
        "disc": {"mesh": "parts/disc.obj"},
        "stem": {"box": [1.0, 0.12, 0.1]},
        "petal": {"mesh": "parts/petal.obj"},
        "leaf": {"mesh": "parts/leaf.obj"},
        "bud": {"box": [0.25, 0.25, 0.12]},
    }, {
        "disc": prism(12, 0.5, -0.1, 0.1, "z"),
        "petal": extrude([(0, 0), (0.5, -0.2), (1, 0), (0.5, 0.2)], 0.08, "z"),
        "leaf": extrude([(0, 0), (0.3, -0.12), (0.6, 0), (0.3, 0.12)], 0.06, "z"),
    }),
    "stations": (station, {
        "hub": {"mesh": "parts/hub.obj"},
        "spoke": {"box": [0.2, 0.2, 1.0]},
        "module": {"box": [1.0, 0.8, 1.0]},
        "panel": {"box": [1.2, 0.05, 0.6]},
        "antenna": {"box": [0.08, 1.0, 0.08]},
        "dock": {"mesh": "parts/dock.obj"},
    }, {
        "hub": prism(12, 0.5, -0.5, 0.5, "y"),
        "dock": pyramid(1.0, 1.0, "y"),
    }),
}


# Floats are written with 12 significant digits: another CPU or BLAS kernel may change
# the last of a double's 17 (e.g. -0.47960647900962994 vs -0.47960647900963016), and
# the stored sets must be what this script makes on any machine.
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


def write_json_atomic(path: Path, data) -> None:
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    with os.fdopen(fd, "w") as handle:
        json.dump(rounded(data), handle, indent=None)
        handle.write("\n")
    os.replace(tmp, path)


def make(name: str, out: Path = HERE, seed: int = 0) -> Path:
    """Write set ``name`` under ``out/name``; returns the examples file."""
    generator, parts, meshes = SETS[name]
    folder = out / name
    (folder / "parts").mkdir(parents=True, exist_ok=True)
    for part, mesh in meshes.items():
        write_obj(folder / "parts" / f"{part}.obj", mesh)
    rng = np.random.default_rng([seed, sorted(SETS).index(name)])
    examples = [generator(rng) for _ in range(N_EXAMPLES)]
    path = folder / "examples.json"
    write_json_atomic(path, {"format": "procmod-examples/1", "parts": parts, "examples": examples})
    return path


if __name__ == "__main__":
    for name in SETS:
        print("wrote", make(name))
