"""Edge-category tagger only: held-out accuracy of the string tagger on a grown collection.

The tagger part of ``bench/strings.py`` without the VAE, prior samples, Table 2 and
instantiation, for tagger settings and collection sizes the full bench does not run: the
same growth, split, categories, training strings, vocabulary and measurement as
``train_model`` and ``bench/strings.py`` (for the same collection and settings it gives the
same figures).

    .venv/bin/python bench/strings_tagger.py --set castle --count 720 --work /tmp/tagger_work
    .venv/bin/python bench/strings_tagger.py --set moonbase --graph-rounds 0 --work W  # no graph pass

Writes ``bench/results/strings_tagger_<set>_<count>.json`` and ``.png`` (training curve).
A run on the same ``--work`` folder reuses the grown collection and resumes the training.
To train on a GPU machine: ``--prepare-only`` here, ``--train-only --device cuda`` there
on a copy of the work folder (needs torch and procmod only), the tagger folder copied back,
then the same command here without either flag: the checkpoint holds CPU tensors and only
the measurement runs. ``train_seconds`` counts this run's training only: the epochs' own
times (and devices) are in ``history``.
"""

from __future__ import annotations

import argparse
import gzip
import json
import shlex
import sys
import time
from dataclasses import asdict
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent
sys.path.insert(0, str(ROOT.parent))
sys.path.insert(0, str(ROOT))

from strings import SETS, edge_category_figures  # noqa: E402

from procmod.parallel import open_executor  # noqa: E402
from procmod.strings.categories import EdgeCategories  # noqa: E402
from procmod.strings.tagger import TaggerConfig, train_tagger  # noqa: E402
from procmod.strings.pipeline import (collection_inputs, read_collection, split_shapes,  # noqa: E402
                                      tagger_training_set, vae_training_strings, write_collection)
from procmod.strings.sampling import DISTINCT_MODES, AugmentParams, augment  # noqa: E402
from procmod.strings.contacts import shape_graph  # noqa: E402
from procmod.strings.shapes import read_shapes  # noqa: E402
from procmod.strings.vae import Vocab, vocab_of  # noqa: E402


def grown_collection(args, folder: Path):
    """The set grown to ``--count`` shapes (read back when ``folder`` already holds it)."""
    inputs = read_shapes(SETS / f"{args.set}.json")
    if (folder / "shapes.json").is_file():
        return read_collection(folder), None
    t0 = time.perf_counter()
    with open_executor(args.workers) as executor:
        grown = augment(inputs, args.count, seed=args.seed, parallel=args.parallel, max_rounds=args.max_rounds,
                        executor=executor, seconds=args.augment_seconds,
                        params=AugmentParams(distinct=args.distinct))
    seconds = time.perf_counter() - t0
    write_collection(inputs, grown.shapes, folder, grown.rounds, 8, args.seed, sheet=False)
    return read_collection(folder), round(seconds, 1)


def write_training_inputs(path: Path, vocab, categories, examples) -> None:
    """The tagger's vocabulary, categories and (string, targets) pairs, for a machine that
    only trains (``--prepare-only`` here, ``--train-only`` there)."""
    data = {"vocab": vocab.chars, "categories": categories.to_json(), "examples": examples}
    with gzip.open(path, "wt") as f:
        json.dump(data, f)


def read_training_inputs(path: Path):
    with gzip.open(path, "rt") as f:
        data = json.load(f)
    return Vocab(data["vocab"]), EdgeCategories.from_json(data["categories"]), data["examples"]


def parser() -> argparse.ArgumentParser:
    """The script's options (the results file's ``command`` parses with these)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--set", default="castle", choices=("castle", "moonbase", "colonnade"))
    ap.add_argument("--count", type=int, default=360, help="collection size")
    ap.add_argument("--augment-seconds", type=float, default=600)
    ap.add_argument("--max-rounds", type=int, default=400,
                    help="growth rounds at most (400, as bench/strings.py; colonnade needs more past 184 shapes)")
    ap.add_argument("--distinct", choices=DISTINCT_MODES, default="histogram",
                    help="which grown variants are duplicates (histogram: seed 001's rule; graph: isomorphic graphs)")
    ap.add_argument("--parallel", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--epochs", type=int, default=24)
    ap.add_argument("--hidden", type=int, default=TaggerConfig.hidden)
    ap.add_argument("--lr-final", type=float, default=TaggerConfig.lr_final)
    ap.add_argument("--dropout", type=float, default=TaggerConfig.dropout)
    ap.add_argument("--graph-rounds", type=int, default=TaggerConfig.graph_rounds)
    ap.add_argument("--strings-per-shape", type=int, default=16, help="tagger training strings per shape")
    ap.add_argument("--work", type=Path, required=True, help="folder for the collection and the tagger")
    ap.add_argument("--device", default="cpu", help="torch device to train the tagger on (cpu, cuda)")
    ap.add_argument("--prepare-only", action="store_true",
                    help="grow the collection and write the tagger's training strings into --work, then stop")
    ap.add_argument("--train-only", action="store_true",
                    help="stop after training (reads what --prepare-only wrote, if there: no geometry is "
                         "computed); a rerun without this flag on the same --work finds the tagger trained")
    ap.add_argument("--out", type=Path, default=ROOT / "results")
    return ap


def main() -> None:
    args = parser().parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    name = f"{args.set}_{args.count}" + ("" if args.distinct == "histogram" else f"_{args.distinct}")
    work = args.work / name
    cache = work / f"tagger_inputs_s{args.strings_per_shape}_seed{args.seed}.json.gz"
    if args.train_only and cache.is_file():  # prepared elsewhere: no collection, no geometry needed
        vocab, categories, examples = read_training_inputs(cache)
    else:
        shape_set, growth_seconds = grown_collection(args, work / "collection")
        graphs = [shape_graph(shape_set, s) for s in shape_set.shapes]
        train_idx, test_idx = split_shapes(len(graphs), 0.2, args.seed,
                                           collection_inputs(work / "collection", len(graphs)))
        # as train_model: the tagger shares the VAE's vocabulary (8 strings a training shape)
        vocab = vocab_of(vae_training_strings(graphs, train_idx, 8, args.seed))
        categories, examples, _ = tagger_training_set(shape_set, graphs, train_idx, args.strings_per_shape,
                                                      args.seed)
    if args.prepare_only:
        write_training_inputs(cache, vocab, categories, examples)
        print(f"collection and training strings in {work}", flush=True)
        return
    config = TaggerConfig(epochs=args.epochs, hidden=args.hidden, lr_final=args.lr_final, dropout=args.dropout,
                          graph_rounds=args.graph_rounds)
    # one folder per setting (the training strings too: a resumed run must see the same data)
    folder = work / (f"tagger_g{args.graph_rounds}_h{args.hidden}_d{args.dropout}_lr{args.lr_final}"
                     f"_s{args.strings_per_shape}")
    t0 = time.perf_counter()
    tagger = train_tagger(examples, vocab, categories, folder, config, args.seed,
                          progress=lambda row: print(row, flush=True), device=args.device)
    train_seconds = time.perf_counter() - t0
    history = json.loads((folder / "tagger.json").read_text())["train"]["history"]
    if args.train_only:
        print(f"trained in {train_seconds:.0f} s: {folder}", flush=True)
        return
    rng = np.random.default_rng(args.seed)  # the bench's measurement, in the bench's order
    figures = edge_category_figures(tagger, shape_set, shape_set, [shape_set.shapes[i] for i in test_idx],
                                    [graphs[i] for i in test_idx], rng)
    # exactly what ran, and nothing else: explanations of a run go in docs/strings.md
    result = {"command": "python bench/strings_tagger.py " + shlex.join(sys.argv[1:]), "set": args.set,
              "distinct": args.distinct, "shapes": len(shape_set.shapes), "train_shapes": len(train_idx), "training_strings": len(examples),
              "growth_seconds": growth_seconds, "tagger": asdict(config), "train_seconds": round(train_seconds, 1),
              "history": history, "categories": len(categories) - 1, **figures}
    stem = args.out / f"strings_tagger_{name}"
    stem.with_suffix(".json").write_text(json.dumps(result, indent=1) + "\n")
    plot(result, stem.with_suffix(".png"))
    print(json.dumps({k: v for k, v in result.items() if k != "history"}), flush=True)


def plot(result: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots(figsize=(6, 4))
    hist = result["history"]
    ax.plot([h["epoch"] for h in hist], [h["train_accuracy"] for h in hist], label="training strings")
    ax.axhline(result["per_character_accuracy"], color="C1", ls="--", label="held out, per character")
    ax.axhline(result["voted_edge_accuracy"], color="C2", ls=":", label="held out, voted")
    ax.set(xlabel="epoch", ylabel="edge-category accuracy", ylim=(0.5, 1.0),
           title=f"{result['set']}, {result['shapes']} shapes"
                 + (f" (duplicates by {result['distinct']})" if result.get("distinct", "histogram") != "histogram" else "")
                 + f", {result['tagger']['graph_rounds']} graph rounds")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


if __name__ == "__main__":
    main()
