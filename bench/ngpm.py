"""Neurally-guided vines (seed 004 section 5.2): Figures 5a, 5b, 6a, 6b, and the circuit
comparison of Figure 12, on this machine.

Guides are trained on SMC traces of scribble targets and tested only on glyphs (DejaVu
Sans Bold; never trained on). For each target and particle count, SMC runs ``--reps``
times; a run's similarity is seed 004's normalised similarity of one particle drawn from
the final weights; a target's figure is the median over its runs, and the curves show the
mean over targets with a 95% bootstrap interval (over targets). Every run, guided or
unguided, resamples adaptively (when the effective sample size drops below half the
particles; ``--ess every`` resamples at every emit instead).

    python bench/ngpm.py --traces DIR [--circuit-traces DIR] [--targets 30] [--reps 3]
                         [--iterations 20000] [--stages train eval speed circuit rate] [--ess 0.5]

``train`` fits every guide the figures need into bench/results/ngpm_guides/ (kept between
runs; a finished guide is reused, an interrupted one resumes from its checkpoint):
the four feature conditions (constant, local, local+target, all; 4-component mixtures,
all traces), the no-mixture ablation, the papers' constant Adam step size (procmod anneals
it by default), training-set sizes for Figure 6b, and a circuit
guide (local state + partial-output features; the circuit score has no target image). ``eval`` runs the
quality comparisons (5a, 6a, 6b); ``speed`` (5b) and ``circuit`` (Fig. 12) the timed ones,
which want a quiet machine; ``rate`` times trace generation with 2 worker processes. Results:
bench/results/ngpm.json, ngpm.png, ngpm_circuit.png.
"""

from __future__ import annotations

import argparse
import json
import sys
import tempfile
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from procmod.data import glyph_set  # noqa: E402
from procmod.guide import FeatureSettings, Guide  # noqa: E402
from procmod.guide.traces import generate_traces, load_traces  # noqa: E402
from procmod.guide.train import train_guide  # noqa: E402
from procmod.infer import smc  # noqa: E402
from procmod.models import get_model  # noqa: E402
from procmod.parallel import open_executor  # noqa: E402
from procmod.targets import Circuit, ShapeMatch  # noqa: E402

RESULTS = Path(__file__).resolve().parent / "results"
GUIDES = RESULTS / "ngpm_guides"
CONDITIONS = ("constant", "local", "local+target", "all")
SIZES = (10, 100, 500, 1000, 2000, 5000)  # plus all traces (seed 004 Fig. 6b goes to 10,000)
BATCH_ABLATION = 4  # traces per Adam step of the optimisation-budget ablation (Fig. 6b)
PARTICLES_5A = tuple(range(1, 11))
UNGUIDED_5B = (1, 2, 5, 10, 20, 50, 100, 150, 200, 300, 400, 600)
GUIDED_5B = (1, 2, 3, 5, 7, 10, 15, 20, 40)
CIRCUIT_PARTICLES = (1, 2, 5, 10, 20, 50)
ESS_THRESHOLD = 0.5  # every SMC run, guided or not, resamples when ESS < 0.5 N (--ess)


def guide_specs(n_traces: int) -> dict:
    """name -> (features, mixture, traces used, step-size schedule, traces per Adam step)."""
    specs = {c: (c, 4, n_traces, "cosine", 1) for c in CONDITIONS}
    specs["all-k1"] = ("all", 1, n_traces, "cosine", 1)
    specs["all-constant-lr"] = ("all", 4, n_traces, "constant", 1)  # the papers' training exactly
    for size in SIZES:
        if size < n_traces:
            specs[f"all-n{size}"] = ("all", 4, size, "cosine", 1)
    # 20000 steps of one trace visit at most 20000 traces: does a larger training set
    # help once the optimiser sees more of it? (4 traces a step: each of 10,000 ~8 times)
    specs[f"all-batch{BATCH_ABLATION}"] = ("all", 4, n_traces, "cosine", BATCH_ABLATION)
    return specs


def train_all(model, traces_dir: Path, circuit_dir: Path | None, iterations: int, count: int | None,
              only: list | None) -> dict:
    _, traces = load_traces(traces_dir, count)
    reports = {}
    GUIDES.mkdir(parents=True, exist_ok=True)
    jobs = [(name, traces, *spec) for name, spec in guide_specs(count or len(traces)).items()]
    if circuit_dir is not None:
        _, circuit = load_traces(circuit_dir)
        jobs.append(("circuit", circuit, "local+partial", 4, len(circuit), "cosine", 1))
    if only:  # in the order given
        jobs = sorted((job for job in jobs if job[0] in only), key=lambda job: only.index(job[0]))
    for name, trace_list, features, mixture, used, schedule, batch in jobs:
        if len(trace_list) < used:
            raise SystemExit(f"guide {name} needs {used} traces; {len(trace_list)} are ready")
        out = GUIDES / name
        if out.with_suffix(".json").exists():
            info = json.loads(out.with_suffix(".json").read_text())["info"]
            print(f"guide {name}: already trained ({info['traces']} traces, {info['seconds']:.0f} s)")
        else:
            t0 = time.perf_counter()
            _, info = train_guide(model, None, out, settings=FeatureSettings.condition(features), mixture=mixture,
                                  iterations=iterations, schedule=schedule, traces=trace_list[:used], seed=0,
                                  batch=batch)
            print(f"guide {name}: {used} traces, {iterations} steps of {batch}, {time.perf_counter() - t0:.0f} s, "
                  f"final nll {info['final_nll']:.1f}")
        reports[name] = {k: v for k, v in info.items() if k not in ("curve", "weights", "metadata")}
    return reports


def _similarity_of_sample(result, target, seed: int) -> float:
    w = np.exp(np.array(result.log_weights) - max(result.log_weights))
    pick = np.random.default_rng(seed).choice(len(w), p=w / w.sum())
    return target.score(result.samples[pick].output)


def run_grid(model, targets, particles, reps: int, guide=None) -> dict:
    """particles -> {"per_target": [median over reps], "seconds": mean seconds per run}."""
    out = {}
    for n in particles:
        medians, seconds = [], []
        for shape in targets:
            sims = []
            for rep in range(reps):
                t0 = time.perf_counter()
                result = smc(model, shape, particles=n, seed=1000 * rep + n, guide=guide,
                             ess_threshold=ESS_THRESHOLD)
                seconds.append(time.perf_counter() - t0)
                sims.append(_similarity_of_sample(result, shape, rep))
            medians.append(float(np.median(sims)))
        out[n] = {"per_target": medians, "seconds": float(np.mean(seconds))}
    return out


def summarise(grid: dict, rng: np.random.Generator) -> dict:
    """Mean over targets with a 95% bootstrap interval (over targets)."""
    rows = {}
    for n, cell in grid.items():
        values = np.array(cell["per_target"])
        boots = [rng.choice(values, len(values)).mean() for _ in range(2000)]
        rows[str(n)] = {"similarity": float(values.mean()), "low": float(np.percentile(boots, 2.5)),
                        "high": float(np.percentile(boots, 97.5)), "seconds": cell["seconds"]}
    return rows


def time_to_reach(curve: dict, level: float) -> float | None:
    """Least seconds per run among settings whose similarity reaches ``level``, with linear
    interpolation between neighbouring settings (None if never reached)."""
    points = sorted((row["seconds"], row["similarity"]) for row in curve.values())
    best_so_far = -np.inf
    previous = None
    for seconds, sim in points:
        if sim >= level:
            if previous is not None and previous[1] < level:
                s0, q0 = previous
                return float(s0 + (seconds - s0) * (level - q0) / (sim - q0))
            return float(seconds)
        if sim > best_so_far:
            best_so_far = sim
            previous = (seconds, sim)
    return None


def _setup(model, args) -> tuple:
    """Test targets and trained guides; compiles the kernels outside any timing."""
    targets = [ShapeMatch(t) for t in glyph_set("dejavu-sans")][: args.targets]
    guides = {name: Guide.load(GUIDES / name) for name in
              list(CONDITIONS) + ["all-k1", "all-constant-lr", "circuit", f"all-batch{BATCH_ABLATION}"]
              + [f"all-n{s}" for s in SIZES]
              if (GUIDES / f"{name}.json").exists()}
    smc(model, targets[0], particles=5, seed=0)
    smc(model, targets[0], particles=5, seed=0, guide=guides["all"])
    return targets, guides


def evaluate(model, args) -> dict:
    """Figures 5a, 6a and 6b: similarity at 1-10 particles (seconds recorded, not the point)."""
    targets, guides = _setup(model, args)
    rng = np.random.default_rng(0)
    results = {"targets": [t.name for t in targets], "reps": args.reps, "ess_threshold": ESS_THRESHOLD}
    print("Figure 5a: similarity vs particles")
    fig5a = {"unguided": summarise(run_grid(model, targets, PARTICLES_5A, args.reps), rng)}
    for c in CONDITIONS:
        fig5a[c] = summarise(run_grid(model, targets, PARTICLES_5A, args.reps, guides[c]), rng)
    for name, rows in fig5a.items():
        print(f"  {name:13s} " + " ".join(f"{rows[str(n)]['similarity']:.2f}" for n in PARTICLES_5A))
    results["fig5a"] = fig5a
    print("Figure 6a: mixtures")
    results["fig6a"] = {"4 components": fig5a["all"],
                        "no mixture": summarise(run_grid(model, targets, PARTICLES_5A, args.reps, guides["all-k1"]), rng)}
    if "all-constant-lr" in guides:  # training ablation: the papers' constant Adam step size
        results["fig6a"]["constant step size"] = summarise(
            run_grid(model, targets, PARTICLES_5A, args.reps, guides["all-constant-lr"]), rng)
    for name, rows in results["fig6a"].items():
        print(f"  {name:19s} " + " ".join(f"{rows[str(n)]['similarity']:.2f}" for n in PARTICLES_5A))
    print("Figure 6b: training-set size (10 particles)")
    sizes = {}
    for size in SIZES:
        if f"all-n{size}" in guides:
            sizes[size] = summarise(run_grid(model, targets, (10,), args.reps, guides[f"all-n{size}"]), rng)["10"]
    sizes[guides["all"].info["traces"]] = fig5a["all"]["10"]
    results["fig6b"] = {str(k): v for k, v in sorted(sizes.items())}
    for k, v in sorted(sizes.items()):
        print(f"  {k:5d} traces: {v['similarity']:.3f}")
    name = f"all-batch{BATCH_ABLATION}"
    if name in guides:  # the same traces as "all", BATCH_ABLATION of them per Adam step
        row = summarise(run_grid(model, targets, (10,), args.reps, guides[name]), rng)["10"]
        results["fig6b_batch"] = {"traces": guides[name].info["traces"], "batch": BATCH_ABLATION, **row}
        print(f"  {guides[name].info['traces']:5d} traces, {BATCH_ABLATION} per step: {row['similarity']:.3f}")
    return results


def evaluate_speed(model, args) -> dict:
    """Figure 5b (wall time to reach a similarity, guided vs unguided): timed, for a quiet
    machine."""
    targets, guides = _setup(model, args)
    rng = np.random.default_rng(1)
    results = {"speed_targets": len(targets), "speed_reps": args.reps, "speed_ess_threshold": ESS_THRESHOLD}
    print("Figure 5b: time to reach a similarity")
    unguided = summarise(run_grid(model, targets, UNGUIDED_5B, args.reps), rng)
    guided = summarise(run_grid(model, targets, GUIDED_5B, args.reps, guides["all"]), rng)
    levels = [round(x, 2) for x in np.arange(0.05, 0.96, 0.05)]
    speedups = []
    for level in levels:
        tu, tg = time_to_reach(unguided, level), time_to_reach(guided, level)
        speedups.append({"similarity": level, "unguided_seconds": tu, "guided_seconds": tg,
                         "speedup": (tu / tg) if tu and tg else None})
    results["fig5b"] = {"unguided": unguided, "guided": guided, "speedups": speedups}
    for name, rows in (("unguided", unguided), ("guided", guided)):
        print(f"  {name:9s} " + " ".join(f"{n}:{r['similarity']:.2f}/{r['seconds']:.3f}s" for n, r in rows.items()))
    for row in speedups:
        if row["speedup"]:
            print(f"  similarity {row['similarity']:.2f}: unguided {row['unguided_seconds']:.3f} s, "
                  f"guided {row['guided_seconds']:.3f} s, {row['speedup']:.1f}x")
    return results


def evaluate_circuit(model, args) -> dict:
    """The circuit comparison of Figure 12 (timed: wants a quiet machine)."""
    _, guides = _setup(model, args)
    if "circuit" not in guides:
        print("no circuit guide: train one with --circuit-traces DIR --only circuit --stages train")
        return {}
    rng = np.random.default_rng(2)
    print("Circuit (Figure 12): score vs particles")
    target = [Circuit()]
    results = {"circuit_traces": guides["circuit"].info["traces"], "circuit": {
        "unguided": summarise(run_grid(model, target, CIRCUIT_PARTICLES, args.circuit_reps), rng),
        "guided": summarise(run_grid(model, target, CIRCUIT_PARTICLES, args.circuit_reps, guides["circuit"]), rng)}}
    for name, rows in results["circuit"].items():
        print(f"  {name:9s} " + " ".join(f"{n}:{rows[str(n)]['similarity']:.2f}/{rows[str(n)]['seconds']:.2f}s"
                                         for n in CIRCUIT_PARTICLES))
    return results


def measure_rate(count: int = 16) -> dict:
    with tempfile.TemporaryDirectory() as tmp, open_executor(workers=2) as executor:
        summary = generate_traces("vines", "scribble", count, tmp, particles=600, seed=12345, executor=executor)
    print(f"trace generation, 2 workers: {summary['traces_per_hour']:.0f} traces/hour ({count} traces)")
    return summary


def plot(results: dict) -> None:
    fig, axes = plt.subplots(1, 4, figsize=(20, 4.5))
    ax = axes[0]
    for name, rows in results["fig5a"].items():
        ns = [int(n) for n in rows]
        ax.plot(ns, [rows[str(n)]["similarity"] for n in ns], marker="o", label=name)
        ax.fill_between(ns, [rows[str(n)]["low"] for n in ns], [rows[str(n)]["high"] for n in ns], alpha=0.15)
    ax.set(title="5a: similarity vs particles (glyphs)", xlabel="particles", ylabel="median normalised similarity")
    ax.legend(fontsize=8)
    ax = axes[1]
    for name in ("unguided", "guided"):
        rows = results["fig5b"][name]
        pts = sorted((r["seconds"], r["similarity"]) for r in rows.values())
        ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=name)
    ax.set_xscale("log")
    ax.set(title="5b: similarity vs seconds per run", xlabel="seconds per target (log)", ylabel="similarity")
    ax.legend()
    ax = axes[2]
    for name, rows in results["fig6a"].items():
        ns = [int(n) for n in rows]
        ax.plot(ns, [rows[str(n)]["similarity"] for n in ns], marker="o", label=name)
        ax.fill_between(ns, [rows[str(n)]["low"] for n in ns], [rows[str(n)]["high"] for n in ns], alpha=0.15)
    ax.set(title="6a: mixture proposals; training schedule", xlabel="particles", ylabel="similarity")
    ax.legend()
    ax = axes[3]
    sizes = sorted(int(k) for k in results["fig6b"])
    ax.errorbar(sizes, [results["fig6b"][str(s)]["similarity"] for s in sizes],
                yerr=[[results["fig6b"][str(s)]["similarity"] - results["fig6b"][str(s)]["low"] for s in sizes],
                      [results["fig6b"][str(s)]["high"] - results["fig6b"][str(s)]["similarity"] for s in sizes]],
                marker="o")
    if "fig6b_batch" in results:
        row = results["fig6b_batch"]
        ax.errorbar([row["traces"]], [row["similarity"]], yerr=[[row["similarity"] - row["low"]], [row["high"] - row["similarity"]]],
                    marker="s", color="C3", label=f"{row['batch']} traces per Adam step")
        ax.legend(fontsize=8)
    ax.set_xscale("log")
    ax.set(title="6b: training-set size (10 particles)", xlabel="training traces (log)", ylabel="similarity")
    fig.tight_layout()
    fig.savefig(RESULTS / "ngpm.png", dpi=110)
    plt.close(fig)
    if "circuit" in results:
        fig, ax = plt.subplots(figsize=(6, 4.5))
        for name, rows in results["circuit"].items():
            pts = sorted((r["seconds"], r["similarity"]) for r in rows.values())
            ax.plot([p[0] for p in pts], [p[1] for p in pts], marker="o", label=name)
        ax.set_xscale("log")
        ax.set(title="circuit score vs seconds per run (vines)", xlabel="seconds (log)", ylabel="circuit score")
        ax.legend()
        fig.tight_layout()
        fig.savefig(RESULTS / "ngpm_circuit.png", dpi=110)
        plt.close(fig)


def main() -> None:
    global RESULTS, GUIDES, ESS_THRESHOLD
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--traces", type=Path, required=True, help="scribble traces of vines (procmod guide traces)")
    parser.add_argument("--circuit-traces", type=Path, help="circuit traces of vines")
    parser.add_argument("--targets", type=int, default=30)
    parser.add_argument("--reps", type=int, default=3)
    parser.add_argument("--circuit-reps", type=int, default=20)
    parser.add_argument("--iterations", type=int, default=20000)
    parser.add_argument("--count", type=int, help="use the first COUNT traces (default: all)")
    parser.add_argument("--only", nargs="+", help="train only these guides, in this order")
    parser.add_argument("--stages", nargs="+", default=["train", "eval", "speed", "circuit", "rate"],
                        choices=("train", "eval", "speed", "circuit", "rate"))
    parser.add_argument("--results", type=Path, default=RESULTS, help="where results and guides go")
    parser.add_argument("--ess", default=str(ESS_THRESHOLD),
                        help="resample when the effective sample size falls below ESS x particles, in every "
                             "run, guided or not (default 0.5; 'every' resamples at every emit)")
    args = parser.parse_args()
    ESS_THRESHOLD = None if args.ess == "every" else float(args.ess)
    RESULTS, GUIDES = args.results, args.results / "ngpm_guides"
    model = get_model("vines")
    path = RESULTS / "ngpm.json"
    results = json.loads(path.read_text()) if path.exists() else {}
    results["python"] = sys.version.split()[0]
    if "train" in args.stages:
        results.setdefault("training", {}).update(
            train_all(model, args.traces, args.circuit_traces, args.iterations, args.count, args.only))
    if "eval" in args.stages:
        results.update(evaluate(model, args))
        # every guide's training record, from its metadata (training jobs may run in parallel)
        results["training"] = {p.stem: {k: v for k, v in json.loads(p.read_text())["info"].items() if k != "curve"}
                               for p in sorted(GUIDES.glob("*.json")) if not p.name.endswith(".ckpt.json")}
    if "speed" in args.stages:
        results.update(evaluate_speed(model, args))
    if "circuit" in args.stages:
        results.update(evaluate_circuit(model, args))
    if "rate" in args.stages:
        results["trace_rate_2_workers"] = measure_rate()
    RESULTS.mkdir(parents=True, exist_ok=True)
    path.write_text(json.dumps(results, indent=1) + "\n")
    if "fig5a" in results:
        plot(results)
    print(f"wrote {path}")


if __name__ == "__main__":
    main()
