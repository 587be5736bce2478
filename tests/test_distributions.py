import math

import numpy as np
import pytest

from procmod.core import (Bernoulli, Categorical, GaussianMixture, ModelError, Normal,
                          TruncatedNormal, Uniform)

N = 20000


def _samples(dist, seed=0, n=N):
    rng = np.random.default_rng(seed)
    return np.array([dist.sample(rng) for _ in range(n)], dtype=float)


def _integral(dist, lo, hi, points=200001):
    xs = np.linspace(lo, hi, points)
    ps = np.exp([dist.log_prob(float(x)) for x in xs])
    return np.trapezoid(ps, xs)


CONTINUOUS = [
    (Normal(1.5, 0.7), 1.5, 0.49, (-6, 9)),
    (Uniform(-2.0, 3.0), 0.5, 25 / 12, (-2, 3)),
    (GaussianMixture([0.3, 0.7], [-1.0, 2.0], [0.5, 0.25]),
     0.3 * -1 + 0.7 * 2, 0.3 * (0.25 + 1) + 0.7 * (0.0625 + 4) - 1.1 ** 2, (-6, 6)),
]


def _truncnorm_moments(mu, s, a, b):
    from statistics import NormalDist
    nd = NormalDist()
    al, be = (a - mu) / s, (b - mu) / s
    z = nd.cdf(be) - nd.cdf(al)
    pa, pb = nd.pdf(al), nd.pdf(be)
    mean = mu + s * (pa - pb) / z
    var = s * s * (1 + (al * pa - be * pb) / z - ((pa - pb) / z) ** 2)
    return mean, var


@pytest.mark.parametrize("dist,mean,var,support", CONTINUOUS + [
    (TruncatedNormal(0.5, 1.0, 0.0, 2.0), *_truncnorm_moments(0.5, 1.0, 0.0, 2.0), (0, 2)),
    (TruncatedNormal(-3.0, 1.0, 0.0, 1.0), *_truncnorm_moments(-3.0, 1.0, 0.0, 1.0), (0, 1)),
])
def test_continuous_moments_and_normalisation(dist, mean, var, support):
    xs = _samples(dist)
    # Sample mean within 5 standard errors; sample variance within 5 of its standard errors
    # (the variance estimator's sd is about var * sqrt(2 / n) for near-normal data; use the
    # fourth central moment to be safe for the skewed ones).
    assert abs(xs.mean() - mean) < 5 * math.sqrt(var / N)
    m4 = np.mean((xs - xs.mean()) ** 4)
    assert abs(xs.var() - var) < 5 * math.sqrt(max(m4 - var ** 2, 1e-12) / N)
    assert xs.min() >= support[0] - 1e-12 or support[0] < -5
    assert abs(_integral(dist, *support) - 1.0) < 1e-3
    assert all(math.isfinite(dist.log_prob(float(x))) for x in xs[:100])


def test_truncated_normal_outside_is_impossible():
    d = TruncatedNormal(0.0, 1.0, -1.0, 1.0)
    assert d.log_prob(1.5) == -math.inf and d.log_prob(-1.01) == -math.inf


@pytest.mark.parametrize("dist,probs", [
    (Bernoulli(0.3), {True: 0.3, False: 0.7}),
    (Categorical([1, 2, 7], labels=("x", "y", "z")), {"x": 0.1, "y": 0.2, "z": 0.7}),
    (Categorical([0.5, 0.25, 0.25]), {0: 0.5, 1: 0.25, 2: 0.25}),
])
def test_discrete_frequencies_match_log_prob(dist, probs):
    xs = [dist.sample(np.random.default_rng(1)) for _ in range(1)]  # type check on one draw
    assert xs[0] in probs
    rng = np.random.default_rng(7)
    counts = {}
    for _ in range(N):
        v = dist.sample(rng)
        counts[v] = counts.get(v, 0) + 1
    assert abs(sum(math.exp(dist.log_prob(v)) for v in probs) - 1.0) < 1e-12
    for value, p in probs.items():
        assert math.isclose(math.exp(dist.log_prob(value)), p, rel_tol=1e-12)
        # Binomial count within 5 standard deviations.
        assert abs(counts.get(value, 0) - N * p) < 5 * math.sqrt(N * p * (1 - p))


def test_values_outside_support_have_zero_probability():
    assert Bernoulli(0.5).log_prob(1) == -math.inf  # 1 is not a bool
    assert Categorical([1, 1], labels=("a", "b")).log_prob("c") == -math.inf
    assert Normal(0, 1).log_prob(float("nan")) == -math.inf
    assert Uniform(0, 1).log_prob(1.5) == -math.inf


def test_a_bool_label_is_only_itself():
    # True == 1 in Python: a bool value matches a bool label only, wherever it stands
    mixed = Categorical([1, 3], labels=(0, True))
    assert mixed.log_prob(True) == pytest.approx(math.log(0.75))
    assert mixed.log_prob(1) == -math.inf and mixed.log_prob(False) == -math.inf
    assert mixed.log_prob(0) == pytest.approx(math.log(0.25))
    assert Categorical([1, 1], labels=(True, False)).log_prob(1) == -math.inf
    assert Categorical([1, 1], labels=(0, 1)).log_prob(True) == -math.inf


def test_a_real_number_is_not_an_integer_label():
    # 2.0 == 2: an edited derivation's 2.0 reached the rule as an index (a learned program's
    # KeyError '2.0.g0.W', a user's "list indices must be integers")
    three = Categorical([1, 1, 1])
    assert three.log_prob(2.0) == -math.inf and three.log_prob(np.float64(1.0)) == -math.inf
    assert three.log_prob(2) == pytest.approx(math.log(1 / 3)) and three.log_prob(np.int64(2)) == three.log_prob(2)
    assert Categorical([1, 1], labels=(0.5, 2.0)).log_prob(2.0) == pytest.approx(math.log(0.5))


@pytest.mark.parametrize("make", [
    lambda: Normal(0, 0), lambda: Uniform(1, 1), lambda: Bernoulli(1.2),
    lambda: Categorical([]), lambda: Categorical([1, -1]), lambda: TruncatedNormal(0, 1, 2, 1),
    lambda: TruncatedNormal(0, 1, 50, 51), lambda: GaussianMixture([1], [0, 1], [1]),
    lambda: Categorical([1, 1], labels=("a", "a")),
])
def test_bad_parameters_raise_model_error(make):
    with pytest.raises(ModelError):
        make()


@pytest.mark.parametrize("make", [
    lambda: Normal(math.nan, 1), lambda: Normal(0, math.inf), lambda: Normal(math.inf, 1),
    lambda: TruncatedNormal(math.nan, 1, 0, 1), lambda: TruncatedNormal(0, math.inf, 0, 1),
    lambda: Uniform(0, math.inf), lambda: Uniform(-math.inf, 0), lambda: Uniform(math.nan, 1),
    lambda: GaussianMixture([1], [math.nan], [1]), lambda: GaussianMixture([1], [0], [math.inf]),
    lambda: Categorical([1, 1], labels=[(1.0, 2.0), (2.0, 3.0)]),
])
def test_non_finite_parameters_and_unsaveable_labels_are_model_errors(make):
    # accepted before: every engine then returned derivations of log prior -inf that did
    # not load back, or a run folder half written when the labels did not save
    with pytest.raises(ModelError):
        make()


def test_an_int_too_large_for_a_float_is_no_value_of_a_continuous_choice():
    # math.isfinite(10**400) raised OverflowError (procmod render crashed on an edited file)
    for dist in (Normal(0, 1), Uniform(0, 1), TruncatedNormal(0, 1, -1, 1), GaussianMixture([1], [0], [1])):
        assert dist.log_prob(10 ** 400) == -math.inf
    assert TruncatedNormal(0, 1, 0, math.inf).log_prob(1.0) > -math.inf  # one-sided stays allowed



def test_block_generator_draws_short_blocks_first_and_keeps_its_stream():
    """SMC's generator drew 4096 uniforms and 4096 normals at its first draw (~0.15 ms, as
    much as a short run's inference); blocks now start at 32 and double to 4096. The draws
    are the wrapped generator's own numbers, in blocks, so a seed still fixes them."""
    from procmod.core.random import BlockGenerator

    blocks = BlockGenerator(np.random.default_rng(0))
    plain = np.random.default_rng(0)
    assert blocks.random() == plain.random(32)[-1]  # one block of 32 (handed out from its end)
    assert blocks.generator.random() == plain.random()  # the generator moved on by 32 only
    sizes = []
    for _ in range(9):  # each refill: the numbers it leaves after handing out one
        while blocks._uniforms:
            blocks.random()
        blocks.random()
        sizes.append(len(blocks._uniforms) + 1)
    assert sizes == [64, 128, 256, 512, 1024, 2048, 4096, 4096, 4096]
    one, other = BlockGenerator(np.random.default_rng(5)), BlockGenerator(np.random.default_rng(5))
    assert [one.standard_normal() for _ in range(5000)] == [other.standard_normal() for _ in range(5000)]
