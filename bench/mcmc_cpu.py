"""procmod's MCMC against WebPPL's MH at equal CPU time, for a machine others share.

    python bench/mcmc_cpu.py                                   # WebPPL's runs of bench/results/vs_webppl_mcmc_base.json
    python bench/mcmc_cpu.py --webppl bench/results/OTHER.json --name mcmc_cpu_other

``bench/vs_webppl.py --mcmc`` gives procmod's engines the wall time WebPPL's MH took. On a
machine shared with other work that time stretches (and differs between the two runs),
so this script takes the WebPPL MH runs of a vs_webppl results file measured while the
machine was quiet (its wall time beyond a 1-sample run, then close to its CPU time) and
runs procmod's ``mcmc`` engine in process on the same target and seed with that many
seconds of this process's **CPU time** as its budget. The engine's clock is
``time.perf_counter``; it is pointed at ``time.process_time`` for this script only (a
shared machine slows both systems' CPU seconds a little through caches, procmod's
here, not WebPPL's quiet run: conservative for procmod). procmod's score is its own
similarity (the scorer's to 1e-15, docs/vines_smc.md). Results:
bench/results/NAME.json and NAME.png.
"""

from __future__ import annotations

import argparse
import json
import platform
import sys
import time
from pathlib import Path

import numpy as np

RESULTS = Path(__file__).resolve().parent / "results"
sys.path.insert(0, str(Path(__file__).resolve().parent))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--webppl", type=Path, default=RESULTS / "vs_webppl_mcmc_base.json",
                        help="a vs_webppl --mcmc results file measured on a quiet machine")
    parser.add_argument("--name", default="mcmc_cpu")
    parser.add_argument("--engine-kwargs", default="{}", help="JSON keyword arguments for procmod.infer.mcmc")
    args = parser.parse_args()

    time.perf_counter = time.process_time  # the engine's budget in CPU seconds (module docstring)
    from procmod.data import target_from_spec
    from procmod.infer import Budget, mcmc
    from procmod.models import get_model
    from vs_webppl import summarise

    kwargs = json.loads(args.engine_kwargs)
    source = json.loads(args.webppl.read_text())
    model = get_model("vines")
    rows = []
    for r in source["mcmc_runs"]:
        if r["system"] != "webppl":
            continue
        target = target_from_spec(r["target"])
        t = time.process_time()
        result = mcmc(model, target, seed=r["seed"], budget=Budget(seconds=r["beyond_seconds"]), **kwargs)
        cpu = time.process_time() - t
        rows.append({"system": "webppl", "method": "MH", "set": r["set"], "target": r["target"], "seed": r["seed"],
                     "similarity": r["similarity"], "seconds": r["beyond_seconds"], "beyond_seconds": r["beyond_seconds"]})
        rows.append({"system": "procmod", "method": "mcmc", "set": r["set"], "target": r["target"], "seed": r["seed"],
                     "similarity": result.best_score, "seconds": cpu, "beyond_seconds": cpu,
                     "evaluations": result.evaluations, "calls": result.best.n_nodes})
        print(f"{r['set']:>10} {r['target']:>22} seed {r['seed']}: MH {r['similarity']:.3f} in {r['beyond_seconds']:.2f} s; "
              f"procmod mcmc {result.best_score:.3f} in {cpu:.2f} CPU s ({result.evaluations / cpu:.0f} moves/s)",
              flush=True)

    summary = summarise(rows, ("system", "method", "set"))
    RESULTS.mkdir(exist_ok=True)
    out = {"command": "python bench/mcmc_cpu.py " + " ".join(sys.argv[1:]), "webppl_source": str(args.webppl.name),
           "engine_kwargs": kwargs, "machine": {"platform": platform.platform(), "python": platform.python_version()},
           "summary": summary, "runs": rows}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(out, indent=1) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    sets = sorted({s["set"] for s in summary})
    fig, ax = plt.subplots(figsize=(5, 3.2))
    for k, (system, method) in enumerate((("webppl", "MH"), ("procmod", "mcmc"))):
        med = [next(s for s in summary if s["set"] == name and s["system"] == system)["similarity_median"]
               for name in sets]
        x = np.arange(len(sets)) + (k - 0.5) * 0.35
        ax.bar(x, [m[0] for m in med], 0.35, label=f"{system} {method}",
               yerr=[[m[0] - m[1] for m in med], [m[2] - m[0] for m in med]], capsize=3)
    ax.set_xticks(np.arange(len(sets)), sets)
    ax.set_ylabel("median similarity at equal CPU time")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=120)
    for s in summary:
        m = s["similarity_median"]
        print(f"{s['system']:>8} {s['method']:>5} {s['set']:>10} median {m[0]:.3f} [{m[1]:.3f}, {m[2]:.3f}]")
    print(f"wrote {RESULTS / (args.name + '.json')}")


if __name__ == "__main__":
    main()
