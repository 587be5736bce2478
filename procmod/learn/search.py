"""Structure search (seed 000 section 6.2) with particle filtering and checkpoints.

One search (a *particle*) holds a program, its objective
``O_D = log p(D | P) - lambda C(P)`` (lambda = 1), a queue of abstractions to try to
split (ordered by how many example nodes each generates, most first) and the set of
rejected ones. A step pops the first abstraction, splits it (:func:`structure.split`),
re-optimises (warm-up steps with the tie-breaking bias, then plain steps), snaps, and
accepts when O_D rises. On acceptance both copies go back into the queue, and every
rejected abstraction that can call one of them is re-queued.

Phases, in lockstep across particles: (1) ``discrete`` — the likelihood has only the
discrete variables; (2) ``fixed`` — all variables, standard deviations fixed to
(log 1.1, pi/8, 0.2), and only abstractions whose least probable Gaussian variable
(``exp(-z^2/2)`` at the MAP assignment) is below tau_gauss = exp(-1) are queued;
(3) a final pass frees the standard deviations. After every round (one proposal per
particle) the particles are resampled by ``exp(O_D)`` (systematic resampling); particles
whose queue is empty wait for the others. The best final particle wins.

Every round's tasks run through :func:`procmod.parallel.open_executor` (inline, a local
process pool, or dask); each task is a module-level function with its own seed, so the
result does not depend on where it ran. After every round the state is checkpointed in
``DIR/checkpoint/`` (JSON + a torch state dict, written atomically); a killed run
started again with the same examples and options resumes from the last round.
"""

from __future__ import annotations

import functools
import hashlib
import json
import math
import shutil
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path

import numpy as np

from ..core.errors import InvalidArgumentError, ProcmodError, argument, plain_fields
from ..core.io import load_tensors, read_versioned_json, save_tensors, write_text_atomic
from ..core.paths import named_file
from ..core.random import resample
from .examples import ExampleSet
from .likelihood import Compiled, fit, log_likelihood, pooled_slot_target, sigmas_from_residuals
from .preprocessing import Dataset, fixed_runs, preprocess
from .program import Program, program_from_json, program_to_json
from ..parallel import InlineExecutor as _Inline
from .structure import TAU_SNAP, initial_program, snap, split, unroll

# /3: transform components measured in the examples' units, directions' angles about the
# diagonal (a /1 checkpoint's programs were neither; /2 was a development step)
CHECKPOINT_FORMAT = "procmod-learn-checkpoint/3"
TAU_GAUSS = math.exp(-1)


class LearnError(ProcmodError):
    """A learning run that cannot start or resume; the message says why."""


@dataclass
class SearchOptions:
    """Knobs of the structure search (defaults are what ``procmod learn`` uses).

    ``init_iterations`` Adam steps set P0 and start phase 2 (the paper: 500);
    ``split_iterations`` re-optimise after a split (the paper: 500, from scratch; we warm
    start from the pre-split parameters, see docs/learn.md); ``warm_iterations`` of them
    carry the tie-breaking bias; ``final_iterations`` free the sigmas at the end.
    ``slot_prior`` is the pseudo-count of the prior that shrinks slot-use probabilities
    towards the pooled ones, each part type's frequencies in the examples
    (:func:`likelihood.fit`, :func:`likelihood.pooled_slot_target`; 0: maximum likelihood, as the
    paper); it enters only the final pass and the free-sigma fit of the phase-1 program,
    not the fits that decide splits.
    ``share_fits``: particles whose tasks have identical inputs (resampled
    copies making the same split) run one fit and share its result; with the exact
    estimator the result is the same as running each (VI never shares: its fits draw
    random numbers from per-particle seeds).
    """

    particles: int = 4
    seed: int = 0
    lam: float = 1.0
    tau_snap: float = TAU_SNAP
    tau_gauss: float = TAU_GAUSS
    init_iterations: int = 200
    split_iterations: int = 100
    warm_iterations: int = 25
    final_iterations: int = 300
    lr: float = 0.05
    estimator: str = "exact"
    max_rounds: int = 400
    slot_prior: float = 2.0
    share_fits: bool = True

    def check(self) -> "SearchOptions":
        plain_fields(self)  # numpy's numbers as Python's: options go into JSON
        if self.particles < 1:
            raise InvalidArgumentError(f"{argument('particles')} must be at least 1, got {self.particles}")
        if self.particles > MAX_SEARCH_PARTICLES:
            raise InvalidArgumentError(f"{argument('particles')} {self.particles:,} is more structure searches than "
                                       f"one run holds (at most {MAX_SEARCH_PARTICLES:,}; the paper uses 4-8)")
        if self.estimator not in ("exact", "vi"):
            raise InvalidArgumentError(f"estimator must be 'exact' or 'vi', got {self.estimator!r}")
        for name in ("init_iterations", "split_iterations", "final_iterations", "max_rounds"):
            if getattr(self, name) < 1:
                raise InvalidArgumentError(f"{name} must be positive, got {getattr(self, name)}")
        if not (self.slot_prior >= 0 and math.isfinite(self.slot_prior)):
            raise InvalidArgumentError(f"slot_prior must be a finite number >= 0, got {self.slot_prior}")
        return self


# Parallel structure searches one run may hold: each keeps a program and its tensors
# (seed 000 runs 4-8; a million would only exhaust memory before the first round ends).
MAX_SEARCH_PARTICLES = 10_000


@dataclass
class Particle:
    program: Program
    objective: float
    loglik: float
    usage: dict  # abstraction id -> expected number of nodes it generates
    queue: list = field(default_factory=list)
    rejected: list = field(default_factory=list)
    done: bool = False
    trace: list = field(default_factory=list)
    cpu: float = 0.0  # CPU seconds of the last task run on this particle


def _objective(ll: float, program: Program, lam: float) -> float:
    return ll - lam * program.complexity()


def _responsibilities(program: Program, data: Dataset, mode: str):
    comp = Compiled(program, data, mode)
    return comp.responsibilities(), comp.ids


def _usage_order(ids: list, usage: dict) -> list:
    return sorted(ids, key=lambda a: (-usage.get(a, 0.0), a))


def _seed(*parts) -> int:
    return int.from_bytes(hashlib.sha256(repr(parts).encode()).digest()[:8], "little")


def _single_threaded(task):
    """Run a task with one torch thread (deterministic sums, no oversubscription of the
    pool's processes), restoring the caller's setting afterwards (inline executors)."""
    @functools.wraps(task)
    def wrapper(*args, **kwargs):
        import torch
        before = torch.get_num_threads()
        torch.set_num_threads(1)
        try:
            return task(*args, **kwargs)
        finally:
            torch.set_num_threads(before)
    return wrapper


# ---- tasks (module-level, picklable arguments) -------------------------------------------

@_single_threaded
def task_initial(data: Dataset, options: SearchOptions) -> dict:
    """P0, fitted on the discrete likelihood (the search start)."""
    start, cpu0 = time.perf_counter(), time.process_time()
    rng = np.random.default_rng(_seed(options.seed, "P0"))
    p0 = initial_program(data, rng)
    fit(p0, data, "discrete", options.init_iterations, lr=options.lr, estimator=options.estimator,
        seed=_seed(options.seed, "P0fit"))
    resp, ids = _responsibilities(p0, data, "discrete")
    ll = log_likelihood(p0, data, "discrete")
    usage = dict(zip(ids, resp.sum(0).tolist()))
    return {"p0": p0, "loglik": ll, "usage": usage,
            "seconds": time.perf_counter() - start, "cpu": time.process_time() - cpu0}


@_single_threaded
def task_free_copy(program: Program, data: Dataset, options: SearchOptions, seed: int, slot_target=None) -> dict:
    """A copy of ``program`` with all parameters fitted, sigmas free (for Table 1 and the
    figure-6 samples of P0 and of the phase-1 program; runs beside the search)."""
    cpu0 = time.process_time()
    full = program.copy()
    r = fit(full, data, "free", options.final_iterations, lr=options.lr, estimator=options.estimator,
            slot_prior=options.slot_prior, slot_target=slot_target,
            ramp=options.final_iterations // 10, seed=seed)
    return {"program": full, "loglik": r["log_likelihood"], "cpu": time.process_time() - cpu0}


@_single_threaded
def prepare_step(particle: Particle, data: Dataset, mode: str, seed: int):
    """Pop the particle's next split target and make the split (cheap: no fitting).

    Returns ``(target, proposal, a2, bias)`` or None when the queue is empty. The driver
    calls it before submitting :func:`task_step`, so that particles that would make the
    same proposal (resampled copies of one program choosing the same partition) share
    one fit instead of repeating it."""
    program = particle.program
    while particle.queue and particle.queue[0] not in program.abstractions:
        particle.queue.pop(0)
    if not particle.queue:
        return None
    target = particle.queue.pop(0)
    rng = np.random.default_rng(seed)
    resp, ids = _responsibilities(program, data, mode)
    proposal, a2, bias = split(program, target, data, resp, ids, rng, continuous=mode != "discrete")
    return target, proposal, a2, bias


@_single_threaded
def task_step(particle: Particle, data: Dataset, options: SearchOptions, mode: str, seed: int,
              slot_target=None, prepared=None) -> Particle:
    """One split proposal of one particle (``slot_target``: the slot prior's, see
    :func:`likelihood.pooled_slot_target`; ``prepared``: what :func:`prepare_step`
    returned for this particle and seed, when the driver already called it)."""
    start, cpu0 = time.perf_counter(), time.process_time()
    if prepared is None:
        prepared = prepare_step(particle, data, mode, seed)
    if prepared is None:
        particle.done = True
        particle.cpu = time.process_time() - cpu0
        return particle
    target, proposal, a2, bias = prepared

    def evaluate(proposal, copies, bias):
        fit(proposal, data, mode, options.split_iterations, lr=options.lr, estimator=options.estimator,
            slot_prior=options.slot_prior, slot_target=slot_target,
            seed=seed, warm_bias=bias, warm_iterations=options.warm_iterations)
        resp2, ids2 = _responsibilities(proposal, data, mode)
        snapped = snap(proposal, data, resp2, ids2, options.tau_snap)
        ll = log_likelihood(snapped, data, mode)
        objective = _objective(ll, snapped, options.lam)
        # a split that snapping undid (one of the copies dropped) changes no structure: it is
        # only a refit of the current program, so it is not accepted (accepting it re-queued
        # the same abstraction for another no-op round)
        survived = all(a in snapped.abstractions for a in copies)
        return snapped, ll, objective, survived, survived and objective > particle.objective + 1e-9

    copies = [target, a2]
    snapped, ll, objective, survived, accepted = evaluate(proposal, copies, bias)
    unrolled = None
    if mode == "discrete" and fixed_runs(data):  # (else no unroll: nothing more is fitted)
        # a run every example repeats the same number of times: try one copy per step
        # (structure.unroll), which no sequence of two-way splits reaches uphill, and keep
        # the better of the two proposals. Tried only after a rejected split, it was never
        # tried where the split itself rose (a body of 3 links each with a tail of 2: the
        # split that separated the body's links scored higher than P0), and once the split
        # was in, the abstraction no longer called only itself, so the body's count stayed
        # a recursion (samples of 2-5 links)
        resp, ids = _responsibilities(particle.program, data, mode)
        made = unroll(particle.program, target, data, resp, ids)
        if made is not None:
            unrolled = made[1]
            result = evaluate(*made)
            unroll_proposed = round(result[2], 4)
            if result[4] and (not accepted or result[2] > objective + 1e-9):
                snapped, ll, objective, survived, accepted = result
                copies = unrolled
    row = {"phase": mode, "split": target, "accepted": bool(accepted), "proposed": round(objective, 4),
           "loglik_proposed": round(ll, 4), "complexity_proposed": snapped.complexity(),
           "abstractions_proposed": len(snapped.abstractions), "split_survived": bool(survived), "seconds": round(time.perf_counter() - start, 3)}
    if unrolled is not None:
        row["unrolled"] = len(unrolled)
        row["unroll_proposed"] = unroll_proposed
        row["unroll_accepted"] = bool(accepted and copies is unrolled)
    if accepted:
        resp3, ids3 = _responsibilities(snapped, data, mode)
        particle.program, particle.objective, particle.loglik = snapped, objective, ll
        particle.usage = dict(zip(ids3, resp3.sum(0).tolist()))
        new = [a for a in copies if a in snapped.abstractions]
        requeue = [b for b in particle.rejected if b in snapped.abstractions and
                   any(a in c for c in snapped.abstractions[b].callees for a in new)]
        particle.rejected = [b for b in particle.rejected if b not in requeue]
        pending = [a for a in particle.queue if a in snapped.abstractions]
        particle.queue = _usage_order(sorted(set(pending + new + requeue)), particle.usage)
    else:
        particle.rejected.append(target)
    row.update(objective=round(particle.objective, 4), abstractions=len(particle.program.abstractions),
               complexity=particle.program.complexity())
    particle.trace.append(row)
    particle.done = not particle.queue
    particle.cpu = time.process_time() - cpu0
    return particle


def gaussian_filter(program: Program, data: Dataset, tau: float) -> dict:
    """Abstraction id -> its least probable Gaussian variable, ``exp(-z^2 / 2)`` with the
    phase-2 fixed sigmas, over the nodes it generates (MAP assignment)."""
    comp = Compiled(program, data, "fixed")
    resp = comp.responsibilities()
    _, _, zinfo = comp.local_table(want_z=True)
    lowest = {a: 1.0 for a in comp.ids}
    for nodes, cols, zsq in zinfo:
        nodes, cols, zsq = nodes.numpy(), cols.numpy(), zsq.numpy()
        for n, c, z in zip(nodes, cols, zsq.max(1)):
            if resp[n, c] > 0.5:
                a = comp.ids[c]
                lowest[a] = min(lowest[a], math.exp(-0.5 * float(z)))
    return lowest


@_single_threaded
def task_phase(particle: Particle, data: Dataset, options: SearchOptions, phase: str, seed: int,
               slot_target=None) -> Particle:
    """Start phase 2 (``"fixed"``) or run the final pass (``"free"``) for one particle."""
    start, cpu0 = time.perf_counter(), time.process_time()
    program = particle.program.copy()
    iterations = options.init_iterations if phase == "fixed" else options.final_iterations
    if phase == "free":
        sigmas_from_residuals(program, data)
    fit(program, data, phase, iterations, lr=options.lr, estimator=options.estimator, seed=seed,
        slot_prior=options.slot_prior, slot_target=slot_target,
        ramp=options.final_iterations // 10 if phase == "free" else 0)
    ll = log_likelihood(program, data, phase)
    particle.program, particle.loglik = program, ll
    particle.objective = _objective(ll, program, options.lam)
    resp, ids = _responsibilities(program, data, phase)
    particle.usage = dict(zip(ids, resp.sum(0).tolist()))
    particle.rejected = []
    if phase == "fixed":
        lowest = gaussian_filter(program, data, options.tau_gauss)
        particle.queue = _usage_order([a for a, v in lowest.items() if v < options.tau_gauss], particle.usage)
    else:
        particle.queue = []
    particle.done = not particle.queue
    particle.trace.append({"phase": phase, "start": True, "objective": round(particle.objective, 4),
                           "loglik": round(ll, 4), "queued": list(particle.queue),
                           "abstractions": len(program.abstractions), "complexity": program.complexity(),
                           "seconds": round(time.perf_counter() - start, 3)})
    particle.cpu = time.process_time() - cpu0
    return particle


# ---- checkpoints -----------------------------------------------------------------------------

def _program_state(program: Program, prefix: str, tensors: dict) -> dict:
    import torch
    for k, v in program.params.items():
        tensors[f"{prefix}/{k}"] = torch.from_numpy(np.ascontiguousarray(v))
    return program_to_json(program, "")


def _program_from_state(state: dict, prefix: str, tensors: dict, parts: dict) -> Program:
    program = program_from_json(state, parts)
    for key in state["param_shapes"]:
        program.params[key] = tensors[f"{prefix}/{key}"].numpy().astype(np.float64)
    return program


def save_checkpoint(folder: Path, state: dict) -> None:
    folder.mkdir(parents=True, exist_ok=True)
    tensors = {}
    doc = {k: v for k, v in state.items() if k not in ("particles", "programs")}
    doc["format"] = CHECKPOINT_FORMAT
    doc["programs"] = {name: _program_state(p, f"prog.{name}", tensors) for name, p in state["programs"].items()}
    doc["particles"] = []
    for k, part in enumerate(state["particles"]):
        doc["particles"].append({"program": _program_state(part.program, f"part{k}", tensors),
                                 "objective": part.objective, "loglik": part.loglik,
                                 "usage": {str(a): u for a, u in part.usage.items()},
                                 "queue": part.queue, "rejected": part.rejected, "done": part.done,
                                 "trace": part.trace})
    name = f"tensors_{state['round']:05d}.pt"
    save_tensors(tensors, folder / name)
    doc["tensors"] = name
    write_text_atomic(folder / "state.json", json.dumps(doc) + "\n")
    for old in folder.glob("tensors_*.pt"):
        if old.name != name:
            old.unlink()


def load_checkpoint(folder: Path, parts: dict) -> dict | None:
    path = folder / "state.json"
    if not path.exists():
        return None
    try:
        doc = read_versioned_json(path, CHECKPOINT_FORMAT, LearnError)
        # written beside state.json by save_checkpoint; a name that leads elsewhere is refused
        tensors = load_tensors(named_file(folder, doc["tensors"], "tensors", {".pt"}, "tensors", same_folder=True),
                               LearnError)
        _check_state(doc)
        programs = {name: _program_from_state(s, f"prog.{name}", tensors, parts)
                    for name, s in doc["programs"].items()}
        particles = []
        for k, p in enumerate(doc["particles"]):
            particles.append(Particle(_program_from_state(p["program"], f"part{k}", tensors, parts),
                                      p["objective"], p["loglik"], {int(a): u for a, u in p["usage"].items()},
                                      list(p["queue"]), list(p["rejected"]), bool(p["done"]), list(p["trace"])))
    except (OSError, ValueError, KeyError, TypeError, AttributeError, IndexError, RuntimeError, ProcmodError) as exc:
        raise LearnError(f"cannot resume from {folder}: {exc}; delete that folder to start afresh") from None
    doc["programs"], doc["particles"] = programs, particles
    return doc


_PHASES = ("discrete", "fixed", "free", "finished")


def _check_state(doc: dict) -> None:
    """The fields of a checkpoint the search reads, of the kinds save_checkpoint writes
    (a hand-edited one ended in a traceback mid-run: KeyError 'zzz', max() of nothing, a
    report written again and then a TypeError); a ValueError naming the first that is not."""
    def kind(key, types, what):
        if not isinstance(doc.get(key), types) or isinstance(doc.get(key), bool):
            raise ValueError(f"its {key!r} is not {what}")

    kind("phase", str, "a phase")
    if doc["phase"] not in _PHASES:
        raise ValueError(f"its 'phase' {doc['phase']!r:.40} is none of {', '.join(_PHASES)}")
    kind("round", int, "a round number")
    kind("rounds", list, "a list of rounds")
    kind("programs", dict, "an object of programs")
    kind("side_logliks", dict, "an object")
    kind("particles", list, "a list of particles")
    kind("elapsed", (int, float), "a number of seconds")
    if not doc["particles"] or "p0" not in doc["programs"]:
        raise ValueError("it holds no particles, or no initial program p0")
    if not all(isinstance(row, dict) for row in doc["rounds"]):
        raise ValueError("its 'rounds' are not all objects")
    try:
        np.random.default_rng().bit_generator.state = doc.get("rng")
    except (TypeError, ValueError, KeyError) as exc:
        raise ValueError(f"its 'rng' is not a random generator's state ({exc})") from None


# ---- the driver --------------------------------------------------------------------------------

@dataclass
class LearnResult:
    """What a learning run produced."""

    program: Program
    data: Dataset
    p0: Program  # P0 with all parameters fitted (for Table 1 and figure 6)
    after_phase1: Program  # best program after phase 1, all parameters fitted
    table: dict
    trace: list
    rounds: list
    seconds: float
    resumed: bool = False


def _fingerprint(p: Particle, *extra) -> str:
    """A digest of everything a task's result depends on (besides the data, the options
    and, for VI, the seed): structure, parameters, queue, rejected list, objective."""
    prog = p.program
    h = hashlib.sha256()
    h.update(repr((sorted((a.id, a.kind, a.type, a.callees) for a in prog.abstractions.values()),
                   prog.root_callees, prog.next_id, getattr(prog, "sigma_mode", None), p.queue, p.rejected,
                   p.done, p.objective, p.loglik, extra)).encode())
    for k in sorted(prog.params):
        h.update(k.encode())
        h.update(np.ascontiguousarray(prog.params[k], dtype=np.float64).tobytes())
    return h.hexdigest()


def _share(result: Particle, new_rows: int, own_trace: list) -> Particle:
    """A particle whose task was identical to the one that produced ``result``: the
    result's state, with its own history ``own_trace`` plus the task's ``new_rows``
    trace rows."""
    out = _copy_particle(result)
    out.trace = [dict(r) for r in own_trace] + [dict(r) for r in result.trace[len(result.trace) - new_rows:]]
    out.cpu = 0.0
    return out


def _run_deduplicated(keys: dict, submit) -> tuple[dict, dict]:
    """Call ``submit(k)`` (a future) once per distinct ``keys[k]`` (None: always);
    returns the results of those that ran, {k: result}, and {key: the k that ran}."""
    first, futures = {}, {}
    for k, key in keys.items():
        if key is not None and key in first:
            continue
        if key is not None:
            first[key] = k
        futures[k] = submit(k)
    return {k: f.result() for k, f in futures.items()}, first


def _copy_particle(p: Particle) -> Particle:
    return Particle(p.program.copy(), p.objective, p.loglik, dict(p.usage), list(p.queue), list(p.rejected),
                    p.done, [dict(r) for r in p.trace])


def _resample(particles: list, rng: np.random.Generator) -> tuple[list, list]:
    """Systematic resampling by exp(O_D); returns the new list and the chosen indices."""
    idx = resample(np.array([p.objective for p in particles], dtype=np.float64), rng, "systematic")
    out, seen = [], set()
    for i in idx:
        out.append(particles[i] if i not in seen else _copy_particle(particles[i]))
        seen.add(int(i))
    return out, [int(i) for i in idx]


def run_search(example_set: ExampleSet, options: SearchOptions, executor, checkpoint: Path | None = None,
               fingerprint: str = "", progress=None, replace_other: bool = False) -> LearnResult:
    """Preprocess the examples and run the particle-filtered structure search.

    Parameters
    ----------
    executor : concurrent.futures.Executor
        Runs the per-particle tasks (see :func:`procmod.parallel.open_executor`).
    checkpoint : Path, optional
        Folder for checkpoints; an existing checkpoint with the same ``fingerprint`` is
        resumed. One of another run is refused, or deleted when ``replace_other``.
    progress : callable, optional
        Called with a one-line status after every round.
    """
    options.check()
    t0 = time.perf_counter()
    data = preprocess(example_set)
    state = load_checkpoint(checkpoint, data.parts) if checkpoint is not None else None
    resumed = state is not None
    if state is not None and (state.get("fingerprint") != fingerprint or state.get("options") != asdict(options)):
        if not replace_other:
            raise LearnError(f"{checkpoint} holds a run with other examples or options; pass "
                             f"{argument('overwrite=True')} to start afresh, or rerun with the same examples and "
                             "options to resume")
        shutil.rmtree(checkpoint)  # the user asked to replace the earlier run (overwrite)
        state, resumed = None, False
    rng = np.random.default_rng(_seed(options.seed, "resample"))
    # tasks with identical inputs give identical results with the exact estimator (its
    # fits use no random numbers), so they run once; VI's fits depend on their seeds
    dedup = options.share_fits and options.estimator == "exact"
    if state is None:
        init = executor.submit(task_initial, data, options).result()
        particles = [Particle(init["p0"].copy(), _objective(init["loglik"], init["p0"], options.lam),
                              init["loglik"], dict(init["usage"]),
                              _usage_order(sorted(init["p0"].abstractions), init["usage"]))
                     for _ in range(options.particles)]
        state = {"fingerprint": fingerprint, "options": asdict(options), "round": 0, "phase": "discrete",
                 "rng": rng.bit_generator.state, "rounds": [], "elapsed": time.perf_counter() - t0,
                 "p0_loglik": init["loglik"], "side_logliks": {},
                 "programs": {"p0": init["p0"]}, "particles": particles, "cpu": init["cpu"]}
        if checkpoint is not None:
            save_checkpoint(checkpoint, state)
    else:
        rng.bit_generator.state = state["rng"]
        particles = state["particles"]
    # the slot prior's target: the pooled model's slot-use probabilities (per part type,
    # the examples' frequencies; recomputed on resume).
    # It enters only the final pass (and the free fit of the phase-1 program, its
    # figure-6 counterpart): the splits are judged by the paper's maximum-likelihood fits
    # (with the prior, each split whose copies differ in slot use paid about alpha nats
    # per differing bit, an extra complexity charge that cost castles three abstractions),
    # and the program that is sampled does not memorise its abstractions' few nodes.
    slot_target = pooled_slot_target(data) if options.slot_prior > 0 else None
    elapsed0 = state["elapsed"]
    t_resume, cpu_resume, cpu0 = time.perf_counter(), time.process_time(), state.get("cpu", 0.0)
    task_cpu = 0.0
    # fits made only for reporting run beside the search: name -> future
    side = {}
    if "p0_free" not in state["programs"]:
        side["p0_free"] = executor.submit(task_free_copy, state["programs"]["p0"], data, options,
                                          _seed(options.seed, "P0free"))

    def collect(wait: bool) -> float:
        cpu = 0.0
        for name in list(side):
            if wait or side[name].done():
                out = side.pop(name).result()
                state["programs"][name] = out["program"]
                state["side_logliks"][name] = out["loglik"]
                cpu += out["cpu"]
        return cpu

    while state["phase"] != "finished":
        phase = state["phase"]
        r = state["round"]
        active = [k for k, p in enumerate(particles) if not p.done]
        if not active or r >= options.max_rounds:
            nxt = {"discrete": "fixed", "fixed": "free", "free": "finished"}[phase]
            if phase == "discrete":
                best = max(particles, key=lambda p: p.objective)
                state["programs"]["phase1"] = best.program
                side["after_phase1"] = executor.submit(task_free_copy, best.program, data, options,
                                                       _seed(options.seed, "P1free"), slot_target)
            if nxt != "finished":
                keys = {k: _fingerprint(p, nxt) if dedup else None for k, p in enumerate(particles)}
                before = list(particles)
                lengths = [len(p.trace) for p in before]
                traces = [list(p.trace) for p in before]
                done, first = _run_deduplicated(keys, lambda k: executor.submit(
                    task_phase, before[k], data, options, nxt, _seed(options.seed, r, k, nxt),
                    slot_target if nxt == "free" else None))
                particles = [done[k] if k in done else
                             _share(done[first[keys[k]]], len(done[first[keys[k]]].trace) - lengths[first[keys[k]]],
                                    traces[k]) for k in range(len(before))]
                state["fits_run"] = state.get("fits_run", 0) + len(done)
                state["fits_shared"] = state.get("fits_shared", 0) + len(before) - len(done)
                task_cpu += sum(p.cpu for p in particles)
            state["phase"] = nxt
            row = {"round": r, "phase": nxt, "event": "phase", "objectives": [round(p.objective, 3) for p in particles],
                   "seconds": round(elapsed0 + time.perf_counter() - t_resume, 3)}
        else:
            # the split is made here (cheap), so identical proposals share one fit
            keys, prepared = {}, {}
            for k in active:
                key = _fingerprint(particles[k], phase) if dedup else None
                # made here only when fits may be shared; otherwise task_step makes it in
                # the worker (same seed, same split), so preparations run in parallel too
                prepared[k] = prepare_step(particles[k], data, phase, _seed(options.seed, r, k)) if dedup else None
                if key is not None and prepared[k] is not None:
                    t, _, a2, bias = prepared[k]
                    key = (key, t, a2, hashlib.sha256(np.ascontiguousarray(bias).tobytes()).hexdigest())
                keys[k] = key
            before = {k: particles[k] for k in active}
            lengths = {k: len(particles[k].trace) for k in active}
            traces = {k: list(particles[k].trace) for k in active}
            done, first = _run_deduplicated(keys, lambda k: executor.submit(
                task_step, before[k], data, options, phase, _seed(options.seed, r, k), None, prepared[k]))
            for k in active:
                if k in done:
                    particles[k] = done[k]
                else:
                    src = first[keys[k]]
                    particles[k] = _share(done[src], len(done[src].trace) - lengths[src], traces[k])
                task_cpu += particles[k].cpu
            # a fit ran where a split was proposed, i.e. where the particle's trace grew
            real = sum(1 for k in done if len(done[k].trace) > lengths[k])
            state["fits_run"] = state.get("fits_run", 0) + real
            state["fits_shared"] = state.get("fits_shared", 0) + sum(
                1 for k in active if k not in done and prepared[k] is not None)
            chosen = list(range(len(particles)))
            if len(particles) > 1:
                particles, chosen = _resample(particles, rng)
            row = {"round": r, "phase": phase, "event": "step", "objectives": [round(p.objective, 3) for p in particles],
                   "resampled_from": chosen, "seconds": round(elapsed0 + time.perf_counter() - t_resume, 3)}
        task_cpu += collect(wait=state["phase"] == "finished")
        state["rounds"].append(row)
        state["round"] = r + 1
        state["particles"] = particles
        state["rng"] = rng.bit_generator.state
        state["elapsed"] = elapsed0 + time.perf_counter() - t_resume
        # CPU of the tasks plus this process (inline tasks are counted in both: subtract)
        own = time.process_time() - cpu_resume
        inline = isinstance(executor, _Inline)
        state["cpu"] = cpu0 + (own if inline else own + task_cpu)
        if checkpoint is not None:
            save_checkpoint(checkpoint, state)
        if progress is not None:
            best = max(p.objective for p in particles)
            progress(f"round {r}: phase {state['phase']}, best O_D {best:.2f}, "
                     f"{sum(not p.done for p in particles)} searching")
    # a run resumed after its last checkpoint may still lack a reporting fit
    for name, source, key in (("p0_free", "p0", "P0free"), ("after_phase1", "phase1", "P1free")):
        if name not in state["programs"] and source in state["programs"]:
            side[name] = executor.submit(task_free_copy, state["programs"][source], data, options,
                                         _seed(options.seed, key), slot_target if name == "after_phase1" else None)
    collect(wait=True)
    best = max(particles, key=lambda p: p.objective)
    program = best.program
    p0 = state["programs"]["p0_free"]
    state["p0_free_loglik"] = state["side_logliks"]["p0_free"]
    lam = options.lam
    table = {
        "parts": len(data.parts),
        "A0": len(p0.abstractions),
        "O_P0": _objective(state["p0_free_loglik"], p0, lam), "L_P0": state["p0_free_loglik"], "C_P0": p0.complexity(),
        "A_star": len(program.abstractions),
        "O_Pstar": best.objective, "L_Pstar": best.loglik, "C_Pstar": program.complexity(),
        "seconds": state["elapsed"],
        "cpu_seconds": state["cpu"],
        "rounds": state["round"],
        "splits_proposed": sum(1 for r in best.trace if "split" in r),
        "splits_accepted": sum(1 for r in best.trace if r.get("accepted")),
        "fits_run": state.get("fits_run", 0),
        "fits_shared": state.get("fits_shared", 0),
    }
    # timings stay out of the program file, so the same run writes the same bytes
    program.info = {"table": {k: v for k, v in table.items() if k not in ("seconds", "cpu_seconds")},
                    "options": asdict(options)}
    return LearnResult(program, data, p0, state["programs"].get("after_phase1", p0), table, best.trace,
                       state["rounds"], state["elapsed"], resumed)
