"""Guided SMC: resampling at every emit (the papers) against resampling only when the
effective sample size falls below a fraction of the particles (procmod's guided default).

Development targets that bench/vs_webppl.py does not use, so that the choice is not tuned
on the bench: DejaVu Sans Bold capitals (A-M without I) and scribbles 61-72 (the shipped
guides trained on 0-48; the bench uses 49-60). Each (target, seed) runs once per
threshold with the same seed, so the differences are paired; in process, CPU time
(``time.thread_time``) per run, runs of the thresholds interleaved.

    python bench/guided_resampling.py [--guide vines-scribbles] [--seeds 8] [--particles 5 10 20]
                                      [--thresholds every 0.5 0.2] [--name guided_resampling]

Results: bench/results/NAME.json (every run, and per set, particle count and threshold:
mean and median best similarity, the mean paired difference from every-emit with its
standard error, CPU seconds) and NAME.png.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from procmod.data import glyph_set, scribble_set  # noqa: E402
from procmod.guide import Guide  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.targets import ShapeMatch  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
CAPITALS = "ABCDEFGHJKLM"


def development_sets() -> dict:
    return {"glyph capitals": [ShapeMatch(t) for t in glyph_set("dejavu-sans") if t.name[-1] in CAPITALS],
            "scribbles 61-72": [ShapeMatch(t) for t in scribble_set(12, first=61)]}


def threshold_value(text: str):
    return None if text == "every" else float(text)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--guide", default="vines-scribbles")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--particles", type=int, nargs="+", default=[5, 10, 20])
    parser.add_argument("--thresholds", nargs="+", default=["every", "0.5", "0.2"],
                        help="'every' (resample at every emit) or ESS fractions; the first is the baseline")
    parser.add_argument("--name", default="guided_resampling")
    args = parser.parse_args()

    model, guide = get_model("vines"), Guide.load(args.guide)
    sets = development_sets()
    runs, summary = [], []
    started = time.time()
    for n in args.particles:
        for set_name, targets in sets.items():
            scores = {t: [] for t in args.thresholds}
            cpu = {t: 0.0 for t in args.thresholds}
            for k, target in enumerate(targets):
                for seed in range(args.seeds):
                    for threshold in args.thresholds:  # interleaved: drift hits them alike
                        t0 = time.thread_time()
                        result = smc(model, target, particles=n, seed=1000 * k + seed, guide=guide,
                                     ess_threshold=threshold_value(threshold))
                        seconds = time.thread_time() - t0
                        scores[threshold].append(result.best_score)
                        cpu[threshold] += seconds
                        runs.append({"set": set_name, "target": target.name, "seed": seed, "particles": n,
                                     "threshold": threshold, "similarity": result.best_score,
                                     "cpu_seconds": seconds, "evaluations": result.evaluations})
            base = np.array(scores[args.thresholds[0]])
            for threshold in args.thresholds:
                values = np.array(scores[threshold])
                diff = values - base
                row = {"set": set_name, "particles": n, "threshold": threshold, "runs": len(values),
                       "mean": float(values.mean()), "median": float(np.median(values)),
                       "paired_difference": float(diff.mean()),
                       "paired_difference_se": float(diff.std(ddof=1) / np.sqrt(len(diff))),
                       "cpu_seconds": cpu[threshold]}
                summary.append(row)
                print(f"n={n:<3} {set_name:16} {threshold:>6}: mean {row['mean']:.3f} median {row['median']:.3f} "
                      f"paired {row['paired_difference']:+.3f} +- {row['paired_difference_se']:.3f} "
                      f"cpu {row['cpu_seconds']:.2f} s", flush=True)

    RESULTS.mkdir(exist_ok=True)
    result = {"command": "python bench/guided_resampling.py " + " ".join(sys.argv[1:]),
              "machine": {"platform": platform.platform(), "python": platform.python_version()},
              "guide": args.guide, "seeds": args.seeds, "targets": {s: [t.name for t in ts] for s, ts in sets.items()},
              "seconds_total": round(time.time() - started, 1), "summary": summary, "runs": runs}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")

    fig, axes = plt.subplots(1, len(sets), figsize=(5.5 * len(sets), 4), squeeze=False)
    for ax, set_name in zip(axes[0], sets):
        for threshold in args.thresholds:
            rows = [r for r in summary if r["set"] == set_name and r["threshold"] == threshold]
            ax.errorbar([r["cpu_seconds"] for r in rows], [r["mean"] for r in rows],
                        yerr=[1.96 * r["paired_difference_se"] for r in rows], marker="o", capsize=3,
                        label="every emit" if threshold == "every" else f"ESS < {threshold} N")
            for r in rows:
                ax.annotate(str(r["particles"]), (r["cpu_seconds"], r["mean"]), fontsize=7,
                            textcoords="offset points", xytext=(3, -9))
        ax.set_title(f"guided SMC ({args.guide}), {set_name}")
        ax.set_xlabel("CPU seconds, all runs (labels: particles)")
        ax.set_ylabel("mean best similarity\n(bars: 95% of the paired difference)", fontsize=9)
        ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=120)
    print(f"wrote {RESULTS / (args.name + '.json')}")


if __name__ == "__main__":
    main()
