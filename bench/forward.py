"""Base costs of the runtime: forward sampling, stepping and copying 2D models at 50x50.

Writes bench/results/forward.json and bench/results/forward.png.

    python bench/forward.py [--seconds 3]

These are the costs every engine pays per particle-step: DESIGN.md's speed budget asks
for about 10 microseconds per vines step and about as much per particle copy.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
import timeit
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from procmod.core import run_forward, start, step  # noqa: E402
from procmod.models import MODELS  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def forward_rate(model, seconds: float) -> dict:
    rng = np.random.default_rng(0)
    run_forward(model, rng)  # compile the raster kernels outside the timing
    samples = calls = emits = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        d = run_forward(model, rng)
        samples += 1
        calls += d.n_nodes
        emits += d.n_emits
    dt = time.perf_counter() - t0
    return {"samples_per_s": samples / dt, "us_per_call": 1e6 * dt / calls,
            "us_per_emit": 1e6 * dt / emits, "mean_calls": calls / samples, "mean_emits": emits / samples}


def step_rate(model, seconds: float) -> dict:
    rng = np.random.default_rng(1)
    steps = 0
    t0 = time.perf_counter()
    while time.perf_counter() - t0 < seconds:
        state = start(model)
        while step(state, rng):
            steps += 1
    dt = time.perf_counter() - t0
    return {"us_per_step": 1e6 * dt / steps}


def copy_cost(model, depth_steps: int = 10) -> dict:
    """Cost of copying a partial derivation after ``depth_steps`` emits (median of runs)."""
    rng = np.random.default_rng(2)
    for seed in range(1000):  # find a run that lasts long enough
        rng = np.random.default_rng(seed)
        state = start(model)
        taken = 0
        while taken < depth_steps and step(state, rng):
            taken += 1
        if taken == depth_steps and not state.done:
            break
    timer = timeit.Timer(state.copy)
    number = 20000
    runs = [timer.timeit(number) / number * 1e6 for _ in range(5)]
    return {"us_per_copy": float(np.median(runs)), "calls_in_copied_state": state.n_nodes,
            "emits_in_copied_state": state.n_emits}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=3.0, help="time per measurement")
    args = parser.parse_args()
    results = {"machine": {"python": sys.version.split()[0], "platform": platform.platform(),
                           "processor": platform.processor()},
               "canvas": "50x50", "models": {}}
    for name in sorted(MODELS):
        model = MODELS[name]
        row = forward_rate(model, args.seconds)
        row.update(step_rate(model, args.seconds))
        row.update(copy_cost(model))
        results["models"][name] = row
        print(f"{name:10s} {row['samples_per_s']:9.0f} samples/s  {row['us_per_emit']:6.1f} us/emit (forward)"
              f"  {row['us_per_step']:6.1f} us/step  {row['us_per_copy']:5.2f} us/copy")
    RESULTS.mkdir(parents=True, exist_ok=True)
    (RESULTS / "forward.json").write_text(json.dumps(results, indent=1) + "\n")

    names = sorted(results["models"])
    fig, axes = plt.subplots(1, 2, figsize=(10, 3.6))
    axes[0].bar(names, [results["models"][n]["samples_per_s"] for n in names], color="#4a6228")
    axes[0].set_ylabel("forward samples / s (50x50)")
    x = np.arange(len(names))
    for offset, key, label in ((-0.27, "us_per_emit", "forward, per emit"),
                               (0.0, "us_per_step", "step to next emit"),
                               (0.27, "us_per_copy", "copy partial derivation")):
        axes[1].bar(x + offset, [results["models"][n][key] for n in names], width=0.27, label=label)
    axes[1].axhline(10, color="grey", linestyle="--", linewidth=1, label="budget: 10 us")
    axes[1].set_xticks(x, names)
    axes[1].set_ylabel("microseconds")
    axes[1].legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / "forward.png", dpi=110)
    print(f"wrote {RESULTS / 'forward.json'} and {RESULTS / 'forward.png'}")


if __name__ == "__main__":
    main()
