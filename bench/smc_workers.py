"""SMC on vines with its particles stepped by 1 or more processes: wall time per run.

    python bench/smc_workers.py [--particles 50 100 200 600] [--workers 1 2] [--count 6] [--seeds 2]

Each run is ``procmod.infer.smc(vines, ShapeMatch(glyph), particles=N, seed=S, workers=W)``
in this process (the engine's own wall time, start-up excluded; the first run of each
process compiles nothing: kernels are warmed before timing). Targets: the first
lower-case glyphs of DejaVu Sans Bold, as bench/vs_webppl.py uses. Different worker counts
draw different random numbers, so their runs take different paths: compare the time per
particle-step as well as the time per run. Writes bench/results/smc_workers.json and .png.
"""

from __future__ import annotations

import argparse
import json
import os
import platform
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from procmod.data import glyph_set  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.targets import ShapeMatch  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--particles", type=int, nargs="+", default=[50, 100, 200, 600])
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--count", type=int, default=6, help="glyphs (default 6)")
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--name", default="smc_workers")
    args = parser.parse_args()

    model = get_model("vines")
    targets = [ShapeMatch(t) for t in glyph_set("dejavu-sans") if t.name[-1].islower()][: args.count]
    smc(model, targets[0], particles=20, seed=0)  # warm the raster kernels
    rows = []
    for target in targets:
        for seed in range(args.seeds):
            for n in args.particles:
                for w in args.workers:
                    t0 = time.perf_counter()
                    result = smc(model, target, particles=n, seed=seed, workers=w)
                    seconds = time.perf_counter() - t0
                    rows.append({"target": target.name, "seed": seed, "particles": n, "workers": w,
                                 "seconds": seconds, "steps": result.evaluations,
                                 "us_per_step": 1e6 * seconds / result.evaluations,
                                 "best_score": result.best_score})
                    print(f"{target.name:>22} seed {seed} n={n:<4} workers={w}: {seconds:6.3f} s, "
                          f"{rows[-1]['us_per_step']:5.1f} us/step, best {result.best_score:.3f}", flush=True)
    summary = []
    for n in args.particles:
        for w in args.workers:
            group = [r for r in rows if r["particles"] == n and r["workers"] == w]
            summary.append({"particles": n, "workers": w, "runs": len(group),
                            "seconds_median": float(np.median([r["seconds"] for r in group])),
                            "seconds_total": float(np.sum([r["seconds"] for r in group])),
                            "us_per_step": 1e6 * float(np.sum([r["seconds"] for r in group]))
                            / float(np.sum([r["steps"] for r in group])),
                            "best_score_median": float(np.median([r["best_score"] for r in group]))})
    RESULTS.mkdir(exist_ok=True)
    result = {"command": "python bench/smc_workers.py " + " ".join(sys.argv[1:]),
              "machine": {"platform": platform.platform(), "cpus": os.cpu_count(),
                          "python": platform.python_version()},
              "targets": [t.name for t in targets], "summary": summary, "runs": rows}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")

    fig, axes = plt.subplots(1, 2, figsize=(10, 3.8))
    for w in args.workers:
        pts = [s for s in summary if s["workers"] == w]
        axes[0].plot([s["particles"] for s in pts], [s["us_per_step"] for s in pts], marker="o", label=f"{w} worker(s)")
        axes[1].plot([s["particles"] for s in pts], [s["seconds_median"] for s in pts], marker="o", label=f"{w} worker(s)")
    axes[0].set_ylabel("wall microseconds per particle-step")
    axes[1].set_ylabel("median seconds per run")
    for ax in axes:
        ax.set_xscale("log")
        ax.set_xlabel("particles")
        ax.grid(alpha=0.3)
        ax.legend()
    fig.suptitle("vines SMC on glyphs: particles stepped by worker processes")
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=110)
    for s in summary:
        print(f"n={s['particles']:<4} workers={s['workers']}: median {s['seconds_median']:.3f} s per run, "
              f"{s['us_per_step']:.1f} us/step, best median {s['best_score_median']:.3f}")
    print(f"wrote {RESULTS / (args.name + '.json')}")


if __name__ == "__main__":
    main()
