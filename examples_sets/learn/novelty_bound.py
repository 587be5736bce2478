"""How many new structures can a learner be expected to sample from the spaceship examples?

    python examples_sets/learn/novelty_bound.py [--draws 200] [--samples 4000]

The spaceship generator (``make_sets.spaceship``) makes its structure from independent
choices, drawn before any continuous one (``make_sets.spaceship_choices``, probabilities
``make_sets.SPACESHIP_CHOICES``): one or two wing pairs, a tip weapon per pair (none,
guns or missiles), the engine layout (three kinds), 0-2 rear hull segments, a top fin or
keel, belly guns, tail fins, a sensor dish, an antenna. An *ideal* learner knows exactly
this factorisation and estimates each choice's probabilities by their frequencies in
the ten examples (maximum likelihood, as seed 000's objective does). This script
measures, on the signatures of ``procmod.learn.evaluate`` (the "% new structures" of
Table 2):

* the ideal learner on the shipped ten examples (their choices are recovered by
  replaying the generator with the set's seed; the script checks that the replay
  reproduces ``spaceships/examples.json``), and
* the ideal learner on fresh draws of ten examples from the generator (mean, 10th and
  90th percentile over draws), and the generator itself against each draw.

A learned program that reaches the first figure generalises as well as the examples
allow; the second says how often a draw of ten examples allows > 90%.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE.parents[1]))
sys.path.insert(0, str(HERE))

import make_sets  # noqa: E402
from procmod.learn import read_examples  # noqa: E402
from procmod.learn.evaluate import signature  # noqa: E402

CATEGORICAL = ("tip", "engines", "segments")
BINARY = ("fin", "belly", "tail", "dish", "antenna")


def dict_signature(n: dict) -> str:
    """``evaluate.signature`` of a node written as a dict by ``make_sets``."""
    return n["part"] + "(" + ",".join(sorted(dict_signature(c) for c in n["children"])) + ")"


_DUMMY = np.random.default_rng(0)


def structure(c: dict) -> str:
    """The signature of a ship made from choices ``c`` (the continuous draws do not matter)."""
    return dict_signature(make_sets.spaceship_from(c, _DUMMY))


def shipped_choices(seed: int = 0):
    """Replay ``make_sets.make('spaceships', seed=seed)``: (choices, example dicts)."""
    rng = np.random.default_rng([seed, sorted(make_sets.SETS).index("spaceships")])
    choices, ships = [], []
    for _ in range(make_sets.N_EXAMPLES):
        c = make_sets.spaceship_choices(rng)
        choices.append(c)
        ships.append(make_sets.spaceship_from(c, rng))
    return choices, ships


def fitted(choices: list) -> dict:
    """Maximum-likelihood probabilities of each choice from a list of choice dicts."""
    tips = [t for c in choices for t in c["tips"]]
    out = {k: float(np.mean([c[k] for c in choices])) for k in ("two_pairs",) + BINARY}
    out["tip"] = tuple(np.bincount(tips, minlength=3) / len(tips))
    for k in ("engines", "segments"):
        out[k] = tuple(np.bincount([c[k] for c in choices], minlength=3) / len(choices))
    return out


def pct_new(p: dict, seen: set, n: int, rng: np.random.Generator) -> float:
    return 100.0 * float(np.mean([structure(make_sets.spaceship_choices(rng, p)) not in seen for _ in range(n)]))


def _close(a, b) -> bool:
    """JSON values equal but for floats within 1e-9 relative: the file holds the
    generator's output rounded to 12 digits (``make_sets.rounded``), and another CPU's
    maths may move the last of them."""
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_close(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_close(x, y) for x, y in zip(a, b))
    if isinstance(a, float) or isinstance(b, float):
        return isinstance(a, (int, float)) and isinstance(b, (int, float)) and abs(a - b) <= 1e-9 * max(abs(a), abs(b))
    return a == b


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--draws", type=int, default=200)
    ap.add_argument("--samples", type=int, default=4000)
    args = ap.parse_args(argv)
    path = HERE / "spaceships" / "examples.json"
    choices, ships = shipped_choices()
    if not _close(json.loads(path.read_text())["examples"], json.loads(json.dumps(make_sets.rounded(ships)))):
        raise SystemExit(f"{path} is not the generator's output; rerun make_sets.py")
    examples = read_examples(path).examples
    seen = {signature(e) for e in examples}
    if {structure(c) for c in choices} != seen:
        raise SystemExit("the choices do not reproduce the example structures")
    rng = np.random.default_rng(0)
    shipped = pct_new(fitted(choices), seen, args.samples, rng)
    learner, generator = [], []
    for _ in range(args.draws):
        draw = [make_sets.spaceship_choices(rng) for _ in range(len(examples))]
        s = {structure(c) for c in draw}
        learner.append(pct_new(fitted(draw), s, args.samples // 10, rng))
        generator.append(pct_new(make_sets.SPACESHIP_CHOICES, s, args.samples // 10, rng))
    print(f"shipped spaceship examples ({len(seen)} distinct structures): ideal learner samples "
          f"{shipped:.1f}% new structures")
    print(f"fresh draws of {len(examples)} examples ({args.draws}): ideal learner {np.mean(learner):.1f}% "
          f"(10th-90th percentile {np.percentile(learner, 10):.1f}-{np.percentile(learner, 90):.1f}%, "
          f"{100 * np.mean(np.asarray(learner) > 90):.0f}% of draws above 90%); "
          f"the generator itself {np.mean(generator):.1f}%")


if __name__ == "__main__":
    main()
