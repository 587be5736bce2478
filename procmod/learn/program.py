"""The learnable program of seed 000 section 5 (Algorithm 1), as a procmod model.

A :class:`Program` holds

* the part library and the preprocessed slot structure (slots and slot groups per part
  type, the child type of every symmetry type, the members counts seen);
* abstractions, each typed as a part node (``kind="part"``, generating one part type) or
  a reflection / translation / rotation symmetry node, with for each slot the set
  ``A(a, s)`` of abstractions it may call;
* parameters (numpy arrays, keyed ``"<abs>.<what>"``; ``root`` for the root call):

  - ``<a>.g<g>.{W,c,V,b}`` — Bernoulli NADE over the use bits of slot group g (hidden
    layer the size of the group, sigmoid);
  - ``<a>.s<s>.callee`` — logits over ``A(a, s)``;
  - ``<a>.s<s>.xf.{W,c,Vm,bm,Vs,bs}`` — Gaussian NADE over the 9 transform components
    of the child in slot s (hidden 9, tanh; log-scales, then rotations, then
    translations, each category in decreasing order of the data's variance), and
    ``<a>.s<s>.sg.{W,c,V,b}`` — Bernoulli NADE over the three scale signs (hidden 3);
  - ``<a>.sym.{mu,rs}`` — independent Gaussians over the symmetry parameters, and
    ``<a>.count`` — logits over the member count.

Transform components are measured in the program's :class:`~procmod.learn.transforms.Units`
(the examples' size for the roots' frame, each part's reference log-scale), so that the
same set modelled in other units learns the same program; a program written before
units existed reads with extent 1 and no references, as it was learned.

Standard deviations are ``min(floor + exp(raw), cap)``; during phase 2 of the search they are
fixed (:data:`procmod.learn.transforms.FIXED_SIGMA`). Every part abstraction generates
exactly one part type (splits preserve types), so its part distribution is a point mass
and contributes nothing to likelihoods; it is stored in the JSON for completeness.

The transform distribution of a child is indexed by (calling abstraction, slot), as in
Algorithm 1; a child of a symmetry node is placed in the frame of the nearest part
ancestor, and the symmetry node's maps copy the whole generated subtree.

As a model: one rule, :func:`gen_node`, called with (program, caller, slot, frame,
copies). It picks its abstraction (choice ``abs``), then for a part abstraction samples
its transform (``x.ls0`` ... ``x.t2``, ``x.sg0..2``), emits its part once per copy, and
flips one ``maybe`` per slot (``s<slot>``, probability from the group's NADE given the
earlier bits) whose child call it spawns; for a symmetry abstraction it samples
``sym.<param>`` and ``count`` and spawns its one child (site ``c``) with the copies
multiplied by the group's maps. Calls deeper than the program's ``max_depth`` (:data:`MAX_DEPTH` at
least, and deeper than its deepest example) spawn nothing.
"""

from __future__ import annotations

import copy
import json
import math
import os
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

import numpy as np

from ..core import Bernoulli, Categorical, Model, Normal
from ..core.distributions import _is_real  # a finite number: not a bool, a string or 10**400
from ..core.errors import ProcmodError, shown_value
from ..core.paths import FileNames, UnsafePathError, named_file
from ..core.io import load_tensors, read_versioned_json, save_tensors, write_text_atomic
from ..core.limits import MAX_COORDINATE
from ..geometry.part_library import read_part_library
from ..geometry.solid import as_transform, new_part_bounds
from .ground import settle_on_ground
from .transforms import (ANCHOR_SIDES, CATEGORY, COMPONENTS, CURRENT, FIXED_SIGMA, LEGACY, LEGACY_SIGMA_FLOOR,
                         SIGMA_FLOOR, SIGMA_MAX, SYM_PARAMS, Units, node_kind,
                         Frame, sym_maps, symmetry_direction, turned_frame, xform_matrix)

PROGRAM_FORMAT = "procmod-program/1"
MAX_DEPTH = 40
ROOT = -1


class ProgramError(ProcmodError):
    """A program file that cannot be read or used; the message says why."""


@dataclass
class Abstraction:
    """One abstraction: its id, kind, generated node type and callable sets per slot."""

    id: int
    kind: str  # "part", "refl", "trans", "rot"
    type: str
    callees: list  # per slot: list of abstraction ids


def _sigmoid(x):
    return 1.0 / (1.0 + math.exp(-x)) if x >= 0 else math.exp(x) / (1.0 + math.exp(x))


def _softmax(logits) -> np.ndarray:
    z = np.asarray(logits, dtype=np.float64)
    z = np.exp(z - z.max())
    return z / z.sum()


def sym_sigma_categories(kind: str) -> list:
    return [cat for _, cat in SYM_PARAMS[kind]]


@dataclass
class Program:
    """A learned (or learnable) program; see the module docstring."""

    parts: dict  # name -> PartShape
    slots: dict  # part type -> list of slot types
    groups: dict  # part type -> list of lists of slot indices
    sym_inner: dict  # symmetry type -> child type
    count_support: dict  # symmetry type -> list of member counts
    orders: dict  # xform key -> permutation of the 9 components (NADE order)
    abstractions: dict = field(default_factory=dict)  # id -> Abstraction
    root_callees: list = field(default_factory=list)
    params: dict = field(default_factory=dict)
    sigma_mode: str = "free"  # "free" or "fixed" (phase 2)
    next_id: int = 0
    info: dict = field(default_factory=dict)
    parts_json: dict = field(default_factory=dict)
    units: Units = Units()  # what the transform components are measured against
    # rotational symmetry types every example closes into a full circle: their members
    # are spaced 2 pi / count, whatever count is drawn (angle and count drawn apart left
    # holes and overlaps: 6 spokes at the 8-spoke step); the sampled angle is kept as a
    # choice (the likelihood is unchanged) but not used
    full_rings: list = field(default_factory=list)
    # levels of calls a derivation may take (MAX_DEPTH at least): deep enough for the
    # deepest example (structure.program_depth); a chain of 60 parts had been cut at 41,
    # learned without a word, its program unable to make its own examples
    max_depth: int = MAX_DEPTH
    # floors on the learned standard deviations, per category (log-scale, rotation,
    # translation): what a variable the examples hold constant is sampled with
    # (transforms.SIGMA_FLOOR; a file written before it was stored: the legacy floor)
    sigma_floor: tuple = SIGMA_FLOOR

    # ---- structure helpers -----------------------------------------------------------

    def kind_of_type(self, type_: str) -> str:
        return node_kind(type_)

    def slot_types(self, a: Abstraction) -> list:
        return self.slots.get(a.type, []) if a.kind == "part" else [self.sym_inner[a.type]]

    def xform_key(self, caller: int, slot: int) -> str:
        """Key of the NADE order for the child in (caller abstraction, slot)."""
        if caller == ROOT:
            return "root"
        a = self.abstractions[caller]
        return f"{a.type}#{slot}" if a.kind == "part" else a.type

    def slot_is_part(self, type_: str) -> bool:
        return self.kind_of_type(type_) == "part"

    def complexity(self) -> int:
        """C(P) = |A| + sum over abstractions and slots of |A(a, s)| (+ the root's set)."""
        return len(self.abstractions) + len(self.root_callees) + sum(
            len(c) for a in self.abstractions.values() for c in a.callees)

    def callers_of(self, target: int) -> list:
        """(caller id or ROOT, slot) pairs whose callable set holds ``target``."""
        out = [(ROOT, 0)] if target in self.root_callees else []
        for a in self.abstractions.values():
            for s, callees in enumerate(a.callees):
                if target in callees:
                    out.append((a.id, s))
        return out

    def callee_list(self, caller: int, slot: int) -> list:
        return self.root_callees if caller == ROOT else self.abstractions[caller].callees[slot]

    def prefix(self, caller: int) -> str:
        return "root" if caller == ROOT else str(caller)

    def copy(self) -> "Program":
        other = copy.copy(self)
        other.abstractions = {k: Abstraction(a.id, a.kind, a.type, [list(c) for c in a.callees])
                              for k, a in self.abstractions.items()}
        other.root_callees = list(self.root_callees)
        other.params = {k: v.copy() for k, v in self.params.items()}
        other.info = dict(self.info)
        return other

    def sigma(self, raw: float, category: int) -> float:
        if self.sigma_mode == "fixed":
            return FIXED_SIGMA[category]
        return min(self.sigma_floor[category] + math.exp(min(raw, 50.0)), SIGMA_MAX[category])

    # ---- sampling helpers (plain numpy, one derivation at a time) --------------------

    def callee_dist(self, caller: int, slot: int) -> Categorical:
        ids = self.callee_list(caller, slot)
        probs = _softmax(self.params[f"{self.prefix(caller)}.s{slot}.callee"])
        return Categorical(probs, labels=tuple(ids))


# ---- the rule ------------------------------------------------------------------------------

def _sample_xform(ctx, program: Program, caller: int, slot: int, frame: Frame, part: str) -> np.ndarray:
    pre = f"{program.prefix(caller)}.s{slot}"
    p = program.params
    order = program.orders[program.xform_key(caller, slot)]
    W, c, Vm, bm, Vs, bs = (p[f"{pre}.xf.{k}"] for k in ("W", "c", "Vm", "bm", "Vs", "bs"))
    x = np.zeros(9)
    a = c.copy()
    for i in range(9):
        h = np.tanh(a)
        mu = float(Vm[i] @ h + bm[i])
        dim = order[i]
        sd = program.sigma(float(Vs[i] @ h + bs[i]), CATEGORY[dim])
        v = ctx.sample(f"x.{COMPONENTS[dim]}", Normal(mu, sd))
        x[dim] = v
        a = a + W[:, i] * v
    sW, sc, sV, sb = (p[f"{pre}.sg.{k}"] for k in ("W", "c", "V", "b"))
    signs = np.zeros(3, dtype=bool)
    a = sc.copy()
    for i in range(3):
        h = 1.0 / (1.0 + np.exp(-a))
        prob = _sigmoid(float(sV[i] @ h + sb[i]))
        bit = ctx.sample(f"x.sg{i}", Bernoulli(prob))
        signs[i] = bit
        a = a + sW[:, i] * float(bit)
    with np.errstate(over="ignore", invalid="ignore"):  # said below, in a line of its own
        world = xform_matrix(x, signs, frame, program.units.log_scale(part), program.parts[part].local_bounds(),
                             program.units.anchor(frame.part, part))
    if not np.isfinite(world).all():
        # finite tensors (the load check) can still overflow: a log-scale of 1e6
        raise ProgramError(f"the learned program's transform at {pre} for a {part!r} is not finite (its choices "
                           f"{', '.join(f'x.{COMPONENTS[d]} = {x[d]:.3g}' for d in range(3))}): a derivation edited to "
                           "such log-scales cannot be built (put them back); the program's own samples never reach "
                           "them unless its tensors were not written by 'procmod learn' (then learn it again)")
    return world


def gen_node(ctx, program: Program, caller: int, slot: int, frame: Frame, copies: tuple):
    """Generate one node: pick the abstraction that ``caller`` calls at ``slot``, then run it."""
    a_id = ctx.sample("abs", program.callee_dist(caller, slot))
    a = program.abstractions[a_id]
    p = program.params
    if a.kind == "part":
        world = _sample_xform(ctx, program, caller, slot, frame, a.type)
        shape = program.parts[a.type]
        for g in copies:
            ctx.emit(shape.part(as_transform(np.asarray(g).reshape(4, 4) @ world)))
        if ctx.depth >= program.max_depth:
            return
        lo, hi = shape.local_bounds()
        own = program.units.frame_of(world, lo, hi, a.type)
        for g_index, group in enumerate(program.groups.get(a.type, [])):
            pre = f"{a_id}.g{g_index}"
            W, c, V, b = p[f"{pre}.W"], p[f"{pre}.c"], p[f"{pre}.V"], p[f"{pre}.b"]
            act = c.copy()
            for i, s in enumerate(group):
                h = 1.0 / (1.0 + np.exp(-act))
                prob = _sigmoid(float(V[i] @ h + b[i]))
                on = ctx.maybe(f"s{s}", prob, gen_node, program, a_id, s, own, copies)
                act = act + W[:, i] * float(on)
        return
    # a symmetry node
    pre = f"{a_id}.sym"
    cats = sym_sigma_categories(a.kind)
    values = []
    for k, (name, cat) in enumerate(SYM_PARAMS[a.kind]):
        values.append(ctx.sample(f"sym.{name}", Normal(float(p[f"{pre}.mu"][k]),
                                                        program.sigma(float(p[f"{pre}.rs"][k]), cats[k]))))
    support = program.count_support[a.type]
    count = ctx.sample("count", Categorical(_softmax(p[f"{a_id}.count"]), labels=tuple(support)))
    if a.type in program.full_rings:  # (rings: the canonical rotation angle is positive)
        values[-1] = 2.0 * math.pi / count
    if a.type in program.units.trans_spans:  # the row's span drawn: its step follows from the count
        values[0:3] = [v / max(count - 1, 1) for v in values[0:3]]
    pole = program.units.pole(a.type)
    measured = frame.for_symmetry()  # its parameters' frame (turned by a symmetry holding it)
    maps = sym_maps(a.kind, values, count, measured, pole)
    new_copies = tuple(as_transform(np.asarray(g).reshape(4, 4) @ m) for g in copies for m in maps)
    reference = program.units.sym_turns.get(a.type)
    if reference is not None:  # a symmetry it holds is measured from its direction (preprocess did so)
        frame = frame._replace(measure=turned_frame(measured, reference, symmetry_direction(values, pole)))
    elif frame.measure is not None:
        frame = frame._replace(measure=None)
    if ctx.depth < program.max_depth:
        ctx.spawn("c", gen_node, program, a_id, 0, frame, new_copies)


IDENTITY_COPIES = (as_transform(np.eye(4)),)


def program_root_args(program: Program, params) -> tuple:
    """Root arguments of a learned program's model (a named function, so models pickle)."""
    return (program, ROOT, 0, program.units.world_frame(), IDENTITY_COPIES)


def is_learned(model: Model) -> bool:
    return model.root is gen_node


def program_model(program: Program, name: str) -> Model:
    """The procmod model of a program (``name`` should be the program.json path)."""
    return Model(name=name, description=f"learned program ({len(program.abstractions)} abstractions)",
                 root=gen_node, root_args=partial(program_root_args, program),
                 new_output_from=new_part_bounds, params={}, rules=(gen_node,),
                 choices_doc=__doc__,
                 # a node emits every copy of its symmetry groups in one call (25 x 25
                 # windows: 625); their counts are the program's own, checked when it is
                 # read, so SMC's guard against emit loops that never end does not apply
                 max_resumed_emits=Model.max_call_emits,
                 # samples set on the ground the examples stand on, where they share one
                 settle=None if program.units.ground is None else partial(settle_on_ground, program.units.ground,
                                                                          slope=program.units.world_extent))


# ---- derivations -> example hierarchies -----------------------------------------------------

def derivation_hierarchies(derivation) -> list:
    """The example hierarchies (procmod-examples/1 nodes as dicts) of a learned program's
    derivation: one hierarchy per root copy (normally one)."""
    from ..geometry.part_library import transform_to_json
    from ..geometry.solid import matrix
    nodes = derivation.nodes()
    part_calls = {}
    roots = []
    for node in nodes:
        if not node.geometry:
            continue
        # the nearest ancestor call that emitted parts is the parent part node
        address = node.address
        parent = None
        for k in range(len(address) - 1, -1, -1):
            if address[:k] in part_calls:
                parent = part_calls[address[:k]]
                break
        entries = [{"part": g.tag, "transform": transform_to_json(matrix(g.transform)), "children": []}
                   for g in node.geometry]
        part_calls[address] = entries
        if parent is None:
            roots.extend(entries)
            continue
        per_parent = len(entries) // len(parent)
        for i, e in enumerate(entries):
            parent[i // per_parent]["children"].append(e)
    return roots


# ---- save / load --------------------------------------------------------------------------------

def _tensor_path(json_path: Path) -> Path:
    return json_path.with_name(json_path.stem + ".pt")


def program_to_json(program: Program, tensors_name: str) -> dict:
    return {
        "format": PROGRAM_FORMAT,
        "tensors": tensors_name,
        "parts": program.parts_json,
        "slots": program.slots,
        "groups": program.groups,
        "sym_inner": program.sym_inner,
        "count_support": program.count_support,
        "full_rings": list(program.full_rings),
        "max_depth": int(program.max_depth),
        "sigma_floor": [float(v) for v in program.sigma_floor],
        "orders": {k: list(map(int, v)) for k, v in program.orders.items()},
        "sigma_mode": program.sigma_mode,
        "next_id": program.next_id,
        "root_callees": list(map(int, program.root_callees)),
        "abstractions": [{"id": a.id, "kind": a.kind, "type": a.type,
                          "part_distribution": {a.type: 1.0} if a.kind == "part" else None,
                          "callees": a.callees} for a in sorted(program.abstractions.values(), key=lambda a: a.id)],
        "info": program.info,
        "units": {"world_extent": program.units.world_extent, "conventions": program.units.conventions,
                  "part_log_scales": {k: [float(v) for v in program.units.part_log_scales[k]]
                                      for k in sorted(program.units.part_log_scales)},
                  **({"sym_poles": {k: [list(map(float, row)) for row in program.units.sym_poles[k]]
                                    for k in sorted(program.units.sym_poles)}} if program.units.sym_poles else {}),
                  **({"sym_turns": {k: list(map(float, program.units.sym_turns[k]))
                                    for k in sorted(program.units.sym_turns)}} if program.units.sym_turns else {}),
                  **({"trans_spans": sorted(program.units.trans_spans)} if program.units.trans_spans else {}),
                  **({"anchors": {parent: {child: [None if a is None else list(map(int, a)) for a in axes]
                                           for child, axes in sorted(program.units.anchors[parent].items())}
                                  for parent in sorted(program.units.anchors)}} if program.units.anchors else {}),
                  **({"ground": float(program.units.ground)} if program.units.ground is not None else {}),
                  **({"facing": float(program.units.facing)} if program.units.facing else {})},
        "param_shapes": {k: list(v.shape) for k, v in sorted(program.params.items())},
    }


def save_program(program: Program, out_dir: str | os.PathLike, source_dir: str | os.PathLike | None = None) -> Path:
    """Write ``out_dir/program.json`` and ``out_dir/program.pt`` (a torch state dict),
    copying mesh parts into ``out_dir/parts/``. Both files are written atomically.

    A part's mesh file is named after the part when the name is a plain file name
    (``wing.obj``); any other name (path separators, ``..``, reserved or very long names,
    one that differs from another only in case) gets a safe name of its own
    (:class:`procmod.core.paths.FileNames`), so nothing is written outside ``out_dir`` and
    no part's mesh overwrites another's. ``program.json`` records which file is whose."""
    import torch
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    parts_json = {}
    files = FileNames(".obj", source=str(out_dir / "program.json"), field="part name")
    for name, shape in program.parts.items():
        if shape.kind == "box":
            parts_json[name] = {"box": list(shape.size)}
        else:
            (out_dir / "parts").mkdir(exist_ok=True)
            file = files.name_for(name)
            _write_obj_atomic(out_dir / "parts" / file, shape)
            parts_json[name] = {"mesh": f"parts/{file}"}
    program.parts_json = parts_json
    json_path = out_dir / "program.json"
    pt_path = _tensor_path(json_path)
    state = {k: torch.from_numpy(np.ascontiguousarray(v)) for k, v in sorted(program.params.items())}
    save_tensors(state, pt_path)
    write_text_atomic(json_path, json.dumps(program_to_json(program, pt_path.name), indent=1) + "\n")
    return json_path


def _write_obj_atomic(path: Path, shape) -> None:
    lines = [f"v {x!r} {y!r} {z!r}" for x, y, z in shape.vertices]
    lines += [f"f {a + 1} {b + 1} {c + 1}" for a, b, c in shape.faces]
    write_text_atomic(path, "\n".join(lines) + "\n")


def _fail(path, problem) -> ProgramError:
    return ProgramError(f"{path}: {problem}")


def read_program(path: str | os.PathLike) -> Program:
    """Read a program saved by :func:`save_program` (``program.json`` or its folder)."""
    path = Path(path)
    if path.is_dir():
        path = path / "program.json"
    data = read_versioned_json(path, PROGRAM_FORMAT, ProgramError, "program file",
                               "; give a program.json written by 'procmod learn' or its folder")
    try:
        parts = read_part_library(data["parts"], path.parent)
        program = program_from_json(data, parts)
        shapes = dict(data["param_shapes"])
    except ProcmodError as exc:
        raise _fail(path, str(exc)) from None
    except (KeyError, TypeError, ValueError, AttributeError) as exc:
        raise _fail(path, f"malformed program ({type(exc).__name__}: {exc}); rewrite it with 'procmod learn'") from None
    try:  # procmod writes the tensors beside program.json; nothing else is read
        pt_path = named_file(path.parent, data.get("tensors", "program.pt"), f"{path}: tensors", {".pt"},
                             "tensors", same_folder=True)
    except UnsafePathError as exc:
        raise ProgramError(str(exc)) from None
    state = load_tensors(pt_path, ProgramError, f"tensors file {pt_path.name}", source=str(path))
    if not isinstance(state, dict):
        raise _fail(path, f"tensors: {pt_path.name} is not a tensors file written by 'procmod learn' "
                          f"(it holds a {type(state).__name__}, not named tensors)")
    for key, shape in shapes.items():
        if key not in state or not hasattr(state[key], "numpy") or list(state[key].shape) != list(shape):
            raise _fail(path, f"tensor {key!r} is missing from {pt_path.name} or has the wrong shape")
        program.params[key] = state[key].numpy().astype(np.float64)
    _check_program(program, path)
    return program


def _whole(value) -> int:
    """An id, slot or count from the JSON: a whole number (int() truncated callee 0.9 to 0)."""
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value):
        raise ValueError(f"expected a whole number, got {shown_value(value, 40)}")
    return int(value)


def program_from_json(data: dict, parts: dict) -> Program:
    """The structure of a program from its JSON (parameters are filled in separately)."""
    abstractions = {}
    for entry in data["abstractions"]:
        callees = entry["callees"]
        if not isinstance(callees, list) or not all(isinstance(c, list) for c in callees):
            raise ProgramError(f"abstraction {shown_value(entry.get('id'), 20)}'s callees are {shown_value(callees)}, "
                               "but they are a list per slot of the abstractions it may call ([[3, 4], [5]]); "
                               "rewrite it with 'procmod learn'")
        a = Abstraction(_whole(entry["id"]), str(entry["kind"]), str(entry["type"]),
                        [[_whole(i) for i in c] for c in entry["callees"]])
        # written for the reader's sake: an abstraction draws its one part type (seed 000's
        # programs learn no mixture of parts), so an edit of it would be ignored without a word
        drawn = entry.get("part_distribution")
        if drawn is not None and not (a.kind == "part" and isinstance(drawn, dict) and list(drawn) == [a.type]
                                      and drawn[a.type] == 1):
            raise ProgramError(f"abstraction {a.id}'s part_distribution is {shown_value(drawn)}, but an abstraction "
                               f"always draws its one part, its type {a.type!r}: a learned program has no mixture of "
                               "parts to edit (to draw another part, change both its 'type' and its part_distribution "
                               "to that part)")
        abstractions[a.id] = a
    return Program(parts=parts, slots={k: list(v) for k, v in data["slots"].items()},
                   groups={k: [list(map(_whole, g)) for g in v] for k, v in data["groups"].items()},
                   sym_inner=dict(data["sym_inner"]),
                   count_support={k: list(map(_whole, v)) for k, v in data["count_support"].items()},
                   full_rings=_full_rings_from_json(data.get("full_rings") or [], data),
                   max_depth=_max_depth_from_json(data.get("max_depth", MAX_DEPTH)),
                   sigma_floor=_sigma_floor_from_json(data.get("sigma_floor", LEGACY_SIGMA_FLOOR)),
                   orders={k: list(map(_whole, v)) for k, v in data["orders"].items()},
                   abstractions=abstractions, root_callees=[_whole(i) for i in data["root_callees"]],
                   sigma_mode=_sigma_mode_from_json(data.get("sigma_mode", "free")), next_id=_whole(data["next_id"]),
                   info=dict(data.get("info", {})), parts_json=data.get("parts", {}),
                   units=_units_from_json(data.get("units", _NO_UNITS)))


_NO_UNITS = object()


SIGMA_MODES = ("free", "fixed")


def _sigma_mode_from_json(value) -> str:
    """A program file's ``sigma_mode``: "free" or "fixed" (anything else had been taken
    for "free" without a word, a hand edit meant to fix the spreads silently ignored)."""
    if value not in SIGMA_MODES:
        raise ProgramError(f"sigma_mode is {shown_value(value)}, but it is one of {', '.join(map(repr, SIGMA_MODES))} "
                           "(\"fixed\": every spread at its fixed value); correct it or rewrite it with 'procmod "
                           "learn'")
    return value


def _sigma_floor_from_json(value) -> tuple:
    """A program file's ``sigma_floor`` (absent in programs learned before it was stored:
    the legacy floor they were learned with), checked: three positive lengths, each under
    its category's cap (a floor of 0 would make a constant variable's density infinite)."""
    if (not isinstance(value, (list, tuple)) or len(value) != 3
            or not all(_is_real(v) and 0 < v < cap for v, cap in zip(value, SIGMA_MAX))):
        raise ValueError(f"sigma_floor must be three positive standard deviations (log-scale, rotation, "
                         f"translation) under {', '.join(f'{c:g}' for c in SIGMA_MAX)}, got {shown_value(value, 60)}")
    return tuple(float(v) for v in value)

MAX_PROGRAM_DEPTH = 5000  # of a program file's max_depth: under the runtime's own limit (Model.max_depth)


def _max_depth_from_json(value) -> int:
    """A program's ``max_depth`` (files written before it was kept: :data:`MAX_DEPTH`)."""
    depth = _whole(value)
    if not MAX_DEPTH <= depth <= MAX_PROGRAM_DEPTH:
        raise ProgramError(f"max_depth must be a whole number from {MAX_DEPTH} to {MAX_PROGRAM_DEPTH}, got "
                           f"{shown_value(value)}")
    return depth


def _full_rings_from_json(value, data) -> list:
    """A program file's ``full_rings`` (absent in programs learned before it: none),
    checked: rotational symmetry types of its own."""
    rot_types = sorted(t for t in data.get("count_support", {}) if str(t).startswith("rot("))
    if not isinstance(value, list) or not all(isinstance(t, str) and t in rot_types for t in value):
        known = ", ".join(rot_types) or "none"
        raise ProgramError(f"full_rings must list rotational symmetry types of the program ({known}), got "
                           f"{shown_value(value, 60)}")
    return list(value)


# What a program's units may hold: lengths and scales within what examples may hold
# (coordinates up to core.limits.MAX_COORDINATE: a diagonal or an axis's scale up to
# sqrt(3) of it); a reference scale of e^700 sampled NaN and 1e304s, one of e^-700 an SVD
# that did not converge.
MAX_UNIT_LENGTH = 4 * MAX_COORDINATE
MAX_LOG_SCALE = math.log(MAX_UNIT_LENGTH)


def _units_from_json(data) -> Units:
    """A program's units. Absent: written before units existed, learned with extent 1, no
    reference scales and the old floor for flat parts (``Units()``). Present: the units
    ``preprocess`` found, flat parts measured by their size. Checked: anything but a
    positive length and three finite log-scales per part raises ValueError, which the
    readers report as a malformed program."""
    if data is _NO_UNITS:
        return Units()
    if not isinstance(data, dict) or not isinstance(data.get("part_log_scales"), dict):
        raise ValueError(f"units must be an object with world_extent and part_log_scales, got {shown_value(data, 60)}")
    extent = data.get("world_extent")
    if not _is_real(extent) or not 0 < extent <= MAX_UNIT_LENGTH:
        raise ValueError(f"units.world_extent must be a positive length up to {MAX_UNIT_LENGTH:g}, "
                         f"got {shown_value(extent, 40)}")
    logs = {}
    for part, values in data["part_log_scales"].items():
        if not isinstance(values, list) or len(values) != 3 or not all(_is_real(v) and abs(v) <= MAX_LOG_SCALE
                                                                          for v in values):
            raise ValueError(f"units.part_log_scales[{part!r}] must be three log-scales within +-{MAX_LOG_SCALE:.1f} "
                             f"(scales of 1/{MAX_UNIT_LENGTH:g} to {MAX_UNIT_LENGTH:g}), got {shown_value(values, 60)}")
        logs[part] = tuple(float(v) for v in values)
    # required: units without it were written only by development commits of this change,
    # whose programs took directions' angles about z (and are not CURRENT)
    conventions = data.get("conventions")
    if conventions not in (LEGACY, CURRENT) or isinstance(conventions, bool):
        raise ValueError(f"units.conventions must be {LEGACY} or {CURRENT}, got {shown_value(conventions, 20)}")
    poles = {}
    given = data.get("sym_poles", {})  # absent: every type takes the default pole
    if not isinstance(given, dict):
        raise ValueError(f"units.sym_poles must be an object of symmetry type -> 3x3 rotation, got "
                         f"{shown_value(given, 60)}")
    for sym_type, rows in given.items():
        matrix = np.array(rows, dtype=np.float64) if isinstance(rows, list) and all(
            isinstance(r, list) and len(r) == 3 and all(_is_real(v) for v in r) for r in rows) else None
        if matrix is None or matrix.shape != (3, 3) or not np.allclose(matrix.T @ matrix, np.eye(3), atol=1e-9) \
                or np.linalg.det(matrix) < 0:
            raise ValueError(f"units.sym_poles[{sym_type!r}] must be a 3x3 rotation (three rows of three numbers), "
                             f"got {shown_value(rows, 60)}")
        poles[sym_type] = tuple(tuple(float(v) for v in row) for row in matrix)
    turns = {}
    given = data.get("sym_turns", {})  # absent: no symmetry turns the frame of the one it holds
    if not isinstance(given, dict):
        raise ValueError(f"units.sym_turns must be an object of symmetry type -> direction, got "
                         f"{shown_value(given, 60)}")
    for sym_type, direction in given.items():
        if not isinstance(direction, list) or len(direction) != 3 or not all(_is_real(v) for v in direction) \
                or not abs(float(np.linalg.norm(direction)) - 1.0) < 1e-6:
            raise ValueError(f"units.sym_turns[{sym_type!r}] must be a unit direction (three numbers), got "
                             f"{shown_value(direction, 60)}")
        turns[sym_type] = tuple(float(v) for v in direction)
    spans = data.get("trans_spans", [])  # absent: every translation symmetry draws its step
    if not isinstance(spans, list) or not all(isinstance(t, str) for t in spans):
        raise ValueError(f"units.trans_spans must be a list of translation symmetry types, got {shown_value(spans, 60)}")
    anchors = {}
    given = data.get("anchors", {})  # absent: every translation between the frames' origins
    if not isinstance(given, dict) or not all(isinstance(v, dict) for v in given.values()):
        raise ValueError(f"units.anchors must be an object of parent part -> child part -> three anchors, got "
                         f"{shown_value(given, 60)}")
    for parent, children in given.items():
        for child, axes in children.items():
            if not isinstance(axes, list) or len(axes) != 3 or not all(
                    a is None or (isinstance(a, list) and len(a) in (2, 3) and all(
                        isinstance(v, int) and not isinstance(v, bool) and v in ANCHOR_SIDES for v in a[:2])
                        and (len(a) == 2 or (type(a[2]) is int and a[2] == 1)))
                    for a in axes):
                raise ValueError(f"units.anchors[{parent!r}][{child!r}] must be three entries, each null, [a, b] or "
                                 f"[a, b, 1] with a and b -1, 0 or 1, got {shown_value(axes, 60)}")
            anchors.setdefault(parent, {})[child] = tuple(None if a is None else tuple(a) for a in axes)
    ground = data.get("ground")  # absent: the examples share no ground (or predate it)
    if ground is not None and not (_is_real(ground) and abs(ground) <= MAX_UNIT_LENGTH):
        raise ValueError(f"units.ground must be a height within +-{MAX_UNIT_LENGTH:g} or absent, got "
                         f"{shown_value(ground, 40)}")
    facing = data.get("facing", 0.0)  # absent: learned facing the world's axes (or before facing was kept)
    if not (_is_real(facing) and abs(facing) <= math.pi + 1e-9):
        raise ValueError(f"units.facing must be an angle within +-pi (radians about the up axis) or absent, got "
                         f"{shown_value(facing, 40)}")
    return Units(float(extent), logs, conventions, poles, turns, tuple(sorted(set(spans))), anchors,
                 None if ground is None else float(ground), float(facing))


MAX_COUNT = 10_000  # members of one symmetry group a program may draw


def _check_program(program: Program, path) -> None:
    try:
        _check_structure(program, path)
        _check_references(program, path)
    except ProgramError:
        raise
    except (KeyError, IndexError, TypeError, ValueError, AttributeError) as exc:
        raise _fail(path, f"malformed program ({type(exc).__name__}: {exc}); rewrite it with 'procmod learn'") from None


def _check_references(program: Program, path) -> None:
    """Everything sampling looks up exists and fits: a hand-edited program failed only
    when a sample reached the edit (a KeyError or IndexError traceback), or sampled
    nonsense (a count below 2, a slot calling an abstraction of another type)."""
    p = program.params
    unknown = sorted((set(program.units.part_log_scales) | set(program.units.anchors)
                      | {c for children in program.units.anchors.values() for c in children}) - set(program.parts))
    if unknown:
        raise _fail(path, f"units name part {unknown[0]!r}, which the program's parts do not hold")
    rows = {a.type for a in program.abstractions.values() if a.kind == "trans"}
    unknown = sorted(set(program.units.trans_spans) - rows)
    if unknown:  # (another kind's parameters would be divided by its count, without a word: h90)
        raise _fail(path, f"units.trans_spans names {unknown[0]!r}, which is no translation symmetry type of the "
                          "program; it lists the types whose span is drawn (learn again)")

    def need(key: str, size: int | None = None) -> None:
        if key not in p:
            raise _fail(path, f"tensor {key!r} is missing; it was not written by 'procmod learn' (learn again)")
        if size is not None and p[key].shape[0] != size:
            raise _fail(path, f"tensor {key!r} has {p[key].shape[0]} entries where the program has {size}")

    calls = [(ROOT, 0, program.root_callees, None)]
    for a in program.abstractions.values():
        types = program.slot_types(a)
        calls += [(a.id, s, callees, types[s]) for s, callees in enumerate(a.callees)]
        if a.kind == "part":
            if a.type not in program.parts:
                raise _fail(path, f"abstraction {a.id} draws part {a.type!r}, which the program's parts do not hold")
            used = [s for group in program.groups.get(a.type, []) for s in group]
            if len(set(used)) != len(used) or not all(isinstance(s, int) and 0 <= s < len(a.callees) for s in used):
                raise _fail(path, f"groups[{a.type!r}] must name each of the type's slots at most once")
            for g in range(len(program.groups.get(a.type, []))):
                for k in ("W", "c", "V", "b"):
                    need(f"{a.id}.g{g}.{k}")
        else:
            if a.kind not in SYM_PARAMS:
                raise _fail(path, f"abstraction {a.id} is of an unknown kind {a.kind!r}")
            support = program.count_support.get(a.type)
            if not isinstance(support, list) or not support or not all(
                    isinstance(c, int) and not isinstance(c, bool) and 2 <= c <= MAX_COUNT for c in support):
                raise _fail(path, f"count_support[{a.type!r}] must list member counts from 2 to {MAX_COUNT:,}, "
                                  f"got {shown_value(support, 60)}")
            need(f"{a.id}.count", len(support))
            need(f"{a.id}.sym.mu", len(SYM_PARAMS[a.kind]))
            need(f"{a.id}.sym.rs", len(SYM_PARAMS[a.kind]))
    for caller, slot, callees, wanted in calls:
        need(f"{program.prefix(caller)}.s{slot}.callee", len(callees))
        for c in callees:
            callee = program.abstractions[c]
            if wanted is not None and callee.type != wanted:
                raise _fail(path, f"abstraction {caller} slot {slot} (of type {wanted!r}) calls abstraction {c} of "
                                  f"type {callee.type!r}")
            if callee.kind == "part":
                key = program.xform_key(caller, slot)
                if key not in program.orders:
                    raise _fail(path, f"orders[{key!r}] is missing")
                pre = f"{program.prefix(caller)}.s{slot}"
                for k in ("W", "c", "Vm", "bm", "Vs", "bs"):
                    need(f"{pre}.xf.{k}")
                for k in ("W", "c", "V", "b"):
                    need(f"{pre}.sg.{k}")


def _check_structure(program: Program, path) -> None:
    for key, order in program.orders.items():
        if sorted(order) != list(range(len(COMPONENTS))):
            raise _fail(path, f"orders[{key!r}] must be an ordering of 0..{len(COMPONENTS) - 1}, got {order}")
    for key, value in program.params.items():
        # biases are in the examples' units (a table modelled in micrometres: 1e7); a
        # file of 1e300s or NaN was not learned, and sampled NaN probabilities
        if not np.isfinite(value).all() or np.abs(value).max(initial=0.0) > 1e15:
            raise _fail(path, f"tensor {key!r} holds NaN, infinity or values beyond 1e15; it was not written "
                              "by 'procmod learn' (learn again)")
    ids = set(program.abstractions)
    for a in program.abstractions.values():
        if len(a.callees) != len(program.slot_types(a)):
            raise _fail(path, f"abstraction {a.id} has {len(a.callees)} slots, its type {len(program.slot_types(a))}")
        for s, callees in enumerate(a.callees):
            if not callees or not set(callees) <= ids:
                raise _fail(path, f"abstraction {a.id} slot {s} calls unknown abstractions {callees}")
    if not program.root_callees or not set(program.root_callees) <= ids:
        raise _fail(path, "the root calls no (or unknown) abstractions")


def example_choice_map(program: Program, data, root: int, assignment: dict) -> dict:
    """The choice map under which the program's model regenerates one preprocessed example.

    ``assignment`` maps node id -> abstraction id (it must be type-correct and allowed by
    the callable sets). Replaying the model under this map reproduces the example's parts
    exactly, and its log-prior is log p(example, assignment | P).
    """
    from .transforms import SYM_PARAMS as _SP
    choices = {}

    def visit(node, address):
        choices[(address, "abs")] = int(assignment[node.id])
        if node.kind == "part":
            for k, name in enumerate(COMPONENTS):
                choices[(address, f"x.{name}")] = float(node.x[k])
            for k in range(3):
                choices[(address, f"x.sg{k}")] = bool(node.signs[k])
            for s in range(len(program.slots.get(node.type, []))):
                choices[(address, f"s{s}")] = bool(node.used[s])
            for s, child in node.children:
                visit(child, address + (f"s{s}",))
        else:
            for k, (name, _) in enumerate(_SP[node.kind]):
                choices[(address, f"sym.{name}")] = float(node.sym[k])
            choices[(address, "count")] = int(node.count)
            visit(node.children[0][1], address + ("c",))

    visit(data.nodes[root], ())
    return choices
