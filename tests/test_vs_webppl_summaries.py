"""The vines bench's similarity summaries: seed 004's Fig. 5 measure (per-target medians
averaged over targets) and the paired guided-against-WebPPL difference."""

import importlib.util
import json
from pathlib import Path

import numpy as np
import pytest

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def bench():
    spec = importlib.util.spec_from_file_location("_bench_vs_webppl", ROOT / "bench" / "vs_webppl.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_target_mean_is_the_mean_of_per_target_medians_not_the_pooled_median(bench):
    # one hard target among easy ones: the pooled median hides it, Fig. 5's measure does not
    runs = {"hard": [0.1, 0.12, 0.08, 0.1], "easy1": [0.8, 0.82, 0.79, 0.8], "easy2": [0.7, 0.71, 0.69, 0.7]}
    point, low, high = bench.target_mean_interval(runs, np.random.default_rng(0))
    assert point == pytest.approx(np.mean([0.1, 0.8, 0.7]))
    assert low <= point <= high
    assert low < 0.4 and high > 0.7  # three targets this far apart: resampling them moves the mean a lot


def test_paired_difference_keeps_runs_paired(bench):
    rng = np.random.default_rng(1)
    runs = {}
    for t in range(6):
        peer = rng.uniform(0.0, 1.0, size=9)  # seeds that scatter widely...
        runs[f"t{t}"] = (peer + 0.05, peer)  # ...and a guided run 0.05 better on each
    point, low, high = bench.target_mean_interval(runs, np.random.default_rng(2))
    # resampled in pairs, every draw sees the same 0.05; unpaired, the seeds' scatter would
    # spread the interval by tenths
    assert point == pytest.approx(0.05)
    assert low == pytest.approx(0.05) and high == pytest.approx(0.05)


def test_paired_similarity_differences_pair_by_target_and_seed(bench):
    rows = []
    for t, (ours, theirs) in {"a": (0.7, 0.2), "b": (0.6, 0.65), "c": (0.5, 0.45)}.items():
        for seed in range(3):
            rows.append({"set": "s", "system": "procmod+guide", "method": "smc", "n": 10, "target": t,
                         "seed": seed, "similarity": ours})
            rows.append({"set": "s", "system": "webppl", "method": "SMC", "n": 200, "target": t,
                         "seed": seed, "similarity": theirs})
    rows.append({"set": "s", "system": "webppl", "method": "SMC", "n": 200, "target": "a", "seed": 7,
                 "similarity": 0.9})  # no guided run of that seed: left out
    (d,) = bench.paired_similarity_differences(rows, ["s"])
    assert (d["pairs"], d["targets"], d["targets_guided_ahead"]) == (9, 3, 2)
    json.dumps(d)  # the results file holds it
    assert d["target_mean_difference"][0] == pytest.approx(np.mean([0.5, -0.05, 0.05]))
    assert (d["guided_median"], d["webppl_median"]) == (0.6, 0.45)
