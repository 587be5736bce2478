"""What one RJMCMC move costs on vines: a full replay of the edited choice map against the
incremental replay from the state's checkpoints (procmod/infer/traced.py).

    python bench/mcmc_cost.py                  # glyph "a" (DejaVu Sans Bold), as vs_webppl's first target

States of three sizes are taken from one chain run for 1,500 / 6,000 / 20,000 moves; from
each, the same ``--moves`` proposals are replayed both ways (the same seed per move), and
the CPU time per move is recorded (process time: the machine may be shared). The two
replays give the same derivation bit for bit (tests/test_mcmc_incremental.py), so only
the time differs. Results: bench/results/mcmc_cost.json and .png.
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


def main() -> None:
    from procmod.data import target_from_spec
    from procmod.infer import Budget, mcmc
    from procmod.infer.common import evaluate
    from procmod.infer.mcmc import _edited_dict, propose
    from procmod.infer.traced import EditedChoices, replay_traced, trace
    from procmod.models import get_model

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--target", default="glyph:dejavu-sans/a")
    parser.add_argument("--moves", type=int, default=600)
    parser.add_argument("--runs", type=int, nargs="+", default=[1500, 6000, 20000],
                        help="moves of the chain run each state is taken from")
    parser.add_argument("--name", default="mcmc_cost")
    args = parser.parse_args()

    target = target_from_spec(args.target)
    model = get_model("vines")
    configured = target.configure(model)
    rows = []
    for evaluations in args.runs:
        run = mcmc(model, target, seed=1, budget=Budget(evaluations=evaluations), init_particles=0)  # grown by moves
        state = trace(configured, target, run.samples[0].choice_map().raw, np.random.default_rng(0))
        rng = np.random.default_rng(0)
        moves = [propose(state, rng, 0.3, 0.1, 0.3) for _ in range(args.moves)]
        maps = [_edited_dict(state.derivation, p.overrides, p.removed) for p in moves]
        t = time.process_time()
        for choices in maps:
            evaluate(configured, target, (choices, 5, None))
        full = (time.process_time() - t) / len(maps)
        t = time.process_time()
        for p in moves:
            replay_traced(configured, target, state, EditedChoices(state, p.overrides, p.removed),
                          np.random.default_rng(5), edited=p.address)
        incremental = (time.process_time() - t) / len(moves)
        rows.append({"chain_moves": evaluations, "calls": len(state.nodes), "primitives": state.derivation.n_emits,
                     "full_ms": round(1e3 * full, 4), "incremental_ms": round(1e3 * incremental, 4),
                     "speedup": round(full / incremental, 2)})
        print(f"{rows[-1]['calls']} calls, {rows[-1]['primitives']} primitives: full replay {full * 1e3:.2f} ms, "
              f"incremental {incremental * 1e3:.2f} ms per move ({full / incremental:.1f}x)", flush=True)

    RESULTS.mkdir(exist_ok=True)
    out = {"command": "python bench/mcmc_cost.py " + " ".join(sys.argv[1:]), "target": args.target,
           "moves": args.moves, "machine": {"platform": platform.platform(), "python": platform.python_version()},
           "rows": rows}
    (RESULTS / f"{args.name}.json").write_text(json.dumps(out, indent=1) + "\n")
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    fig, ax = plt.subplots(figsize=(5, 3.2))
    calls = [r["calls"] for r in rows]
    ax.plot(calls, [r["full_ms"] for r in rows], "o-", label="full replay")
    ax.plot(calls, [r["incremental_ms"] for r in rows], "o-", label="incremental (checkpoints)")
    ax.set_xlabel("calls in the vine")
    ax.set_ylabel("CPU ms per move")
    ax.set_title(f"RJMCMC move on vines, {args.target}", fontsize=9)
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(RESULTS / f"{args.name}.png", dpi=120)
    print(f"wrote {RESULTS / (args.name + '.json')}")


if __name__ == "__main__":
    main()
