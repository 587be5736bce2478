"""Program structures: the initial program P0, abstraction splits, snapping.

* :func:`initial_program` — seed 000's P0: one part abstraction per part type and, for
  every slot holding symmetry nodes, one symmetry abstraction per symmetry level (so a
  ``trans(refl(panel))`` slot gets a translation abstraction calling a reflection
  abstraction calling the ``panel`` abstraction). Parameters start at the data's
  statistics: NADE output biases at the mean (transforms) or the log-odds (bits), small
  random weights (so the hidden units can learn), uniform callee choices.
* :func:`split` — replace abstraction a by two copies, dividing every caller's
  probability of a evenly between them. The exact likelihood is symmetric in the two
  copies, so something must break the tie (the paper's VI does it by sampling noise):
  the nodes a currently generates are split in two by 2-means on what a controls
  (the node's place in its parent, its slot-use bits, its children's transforms and
  abstractions, its symmetry parameters) and a warm-up bias keeps each cluster off the
  other copy for the first optimisation steps. The 2-means seed comes from the search's
  random generator, so parallel searches try different splits.
* :func:`snap` — callee probabilities below ``tau_snap`` = 0.02 are set to zero (the
  abstraction leaves ``A(a, s)``); a slot the abstraction never uses (expected use below
  1e-3 under the posterior) keeps only its most probable callee, and an abstraction that
  generates no example node is removed. Both only remove terms that cannot affect the
  likelihood of the examples, so the complexity C(P) counts what the data support.
"""

from __future__ import annotations

import math
import warnings

import numpy as np

from .preprocessing import Dataset, fixed_runs, run_steps
from .program import MAX_DEPTH, ROOT, Abstraction, Program
from .transforms import CATEGORY, SYM_PARAMS, node_kind

TAU_SNAP = 0.02
WARM_BIAS = 30.0


def _logit(p: float) -> float:
    p = min(max(p, 0.02), 0.98)
    return math.log(p / (1 - p))


def xform_data(data: Dataset) -> dict:
    """Key -> (x rows (n, 9), sign rows (n, 3)) of the children placed under that key."""
    out = {}

    def add(key, node):
        xs, ss = out.setdefault(key, ([], []))
        xs.append(node.x)
        ss.append(node.signs)

    for r in data.roots:
        add("root", data.nodes[r])
    for n in data.nodes:
        for s, child in n.children:
            if child.kind != "part":
                continue
            add(f"{n.type}#{s}" if n.kind == "part" else n.type, child)
    return {k: (np.array(v[0]), np.array(v[1], dtype=float)) for k, v in out.items()}


def nade_order(x: np.ndarray) -> list:
    """Log-scales, then rotations, then translations; each in decreasing data variance."""
    var = x.var(axis=0) if len(x) > 1 else np.zeros(9)
    order = []
    for cat in (0, 1, 2):
        dims = [d for d in range(9) if CATEGORY[d] == cat]
        order += sorted(dims, key=lambda d: (-var[d], d))
    return order


def _init_xform(params: dict, pre: str, x: np.ndarray, signs: np.ndarray, order: list, sigma_floor: tuple,
                rng) -> None:
    xo = x[:, order]
    mean = xo.mean(0)
    std = xo.std(0) if len(xo) > 1 else np.zeros(9)
    floor = np.array([sigma_floor[CATEGORY[d]] for d in order])
    params[f"{pre}.xf.W"] = 0.1 * rng.standard_normal((9, 9))
    params[f"{pre}.xf.c"] = np.zeros(9)
    params[f"{pre}.xf.Vm"] = 0.01 * rng.standard_normal((9, 9))
    params[f"{pre}.xf.bm"] = mean
    params[f"{pre}.xf.Vs"] = 0.01 * rng.standard_normal((9, 9))
    params[f"{pre}.xf.bs"] = np.log(np.maximum(std - floor, 1e-5))
    params[f"{pre}.sg.W"] = 0.1 * rng.standard_normal((3, 3))
    params[f"{pre}.sg.c"] = np.zeros(3)
    params[f"{pre}.sg.V"] = 0.1 * rng.standard_normal((3, 3))
    params[f"{pre}.sg.b"] = np.array([_logit(f) for f in signs.mean(0)])


RING_CLOSURE = 1e-3
"""Radians by which a ring's members' angles times their count may miss a full turn for
the ring to count as closed (preprocessing snaps a ring that nearly closes to 2 pi / n)."""


def full_rings(data: Dataset) -> list:
    """The rotational symmetry types that close into a full circle in every example
    (:attr:`Program.full_rings`)."""
    closes = {}
    for n in data.nodes:
        if n.kind == "rot":
            # the angle's 2 pi wraps set aside; k whole turns with k and the count coprime visit
            # every member of the ring once (5 spokes found at 144 degrees: two turns)
            turns = abs(math.remainder(float(n.sym[-1]), 2.0 * math.pi)) * n.count / (2.0 * math.pi)
            k = round(turns)
            full = k >= 1 and abs(turns - k) * 2.0 * math.pi < RING_CLOSURE and math.gcd(k, n.count) == 1
            closes[n.type] = closes.get(n.type, True) and full
    return sorted(t for t, full in closes.items() if full)


DEPTH_HEADROOM = 1.5
"""A learned program's calls may go this many times deeper than its deepest example (a
chain learned from chains of 60 parts may grow a little longer, not without end)."""


def program_depth(data: Dataset) -> int:
    """:attr:`Program.max_depth` for the examples of ``data``: the levels of calls their
    deepest derivation takes (a part or symmetry node a level, below the root's call),
    with :data:`DEPTH_HEADROOM`, and never under :data:`~procmod.learn.program.MAX_DEPTH`."""
    deepest, stack = 0, [(data.nodes[root], 1) for root in data.roots]
    while stack:  # iterative: a hierarchy may be deeper than Python's recursion limit
        node, depth = stack.pop()
        deepest = max(deepest, depth)
        stack.extend((child, depth + 1) for _, child in node.children)
    return max(MAX_DEPTH, math.ceil(DEPTH_HEADROOM * (deepest + 1)))


def initial_program(data: Dataset, rng: np.random.Generator) -> Program:
    """P0 (see the module docstring), parameters initialised from the data."""
    part_types = sorted({n.type for n in data.nodes if n.kind == "part"})
    stats = xform_data(data)
    orders = {key: nade_order(x) for key, (x, _) in stats.items()}
    program = Program(parts=data.parts, slots=data.slots, groups=data.groups, sym_inner=data.sym_inner,
                      count_support={t: list(range(2, m + 1)) for t, m in data.max_count.items()},
                      orders=orders, units=data.units, full_rings=full_rings(data), max_depth=program_depth(data))
    ids = {}
    for t in part_types:
        ids[t] = program.next_id
        program.abstractions[program.next_id] = Abstraction(program.next_id, "part", t, [])
        program.next_id += 1

    def sym_chain(type_: str) -> int:
        kind = node_kind(type_)
        inner = data.sym_inner[type_]
        callee = ids[inner] if inner in ids else sym_chain(inner)
        a = program.next_id
        program.abstractions[a] = Abstraction(a, kind, type_, [[callee]])
        program.next_id += 1
        return a

    for t in part_types:
        a = program.abstractions[ids[t]]
        a.callees = [[ids[st]] if st in ids else [sym_chain(st)] for st in data.slots.get(t, [])]
    program.root_callees = sorted({ids[data.nodes[r].type] for r in data.roots})
    # parameters
    p = program.params
    nodes_of = {}
    for n in data.nodes:
        nodes_of.setdefault(n.type, []).append(n)
    for a in sorted(program.abstractions.values(), key=lambda a: a.id):
        own = nodes_of.get(a.type, [])
        if a.kind == "part":
            for g, group in enumerate(data.groups.get(a.type, [])):
                k = len(group)
                used = np.array([n.used[group] for n in own], dtype=float).reshape(-1, k)
                p[f"{a.id}.g{g}.W"] = 0.1 * rng.standard_normal((k, k))
                p[f"{a.id}.g{g}.c"] = np.zeros(k)
                p[f"{a.id}.g{g}.V"] = 0.1 * rng.standard_normal((k, k))
                p[f"{a.id}.g{g}.b"] = np.array([_logit(f) for f in used.mean(0)])
        else:
            D = len(SYM_PARAMS[a.kind])
            values = np.array([n.sym for n in own]).reshape(-1, D)
            cats = [c for _, c in SYM_PARAMS[a.kind]]
            floor = np.array([program.sigma_floor[c] for c in cats])
            std = values.std(0) if len(values) > 1 else np.zeros(D)
            p[f"{a.id}.sym.mu"] = values.mean(0)
            p[f"{a.id}.sym.rs"] = np.log(np.maximum(std - floor, 1e-5))
            support = program.count_support[a.type]
            counts = np.array([sum(n.count == c for n in own) for c in support], dtype=float)
            p[f"{a.id}.count"] = np.log(counts / max(counts.sum(), 1) + 0.05)
        for s, callees in enumerate(a.callees):
            p[f"{a.id}.s{s}.callee"] = np.zeros(len(callees))
            if program.slot_is_part(program.slot_types(a)[s]):
                key = program.xform_key(a.id, s)
                x, signs = stats.get(key, (np.zeros((1, 9)), np.zeros((1, 3))))
                _init_xform(p, f"{a.id}.s{s}", x, signs, orders.setdefault(key, list(range(9))),
                            program.sigma_floor, rng)
    p["root.s0.callee"] = np.zeros(len(program.root_callees))
    x, signs = stats["root"]
    _init_xform(p, "root.s0", x, signs, orders["root"], program.sigma_floor, rng)
    return program


# ---- splitting -----------------------------------------------------------------------------

def node_features(data: Dataset, assignment: np.ndarray, continuous: bool) -> np.ndarray:
    """Per node, what its abstraction controls, one row per node (unscaled).

    Discrete phase: the node's place in its parent (parent type and slot), its slot-use
    bits and its children's MAP abstractions. Continuous phase: the transforms of the
    children it places and its symmetry parameters only (the modes phase 2 separates).
    """
    places = sorted({(data.nodes[n.parent].type, n.parent_slot) for n in data.nodes if n.parent >= 0})
    place_index = {p: i for i, p in enumerate(places)}
    top = int(assignment.max()) + 1 if len(assignment) else 1
    rows = []
    for n in data.nodes:
        width = len(data.slots.get(n.type, [])) if n.kind == "part" else 1
        if continuous:
            kx = np.full((width, 9), np.nan)  # unused slots: missing, imputed before clustering
            for s, child in n.children:
                if child.x is not None:
                    kx[s] = child.x
            sym = np.zeros(6) if n.sym is None else np.pad(n.sym, (0, 6 - len(n.sym)))
            rows.append(np.concatenate([kx.ravel(), sym]))
            continue
        f = np.zeros(len(places))
        if n.parent >= 0:
            f[place_index[(data.nodes[n.parent].type, n.parent_slot)]] = 1
        used = n.used.astype(float) if n.used is not None else np.ones(1)
        kids = np.zeros((width, top))
        for s, child in n.children:
            kids[s, assignment[child.id]] = 1
        rows.append(np.concatenate([f, used, kids.ravel()]))
    width = max(len(r) for r in rows)
    return np.array([np.pad(r, (0, width - len(r)), constant_values=np.nan) for r in rows])


def _two_means(x: np.ndarray, rng: np.random.Generator, iterations: int = 20, restarts: int = 4) -> np.ndarray:
    """Labels 0/1 of a 2-means clustering: standardised features (missing values imputed
    with the column mean) with a mild random weight per feature, k-means++ starts, the
    best of ``restarts`` runs; all randomness from ``rng``."""
    n = len(x)
    if n < 2:
        return np.zeros(n, dtype=int)
    x = np.array(x, dtype=np.float64)
    if np.isnan(x).any():
        with warnings.catch_warnings():  # all-missing columns: "mean of empty slice"
            warnings.simplefilter("ignore", RuntimeWarning)
            means = np.nanmean(x, axis=0)
        x = np.where(np.isnan(x), np.nan_to_num(means)[None, :], x)
    scale = x.std(0)
    keep = scale > 1e-9
    if not keep.any():
        return (rng.random(n) < 0.5).astype(int)
    z = x[:, keep] / scale[keep] * rng.uniform(0.75, 1.25, int(keep.sum()))
    best, best_cost = None, np.inf
    for _ in range(restarts):
        first = int(rng.integers(n))
        d = ((z - z[first]) ** 2).sum(1)
        second = int(rng.choice(n, p=d / d.sum())) if d.sum() > 0 else int(rng.integers(n))
        centres = z[[first, second]].copy()
        labels = -np.ones(n, dtype=int)
        for _ in range(iterations):
            new = ((z[:, None, :] - centres[None]) ** 2).sum(-1).argmin(1)
            if (new == labels).all():
                break
            labels = new
            for k in (0, 1):
                if (labels == k).any():
                    centres[k] = z[labels == k].mean(0)
        cost = float(((z - centres[labels]) ** 2).sum())
        if labels.min() != labels.max() and cost < best_cost - 1e-12:
            best, best_cost = labels, cost
    if best is None:  # degenerate: split at random
        best = (rng.random(n) < 0.5).astype(int)
    return best


def split(program: Program, target: int, data: Dataset, resp: np.ndarray, ids: list,
          rng: np.random.Generator, continuous: bool) -> tuple[Program, int, np.ndarray]:
    """A copy of ``program`` with abstraction ``target`` split in two; returns the new
    program, the new abstraction's id and the warm-up bias (N, M') for its columns."""
    new = program.copy()
    a2 = new.next_id
    new.next_id += 1
    old = new.abstractions[target]
    new.abstractions[a2] = Abstraction(a2, old.kind, old.type, [list(c) for c in old.callees])
    for key in [k for k in new.params if k.startswith(f"{target}.")]:
        new.params[f"{a2}." + key.split(".", 1)[1]] = new.params[key].copy()
    half = math.log(0.5)
    for caller, slot in new.callers_of(target):  # includes the new copy's own recursive slots
        callees = new.callee_list(caller, slot)
        pos = callees.index(target)
        key = f"{new.prefix(caller)}.s{slot}.callee"
        logits = new.params[key]
        callees.insert(pos + 1, a2)
        value = logits[pos] + half
        new.params[key] = np.concatenate([logits[:pos], [value, value], logits[pos + 1:]])
    # tie-break: 2-means over the nodes the abstraction generates
    col = ids.index(target)
    assignment = resp.argmax(1)
    mine = np.flatnonzero(resp[:, col] > 0.5)
    feats = node_features(data, assignment, continuous)
    labels = _two_means(feats[mine], rng)
    new_ids = sorted(new.abstractions)
    bias = np.zeros((len(data.nodes), len(new_ids)))
    c1, c2 = new_ids.index(target), new_ids.index(a2)
    for n, lab in zip(mine, labels):
        bias[n, c2 if lab == 0 else c1] = -WARM_BIAS
    return new, a2, bias


MAX_UNROLL = 32
"""Longest run of a self-calling abstraction that :func:`unroll` copies out (a chain of
hundreds of links would make a program of hundreds of abstractions to fit, and the
complexity term rejects it anyway)."""


def unroll(program: Program, target: int, data: Dataset, resp: np.ndarray,
           ids: list) -> tuple[Program, list, np.ndarray] | None:
    """A copy of ``program`` in which the part abstraction ``target``, which calls itself
    through one slot and only itself there, is unrolled into one copy per step of its runs,
    when every run it generates (MAP assignment) has the same length L >= 2: copy k
    generates the run's k-th node and calls copy k + 1 (a design addition to seed 000's
    two-way split, see docs/learn.md). Returns ``(program, the copies' ids in run order,
    warm-up bias)``, or None where ``target`` does not qualify.

    Why: a chain that every example repeats exactly L times (a snake of five links) is a
    geometric count under one self-calling abstraction; the per-step program scores
    higher by O_D once a few examples agree, but every two-way split on the way there
    scores lower, so the greedy search never reached it and samples had 1 to 25 links."""
    ab = program.abstractions.get(target)
    if ab is None or ab.kind != "part":
        return None
    own = [s for s, callees in enumerate(ab.callees) if target in callees]
    if len(own) != 1 or ab.callees[own[0]] != [target]:
        return None
    slot = own[0]
    if fixed_runs(data).get(ab.type, (None,))[0] != slot:
        return None  # the examples' runs of this type vary in length: the paper's recursion
    mine = resp[:, ids.index(target)] > 0.5
    depth = run_steps(data, mine, slot)
    if not depth or len(depth) != int(mine.sum()):
        return None
    lengths = [k for n, k in depth.items() if not any(s == slot for s, _ in data.nodes[n].children)]
    length = lengths[0]
    if length < 2 or length > MAX_UNROLL or any(k != length for k in lengths):
        return None
    new = program.copy()
    chain = [target]
    for _ in range(length - 1):
        a = new.next_id
        new.next_id += 1
        new.abstractions[a] = Abstraction(a, ab.kind, ab.type, [list(c) for c in ab.callees])
        for key in [k for k in program.params if k.startswith(f"{target}.")]:
            new.params[f"{a}." + key.split(".", 1)[1]] = program.params[key].copy()
        chain.append(a)
    for a, b in zip(chain, chain[1:] + chain[-1:]):  # the last copy's slot is unused: itself
        new.abstractions[a].callees[slot] = [b]
        new.params[f"{a}.s{slot}.callee"] = np.zeros(1)
    # each copy's slot-use biases start at its own step's frequencies, as P0's start at the
    # data's (copied, every step would start at the run's mean and the last copy needs
    # many more steps than a split's refit to learn that it stops)
    for k, a in enumerate(chain, 1):
        at = [data.nodes[n] for n, step in depth.items() if step == k]
        for g, group in enumerate(data.groups.get(ab.type, [])):
            used = np.array([n.used[group] for n in at], dtype=float).reshape(-1, len(group))
            new.params[f"{a}.g{g}.b"] = np.array([_logit(f) for f in used.mean(0)])
    new_ids = sorted(new.abstractions)
    bias = np.zeros((len(data.nodes), len(new_ids)))
    cols = [new_ids.index(a) for a in chain]
    for n, k in depth.items():
        bias[n, cols] = -WARM_BIAS
        bias[n, cols[k - 1]] = 0.0
    return new, chain, bias


def snap(program: Program, data: Dataset, resp: np.ndarray, ids: list, tau: float = TAU_SNAP) -> Program:
    """Snap small callee probabilities to zero, collapse unused slots, drop unused
    abstractions (see the module docstring); returns a new program."""
    new = program.copy()
    usage = resp.sum(0)
    col = {a: k for k, a in enumerate(ids)}
    used_slots = {}
    for a in ids:
        ab = new.abstractions[a]
        if ab.kind == "part":
            own = [n for n in data.nodes if n.type == ab.type]
            for s in range(len(ab.callees)):
                used_slots[(a, s)] = sum(resp[n.id, col[a]] * float(n.used[s]) for n in own)
        else:
            used_slots[(a, 0)] = usage[col[a]]
    used_slots[(ROOT, 0)] = float(len(data.roots))
    for (caller, slot), expected in used_slots.items():
        callees = new.callee_list(caller, slot)
        key = f"{new.prefix(caller)}.s{slot}.callee"
        logits = new.params[key]
        probs = np.exp(logits - logits.max())
        probs /= probs.sum()
        keep = [i for i, pr in enumerate(probs) if pr >= tau] if expected >= 1e-3 else [int(probs.argmax())]
        if not keep:
            keep = [int(probs.argmax())]
        if len(keep) < len(callees):
            kept = probs[keep] / probs[keep].sum()
            callees[:] = [callees[i] for i in keep]
            new.params[key] = np.log(kept)
    # abstractions that generate nothing and that nothing needs
    changed = True
    while changed:
        changed = False
        for a in ids:
            if usage[col[a]] < 1e-3 and a in new.abstractions:
                if all(a not in c or len(c) > 1 for c in _all_callee_lists(new)):
                    _remove(new, a)
                    changed = True
    return new


def _all_callee_lists(program: Program):
    yield program.root_callees
    for ab in program.abstractions.values():
        yield from ab.callees


def _remove(program: Program, a: int) -> None:
    for caller, slot in program.callers_of(a):
        callees = program.callee_list(caller, slot)
        key = f"{program.prefix(caller)}.s{slot}.callee"
        pos = callees.index(a)
        del callees[pos]
        program.params[key] = np.delete(program.params[key], pos)
    del program.abstractions[a]
    for key in [k for k in program.params if k.startswith(f"{a}.")]:
        del program.params[key]


def reset_parameters(program: Program, data: Dataset, rng: np.random.Generator) -> Program:
    """A copy of ``program`` with every parameter re-initialised as in P0 (data
    statistics for the NADE biases) and random callee logits (N(0, 1), so that copies of
    an abstraction are not exactly symmetric): the starting point for comparing
    parameter estimators on a learned structure."""
    template = initial_program(data, rng)
    by_type = {}
    for t in template.abstractions.values():
        by_type.setdefault((t.kind, t.type), t.id)
    new = program.copy()
    new.params = {}
    for a in new.abstractions.values():
        t = by_type[(a.kind, a.type)]
        for key, value in template.params.items():
            if key.startswith(f"{t}.") and not key.endswith(".callee"):
                new.params[f"{a.id}." + key.split(".", 1)[1]] = value.copy()
        for s, callees in enumerate(a.callees):
            new.params[f"{a.id}.s{s}.callee"] = rng.standard_normal(len(callees))
    for key, value in template.params.items():
        if key.startswith("root.") and not key.endswith(".callee"):
            new.params[key] = value.copy()
    new.params["root.s0.callee"] = rng.standard_normal(len(new.root_callees))
    return new
