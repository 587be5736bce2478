"""The vines bench's similarity summaries: seed 004's Fig. 5 measure (per-target medians
averaged over targets), the guided-against-WebPPL difference on shared runs, and the
Fig. 5b times by either measure."""

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


def _row(system, n, target, seed, similarity, seconds=0.1):
    return {"set": "s", "system": system, "method": "SMC" if system == "webppl" else "smc", "n": n,
            "target": target, "seed": seed, "similarity": similarity, "seconds": seconds,
            "beyond_seconds": seconds, "infer_seconds": seconds}


def test_interval_resamples_targets(bench):
    # one target far from five alike: a draw without it (probability (5/6)^6 = 0.33) has
    # mean 0, one with it twice or more (probability 0.26) has mean 0.1 or more
    point, low, high = bench.mean_over_targets([0.3, 0, 0, 0, 0, 0], np.random.default_rng(0))
    assert point == pytest.approx(0.05)
    assert low == 0.0 and high >= 0.1
    with pytest.raises(ValueError):
        bench.mean_over_targets([], np.random.default_rng(0))


def test_summary_gives_the_mean_of_per_target_medians_not_the_pooled_median(bench):
    # one hard target among easy ones: the pooled median hides it, Fig. 5's measure does not
    runs = {"hard": [0.1, 0.12, 0.08, 0.1], "easy1": [0.8, 0.82, 0.79, 0.8], "easy2": [0.7, 0.71, 0.69, 0.7]}
    rows = [_row("webppl", 200, t, seed, v) for t, values in runs.items() for seed, v in enumerate(values)]
    (summary,) = bench.summarise(rows, ("system", "method", "set", "n"))
    assert summary["similarity_median"][0] == pytest.approx(0.7)
    assert summary["similarity_target_mean"][0] == pytest.approx(np.mean([0.1, 0.8, 0.7]))


def test_difference_is_of_medians_on_shared_runs(bench):
    ours = {"a": [0.9, 0.1, 0.5], "b": [0.6, 0.7, 0.2], "c": [0.5, 0.4, 0.3]}
    theirs = {"a": [0.2, 0.8, 0.4], "b": [0.65, 0.1, 0.3], "c": [0.45, 0.5, 0.35]}
    rows = [_row("procmod+guide", 10, t, seed, v) for t, values in ours.items() for seed, v in enumerate(values)]
    rows += [_row("webppl", 200, t, seed, v) for t, values in theirs.items() for seed, v in enumerate(values)]
    rows.append(_row("webppl", 200, "a", 7, 0.9))  # no guided run of that seed: left out
    (d,) = bench.paired_similarity_differences(rows, ["s"])
    json.dumps(d)  # the results file holds it
    # median(ours) - median(theirs) per target; the median of the runs' differences would
    # give "b" -0.05 instead of 0.3
    per_target = [0.5 - 0.4, 0.6 - 0.3, 0.4 - 0.45]
    assert (d["pairs"], d["targets"], d["targets_guided_ahead"]) == (9, 3, 2)
    assert d["target_mean_difference"][0] == pytest.approx(np.mean(per_target))
    assert (d["guided_median"], d["webppl_median"]) == (0.5, 0.4)


def test_fig5b_times_follow_the_measure_asked_for(bench):
    # pooled median and per-target mean disagree at 10 particles: 0.55 against 0.4
    summary = [{"set": "s", "system": "webppl", "method": "SMC", "n": n, "beyond_seconds_median": t,
                "similarity_median": [m, 0, 0], "similarity_target_mean": [tm, 0, 0]}
               for n, t, m, tm in ((10, 1.0, 0.55, 0.4), (20, 2.0, 0.65, 0.6))]
    pooled = bench.time_to_similarity(summary, "s", "webppl", "beyond_seconds_median")
    fig5 = bench.time_to_similarity(summary, "s", "webppl", "beyond_seconds_median", "similarity_target_mean")
    assert pooled[0.5] == 1.0 and pooled[0.6] == pytest.approx(1.5) and pooled[0.7] is None
    assert fig5[0.5] == pytest.approx(1.5) and fig5[0.6] == 2.0
