"""Would evaluating the guide's networks in batches across particles make guided SMC faster?

Seed 004 evaluates a guide's network for a batch of particles at once (on a GPU), and the
guides issue asks for batching "where that is faster". In procmod every particle runs its
rules as plain Python; a particle cannot hand its choice to a batch and wait, unless the
runtime suspends it at the choice and resumes it once the batch is done. procmod's
runtime already suspends a call at each emit (SMC reweights there) by pausing it and
later re-running it over the choices it has made, so the cost of one more suspension is
measurable. This script measures, in process, on one core:

* ``single_us``: one guided choice as procmod makes it now, one fused numba call
  (features, network, draw: ``procmod.guide.fast.guided_draw``) per choice, on the
  inputs recorded from real guided runs;
* ``batched_us[B]``: the same work as a batching proposer would do it for B particles'
  choices of one site, per choice: each suspended particle writes its features into the
  batch (one numba call each: the features need its own partial output), then one call
  runs the network and the draw for the whole batch (``batched_network_us[B]``: that
  call alone);
* ``suspend_us``: what suspending and resuming a particle once costs, as the time per emit
  of stepping vines derivations emit by emit (each emit suspends the call) minus running
  the same derivations straight through (same seeds, same derivations).

Batching pays where ``single_us - batched_us[B] > suspend_us``: the choice saved against
the suspension paid. Timings are the least of ``--repeats`` rounds, rounds interleaved.

    python bench/guide_batching.py [--guide vines-scribbles] [--repeats 5] [--name guide_batching]

Results: bench/results/NAME.json and NAME.png.
"""

from __future__ import annotations

import argparse
import json
import platform
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numba  # noqa: E402
import numpy as np  # noqa: E402

import procmod.guide.guide as guide_module  # noqa: E402
from procmod.core import start, step  # noqa: E402
from procmod.core.runtime import finish  # noqa: E402
from procmod.data import glyph_set, scribble_set  # noqa: E402
from procmod.guide import Guide  # noqa: E402
from procmod.guide.fast import guided_draw, mixture_draw, network_outputs, site_features  # noqa: E402
from procmod.guide.network import LOG_SCALE_MAX, LOG_SCALE_MIN  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.targets import ShapeMatch  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
BATCH_SIZES = (1, 5, 10, 20, 50, 200)


@numba.njit(cache=False)
def features_into(x, row, raw, params, target, partial, layout, px, py):
    """Row ``row`` of ``x``: a choice's feature vector, as the fused call builds it."""
    site_features(raw, params, target, partial, layout, px, py, x[row])


@numba.njit(cache=False)
def draw_batch(k, c0, s0, u, z, x, params, values, log_q):
    """Network and draw of a real-valued site for every row of ``x`` (one particle's
    features each), as the fused call computes them."""
    for r in range(x.shape[0]):
        values[r], log_q[r] = mixture_draw(network_outputs(x[r], params), k, c0[r], s0[r], LOG_SCALE_MIN,
                                           LOG_SCALE_MAX, u[r], z[r])


def record_choices(model, guide, targets, seeds: int) -> list:
    """The arguments of every guided choice of 10-particle guided SMC runs. The site's
    network, the target's and the partial output's pyramids are kept as the run shares
    them (none is changed once made); the local-state array is copied (the proposer
    reuses it)."""
    recorded = []
    original = guide_module.guided_draw

    def recording(*args):
        recorded.append(args[:7] + (args[7].copy(),) + args[8:])
        return original(*args)

    guide_module.guided_draw = recording
    try:
        for target in targets:
            for seed in range(seeds):
                smc(model, target, particles=10, seed=seed, guide=guide, workers=1)
    finally:
        guide_module.guided_draw = original
    return recorded


def largest_site(recorded: list) -> list:
    """The recorded choices of the site with most choices (kind 0: a real-valued choice),
    over every run (each run packs its own copy of a site's network: grouped by content)."""
    digests, by_site = {}, {}
    for args in recorded:
        if args[0] == 0:
            key = digests.get(id(args[8]))  # the recorded arguments keep every array alive
            if key is None:
                key = digests[id(args[8])] = args[8].tobytes()
            by_site.setdefault(key, []).append(args)
    return max(by_site.values(), key=len)


def groups(rows: list, size: int) -> list:
    return [rows[i:i + size] for i in range(0, len(rows) - size + 1, size)]


def time_single(rows: list, particles: int = 10) -> float:
    """Per choice, one fused call each; every group of ``particles`` choices is run once
    untimed first, so that its arrays are in cache as a run's current particles' are."""
    total = 0.0
    for group in groups(rows, particles):
        for args in group:
            guided_draw(*args)
        t0 = time.perf_counter()
        for args in group:
            guided_draw(*args)
        total += time.perf_counter() - t0
    return total / len(rows)


def time_batched(rows: list, size: int) -> tuple:
    """Per choice, batches of ``size``: (the batched network and draw alone, the whole:
    each choice's features written into the batch by a call of its own, as a particle
    would at its suspension, then the batch). Each batch is run once untimed first."""
    first = rows[0]
    k, params = first[1], first[8]
    x = np.empty((size, int(params[1])))
    c0, s0, u, z = (np.empty(size) for _ in range(4))
    values, log_q = np.empty(size), np.empty(size)
    network = whole = 0.0
    batches = groups(rows, size)
    for batch in batches:
        for _ in range(2):
            t0 = time.perf_counter()
            for i, r in enumerate(batch):
                c0[i], s0[i], u[i], z[i] = r[2], r[3], r[5], r[6]
                features_into(x, i, r[7], params, r[9], r[10], r[11], r[12], r[13])
            t1 = time.perf_counter()
            draw_batch(k, c0, s0, u, z, x, params, values, log_q)
            t2 = time.perf_counter()
        network += t2 - t1
        whole += t2 - t0
    n = len(batches) * size
    return network / n, whole / n


def check_batched_equals_single(rows: list) -> None:
    """The batched path draws what the fused call draws (up to rounding)."""
    batch = rows[:10]
    first = batch[0]
    x = np.empty((10, int(first[8][1])))
    values, log_q = np.empty(10), np.empty(10)
    for i, r in enumerate(batch):
        features_into(x, i, r[7], first[8], r[9], r[10], r[11], r[12], r[13])
    draw_batch(first[1], np.array([r[2] for r in batch]), np.array([r[3] for r in batch]),
               np.array([r[5] for r in batch]), np.array([r[6] for r in batch]), x, first[8], values, log_q)
    single = np.array([guided_draw(*r) for r in batch])
    if not (np.allclose(values, single[:, 0], rtol=1e-9, atol=1e-9)
            and np.allclose(log_q, single[:, 1], rtol=1e-9, atol=1e-9)):
        raise SystemExit("guide_batching: the batched kernel does not draw what guided_draw draws")


def time_suspension(model, seeds: range) -> tuple:
    """(seconds per emit straight through, stepped emit by emit, emits)."""
    def through():
        for s in seeds:
            finish(start(model, model.new_output()), np.random.default_rng(s))

    def stepped():
        n = 0
        for s in seeds:
            state, rng = start(model, model.new_output()), np.random.default_rng(s)
            while step(state, rng):
                pass
            n += state.n_emits
        return n

    t0 = time.perf_counter()
    through()
    t1 = time.perf_counter()
    emits = stepped()
    t2 = time.perf_counter()
    return (t1 - t0) / emits, (t2 - t1) / emits, emits


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--guide", default="vines-scribbles")
    parser.add_argument("--seeds", type=int, default=3, help="guided runs per target whose choices are recorded")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--name", default="guide_batching")
    args = parser.parse_args()
    if args.repeats < 1 or args.seeds < 1:
        parser.error("--repeats and --seeds must be at least 1")
    model = get_model("vines")
    guide = Guide.load(args.guide)
    targets = [ShapeMatch(t) for t in glyph_set("dejavu-sans")[:6]] + [ShapeMatch(t) for t in scribble_set(6, first=49)]
    rows = largest_site(record_choices(model, guide, targets, args.seeds))
    rows = rows[: (len(rows) // max(BATCH_SIZES)) * max(BATCH_SIZES)]
    # one choice at a time runs in the order of the runs (a particle's choices of one step
    # read the same partial output); a batch holds choices of different particles, so
    # batches are drawn from the choices shuffled
    shuffled = [rows[i] for i in np.random.default_rng(0).permutation(len(rows))]
    seeds = range(2000)
    check_batched_equals_single(rows)
    time_single(rows[:50])  # compile / warm
    for size in BATCH_SIZES:
        time_batched(rows[: 2 * size], size)
    time_suspension(model, range(50))
    single, batched, copied, through, stepped = [], {b: [] for b in BATCH_SIZES}, {b: [] for b in BATCH_SIZES}, [], []
    for _ in range(args.repeats):  # rounds interleaved: the machine's speed drifts
        single.append(time_single(rows))
        for size in BATCH_SIZES:
            k, c = time_batched(shuffled, size)
            batched[size].append(k)
            copied[size].append(c)
        t, s, emits = time_suspension(model, seeds)
        through.append(t)
        stepped.append(s)
    us = 1e6
    result = {
        "command": "python bench/guide_batching.py " + " ".join(
            f"--{k.replace('_', '-')} {v}" for k, v in vars(args).items()),
        "machine": {"platform": platform.platform(), "python": platform.python_version(),
                    "processor": platform.processor()},
        # each run has a target pyramid of its own
        "guide": args.guide, "choices_timed": len(rows), "runs_timed": len({id(r[9]) for r in rows}),
        "site_inputs": int(rows[0][8][1]),
        "single_us": us * min(single),
        "batched_network_us": {str(b): us * min(v) for b, v in batched.items()},
        "batched_us": {str(b): us * min(v) for b, v in copied.items()},
        "emit_straight_through_us": us * min(through), "emit_stepped_us": us * min(stepped),
        "suspend_us": us * (min(stepped) - min(through)), "emits": emits,
    }
    result["saving_per_choice_us"] = {b: result["single_us"] - v for b, v in result["batched_us"].items()}
    result["batching_pays"] = {b: v > result["suspend_us"] for b, v in result["saving_per_choice_us"].items()}
    RESULTS.mkdir(exist_ok=True)
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")

    fig, ax = plt.subplots(figsize=(6.4, 4))
    sizes = list(BATCH_SIZES)
    ax.axhline(result["single_us"], color="C0", label="one fused call per choice (procmod now)")
    ax.plot(sizes, [result["batched_network_us"][str(b)] for b in sizes], "o-", color="C1",
            label="batched: the network and draw alone")
    ax.plot(sizes, [result["batched_us"][str(b)] for b in sizes], "s-", color="C2",
            label="batched: with each choice's features")
    ax.plot(sizes, [result["batched_us"][str(b)] + result["suspend_us"] for b in sizes], "^--",
            color="C3", label="batched + one suspension")
    ax.set_xscale("log")
    ax.set_xlabel("choices per batch (particles)")
    ax.set_ylabel("microseconds per guided choice")
    ax.set_ylim(bottom=0)
    ax.set_title(f"vines guide ({result['site_inputs']} inputs): batching across particles")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=120)
    print(json.dumps({k: result[k] for k in ("single_us", "batched_network_us", "batched_us", "suspend_us",
                                             "batching_pays")}, indent=1))


if __name__ == "__main__":
    main()
