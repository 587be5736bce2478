"""Where a target picture's derived start heads: the direction toward the nearby
foreground's centroid (procmod's rule before) against the current rule, which turns along
the shape when that way leaves it early (``procmod.targets.image.lowest_point_start``).

Development sets no other bench uses for the vines engines: every glyph of DejaVu Serif
Bold, and of STIX General Bold, whose start direction the two rules set differently. Each
runs guided SMC-10 (``--guide``) and unguided SMC-200 from both directions, same seeds
(paired), in process; the score is procmod's own similarity (both runs of a pair share
the target, only the start direction differs).

    python bench/start_directions.py [--faces dejavu-serif stix] [--seeds 4] [--name start_directions]
    python bench/start_directions.py --compare branches --faces stix --pictures bench/targets/drawn \
        --name start_branches

``--compare branches`` compares the rule with and without its turn into the larger
branch at a start in the middle of a stroke (``branches=`` of ``lowest_point_start``)
instead; ``--pictures DIR`` adds the pictures of a folder (read as ``procmod infer``
reads a target picture) to the faces' glyphs.

Results: bench/results/NAME.json (every run; per face and engine the mean best score from
each rule, the mean paired difference with its standard error, runs under 0.1) and
NAME.png.
"""

from __future__ import annotations

import argparse
import json
import math
import platform
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from procmod.data import glyph_set  # noqa: E402
from procmod.guide import Guide  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.targets import ShapeMatch, TargetImage  # noqa: E402
from procmod.targets.image import load_target_image, lowest_point_start  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--faces", nargs="+", default=["dejavu-serif", "stix"])
    parser.add_argument("--guide", default="vines-scribbles")
    parser.add_argument("--seeds", type=int, default=4)
    parser.add_argument("--name", default="start_directions")
    parser.add_argument("--compare", choices=("along-shape", "branches"), default="along-shape",
                        help="the rule before against now (default), or now without and with the turn into the "
                             "larger branch")
    parser.add_argument("--pictures", type=Path, default=None, help="a folder of target pictures to add")
    args = parser.parse_args()
    if args.seeds < 2:
        parser.error("--seeds must be at least 2 (a standard error needs pairs)")
    model = get_model("vines")
    guide = Guide.load(args.guide)
    engines = {"guided SMC-10": {"particles": 10, "guide": guide}, "SMC-200": {"particles": 200}}
    runs, summary = [], []
    before_rule = {"along-shape": {"along_shape": False}, "branches": {"branches": False}}[args.compare]
    sets = [(face, glyph_set(face)) for face in args.faces]
    if args.pictures is not None:
        sets.append((args.pictures.name, [load_target_image(p) for p in sorted(args.pictures.iterdir())
                                          if p.suffix.lower() in (".png", ".jpg", ".jpeg")]))
    for face, targets in sets:
        changed = []
        for target in targets:
            start, before = lowest_point_start(target.mask, **before_rule)
            _, after = lowest_point_start(target.mask)
            if not np.allclose(before, after):
                changed.append((target, start, before, after))
        print(f"{face}: {len(changed)} of {len(targets)} targets start in another direction", flush=True)
        if not changed:
            continue
        for label, settings in engines.items():
            pairs = []
            for target, start, before, after in changed:
                for seed in range(args.seeds):
                    scores = [smc(model, ShapeMatch(TargetImage(target.name, target.mask, start, direction)),
                                  seed=seed, workers=1, **settings).best_score for direction in (before, after)]
                    pairs.append(scores)
                    runs.append({"face": face, "engine": label, "target": target.name, "seed": seed,
                                 "before": scores[0], "after": scores[1],
                                 "direction_before": list(before), "direction_after": list(after)})
            a = np.array(pairs)
            d = a[:, 1] - a[:, 0]
            row = {"face": face, "engine": label, "glyphs": len(changed), "runs": len(d),
                   "mean_before": float(a[:, 0].mean()), "mean_after": float(a[:, 1].mean()),
                   "mean_difference": float(d.mean()), "standard_error": float(d.std(ddof=1) / math.sqrt(len(d))),
                   "under_0.1_before": int((a[:, 0] < 0.1).sum()), "under_0.1_after": int((a[:, 1] < 0.1).sum())}
            summary.append(row)
            print(f"  {label}: {row['mean_before']:.3f} -> {row['mean_after']:.3f} "
                  f"({row['mean_difference']:+.3f} +- {row['standard_error']:.3f}; under 0.1: "
                  f"{row['under_0.1_before']} -> {row['under_0.1_after']})", flush=True)
    RESULTS.mkdir(exist_ok=True)
    result = {"command": f"python bench/start_directions.py --faces {' '.join(args.faces)} --guide {args.guide} "
                         f"--seeds {args.seeds} --name {args.name} --compare {args.compare}"
                         + (f" --pictures {args.pictures}" if args.pictures is not None else ""),
              "machine": {"platform": platform.platform(), "python": platform.python_version()},
              "summary": summary, "runs": runs}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(result, indent=1) + "\n")
    fig, axes = plt.subplots(1, len(summary), figsize=(3.2 * len(summary), 3.4), squeeze=False)
    for ax, row in zip(axes[0], summary):
        mine = [r for r in runs if r["face"] == row["face"] and r["engine"] == row["engine"]]
        ax.scatter([r["before"] for r in mine], [r["after"] for r in mine], s=9, alpha=0.6)
        ax.plot([-0.1, 1], [-0.1, 1], color="grey", lw=0.8)
        ax.set_title(f"{row['face']}\n{row['engine']}", fontsize=9)
        ax.set_xlabel({"along-shape": "toward the centroid (before)",
                       "branches": "without the larger branch"}[args.compare], fontsize=8)
        ax.set_ylabel({"along-shape": "along the shape (now)",
                       "branches": "into the larger branch (now)"}[args.compare], fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=120)


if __name__ == "__main__":
    main()
