"""Unguided SMC on vines at 50x50: seconds per run and quality vs particle count.

The peer is WebPPL running the same program (DESIGN.md "Speed budget", on this 2-core
machine): 600 particles ~1.6 s (median normalised similarity 0.82), 200 ~0.5 s (0.75),
50 ~0.26 s (0.41), 10 ~0.14 s (0.05). procmod's aim: half WebPPL's time at equal quality.

    python bench/smc_vines.py [--targets 10] [--seeds 2] [--set glyphs|scribbles]

Targets are the first N usable lower-case glyphs of DejaVu Sans Bold, or scribbles
0..N-1 (procedural brush strokes, the closest thing here to WebPPL's hand-drawn targets). Similarity is the
normalised similarity of seed 004 eq. 3 (binary edge weights, w_filled 0.6) of one
particle drawn from the final SMC weights (what SMC returns as a posterior sample); the
best final particle is reported too. Writes bench/results/smc_vines.json and .png.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from procmod.data import glyph_set, scribble_set  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.targets import ShapeMatch  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
WEBPPL = {600: (1.6, 0.82), 200: (0.5, 0.75), 50: (0.26, 0.41), 10: (0.14, 0.05)}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=10)
    parser.add_argument("--seeds", type=int, default=2)
    parser.add_argument("--particles", type=int, nargs="+", default=[10, 50, 200, 600])
    parser.add_argument("--set", choices=("glyphs", "scribbles"), default="glyphs")
    args = parser.parse_args()
    if args.set == "glyphs":
        targets = [t for t in glyph_set("dejavu-sans") if t.name[-1].islower()][: args.targets]
    else:
        targets = scribble_set(args.targets)
    model = get_model("vines")
    smc(model, ShapeMatch(targets[0]), particles=10, seed=0)  # compile kernels outside the timing
    rows = {}
    for n in args.particles:
        times, steps, sample_sims, best_sims = [], [], [], []
        for target in targets:
            shape = ShapeMatch(target)
            for seed in range(args.seeds):
                t0 = time.perf_counter()
                result = smc(model, shape, particles=n, seed=seed)
                times.append(time.perf_counter() - t0)
                steps.append(result.evaluations)
                w = np.exp(np.array(result.log_weights) - max(result.log_weights))
                pick = np.random.default_rng(seed).choice(len(w), p=w / w.sum())
                sample_sims.append(shape.score(result.samples[pick].output))
                best_sims.append(max(shape.score(s.output) for s in result.samples))
        rows[n] = {
            "seconds_per_run_mean": float(np.mean(times)), "seconds_per_run_median": float(np.median(times)),
            "particle_steps_per_second": float(np.sum(steps) / np.sum(times)),
            "us_per_particle_step": float(1e6 * np.sum(times) / np.sum(steps)),
            "median_similarity_sample": float(np.median(sample_sims)),
            "median_similarity_best": float(np.median(best_sims)),
            "webppl_seconds": WEBPPL.get(n, (None, None))[0], "webppl_similarity": WEBPPL.get(n, (None, None))[1],
        }
        r = rows[n]
        print(f"{n:4d} particles: {r['seconds_per_run_mean']:.3f} s/run (median {r['seconds_per_run_median']:.3f}),"
              f" {r['particle_steps_per_second']:,.0f} particle-steps/s, similarity {r['median_similarity_sample']:.3f}"
              f" (best particle {r['median_similarity_best']:.3f}); WebPPL {WEBPPL.get(n)}")
    RESULTS.mkdir(parents=True, exist_ok=True)
    out = {"python": sys.version.split()[0], "targets": [t.name for t in targets], "seeds": args.seeds,
           "canvas": "50x50", "rows": {str(k): v for k, v in rows.items()}}
    stem = "smc_vines" if args.set == "glyphs" else "smc_vines_scribbles"
    (RESULTS / f"{stem}.json").write_text(json.dumps(out, indent=1) + "\n")
    fig, ax = plt.subplots(figsize=(6, 4))
    ns = sorted(rows)
    ax.plot([rows[n]["seconds_per_run_mean"] for n in ns], [rows[n]["median_similarity_sample"] for n in ns],
            "o-", label="procmod SMC")
    for n in ns:
        ax.annotate(str(n), (rows[n]["seconds_per_run_mean"], rows[n]["median_similarity_sample"]),
                    textcoords="offset points", xytext=(4, -10), fontsize=8)
    wn = sorted(WEBPPL)
    ax.plot([WEBPPL[n][0] for n in wn], [WEBPPL[n][1] for n in wn], "s--", color="grey", label="WebPPL (DESIGN.md)")
    ax.set_xscale("log")
    ax.set_xlabel("seconds per SMC run (one core)")
    ax.set_ylabel("median normalised similarity")
    ax.grid(alpha=0.3)
    ax.legend()
    fig.tight_layout()
    fig.savefig(RESULTS / f"{stem}.png", dpi=110)
    print(f"wrote {RESULTS / (stem + '.json')} and {RESULTS / (stem + '.png')}")


if __name__ == "__main__":
    main()
