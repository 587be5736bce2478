"""The GA's selection functions on their own: roulette wheel, k-tournament, elitism."""

import math

import numpy as np
import pytest

from procmod.infer.ga import elite_count, roulette, roulette_wheel, tournament


def _close(got: float, expected: float, n: int) -> bool:
    # 5 binomial standard errors: a correct sampler fails this with probability ~6e-7
    return abs(got - expected) < 5 * math.sqrt(expected * (1 - expected) / n)


def test_roulette_wheel_shares_are_fitness_shifted_to_be_non_negative():
    # fitness = score - min finite score: 4, 2, 0 (the worst gets nothing), 0 (-inf: no share)
    wheel = roulette_wheel([3.0, 1.0, -1.0, -math.inf])
    assert np.diff(np.concatenate([[0.0], wheel])) == pytest.approx([4 / 6, 2 / 6, 0.0, 0.0])
    # shifting every score changes nothing; all equal (or none finite): equal shares
    assert roulette_wheel([103.0, 101.0, 99.0, -math.inf]) == pytest.approx(wheel)
    assert roulette_wheel([2.0, 2.0, 2.0, 2.0]) == pytest.approx([0.25, 0.5, 0.75, 1.0])
    assert roulette_wheel([-math.inf, -math.inf]) == pytest.approx([0.5, 1.0])
    # equal shares leave out what is not finite (a ruled-out individual's -inf took a share)
    assert roulette_wheel([0.9, -math.inf, -math.inf, -math.inf]) == pytest.approx([1.0, 1.0, 1.0, 1.0])
    assert roulette_wheel([2.0, -math.inf, 2.0]) == pytest.approx([0.5, 0.5, 1.0])


def test_roulette_picks_in_proportion_to_shifted_fitness():
    scores = [5.0, 3.0, 2.0, 1.0, 0.0]  # fitness 5, 3, 2, 1, 0 of 11
    wheel = roulette_wheel(scores)
    rng = np.random.default_rng(0)
    n = 20000
    picks = np.bincount([roulette(wheel, rng) for _ in range(n)], minlength=len(scores))
    assert picks[-1] == 0  # the worst individual has no share
    for i, f in enumerate([5, 3, 2, 1]):
        assert _close(picks[i] / n, f / 11, n)


def test_tournament_picks_the_best_ranked_of_k_entrants():
    # The population is ranked best first, so the best of the k entrants is the lowest index.
    rng, twin = np.random.default_rng(1), np.random.default_rng(1)
    scores = np.sort(np.random.default_rng(2).normal(size=30))[::-1]
    for k in (1, 3, 10):
        for _ in range(50):
            winner = tournament(len(scores), k, rng)
            entrants = twin.integers(0, len(scores), size=k)  # the twin replays the draws
            assert scores[winner] == scores[entrants].max()


def test_tournament_selection_pressure_grows_with_k():
    # P(winner ranks below i) = ((size - i) / size) ** k: for i = 1, the best is missed
    # by every entrant with probability (1 - 1/size) ** k.
    size, n = 20, 5000
    rng = np.random.default_rng(3)
    for k in (1, 2, 10):
        wins = sum(tournament(size, k, rng) == 0 for _ in range(n))
        assert _close(wins / n, 1 - (1 - 1 / size) ** k, n)


def test_elite_count_rounds_the_fraction_up():
    assert elite_count(0.2, 200) == 40
    assert elite_count(0.2, 12) == 3  # 2.4 rounds up
    assert elite_count(0.0, 50) == 0
    assert elite_count(0.01, 10) == 1
