"""Distributions for random choices: each can ``sample(rng)`` and give ``log_prob(x)``.

All of them are scalar and implemented with :mod:`math` rather than numpy array code,
because a procedural model draws one value at a time and the per-call overhead of
numpy on scalars would dominate. Randomness always comes from a
``numpy.random.Generator`` passed in by the caller; nothing here keeps global state.

Values are plain Python objects (``float``, ``bool``, ``int`` or a label ``str``) so that
derivations serialise to JSON exactly.
"""

from __future__ import annotations

import math
from statistics import NormalDist

import numpy as np

from .errors import DistributionError

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)
_STANDARD_NORMAL = NormalDist()


def _normal_log_pdf(x: float, mu: float, sigma: float) -> float:
    z = (x - mu) / sigma
    return -0.5 * z * z - math.log(sigma) - _LOG_SQRT_2PI


_INF = math.inf
# what a derivation's JSON holds as a choice value (procmod.core.serialize._json_value)
_LABEL_TYPES = (str, int, float, np.integer, np.floating, np.bool_)


def _is_real(x) -> bool:
    """A finite int or float (numpy's too); an int too large for a float is not one."""
    if x.__class__ is float:  # the hot path: log_prob of a value a distribution drew
        return math.isfinite(x)
    if not isinstance(x, (float, int, np.floating, np.integer)) or isinstance(x, bool):
        return False
    try:
        return math.isfinite(x)
    except OverflowError:
        return False


def _finite(*values) -> bool:
    """Whether every value compares as a finite number (floats, ints, numpy scalars and
    0-d arrays, Fractions, ...): comparisons, not type checks, so that what ``float()``
    takes keeps working; NaN fails every comparison."""
    try:
        return all(-_INF < v < _INF for v in values)
    except (TypeError, ValueError, OverflowError):
        return False


class Distribution:
    """Base class. Subclasses define ``sample``, ``log_prob`` and ``contains``.

    Attributes
    ----------
    discrete : bool
        True for distributions over a finite set (MCMC diffusion moves skip these).
    low, high : float or None
        The bounds of a continuous support (``Uniform``, ``TruncatedNormal``; either may
        be infinite there), None for a distribution without them (the GA's nudge reflects
        a value at the bounds a distribution declares).
    """

    discrete = False
    low = None  # subclasses with bounds hold them in slots of these names
    high = None

    @property
    def scale(self) -> float:
        """A typical spread of the distribution (step size unit for MCMC diffusion moves)."""
        raise NotImplementedError(f"{type(self).__name__} has no scale")

    def sample(self, rng: np.random.Generator):
        raise NotImplementedError

    def log_prob(self, value) -> float:
        raise NotImplementedError

    def contains(self, value) -> bool:
        """Whether ``value`` is in the support (a replayed value must be)."""
        return self.log_prob(value) > -math.inf

    def _params(self) -> dict:
        return {}

    def __repr__(self) -> str:
        args = ", ".join(f"{k}={v!r}" for k, v in self._params().items())
        return f"{type(self).__name__}({args})"


class Normal(Distribution):
    """Gaussian with mean ``mu`` and standard deviation ``sigma`` (> 0)."""

    __slots__ = ("mu", "sigma")

    def __init__(self, mu: float, sigma: float):
        try:  # the hot path: two comparisons (NaN fails both); a non-number fails in them or in float()
            if 0 < sigma < _INF and -_INF < mu < _INF:
                self.mu = float(mu)
                self.sigma = float(sigma)
                return
        except (TypeError, ValueError):
            pass
        raise DistributionError(f"Normal needs a finite number mu and a finite number sigma > 0, got mu={mu!r:.40}, "
                         f"sigma={sigma!r:.40}")

    def sample(self, rng):
        return self.mu + self.sigma * rng.standard_normal()

    def log_prob(self, value):
        if not _is_real(value):
            return -math.inf
        return _normal_log_pdf(value, self.mu, self.sigma)

    def _params(self):
        return {"mu": self.mu, "sigma": self.sigma}

    @property
    def scale(self):
        return self.sigma


class TruncatedNormal(Distribution):
    """Gaussian ``Normal(mu, sigma)`` restricted to ``[low, high]`` and renormalised."""

    __slots__ = ("mu", "sigma", "low", "high", "_cdf_low", "_mass", "_log_mass")

    def __init__(self, mu: float, sigma: float, low: float, high: float):
        try:  # chained comparisons: NaN fails them, what float() takes passes
            ok = -_INF < mu < _INF and 0 < sigma < _INF
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise DistributionError(f"TruncatedNormal needs a finite mu and a finite sigma > 0, got mu={mu!r:.40}, "
                             f"sigma={sigma!r:.40}")
        if not low < high:
            raise DistributionError(f"TruncatedNormal needs low < high, got [{low!r}, {high!r}]")
        self.mu, self.sigma, self.low, self.high = float(mu), float(sigma), float(low), float(high)
        self._cdf_low = _STANDARD_NORMAL.cdf((self.low - self.mu) / self.sigma)
        self._mass = _STANDARD_NORMAL.cdf((self.high - self.mu) / self.sigma) - self._cdf_low
        if not self._mass > 1e-300:
            raise DistributionError(
                f"TruncatedNormal({mu}, {sigma}, {low}, {high}) has no probability mass in its"
                " interval; move the interval towards mu or widen sigma")
        self._log_mass = math.log(self._mass)

    def sample(self, rng):
        if self._mass > 0.25:
            # Rejection from the untruncated normal: exact, and cheap when the mass is large.
            for _ in range(32):
                x = self.mu + self.sigma * rng.standard_normal()
                if self.low <= x <= self.high:
                    return x
        # Inverse CDF (also the fallback after 32 rejections, which has probability < 1e-4).
        u = self._cdf_low + rng.random() * self._mass
        u = min(max(u, 1e-16), 1.0 - 1e-16)
        x = self.mu + self.sigma * _STANDARD_NORMAL.inv_cdf(u)
        return min(max(x, self.low), self.high)

    def log_prob(self, value):
        if not _is_real(value) or not self.low <= value <= self.high:
            return -math.inf
        return _normal_log_pdf(value, self.mu, self.sigma) - self._log_mass

    def _params(self):
        return {"mu": self.mu, "sigma": self.sigma, "low": self.low, "high": self.high}

    @property
    def scale(self):
        return min(self.sigma, (self.high - self.low) / math.sqrt(12.0))


class Uniform(Distribution):
    """Continuous uniform on ``[low, high]``."""

    __slots__ = ("low", "high", "_log_width")

    def __init__(self, low: float, high: float):
        try:  # the hot path (tree, spaceship, city make one per choice): one chained comparison
            ok = -_INF < low < high < _INF
        except (TypeError, ValueError, OverflowError):
            ok = False
        if not ok:
            raise DistributionError(f"Uniform needs finite numbers low < high, got [{low!r:.40}, {high!r:.40}]")
        self.low, self.high = float(low), float(high)
        self._log_width = math.log(self.high - self.low)

    def sample(self, rng):
        return self.low + (self.high - self.low) * rng.random()

    def log_prob(self, value):
        if not _is_real(value) or not self.low <= value <= self.high:
            return -math.inf
        return -self._log_width

    def _params(self):
        return {"low": self.low, "high": self.high}

    @property
    def scale(self):
        return (self.high - self.low) / math.sqrt(12.0)


class Bernoulli(Distribution):
    """A coin with probability ``p`` of ``True``."""

    discrete = True
    __slots__ = ("p", "_log_p", "_log_q")

    def __init__(self, p: float):
        try:
            valid = 0.0 <= p <= 1.0
        except TypeError:
            valid = False
        if not valid:
            raise DistributionError(f"Bernoulli needs a number 0 <= p <= 1, got {p!r:.40}")
        self.p = float(p)
        self._log_p = math.log(p) if p > 0 else -math.inf
        self._log_q = math.log1p(-p) if p < 1 else -math.inf

    def sample(self, rng):
        return bool(rng.random() < self.p)

    def log_prob(self, value):
        if value is True:
            return self._log_p
        if value is False:
            return self._log_q
        return -math.inf

    def _params(self):
        return {"p": self.p}


class Categorical(Distribution):
    """A draw from a finite set with probabilities ``probs`` (normalised here).

    The value is the index ``0..k-1``, or the matching entry of ``labels`` when given
    (labels must be distinct strings, ints, finite floats or bools, so they serialise to JSON).
    """

    discrete = True
    __slots__ = ("probs", "labels", "_cumulative", "_log_probs", "_index")

    def __init__(self, probs, labels=None):
        try:
            probs = [float(p) for p in probs]
        except (TypeError, ValueError):
            raise DistributionError(f"Categorical needs a list of numbers, got {probs!r:.60}") from None
        if not probs or any(not (p >= 0.0 and math.isfinite(p)) for p in probs) or sum(probs) <= 0:
            raise DistributionError(f"Categorical needs non-negative probabilities with a positive sum, got {probs!r}")
        total = sum(probs)
        self.probs = tuple(p / total for p in probs)
        if labels is None:
            labels = tuple(range(len(probs)))
        # numpy bools as Python bools: a saved run's JSON true must find its label again (it
        # did not replay); numbers keep their numpy type, so a float32 label's arithmetic
        # stays float32
        labels = tuple(bool(label) if isinstance(label, np.bool_) else label for label in labels)
        if any(isinstance(label, np.longdouble) for label in labels):  # (a traceback on saving, h90)
            raise DistributionError(f"Categorical labels are saved as JSON, which has no numpy longdouble, got "
                             f"{labels!r:.80}; give them as floats (float(x))")
        if not all(isinstance(label, _LABEL_TYPES) and not (isinstance(label, (float, np.floating))
                                                              and not math.isfinite(label)) for label in labels):
            raise DistributionError(f"Categorical labels must be strings, numbers or bools (they are saved as JSON), got "
                             f"{labels!r:.80}; label by index and look the value up in the rule")
        if len(labels) != len(probs) or len(set(labels)) != len(labels):
            raise DistributionError(f"Categorical needs one distinct label per probability, got {labels!r}")
        self.labels = labels
        self._index = {label: i for i, label in enumerate(labels)}
        acc, cumulative = 0.0, []
        for p in self.probs:
            acc += p
            cumulative.append(acc)
        cumulative[-1] = 1.0
        self._cumulative = tuple(cumulative)
        self._log_probs = tuple(math.log(p) if p > 0 else -math.inf for p in self.probs)

    def sample(self, rng):
        u = rng.random()
        for i, c in enumerate(self._cumulative):
            if u < c:
                return self.labels[i]
        return self.labels[-1]

    def log_prob(self, value):
        i = self._index.get(value)
        # True == 1 and False == 0 in Python: a bool is only its own label, never an int's;
        # and 2.0 == 2: a real number is not an integer label (an edited file's 2.0 reached
        # the rule as an index, a traceback in the model's code)
        if i is None or isinstance(value, bool) != isinstance(self.labels[i], bool) or (
                isinstance(value, (float, np.floating)) and isinstance(self.labels[i], (int, np.integer))):
            return -math.inf
        return self._log_probs[i]

    def _params(self):
        return {"probs": self.probs, "labels": self.labels}


class GaussianMixture(Distribution):
    """A one-dimensional mixture of Gaussians: weights, means and standard deviations."""

    __slots__ = ("weights", "means", "sigmas", "_log_weights", "_component")

    def __init__(self, weights, means, sigmas):
        weights, means, sigmas = list(weights), list(means), list(sigmas)
        if not (len(weights) == len(means) == len(sigmas) >= 1):
            raise DistributionError("GaussianMixture needs equally many weights, means and sigmas (at least one)")
        if not (_finite(*means, *sigmas) and all(s > 0 for s in sigmas)):
            raise DistributionError(f"GaussianMixture needs finite means and finite sigmas > 0, got means={means!r:.60}, "
                             f"sigmas={sigmas!r:.60}")
        self._component = Categorical(weights)
        self.weights = self._component.probs
        self.means = tuple(float(m) for m in means)
        self.sigmas = tuple(float(s) for s in sigmas)
        self._log_weights = self._component._log_probs

    def sample(self, rng):
        k = self._component.sample(rng)
        return self.means[k] + self.sigmas[k] * rng.standard_normal()

    def log_prob(self, value):
        if not _is_real(value):
            return -math.inf
        terms = [lw + _normal_log_pdf(value, m, s)
                 for lw, m, s in zip(self._log_weights, self.means, self.sigmas) if lw > -math.inf]
        top = max(terms)
        return top + math.log(sum(math.exp(t - top) for t in terms))

    def _params(self):
        return {"weights": self.weights, "means": self.means, "sigmas": self.sigmas}

    @property
    def scale(self):
        return min(self.sigmas)
