"""Seed 000 Tables 1-2 and Figure 6 on the authored example sets; exact marginal vs VI.

    python bench/learn.py [--sets spaceships,castles,ornaments,stations] [--particles 4]
                          [--workers 2] [--samples 100] [--vi-search spaceships]

For each set: structure search (``procmod.learn``, N particles through a process pool),
Table 1 (parts, |A0|, O_D(P0) = L - C, |A*|, O_D(P*), wall time of the search), Table 2
(s_struc among examples vs among samples with Welch's t-test on the pairwise values,
% new structures, s_max struc; s_vis and s_max vis from multi-view silhouettes), the
Figure-6 samples (P0, after phase 1, after phase 2), and the parameter-estimation
comparison: P0's parameters fitted with the exact marginal likelihood and with the
paper's score-function VI, both from the same re-initialised parameters of the learned
structure P* and for the same number of Adam steps (exact log p(D|P) reached, time).
``--vi-search SET`` also runs the whole search with VI on that set.

Writes ``bench/results/learn.json`` and ``bench/results/learn.png`` (Figure 6).
"""

from __future__ import annotations

import argparse
import io
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from procmod.core import run_forward  # noqa: E402
from procmod.learn import read_examples  # noqa: E402
from procmod.learn.evaluate import hierarchy_from_dict, table2  # noqa: E402
from procmod.learn.likelihood import fit, log_likelihood  # noqa: E402
from procmod.learn.pipeline import render_parts  # noqa: E402
from procmod.learn.preprocessing import preprocess  # noqa: E402
from procmod.learn.program import derivation_hierarchies, program_model  # noqa: E402
from procmod.learn.search import SearchOptions, run_search  # noqa: E402
from procmod.learn.structure import reset_parameters  # noqa: E402
from procmod.parallel import open_executor  # noqa: E402

SETS = ("spaceships", "castles", "ornaments", "stations")


def samples_of(program, n, seed):
    model = program_model(program, "bench")
    return [run_forward(model, np.random.default_rng([seed, i])) for i in range(n)]


def estimator_comparison(program, data, iterations: int, seed: int) -> dict:
    """Fit the learned structure's parameters from the P0-style initialisation with the
    exact marginal likelihood and with VI, same Adam steps; exact log p(D|P) reached."""
    out = {}
    for estimator in ("exact", "vi"):
        p = reset_parameters(program, data, np.random.default_rng(seed))
        r = fit(p, data, "free", iterations, estimator=estimator, seed=seed)
        out[estimator] = {"log_likelihood": r["log_likelihood"], "O_D": r["log_likelihood"] - p.complexity(),
                          "elbo": r["elbo"], "seconds": r["seconds"]}
    out["iterations"] = iterations
    return out


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sets", default=",".join(SETS))
    ap.add_argument("--particles", type=int, default=4)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--samples", type=int, default=100)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--vi-search", default="", help="comma-separated sets to also search with VI")
    ap.add_argument("--out", default=str(ROOT / "bench" / "results"))
    args = ap.parse_args(argv)
    out = Path(args.out)
    out.mkdir(parents=True, exist_ok=True)
    import torch
    torch.set_num_threads(1)
    results = {"command": "python bench/learn.py " + " ".join(argv if argv is not None else sys.argv[1:]),
               "machine": f"{os.cpu_count()} cores (shared)", "sets": {}}
    figure = []
    for name in args.sets.split(","):
        example_set = read_examples(ROOT / f"examples_sets/learn/{name}/examples.json")
        options = SearchOptions(particles=args.particles, seed=args.seed)
        t0 = time.perf_counter()
        with open_executor(args.workers) as ex:
            r = run_search(example_set, options, ex)
        wall = time.perf_counter() - t0
        samples = samples_of(r.program, args.samples, args.seed)
        sample_h = [hierarchy_from_dict(h) for d in samples for h in derivation_hierarchies(d)]
        t2 = table2(example_set.examples, sample_h[:40], example_set.parts)
        # % new structures over all samples (cheap); the pairwise tables use 40 of them
        from procmod.learn.evaluate import signature
        sigs = {signature(e) for e in example_set.examples}
        t2["pct_new_structures"] = 100 * float(np.mean([signature(h) not in sigs for h in sample_h]))
        t2["n_samples_new"] = len(sample_h)
        entry = {"table1": dict(r.table, wall_seconds=wall), "table2": t2,
                 "estimators": estimator_comparison(r.program, r.data, 2 * options.final_iterations, args.seed),
                 "trace": r.trace}
        if name in args.vi_search.split(","):
            t0 = time.perf_counter()
            with open_executor(args.workers) as ex:
                rv = run_search(example_set, SearchOptions(particles=args.particles, seed=args.seed,
                                                           estimator="vi"), ex)
            entry["vi_search"] = dict(rv.table, wall_seconds=time.perf_counter() - t0)
        results["sets"][name] = entry
        print(f"{name}: |A0| {r.table['A0']} O_D(P0) {r.table['O_P0']:.1f} -> |A*| {r.table['A_star']} "
              f"O_D(P*) {r.table['O_Pstar']:.1f} in {r.table['seconds']:.1f} s ({r.table['cpu_seconds']:.1f} CPU s, "
              f"{r.table['fits_run']} fits run, {r.table['fits_shared']} shared); s_struc {t2['s_struc_examples']:.2f} "
              f"vs {t2['s_struc_samples']:.2f} (p={t2['s_struc_p_value']:.2g}), new {t2['pct_new_structures']:.0f}%",
              flush=True)
        stages = [("P0", r.p0), ("after phase 1", r.after_phase1), ("after phase 2", r.program)]
        for label, prog in stages:
            ds = samples_of(prog, 5, args.seed + 1)
            figure.append((f"{name}: {label}", [render_parts(d.geometry(), 128) for d in ds]))
    (out / "learn.json").write_text(json.dumps(results, indent=1) + "\n")
    write_figure(figure, out / "learn.png")
    print(f"wrote {out / 'learn.json'} and {out / 'learn.png'}")


def write_figure(rows, path):
    from PIL import Image, ImageDraw
    if not rows:
        return
    tile = rows[0][1][0].size[0]
    label_w = 170
    width = label_w + tile * max(len(r[1]) for r in rows)
    sheet = Image.new("RGB", (width, tile * len(rows)), (255, 255, 255))
    draw = ImageDraw.Draw(sheet)
    for i, (label, images) in enumerate(rows):
        draw.text((6, i * tile + tile // 2 - 6), label, fill=(30, 30, 30))
        for j, im in enumerate(images):
            sheet.paste(im, (label_w + j * tile, i * tile))
    buffer = io.BytesIO()
    sheet.save(buffer, format="PNG")
    Path(path).write_bytes(buffer.getvalue())


if __name__ == "__main__":
    main()
