"""How many new structures can a learner be expected to sample from the spaceship examples?

    python examples_sets/learn/novelty_bound.py [--draws 200] [--samples 4000]

The spaceship generator (``make_sets.spaceship``) makes its structure from independent
choices: one or two wing pairs, guns on each pair (p 1/2), the engine layout (three
kinds, p 1/3 each), a top fin or keel (p 0.6), belly guns (p 1/2), tail fins (p 0.4), an
antenna (p 1/2). An *ideal* learner knows exactly this factorisation and estimates each
choice's probability by its frequency in the ten examples (maximum likelihood, as
seed 000's objective does). This script measures, on the signatures of
``procmod.learn.evaluate`` (the "% new structures" of Table 2):

* the ideal learner on the shipped ten examples (their choices are read back from the
  example hierarchies), and
* the ideal learner on fresh draws of ten examples from the generator (mean, 10th and
  90th percentile over draws), and the generator itself against each draw.

A learned program that reaches the first figure generalises as well as the examples
allow; the second says how often a draw of ten examples allows > 90%.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))

from procmod.learn import read_examples  # noqa: E402
from procmod.learn.evaluate import signature  # noqa: E402

# the generator's probabilities, as written in make_sets.spaceship
GENERATOR = {"two_pairs": 0.5, "gun": 0.5, "kind": (1 / 3, 1 / 3, 1 / 3), "fin": 0.6, "belly": 0.5,
             "tail": 0.4, "antenna": 0.5}


def draw_choices(rng: np.random.Generator, p: dict) -> dict:
    two = rng.random() < p["two_pairs"]
    return {"two_pairs": two, "guns": [bool(rng.random() < p["gun"]) for _ in range(2 if two else 1)],
            "kind": int(rng.choice(3, p=np.asarray(p["kind"]))), "fin": bool(rng.random() < p["fin"]),
            "belly": bool(rng.random() < p["belly"]), "tail": bool(rng.random() < p["tail"]),
            "antenna": bool(rng.random() < p["antenna"])}


def structure(c: dict) -> str:
    """The signature (``evaluate.signature``) of a ship made from choices ``c``."""
    kids = []
    for gun in c["guns"]:
        kids += ["wing(gun())" if gun else "wing()"] * 2
    kids += ["engine()"] * (c["kind"] + 1)
    kids += ["fin()"] * (int(c["fin"]) + 2 * int(c["tail"]))
    kids += ["gun()"] * (2 * int(c["belly"]))
    kids.append("cockpit(antenna())" if c["antenna"] else "cockpit()")
    return "body(" + ",".join(sorted(kids)) + ")"


def choices_of(example) -> dict:
    """Read a spaceship example's structural choices back from its hierarchy."""
    kids = Counter(k.part for k in example.children)
    wings = [k for k in example.children if k.part == "wing"]
    pairs = len(wings) // 2
    with_gun = sum(1 for w in wings if w.children) // 2
    fins = kids["fin"]
    cockpit = next(k for k in example.children if k.part == "cockpit")
    return {"two_pairs": pairs == 2, "guns": [True] * with_gun + [False] * (pairs - with_gun),
            "kind": kids["engine"] - 1, "fin": fins in (1, 3), "belly": kids["gun"] > 0, "tail": fins >= 2,
            "antenna": bool(cockpit.children)}


def fitted(choices: list) -> dict:
    """Maximum-likelihood probabilities of each choice from a list of choice dicts."""
    guns = [g for c in choices for g in c["guns"]]
    kinds = np.bincount([c["kind"] for c in choices], minlength=3) / len(choices)
    out = {k: float(np.mean([c[k] for c in choices])) for k in ("two_pairs", "fin", "belly", "tail", "antenna")}
    out.update(gun=float(np.mean(guns)) if guns else 0.5, kind=tuple(kinds))
    return out


def pct_new(p: dict, seen: set, n: int, rng: np.random.Generator) -> float:
    return 100.0 * float(np.mean([structure(draw_choices(rng, p)) not in seen for _ in range(n)]))


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--samples", type=int, default=4000)
    args = ap.parse_args(argv)
    examples = read_examples(HERE / "spaceships" / "examples.json").examples
    choices = [choices_of(e) for e in examples]
    seen = {signature(e) for e in examples}
    if {structure(c) for c in choices} != seen:
        raise SystemExit("the examples do not read back as generator choices; update choices_of")
    rng = np.random.default_rng(0)
    shipped = pct_new(fitted(choices), seen, args.samples, rng)
    learner, generator = [], []
    for _ in range(args.draws):
        draw = [draw_choices(rng, GENERATOR) for _ in range(len(examples))]
        s = {structure(c) for c in draw}
        learner.append(pct_new(fitted(draw), s, args.samples // 10, rng))
        generator.append(pct_new(GENERATOR, s, args.samples // 10, rng))
    print(f"shipped spaceship examples: ideal learner samples {shipped:.1f}% new structures")
    print(f"fresh draws of {len(examples)} examples ({args.draws}): ideal learner {np.mean(learner):.1f}% "
          f"(10th-90th percentile {np.percentile(learner, 10):.1f}-{np.percentile(learner, 90):.1f}%, "
          f"{100 * np.mean(np.asarray(learner) > 90):.0f}% of draws above 90%); "
          f"the generator itself {np.mean(generator):.1f}%")


if __name__ == "__main__":
    main()
