"""The GA's selection (seed 002, section 6): one parent by roulette wheel, the other by
k-tournament, and the best individuals kept unchanged (elitism).

Each function works on a population ranked best first (the GA sorts it by score once a
generation) and returns indices into it, drawing from the generator it is given.
"""

from __future__ import annotations

import math

import numpy as np

from ...core import InvalidArgumentError
from ...core.errors import cut_text, shown_value, whole_number
from ...core.runtime import check_rng


def roulette_wheel(scores) -> np.ndarray:
    """The cumulative wheel of a population with these scores: individual i's share is
    its fitness, the score shifted to be non-negative (``score - min score``: similarities
    can be negative), over the total; individuals whose score is not finite get no share,
    and when no fitness is positive every other individual gets an equal one (every
    individual, when none is finite)."""
    try:
        scores = np.asarray(scores, dtype=np.float64)
    except (TypeError, ValueError):
        raise InvalidArgumentError(f"roulette_wheel takes the scores of a population (numbers), got "
                                   f"{cut_text(repr(scores), 40)}") from None
    if scores.ndim != 1 or len(scores) == 0:
        raise InvalidArgumentError(f"roulette_wheel takes the scores of a population of one or more, got "
                                   f"{len(scores) if scores.ndim == 1 else scores.shape}")
    finite = np.isfinite(scores)
    floor = scores[finite].min() if finite.any() else 0.0
    with np.errstate(over="ignore"):
        fitness = np.where(finite, scores, floor) - floor
        total = fitness.sum()
    if not np.isfinite(total):
        # scores spanning more than the float range (a target's -sys.float_info.max for
        # "ruled out"): the shifts overflowed to inf (or their sum did), and the wheel had
        # given every spin to the worst; the same shares, measured in halves and against
        # the largest (halving is exact, so no share moves but by rounding)
        half = np.where(finite, scores, floor) * 0.5 - floor * 0.5
        fitness = half / half.max()
        total = fitness.sum()
    if total > 0:
        fitness = fitness / total
    elif finite.any():  # equal shares, still none for a score that is not finite (a ruled-out one's -inf)
        fitness = finite / finite.sum()
    else:
        fitness = np.full(len(scores), 1.0 / len(scores))
    return np.cumsum(fitness)


def roulette(wheel: np.ndarray, rng) -> int:
    """The index of the individual the ball of one spin stops at: probability
    proportional to its share of :func:`roulette_wheel`."""
    if len(wheel) == 0:
        raise InvalidArgumentError("roulette takes the wheel of a population of one or more (roulette_wheel's), "
                                   "got an empty one")
    check_rng(rng, "roulette")
    return min(int(np.searchsorted(wheel, rng.random() * wheel[-1], side="right")), len(wheel) - 1)


def tournament(size: int, k: int, rng) -> int:
    """The winner of a k-tournament in a population of ``size`` ranked best first: ``k``
    entrants drawn uniformly (with replacement), the best-ranked one wins."""
    if whole_number(size) is None or whole_number(k) is None or size < 1 or k < 1:
        raise InvalidArgumentError(f"tournament needs a population (size) and entrants (k) of one or more, got "
                                   f"size {shown_value(size)}, k {shown_value(k)}")
    check_rng(rng, "tournament")
    size, k = int(size), int(k)
    return int(min(rng.integers(0, size, size=k)))


def elite_count(elitism: float, size: int) -> int:
    """How many of the best individuals elitism keeps: the fraction ``elitism`` of the
    population, rounded up."""
    if isinstance(elitism, bool) or not isinstance(elitism, (int, float, np.integer, np.floating)) \
            or not 0 <= elitism <= 1:
        raise InvalidArgumentError(f"elitism is the fraction of the population kept, from 0 to 1, got "
                                   f"{shown_value(elitism)}")
    return int(math.ceil(elitism * size)) if elitism > 0 else 0
