"""Seed 001 evaluation: Table 1 (inputs, collection growth), edge-category accuracy,
Table 2 (naive vs latent search graph), VAE prior samples, instantiation success, latent
walks (interpolation and latent paths).

    .venv/bin/python bench/strings.py                       # all three example sets
    .venv/bin/python bench/strings.py --sets castle --count 60 --epochs 5   # a quick look
    .venv/bin/python bench/strings.py --sets pavilion --results strings_pavilion ...   # the off-grid set

Writes ``bench/results/strings.json`` and ``bench/results/strings.png`` (plus a contact
sheet of instantiated prior samples per set, ``strings_<set>.png``). Work folders (the
collections and models) go to ``--work`` (default: a temporary folder).
"""

from __future__ import annotations

import argparse
import copy
import json
import shlex
import sys
import tempfile
import time
from pathlib import Path

import networkx as nx
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from procmod.parallel import open_executor  # noqa: E402
from procmod.strings.codec import encode, parse  # noqa: E402
from procmod.strings.categories import shape_labelings  # noqa: E402
from procmod.strings.tagger import TaggerConfig, tagging_accuracy, tagging_examples  # noqa: E402
from procmod.strings.latent import (GraphIndex, interpolate, latent_path, naive_graph, one_per_graph,  # noqa: E402
                                    path_statistics, perturb, sample_path, search_graph)
from procmod.strings.pipeline import (TrainedModel, collection_inputs, split_shapes, train_model,  # noqa: E402
                                      write_collection)
from procmod.strings.render import write_sheet  # noqa: E402
from procmod.strings.sampling import DISTINCT_MODES, AugmentParams, augment  # noqa: E402
from procmod.strings.contacts import shape_graph  # noqa: E402
from procmod.strings.shapes import histogram_distance, read_shapes  # noqa: E402
from procmod.strings.vae import VAEConfig  # noqa: E402

SETS = ROOT / "examples_sets" / "strings"
WALK_POINTS = 8  # points a latent walk decodes at: the segment's (interpolation) or the path's (latent path)


def triangles(shape_set, shape) -> int:
    return sum(12 if shape_set.library[p].kind == "box" else len(shape_set.library[p].faces) for p in shape.parts)


def graph_index(graphs):
    return GraphIndex(graphs)


def is_known(g, index) -> bool:
    return g in index


def rates(model, strings, known_index):
    valid = [s for s in strings if model.vae.is_valid(s)]
    unique = one_per_graph(valid, lambda s: parse(s).graph)  # (until 2026-12-06: distinct strings)
    novel = [s for s in unique if not is_known(parse(s).graph, known_index)]
    n = max(len(strings), 1)
    return {"decoded": len(strings), "valid": len(valid) / n, "unique": len(unique) / max(len(valid), 1),
            "novel_of_valid": len(novel) / max(len(unique), 1), "valid_count": len(valid),
            "unique_count": len(unique), "novel_count": len(novel)}, novel


def edge_category_figures(tagger, shape_set, collection_set, held_shapes, held_graphs, rng) -> dict:
    """Held-out edge-category accuracy: per character of 4 strings of each held-out graph
    (against the closest of the string's equivalent target sequences: the shape up to a
    turn / mirror and up to an automorphism of its graph; ``_without_automorphisms``: up to
    a turn / mirror only, the definition before automorphisms were forgiven), labelled by
    structured decoding (``_argmax``: each character's most probable category alone), and
    per edge after the vote over 8 strings (aligned by symmetry and automorphism): the soft
    vote with structured decoding (``voted_``, the default) and the paper's majority vote
    (``majority_voted_``). ``shape_set`` gives the part library for the truth,
    ``collection_set`` the training shapes the decoding and the vote use."""
    plain_rng = copy.deepcopy(rng)  # draws the same strings
    held = tagging_examples(shape_set, held_shapes, held_graphs, tagger.categories, 4, rng, every_symmetry=True)
    held_plain = tagging_examples(shape_set, held_shapes, held_graphs, tagger.categories, 4, plain_rng,
                                  every_symmetry=True, automorphisms=1)
    assert [t for t, _ in held] == [t for t, _ in held_plain]
    texts = [t for t, _ in held]
    t0 = time.perf_counter()
    decoded = tagger.labels(texts, collection_set)
    decode_seconds = time.perf_counter() - t0
    argmax = tagger.labels(texts, structured=False)
    voted_right = voted_total = all_right = majority_right = majority_all_right = plain_voted_right = 0
    for s, g in zip(held_shapes, held_graphs):
        same_strings = copy.deepcopy(rng)  # the majority vote sees the soft vote's strings
        vote = tagger.vote(g, 8, rng, collection_set)
        majority = tagger.vote(g, 8, same_strings, collection_set, soft=False)
        truths = shape_labelings(shape_set, s, g, tagger.categories)  # every labelling of the same shape
        plain_truths = shape_labelings(shape_set, s, g, tagger.categories, automorphisms=1)
        best = max((sum(vote.get(e) == c for e, c in t.items()) for t in truths), default=0)
        best_majority = max((sum(majority.get(e) == c for e, c in t.items()) for t in truths), default=0)
        plain_voted_right += max((sum(vote.get(e) == c for e, c in t.items()) for t in plain_truths), default=0)
        voted_right += best
        all_right += best == g.number_of_edges()
        majority_right += best_majority
        majority_all_right += best_majority == g.number_of_edges()
        voted_total += g.number_of_edges()
    accuracy = lambda examples, labels, every=False: tagging_accuracy(  # noqa: E731
        tagger, examples, every, predicted=labels) if examples else None
    return {"held_out_shapes": len(held_shapes), "held_out_strings": len(held),
            "per_character_accuracy": accuracy(held, decoded),
            "per_character_accuracy_argmax": accuracy(held, argmax),
            "per_character_accuracy_without_automorphisms": accuracy(held_plain, decoded),
            "per_character_accuracy_argmax_without_automorphisms": accuracy(held_plain, argmax),
            "decoding_ms_per_string": round(1000 * decode_seconds / max(len(held), 1), 1),
            "all_characters_accuracy": accuracy(held, argmax, True),
            "voted_edge_accuracy": voted_right / max(voted_total, 1),
            "voted_edge_accuracy_without_automorphisms": plain_voted_right / max(voted_total, 1),
            "voted_graphs_all_right": all_right,
            "majority_voted_edge_accuracy": majority_right / max(voted_total, 1),
            "majority_voted_graphs_all_right": majority_all_right}


def run_set(name: str, args, work: Path) -> dict:
    print(f"== {name}", flush=True)
    shape_set = read_shapes(SETS / f"{name}.json")
    graphs = [shape_graph(shape_set, s) for s in shape_set.shapes]
    row: dict = {"inputs": [{"parts": len(s), "triangles": triangles(shape_set, s),
                             "cycles": g.number_of_edges() - g.number_of_nodes() + 1}
                            for s, g in zip(shape_set.shapes, graphs)]}
    # Table 1: growth
    t0 = time.perf_counter()
    with open_executor(args.workers) as executor:
        grown = augment(shape_set, args.count, seed=args.seed, parallel=args.parallel, max_rounds=400,
                        executor=executor, seconds=args.augment_seconds,
                        params=AugmentParams(distinct=args.distinct, rotate=not args.translations_only))
    seconds = time.perf_counter() - t0
    # one folder per duplicate rule: the rules grow different collections, and a model
    # folder refuses to resume on other strings
    folder = work / (name if args.distinct == "histogram" else f"{name}_{args.distinct}")
    coll = folder / "collection"
    strings = write_collection(shape_set, grown.shapes, coll, grown.rounds, args.strings_per_shape, args.seed,
                               sheet=False)
    new = len(grown.shapes) - len(shape_set.shapes)
    per_round = []
    for r in grown.rounds:
        per_round.append({"round": r["round"], "shapes": r["shapes"], "seconds": r["seconds"]})
    row["growth"] = {"rounds": per_round, "shapes": len(grown.shapes), "strings": len(strings),
                     "seconds": round(seconds, 2), "variants_per_minute": round(60 * new / max(seconds, 1e-9), 1),
                     "parallel": args.parallel, "workers": args.workers,
                     "parts_min": min(len(s) for s in grown.shapes), "parts_max": max(len(s) for s in grown.shapes)}
    print(f"  growth: {len(grown.shapes)} shapes, {len(strings)} strings in {seconds:.1f} s", flush=True)
    # Training
    model_dir = folder / "model"
    # a work folder from an earlier run with the same settings: training only checks and reloads
    reused = (model_dir / "model.json").is_file()
    t0 = time.perf_counter()
    tagger = TaggerConfig(epochs=args.tagger_epochs, hidden=args.tagger_hidden, lr_final=args.tagger_lr_final,
                          graph_rounds=args.tagger_graph_rounds)
    meta = train_model(coll, model_dir, VAEConfig(epochs=args.epochs), tagger, args.strings_per_shape, 0.2, args.seed,
                       tagger_strings_per_shape=args.tagger_strings_per_shape, device=args.device)
    row["training"] = {"seconds": round(time.perf_counter() - t0, 1), "reused_trained_model": reused,
                       "strings": meta["training_strings"],
                       "shapes": meta["train_shapes"], "categories": meta["categories"]}
    model = TrainedModel(model_dir)
    row["training"]["vae_history"] = json.loads((model_dir / "vae.json").read_text())["train"]["history"]
    print(f"  trained in {row['training']['seconds']} s", flush=True)
    # Edge categories on held-out strings
    all_graphs = [shape_graph(shape_set, s) for s in grown.shapes]
    _, test_idx = split_shapes(len(grown.shapes), 0.2, args.seed, collection_inputs(coll, len(grown.shapes)))
    rng = np.random.default_rng(args.seed)
    held_shapes = [grown.shapes[i] for i in test_idx]
    held_graphs = [all_graphs[i] for i in test_idx]
    row["edge_categories"] = {**edge_category_figures(model.tagger, shape_set, model.shape_set, held_shapes,
                                                      held_graphs, rng),
                              "categories": meta["categories"]}
    print(f"  edge categories: {row['edge_categories']}", flush=True)
    # Prior samples
    known = graph_index(all_graphs)
    z = rng.standard_normal((args.samples, model.vae.net.config.latent))
    prior = {}
    novel_strings = []
    # constrained (with wrap-up, the default), constrained without wrap-up, free decoding
    for label, kw in (("constrained", {}), ("constrained_no_wrap", {"wrap": False}),
                      ("unconstrained", {"constrained": False})):
        t0 = time.perf_counter()
        decoded = model.vae.decode(z, rng=rng, **kw)
        r, novel = rates(model, decoded, known)
        r["seconds"] = round(time.perf_counter() - t0, 1)
        prior[label] = r
        if label == "constrained":
            novel_strings = novel
    row["prior_samples"] = prior
    print(f"  prior: {prior}", flush=True)
    # Perturbation sampling around training strings
    anchors_idx = rng.choice(len(model.training_strings), size=min(args.perturb, len(model.training_strings)),
                             replace=False)
    anchor_strings = [model.training_strings[int(i)] for i in anchors_idx]
    anchor_z = model.vae.encode(anchor_strings)
    found = [perturb(model.vae, zz, s, rng) for zz, s in zip(anchor_z, anchor_strings)]
    r, _ = rates(model, [f for f in found], known)
    row["perturbation_samples"] = r
    # Table 2: search graphs over the same valid strings
    pool = list(dict.fromkeys(model.training_strings))
    pool = [pool[int(i)] for i in rng.permutation(len(pool))[:args.graph_size]]
    extra = [f for f in found if f is not None and f not in pool]
    nodes = pool + extra
    zs = model.vae.encode(nodes)
    t2 = {"ours": path_statistics(search_graph(zs, nodes, 3), 200, rng),
          "naive": path_statistics(naive_graph(nodes, 3), 200, rng)}
    row["search_graph"] = t2
    print(f"  table 2: {t2}", flush=True)
    # Instantiation
    # Every ring of these sets' shapes alternates cells (towers, modules, columns) and links
    # (walls, corridors, beams) on a square grid, so its length is a multiple of 4 (an even
    # number of grid steps), and a sampled graph with a ring of another length has no
    # embedding. The grammar's learned ring-length rule (Grammar.ring_multiple) keeps decoded
    # samples to it; the count below checks that, from the residues of cycle-basis lengths
    # mod 4 that the collection's graphs show (not assumed).
    seen_residues = {len(c) % 4 for g in all_graphs for c in nx.cycle_basis(g)}
    inst = {}
    for label, texts in (("held_out", [encode(g) for g in held_graphs][:args.instantiate]),
                         ("novel_prior_samples", novel_strings[:args.instantiate])):
        ok, fallbacks, shapes, impossible, budget, t0 = 0, 0, [], 0, 0, time.perf_counter()
        odd, ok_regular = 0, 0
        for text in texts:
            res = model.instantiate(text, rng)
            unseen = any(len(c) % 4 not in seen_residues for c in nx.cycle_basis(parse(text).graph))
            odd += unseen
            ok_regular += res.success and not unseen
            ok += res.success
            fallbacks += res.fallbacks
            # the search either finds a shape, proves that no choice of example poses realises
            # the graph (every candidate tried), or runs out of its placement budget
            impossible += "every candidate pose tried" in res.reason
            budget += "budget" in res.reason
            if res.success:
                shapes.append(res.shape)
        inst[label] = {"tried": len(texts), "succeeded": ok, "rate": ok / max(len(texts), 1),
                       "fallbacks_per_string": fallbacks / max(len(texts), 1),
                       "proven_impossible": impossible, "budget_spent": budget,
                       "ring_length_unseen_mod4": odd, "succeeded_of_the_rest": ok_regular,
                       "ring_residues_in_collection": sorted(seen_residues),
                       "seconds": round(time.perf_counter() - t0, 1)}
        if label == "novel_prior_samples" and shapes:
            write_sheet(model.shape_set, shapes[:16], args.out / f"strings_{name}.png", 160)
    row["instantiation"] = inst
    print(f"  instantiation: {inst}", flush=True)
    # Section 5.2's latent walks, last (the random stream above stays that of earlier runs)
    row["latent_walks"] = latent_walks(model, known, rng, args.walks)
    print(f"  latent walks: {row['latent_walks']}", flush=True)
    return row


def latent_walks(model, known, rng, pairs: int) -> dict:
    """Interpolation and latent-path sampling (seed 001, section 5.2) between ``pairs`` random
    pairs of training strings: how many points on the way decode to a valid string, the
    valid / unique / novel rates of what they decode to, and how large the steps between
    consecutive shapes are (type-histogram metric E, the pair's two ends included), which
    is what a path through the training encodings is meant to keep small."""
    train = model.training_strings
    anchors = model.vae.encode(train)
    out = {}
    for mode in ("interpolate", "path"):
        found_all, steps, points, t0 = [], [], 0, time.perf_counter()
        for _ in range(pairs):
            i, j = (int(k) for k in rng.integers(len(train), size=2))
            if mode == "interpolate":
                found = interpolate(model.vae, anchors[i], anchors[j], WALK_POINTS, rng)
                points += WALK_POINTS
            else:
                path = latent_path(anchors[i], anchors[j], anchors, WALK_POINTS)
                found = sample_path(model.vae, path, 2, rng)
                points += 2 * (len(path) - 1)
            found_all += found
            walk = [train[i]] + found + [train[j]]
            steps += [histogram_distance([c for c in a if c.isalpha()], [c for c in b if c.isalpha()])
                      for a, b in zip(walk, walk[1:])]
        r, _ = rates(model, found_all, known)
        out[mode] = {"pairs": pairs, "points": points, "points_with_valid_string": len(found_all) / max(points, 1),
                     **{k: r[k] for k in ("unique", "novel_of_valid", "unique_count", "novel_count")},
                     "mean_step_E": float(np.mean(steps)) if steps else None,
                     "max_step_E": float(np.max(steps)) if steps else None,
                     "seconds": round(time.perf_counter() - t0, 1)}
    return out


def plot(results: dict, path: Path) -> None:
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, axes = plt.subplots(1, 3, figsize=(15, 4.2))
    for name, row in results["sets"].items():
        rounds = row["growth"]["rounds"]
        axes[0].plot([r["seconds"] for r in rounds], [r["shapes"] for r in rounds], label=name)
        hist = row["training"]["vae_history"]
        axes[1].plot([h["epoch"] for h in hist], [h["recon"] for h in hist], label=f"{name} recon")
    axes[0].set(xlabel="seconds", ylabel="shapes in collection", title="Collection growth (Table 1)")
    axes[1].set(xlabel="epoch", ylabel="reconstruction (nats / string)", title="VAE training")
    names = list(results["sets"])
    x = np.arange(len(names))
    metrics = [("valid", lambda r: r["prior_samples"]["constrained"]["valid"]),
               ("valid (free)", lambda r: r["prior_samples"]["unconstrained"]["valid"]),
               ("novel of valid", lambda r: r["prior_samples"]["constrained"]["novel_of_valid"]),
               ("edge cat. acc.", lambda r: r["edge_categories"]["per_character_accuracy"] or 0),
               ("instantiated", lambda r: r["instantiation"]["held_out"]["rate"])]
    for k, (label, f) in enumerate(metrics):
        axes[2].bar(x + k * 0.16 - 0.32, [f(results["sets"][n]) for n in names], 0.16, label=label)
    axes[2].set_xticks(x, names)
    axes[2].set(ylim=(0, 1.05), title="Rates per set")
    for ax in axes:
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=110)


def parser() -> argparse.ArgumentParser:
    """The bench's options (``settings`` in the results file are these, parsed from its ``command``)."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sets", nargs="+", default=["castle", "moonbase", "colonnade"])
    ap.add_argument("--count", type=int, default=150, help="collection size per set")
    ap.add_argument("--augment-seconds", type=float, default=120)
    ap.add_argument("--distinct", choices=DISTINCT_MODES, default="histogram",
                    help="which grown variants are duplicates (histogram: seed 001's rule; graph: isomorphic "
                         "graphs); not the default: results go to strings_<distinct>.json")
    ap.add_argument("--translations-only", action="store_true",
                    help="dock by translations only (sampling's default before off-grid sets: keep the rotations)")
    ap.add_argument("--results", help="results file stem in --out (default: strings, or strings_<distinct>)")
    ap.add_argument("--parallel", type=int, default=8)
    ap.add_argument("--workers", type=int, default=2)
    ap.add_argument("--strings-per-shape", type=int, default=8)
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--tagger-epochs", type=int, default=24)
    ap.add_argument("--tagger-hidden", type=int, default=TaggerConfig.hidden)
    ap.add_argument("--tagger-lr-final", type=float, default=TaggerConfig.lr_final,
                    help="tagger learning rate at the last epoch, as a fraction of the first (cosine)")
    ap.add_argument("--tagger-graph-rounds", type=int, default=TaggerConfig.graph_rounds,
                    help="tagger rounds of message passing over the string's graph")
    ap.add_argument("--tagger-strings-per-shape", type=int, default=16)
    ap.add_argument("--samples", type=int, default=200)
    ap.add_argument("--perturb", type=int, default=40)
    ap.add_argument("--graph-size", type=int, default=300)
    ap.add_argument("--instantiate", type=int, default=20)
    ap.add_argument("--walks", type=int, default=20, help="pairs for interpolation and latent-path sampling")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--device", default="cpu", help="torch device to train the VAE and the tagger on (cpu, cuda)")
    ap.add_argument("--work", type=Path)
    ap.add_argument("--out", type=Path, default=ROOT / "bench" / "results")
    return ap


def main() -> None:
    args = parser().parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    work = args.work or Path(tempfile.mkdtemp(prefix="procmod-strings-bench-"))
    # exactly what ran, and nothing else: explanations of a run go in docs/strings.md
    results = {"command": "python bench/strings.py " + shlex.join(sys.argv[1:]), "settings": {
        k: (str(v) if isinstance(v, Path) else v) for k, v in vars(args).items()}, "sets": {}}
    stem = args.out / (args.results or ("strings" if args.distinct == "histogram" else f"strings_{args.distinct}"))
    t0 = time.perf_counter()
    for name in args.sets:
        results["sets"][name] = run_set(name, args, work)
        results["seconds"] = round(time.perf_counter() - t0, 1)
        stem.with_suffix(".json").write_text(json.dumps(results, indent=1) + "\n")
    plot(results, stem.with_suffix(".png"))
    print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.png')} in {results['seconds']} s")


if __name__ == "__main__":
    main()
