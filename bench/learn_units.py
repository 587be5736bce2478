"""Does what ``procmod learn`` learns depend on the units the examples were modelled in?

Maya works in centimetres, and its FBX and glTF exports often carry the unit as a scale
of 100 (or 0.01) on the root node; Blender and URDF work in metres. The same objects
should learn the same program whatever the unit. For each authored set this script
learns the set as it is and the same set exported at other scales through its
transforms (every world transform multiplied by ``diag(k, k, k, 1)``: parts, placements
and sizes all ``k`` times larger), with the same options and seed, and reports per
scale seed 000's Table-1 figures (|A0|, O_D(P0), |A*|, O_D(P*), search seconds) and two
Table-2 figures (structural novelty and visual similarity of the samples to the
examples, from 40 samples; the visual similarity compares silhouettes, which do not see
size). A learner that does not depend on units gives the same row at every scale, up to
rounding.

    python bench/learn_units.py [--sets castles,spaceships,ornaments,stations]
                                [--scales 1,100,0.01] [--particles 2] [--workers 2]
                                [--name learn_units]

Results: bench/results/NAME.json and NAME.png. Run from another checkout with
``PYTHONPATH=that/checkout python bench/learn_units.py`` to measure that code.
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

import procmod  # noqa: E402
from procmod.core import run_forward  # noqa: E402
from procmod.learn import read_examples  # noqa: E402
from procmod.learn.evaluate import hierarchy_from_dict, signature, table2  # noqa: E402
from procmod.learn.examples import ExampleNode  # noqa: E402
from procmod.learn.program import derivation_hierarchies, program_model  # noqa: E402
from procmod.learn.search import SearchOptions, run_search  # noqa: E402
from procmod.parallel import open_executor  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]
RESULTS = Path(__file__).resolve().parent / "results"


def scaled(example_set, k: float):
    """``example_set`` exported at ``k`` times its size, through the transforms."""
    scale = np.diag([k, k, k, 1.0])

    def walk(n):
        return ExampleNode(n.part, scale @ np.asarray(n.transform, dtype=np.float64), [walk(c) for c in n.children])

    return type(example_set)(example_set.parts, [walk(e) for e in example_set.examples], example_set.base_dir)


def learn_row(example_set, particles: int, workers: int, seed: int, samples: int) -> dict:
    options = SearchOptions(particles=particles, seed=seed)
    t0 = time.perf_counter()
    with open_executor(workers) as ex:
        r = run_search(example_set, options, ex)
    wall = time.perf_counter() - t0
    model = program_model(r.program, "bench")
    hierarchies = [hierarchy_from_dict(h) for i in range(samples)
                   for h in derivation_hierarchies(run_forward(model, np.random.default_rng([seed, i])))]
    t2 = table2(example_set.examples, hierarchies, example_set.parts)
    known = {signature(e) for e in example_set.examples}
    return {"A0": r.table["A0"], "O_P0": r.table["O_P0"], "A_star": r.table["A_star"], "O_Pstar": r.table["O_Pstar"],
            "search_seconds": r.table["seconds"], "wall_seconds": wall,
            "pct_new_structures": 100 * float(np.mean([signature(h) not in known for h in hierarchies])),
            "s_vis_examples": t2["s_vis_examples"], "s_vis_samples": t2["s_vis_samples"]}


def plot(rows: list, sets: list, scales: list, path: Path, title: str) -> None:
    fig, axes = plt.subplots(1, 3, figsize=(14, 4))
    width = 0.8 / len(scales)
    for j, k in enumerate(scales):
        at = np.arange(len(sets)) + (j - (len(scales) - 1) / 2) * width
        by = {r["set"]: r for r in rows if r["scale"] == k}
        for ax, field in zip(axes, ("A_star", "O_Pstar", "search_seconds")):
            ax.bar(at, [by[s][field] if s in by else np.nan for s in sets], width, label=f"x{k:g}")
    for ax, label in zip(axes, ("abstractions learned |A*|", "O_D(P*)", "search seconds")):
        ax.set_xticks(np.arange(len(sets)), sets)
        ax.set_title(label)
    axes[0].legend(title="examples exported at")
    fig.suptitle(title)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


def main(argv=None) -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sets", default="castles,spaceships,ornaments,stations")
    ap.add_argument("--scales", default="1,100,0.01")
    ap.add_argument("--particles", type=int, default=2)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--samples", type=int, default=40)
    ap.add_argument("--name", default="learn_units")
    args = ap.parse_args(argv)
    sets = [s for s in args.sets.split(",") if s]
    scales = [float(k) for k in args.scales.split(",") if k]
    rows = []
    for name in sets:
        example_set = read_examples(ROOT / f"examples_sets/learn/{name}/examples.json")
        for k in scales:
            row = {"set": name, "scale": k,
                   **learn_row(scaled(example_set, k), args.particles, args.workers, args.seed, args.samples)}
            rows.append(row)
            print(f"{name} x{k:g}: |A0| {row['A0']} O_D(P0) {row['O_P0']:.1f} -> |A*| {row['A_star']} "
                  f"O_D(P*) {row['O_Pstar']:.1f} in {row['search_seconds']:.1f} s; new {row['pct_new_structures']:.0f}%, "
                  f"s_vis {row['s_vis_examples']:.2f} / {row['s_vis_samples']:.2f}", flush=True)
    RESULTS.mkdir(exist_ok=True)
    doc = {"command": " ".join(["python", "bench/learn_units.py", *sys.argv[1:]]),
           "procmod": str(Path(procmod.__file__).resolve().parent),
           "machine": {"python": platform.python_version(), "processor": platform.processor() or platform.machine()},
           "options": vars(args), "rows": rows}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(doc, indent=1) + "\n")
    plot(rows, sets, scales, RESULTS / f"{args.name}.png", f"procmod learn at other units ({args.name})")
    print(f"wrote {RESULTS / args.name}.json, .png")


if __name__ == "__main__":
    main()
