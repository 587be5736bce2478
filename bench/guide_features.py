"""Guide feature conditions against each other, each trained with several seeds: how much
of a difference between two conditions is the condition, how much the training seed.

Each condition (``procmod guide train --features``; default ``all`` and ``all+progress``,
the progress features of :mod:`procmod.guide.features`) is trained on the same traces
with each training seed, then every guide runs guided SMC on the development targets of
bench/guided_resampling.py (DejaVu Sans Bold capitals A-M without I, scribbles 61-72:
neither the guides' training scribbles 0-48 nor bench/vs_webppl.py's targets). A
target's figure is the median best similarity over the SMC seeds (the same SMC seeds for
every guide), a guide's the mean over targets. Differences between conditions are paired
by training seed and target: [mean, 95% bootstrap interval over targets], per training
seed and for each target's difference averaged over the training seeds.

    python bench/guide_features.py --traces DIR [--conditions all all+progress]
        [--train-seeds 0 1 2] [--particles 1 5 10] [--seeds 24] [--workers 2]
        [--name guide_features]

``DIR``: a traces folder (``procmod guide traces vines --targets scribble --count 2000
--particles 600 --seed 0 --out DIR`` makes the one the shipped guide was trained on).
Guides go to bench/.cache/guide_features/ (reused when there). Results:
bench/results/NAME.json and NAME.png.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from guided_resampling import development_sets  # noqa: E402
from procmod.guide import FeatureSettings, Guide  # noqa: E402
from procmod.guide.traces import load_traces  # noqa: E402
from procmod.guide.train import train_guide  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from vs_webppl import by_target, mean_over_targets  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
GUIDES = Path(__file__).resolve().parent / ".cache" / "guide_features"


def guide_path(traces: Path, condition: str, train_seed: int) -> Path:
    return GUIDES / f"{traces.name}-{condition.replace('+', '_')}-seed{train_seed}"


def train(job: tuple) -> dict:
    """Train one (condition, training seed) guide unless it is there; its report."""
    traces, condition, train_seed = job
    out = guide_path(traces, condition, train_seed)
    if not out.with_suffix(".json").exists():
        train_guide(get_model("vines"), traces, out, settings=FeatureSettings.condition(condition), seed=train_seed)
    info = json.loads(out.with_suffix(".json").read_text())["info"]
    return {"condition": condition, "train_seed": train_seed, "final_nll": info["final_nll"],
            "train_seconds": info["seconds"], "traces": info["traces"]}


def evaluate(job: tuple) -> list:
    """Every development run of one guide: (set, target, particles, seed, similarity, CPU s)."""
    traces, condition, train_seed, particles, seeds = job
    model, guide = get_model("vines"), Guide.load(guide_path(traces, condition, train_seed))
    runs = []
    for set_name, targets in development_sets().items():
        for n in particles:
            for k, target in enumerate(targets):
                for seed in range(seeds):
                    t0 = time.thread_time()
                    result = smc(model, target, particles=n, seed=1000 * k + seed, guide=guide)
                    runs.append({"condition": condition, "train_seed": train_seed, "set": set_name,
                                 "target": target.name, "particles": n, "seed": seed,
                                 "similarity": result.best_score, "cpu_seconds": time.thread_time() - t0,
                                 "steps": result.evaluations})
    return runs


def cells(runs: list) -> dict:
    """(set, particles, condition, training seed) -> its runs."""
    out = {}
    for r in runs:
        out.setdefault((r["set"], r["particles"], r["condition"], r["train_seed"]), []).append(r)
    return out


def step_cost(groups: list) -> float:
    """CPU microseconds per particle-step over groups of runs. A run's CPU time includes
    its set-up (~0.1 ms), which weighs most in the short 1-particle runs."""
    runs = [r for group in groups for r in group]
    return 1e6 * sum(r["cpu_seconds"] for r in runs) / sum(r["steps"] for r in runs)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--traces", type=Path, required=True)
    parser.add_argument("--conditions", nargs="+", default=["all", "all+progress"],
                        help="feature conditions; the first is the baseline of the differences")
    parser.add_argument("--train-seeds", type=int, nargs="+", default=[0, 1, 2])
    parser.add_argument("--particles", type=int, nargs="+", default=[1, 5, 10])
    parser.add_argument("--seeds", type=int, default=24, help="SMC seeds per target")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--name", default="guide_features")
    args = parser.parse_args()
    for condition in args.conditions:
        FeatureSettings.condition(condition)  # refuse a typo before any work
    traces = args.traces.resolve()
    job = load_traces(traces, limit=1)[0]

    started = time.time()
    GUIDES.mkdir(parents=True, exist_ok=True)
    # seconds_total counts training only for the guides not already in GUIDES
    reused = sorted(guide_path(traces, c, s).name for c in args.conditions for s in args.train_seeds
                    if guide_path(traces, c, s).with_suffix(".json").exists())
    # conditions interleaved: the workers evaluate two conditions side by side, so that the
    # machine's drift hits them alike (CPU time per step is compared too)
    guides = [(traces, c, s) for s in args.train_seeds for c in args.conditions]
    with ProcessPoolExecutor(args.workers) as pool:
        training = list(pool.map(train, guides))
        runs = [r for chunk in pool.map(evaluate, [g + (args.particles, args.seeds) for g in guides])
                for r in chunk]

    rng = np.random.default_rng(0)
    sets = list(development_sets())
    by_cell = cells(runs)
    summary, differences = [], []
    for set_name in sets:
        for n in args.particles:
            medians = {}  # (condition, training seed) -> target -> median similarity over the SMC seeds
            for condition in args.conditions:
                for s in args.train_seeds:
                    cell = by_cell[(set_name, n, condition, s)]
                    medians[condition, s] = {t: float(np.median(v)) for t, v in by_target(cell).items()}
                    sims = np.array([r["similarity"] for r in cell])
                    summary.append({"set": set_name, "particles": n, "condition": condition, "train_seed": s,
                                    "target_mean_of_medians": float(np.mean(list(medians[condition, s].values()))),
                                    "run_mean": float(sims.mean()), "fraction_below_0.1": float(np.mean(sims < 0.1)),
                                    "cpu_seconds_per_run": sum(r["cpu_seconds"] for r in cell) / len(cell),
                                    "cpu_us_per_step": step_cost([cell])})
            baseline = args.conditions[0]
            for condition in args.conditions[1:]:
                # paired by training seed and target
                per_seed, pooled = {}, []
                for s in args.train_seeds:
                    d = np.array([medians[condition, s][t] - medians[baseline, s][t]
                                  for t in sorted(medians[condition, s])])
                    per_seed[s] = {"difference": mean_over_targets(d, rng), "targets_ahead": int((d > 0).sum()),
                                   "targets": len(d)}
                    pooled.append(d)
                # each target's difference averaged over the training seeds, then over targets
                difference = mean_over_targets(np.mean(pooled, axis=0), rng)
                us = {c: step_cost([by_cell[(set_name, n, c, s)] for s in args.train_seeds])
                      for c in (baseline, condition)}
                differences.append({"set": set_name, "particles": n, "condition": condition, "baseline": baseline,
                                    "per_train_seed": per_seed, "difference": difference,
                                    "cpu_us_per_step": us[condition], "baseline_cpu_us_per_step": us[baseline]})
                print(f"{set_name:16} n={n:<3} {condition} - {baseline}: {difference[0]:+.3f} "
                      f"[{difference[1]:+.3f}, {difference[2]:+.3f}]; by training seed "
                      + ", ".join(f"{s}: {v['difference'][0]:+.3f}" for s, v in per_seed.items())
                      + f"; CPU {us[condition]:.1f} against {us[baseline]:.1f} us a step", flush=True)

    RESULTS.mkdir(exist_ok=True)
    result = {"command": "python bench/guide_features.py " + " ".join(sys.argv[1:]),
              "machine": {"platform": platform.platform(), "python": platform.python_version()},
              "trace_job": job, "traces_folder": traces.name, "seeds": args.seeds,
              "guides_reused": reused,
              "targets": {s: [t.name for t in ts] for s, ts in development_sets().items()},
              "seconds_total": round(time.time() - started, 1), "training": training,
              "summary": summary, "differences": differences}
    # every run, one compact row each (about 10,000 of them), appended to the indented
    # rest: json.dumps(..., indent=1) ends its text with "\n}", cut off to add "runs"
    fields = list(runs[0])
    rows = ",\n  ".join(json.dumps([r[f] for f in fields]) for r in runs)
    text = json.dumps({**result, "run_fields": fields}, indent=1)[:-2]
    (RESULTS / f"{args.name}.json").write_text(f'{text},\n "runs": [\n  {rows}\n ]\n}}\n')

    fig, axes = plt.subplots(1, len(sets), figsize=(5.5 * len(sets), 4), squeeze=False)
    colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
    for ax, set_name in zip(axes[0], sets):
        for c, condition in enumerate(args.conditions):
            for k, s in enumerate(args.train_seeds):
                rows = [r for r in summary if (r["set"], r["condition"], r["train_seed"]) == (set_name, condition, s)]
                ax.plot([r["particles"] for r in rows], [r["target_mean_of_medians"] for r in rows], marker="o",
                        color=colours[c % len(colours)], alpha=0.8, linestyle=("-", "--", ":", "-.")[k % 4],
                        label=f"{condition}, training seed {s}")
        ax.set_xscale("log")
        ax.set_title(f"guided SMC, {set_name}")
        ax.set_xlabel("particles")
        ax.set_ylabel("median best similarity, mean over targets", fontsize=9)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=120)
    print(f"wrote {RESULTS / (args.name + '.json')}")


if __name__ == "__main__":
    main()
