"""Guide networks: one small MLP per random-choice site, and the proposal each one sets.

A *site* is a rule plus a choice name (``branch:angle``). Its network (seed 004 4.1) maps
the site's n_f features through one tanh hidden layer of n_f / 2 units to the parameters
of a proposal distribution; with no features (the "constant" condition) the network is
just a learned parameter vector.

Outputs are *relative to the prior the program asked for*, so an untrained network
proposes roughly the prior and training learns corrections:

- ``real`` (Normal, GaussianMixture priors): a mixture of K Gaussians, component k with
  weight softmax(a)_k, mean mu0 + s0 m_k and sd s0 exp(l_k), where mu0, s0 are the prior's
  mean and spread (the bounding transforms are softmax and exp);
  a TruncatedNormal bounded on one side only gets the same mixture cut to its support
  and renormalised (a rule never sees a value its prior cannot draw);
- ``interval`` (Uniform, TruncatedNormal with finite bounds): the same mixture over the
  logit of the value's position in [low, high] (so proposals never leave the support),
  with the change-of-variables term in the density;
- ``bernoulli``: p = sigmoid(logit(p0) + o);
- ``categorical``: probabilities softmax(log p0 + o).

Sites the guide never saw in training propose from the prior.
"""

from __future__ import annotations

import math

import numpy as np

from ..core.distributions import Bernoulli, Categorical, GaussianMixture, Normal, TruncatedNormal, Uniform
from .features import GuideError

LOGISTIC_SD = math.pi / math.sqrt(3.0)  # spread of the logit of a uniform variable
LOG_SCALE_MIN, LOG_SCALE_MAX = -7.0, 4.0
EDGE = 1e-9  # keeps logits of interval values finite


def head_kind(dist) -> str:
    """The proposal family for a prior distribution."""
    if isinstance(dist, Bernoulli):
        return "bernoulli"
    if isinstance(dist, Categorical):
        return f"categorical:{len(dist.probs)}"
    if isinstance(dist, (Normal, GaussianMixture)):
        return "real"
    if isinstance(dist, Uniform):
        return "interval"
    if isinstance(dist, TruncatedNormal):
        if math.isfinite(dist.low) and math.isfinite(dist.high):
            return "interval"
        return "real"  # half-bounded: the mixture cut to the support (propose)
    raise GuideError(f"neural guides do not support {type(dist).__name__} choices yet")


def n_outputs(kind: str, mixture: int) -> int:
    if kind in ("real", "interval"):
        return 3 * mixture
    if kind == "bernoulli":
        return 1
    return int(kind.split(":")[1])


def _mixture_mean_sd(dist: GaussianMixture) -> tuple[float, float]:
    mean = sum(w * m for w, m in zip(dist.weights, dist.means))
    var = sum(w * (s * s + (m - mean) ** 2) for w, m, s in zip(dist.weights, dist.means, dist.sigmas))
    return mean, math.sqrt(var)


def base_params(kind: str, dist) -> tuple:
    """The prior's parameters the network's outputs are relative to."""
    if kind == "real":
        if isinstance(dist, GaussianMixture):
            return _mixture_mean_sd(dist)
        return (dist.mu, dist.sigma)
    if kind == "interval":
        mean = 0.5 * (dist.low + dist.high) if isinstance(dist, Uniform) else dist.mu
        frac = min(max((mean - dist.low) / (dist.high - dist.low), 0.05), 0.95)
        return (dist.low, dist.high, math.log(frac / (1.0 - frac)))
    if kind == "bernoulli":
        p = min(max(dist.p, 1e-12), 1.0 - 1e-12)
        return (math.log(p / (1.0 - p)),)
    return tuple(max(lp, -1e9) for lp in dist._log_probs)


def encode_value(kind: str, dist, value) -> float:
    """A choice value as the number the training loss reads (category index, 0/1)."""
    if kind == "bernoulli":
        return 1.0 if value else 0.0
    if kind.startswith("categorical"):
        return float(dist._index[value])
    return float(value)


def initial_bias(kind: str, mixture: int) -> np.ndarray:
    """Output-layer bias that makes an untrained network propose about the prior."""
    if kind in ("real", "interval"):
        means = np.linspace(-0.5, 0.5, mixture) if mixture > 1 else np.zeros(1)
        return np.concatenate([np.zeros(mixture), means, np.zeros(mixture)])
    return np.zeros(n_outputs(kind, mixture))


# ---- inference side: plain numpy / math, one choice at a time -----------------------

def _log_softmax(v: np.ndarray) -> np.ndarray:
    top = v.max()
    return v - (top + math.log(np.exp(v - top).sum()))


def _sample_mixture(log_w, centres, sds, rng) -> float:
    u = rng.random()
    acc = 0.0
    k = len(log_w) - 1
    for j in range(len(log_w)):
        acc += math.exp(log_w[j])
        if u < acc:
            k = j
            break
    return centres[k] + sds[k] * rng.standard_normal()


def _mixture_log_density(x, log_w, centres, sds) -> float:
    terms = [log_w[j] - 0.5 * ((x - centres[j]) / sds[j]) ** 2 - math.log(sds[j]) for j in range(len(log_w))]
    top = max(terms)
    return top + math.log(sum(math.exp(t - top) for t in terms)) - 0.5 * math.log(2 * math.pi)


def _log_mass(alpha: float, beta: float) -> float:
    """log P(alpha < Z < beta) for a standard normal Z, without cancellation in the tails."""
    from scipy.special import log_ndtr

    if alpha > 0.0:  # the upper tail: by symmetry, the lower one, where log_ndtr is exact
        alpha, beta = -beta, -alpha
    upper = float(log_ndtr(beta))
    lower = float(log_ndtr(alpha))
    return upper + math.log1p(-math.exp(lower - upper)) if lower < upper else -math.inf


def truncated_mixture_draw(log_w, centres, sds, low: float, high: float, rng):
    """Draw from a Gaussian mixture cut to [low, high] and renormalised; returns (x, log
    density of x under the cut mixture), or None when the mixture puts no measurable mass
    there (the caller falls back to the prior)."""
    from scipy.special import ndtr, ndtri

    k = len(log_w)
    alphas = [(low - centres[j]) / sds[j] for j in range(k)]
    betas = [(high - centres[j]) / sds[j] for j in range(k)]
    terms = [log_w[j] + _log_mass(alphas[j], betas[j]) for j in range(k)]
    top = max(terms)
    if not top > -700.0:
        return None
    log_z = top + math.log(sum(math.exp(t - top) for t in terms))
    u, chosen, acc = rng.random(), k - 1, 0.0
    for j in range(k):
        acc += math.exp(terms[j] - log_z)
        if u < acc:
            chosen = j
            break
    a, b, v = alphas[chosen], betas[chosen], rng.random()
    if a > 0.0:  # in the upper tail: draw -Z from the mirrored lower one, where ndtr keeps its digits
        lo, hi = float(ndtr(-b)), float(ndtr(-a))
        z = -float(ndtri(lo + v * (hi - lo)))
    else:
        lo, hi = float(ndtr(a)), float(ndtr(b))
        z = float(ndtri(lo + v * (hi - lo)))
    x = min(max(centres[chosen] + sds[chosen] * min(max(z, a), b), low), high)
    return x, _mixture_log_density(x, log_w, centres, sds) - log_z


def propose(kind: str, mixture: int, out: np.ndarray, base: tuple, dist, rng: np.random.Generator):
    """Draw a value from the proposal the outputs set; returns (value, log q(value))."""
    if kind == "bernoulli":
        logit = base[0] + out[0]
        p = 1.0 / (1.0 + math.exp(-logit)) if logit > -700 else 0.0
        on = rng.random() < p
        lq = -math.log1p(math.exp(-logit)) if on else -math.log1p(math.exp(logit))
        return bool(on), lq
    if kind.startswith("categorical"):
        log_p = _log_softmax(np.asarray(base) + out)
        i = len(log_p) - 1
        u, acc = rng.random(), 0.0
        for j, lp in enumerate(log_p):
            acc += math.exp(lp)
            if u < acc:
                i = j
                break
        return dist.labels[i], float(log_p[i])
    k = mixture
    log_w = _log_softmax(out[:k])
    log_scales = np.clip(out[2 * k:3 * k], LOG_SCALE_MIN, LOG_SCALE_MAX)
    if kind == "real":
        mu0, s0 = base
        centres = mu0 + s0 * out[k:2 * k]
        sds = s0 * np.exp(log_scales)
        if isinstance(dist, TruncatedNormal):  # bounded on one side: never a value outside
            drawn = truncated_mixture_draw(log_w, centres, sds, dist.low, dist.high, rng)
            if drawn is None:  # the proposal misses the support altogether: the prior's draw
                value = dist.sample(rng)
                return value, dist.log_prob(value)
            return drawn
        x = _sample_mixture(log_w, centres, sds, rng)
        return x, _mixture_log_density(x, log_w, centres, sds)
    low, high, c = base
    centres = c + LOGISTIC_SD * out[k:2 * k]
    sds = LOGISTIC_SD * np.exp(log_scales)
    u = _sample_mixture(log_w, centres, sds, rng)
    frac = 1.0 / (1.0 + math.exp(-u)) if u > -700 else 0.0
    frac = min(max(frac, EDGE), 1.0 - EDGE)
    u = math.log(frac / (1.0 - frac))
    x = low + (high - low) * frac
    lq = _mixture_log_density(u, log_w, centres, sds) - math.log(frac) - math.log1p(-frac) - math.log(high - low)
    return x, lq
