"""Sweep 34: example sets made by hand (procmod.learn): chains of a fixed length."""

import math

import numpy as np

from procmod.core import run_forward
from procmod.learn import examples_from_dict
from procmod.learn.preprocessing import preprocess
from procmod.learn.program import derivation_hierarchies, program_model
from procmod.learn.search import SearchOptions, run_search
from procmod.parallel import InlineExecutor

QUICK = dict(init_iterations=80, split_iterations=40, warm_iterations=10, final_iterations=300)


def _snakes(lengths, noise=0.01, seed=0):
    """Snakes of links placed by eye, each link under the one before it, turned a few
    degrees about the vertical and about a link's length from it."""
    rng = np.random.default_rng(seed)

    def link(k, links):
        m = np.eye(4)
        if k == 0:
            m[:3, 3] = (0, 0.05, 0)
        else:
            a = rng.normal(0, 0.05)
            m[:3, :3] = [[math.cos(a), 0, math.sin(a)], [0, 1, 0], [-math.sin(a), 0, math.cos(a)]]
            m[:3, 3] = (1 + rng.normal(0, noise), rng.normal(0, noise / 10), rng.normal(0, noise / 10))
        return {"part": "link", "transform": m.tolist(), "children": [link(k + 1, links)] if k + 1 < links else []}

    return examples_from_dict({"format": "procmod-examples/1", "parts": {"link": {"box": [1.0, 0.1, 0.2]}},
                               "examples": [link(0, n) for n in lengths]})


def _lengths(program, count, seed=1):
    model = program_model(program, "snakes")
    out = []
    for i in range(count):
        for h in derivation_hierarchies(run_forward(model, np.random.default_rng([seed, i]))):
            n, stack = 0, [h]
            while stack:
                node = stack.pop()
                n += 1
                stack.extend(node["children"])
            out.append(n)
    return out


def test_a_chain_every_example_repeats_five_times_is_sampled_five_long():
    """Eight snakes of exactly five links were learned as one self-calling abstraction
    (a geometric count): 87 of 100 samples had 2 to 21 links. The program with one
    abstraction per link scores higher by O_D, but no two-way split leads there uphill;
    the search now also tries it (structure.unroll), and the slot prior's target keeps the
    count (32 of 100 samples were another length with the pooled geometric target)."""
    example_set = _snakes([5] * 8)
    result = run_search(example_set, SearchOptions(particles=1, **QUICK), InlineExecutor())
    lengths = _lengths(result.program, 60)
    assert lengths.count(5) == len(lengths), np.bincount(lengths)


def test_chains_of_varying_length_keep_the_papers_recursion():
    """Walls of 2-5 segments, stems of 1-4 (the shipped castles and ornaments): runs whose
    lengths vary are no fixed count."""
    from procmod.learn.preprocessing import fixed_runs

    assert fixed_runs(preprocess(_snakes([5] * 3))) == {"link": (0, 5)}
    assert fixed_runs(preprocess(_snakes([4, 5, 6, 5]))) == {}
    assert fixed_runs(preprocess(_snakes([1, 1, 1]))) == {}
    # one run alone (one robot's two chassis halves among ten robots) is no count examples agree on
    assert fixed_runs(preprocess(_snakes([5]))) == {}
    assert fixed_runs(preprocess(_snakes([5, 5]))) == {"link": (0, 5)}
