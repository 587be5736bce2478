"""All five engines controlling vines toward glyph targets at equal wall-time budgets.

    python bench/engines_2d.py [--targets 10] [--seeds 2] [--seconds 30] [--workers 2]

For each (engine, target, seed) one run with the budget; the anytime curve is the best
normalised similarity (seed 004 eq. 3) found by time t (0 before any complete
derivation: the score of an empty image). Reports the median over targets and seeds at
each t, a plot, a JSON of every curve, and a table at 1, 5 and 30 s. Runs go through a
process pool (one run per worker process, ``--workers`` of them at a time), so on a
2-core machine use at most 2 workers to keep timings honest.
"""

from __future__ import annotations

import argparse
import concurrent.futures
import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from _common import best_by, improvements  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
SETTINGS = {
    "forward": {"particles": 100},
    "smc": {"particles": 600},
    "sosmc": {"particles": 600},
    "mcmc": {"chains": 8, "init_particles": 0},  # as measured before chains started from an SMC run
    "ga": {"population": 200},
}
REPORT_AT = (1.0, 5.0, 30.0)


def run_one(engine: str, target_name: str, seed: int, seconds: float) -> dict:
    from procmod.data import target_image
    from procmod.infer import ENGINES, Budget
    from procmod.models import get_model
    from procmod.targets import ShapeMatch

    target = ShapeMatch(target_image(target_name))
    model = get_model("vines")
    ENGINES["smc"](model, target, particles=5, seed=0)  # compile kernels before timing
    t0 = time.perf_counter()
    result = ENGINES[engine](model, target, seed=seed, budget=Budget(seconds=seconds), **SETTINGS[engine])
    wall = time.perf_counter() - t0
    return {"engine": engine, "target": target_name, "seed": seed, "wall": wall,
            "evaluations": result.evaluations, "best": result.best_score,
            "curve": improvements(result.history)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=10)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--seconds", type=float, default=30.0)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--engines", nargs="+", default=list(SETTINGS))
    args = parser.parse_args()
    from procmod.data import glyph_set
    targets = [t.name for t in glyph_set("dejavu-sans") if t.name[-1].islower()][: args.targets]
    jobs = [(e, t, s, args.seconds) for e in args.engines for t in targets for s in range(args.seeds)]
    runs = []
    with concurrent.futures.ProcessPoolExecutor(args.workers) as pool:
        futures = [pool.submit(run_one, *job) for job in jobs]
        for i, future in enumerate(concurrent.futures.as_completed(futures), 1):
            run = future.result()
            runs.append(run)
            print(f"[{i}/{len(jobs)}] {run['engine']:8s} {run['target']:22s} seed {run['seed']}: "
                  f"best {run['best']:.3f} ({run['evaluations']} evals)", flush=True)
    grid = np.geomspace(0.1, args.seconds, 60)
    summary = {}
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for i, engine in enumerate(args.engines):
        curves = [r["curve"] for r in runs if r["engine"] == engine]
        table = np.array([[best_by(c, t, 0.0) for t in grid] for c in curves])
        median = np.median(table, axis=0)
        lo, hi = np.percentile(table, 25, axis=0), np.percentile(table, 75, axis=0)
        ax.plot(grid, median, color=f"C{i}", label=engine)
        ax.fill_between(grid, lo, hi, color=f"C{i}", alpha=0.15)
        summary[engine] = {f"{t:g}s": float(np.median([best_by(c, t, 0.0) for c in curves]))
                           for t in REPORT_AT if t <= args.seconds}
        summary[engine]["evaluations_median"] = float(np.median([r["evaluations"] for r in runs if r["engine"] == engine]))
    ax.set_xscale("log")
    ax.set_xlabel("seconds (one core per run)")
    ax.set_ylabel("median best normalised similarity")
    ax.set_title(f"vines -> {len(targets)} glyphs x {args.seeds} seeds (shaded: quartiles)")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    RESULTS.mkdir(parents=True, exist_ok=True)
    fig.savefig(RESULTS / "engines_2d.png", dpi=110)
    (RESULTS / "engines_2d.json").write_text(json.dumps(
        {"python": sys.version.split()[0], "targets": targets, "seeds": args.seeds, "seconds": args.seconds,
         "settings": SETTINGS, "summary": summary, "runs": runs}, indent=1) + "\n")
    print("\nmedian best similarity at", ", ".join(f"{t:g} s" for t in REPORT_AT))
    for engine, row in summary.items():
        print(f"  {engine:8s} " + "  ".join(f"{row.get(f'{t:g}s', float('nan')):.3f}" for t in REPORT_AT))
    print(f"wrote {RESULTS / 'engines_2d.json'} and {RESULTS / 'engines_2d.png'}")


if __name__ == "__main__":
    main()
