"""The guided proposal's hot path, fused into numba kernels.

Guided SMC asks a network for every random choice of every particle, so the cost per
choice bounds its speed (DESIGN.md, "Speed budget"). Building the feature vector, running
the MLP and drawing from a Gaussian mixture as separate numpy calls costs ~30 us per
choice, almost all of it call overhead on tiny arrays; one kernel call does the same work
in a few microseconds. :mod:`procmod.guide.features` and :mod:`procmod.guide.network`
remain the readable reference (and what training uses); tests check these kernels
against them.
"""

from __future__ import annotations

import math

import numba
import numpy as np

from .features import local_features, windows_flat
from .network import LOG_SCALE_MAX as _LOG_SCALE_MAX
from .network import LOG_SCALE_MIN as _LOG_SCALE_MIN

_LOG_SQRT_2PI = 0.5 * math.log(2.0 * math.pi)


# A site's constants travel packed in one float array (see pack_site): numba unboxes every
# argument of every call, ~0.1-0.2 us each, and a choice used to pass 22 of them.
_HEAD = 6  # params[0:6]: raw local values, inputs, hidden units, outputs, use target, use partial


def pack_site(lows, spans, angular, weights, use_target: bool, use_partial: bool) -> np.ndarray:
    """One site's feature ranges and network ``(W1, b1, W2, b2)`` as the flat array the
    kernels read (a constant network has ``W1`` of shape ``(0, 0)``)."""
    w1, b1, w2, b2 = weights
    n_hidden, n_in = w1.shape
    head = [len(lows), n_in, n_hidden, w2.shape[0], float(use_target), float(use_partial)]
    parts = [head, lows, spans, np.asarray(angular, dtype=np.float64), w1.ravel(), b1, w2.ravel(), b2]
    return np.ascontiguousarray(np.concatenate([np.asarray(p, dtype=np.float64).ravel() for p in parts]))


@numba.njit(cache=True)
def site_features(raw_local, params, target, partial, layout, px, py, x):
    """A choice's feature vector (local state, target windows, partial-output windows)
    into ``x`` (length ``n_in``).

    ``raw_local`` are the call's scalar arguments, then the heading and the progress values
    where the guide has them, mapped to [-1, 1] by the site's ranges and clipped (angles
    to cos, sin), as :meth:`FeatureExtractor.features` does;
    ``target`` and ``partial`` are flat pyramids laid out by ``layout``; ``params`` is
    :func:`pack_site`'s array.
    """
    n_raw = int(params[0])
    o = _HEAD
    k = local_features(raw_local, params[o:o + n_raw], params[o + n_raw:o + 2 * n_raw],
                       params[o + 2 * n_raw:o + 3 * n_raw], x)
    if params[4] != 0.0:
        windows_flat(target, layout, px, py, x, k)
        k += 36
    if params[5] != 0.0:
        windows_flat(partial, layout, px, py, x, k)


_TANH_CLAMP = 10.5  # beyond it tanh is 1 to within 1.5e-9
_TANH_TERMS = 16


@numba.njit(cache=True, fastmath=True, inline="always")
def _tanh(a):
    """tanh(a) to within 5e-9, by the 16th convergent of Lambert's continued fraction
    (tanh a = a / (1 + a^2 / (3 + a^2 / (5 + ...)))), numerator and denominator by their
    three-term recurrences. A loop of calls of libm's tanh does not vectorise; this,
    arithmetic only, does: about a fifth less network time in a micro-benchmark (81
    inputs, 40 hidden units), 4-6% less time a guided run in an in-run A/B;
    tests/test_guide.py holds the outputs to torch's."""
    a = min(max(a, -_TANH_CLAMP), _TANH_CLAMP)
    t = a * a
    num2, num1, den2, den1 = 0.0, a, 1.0, 1.0
    for k in range(2, _TANH_TERMS + 1):
        b = 2.0 * k - 1.0
        num = b * num1 + t * num2
        den = b * den1 + t * den2
        num2, num1, den2, den1 = num1, num, den1, den
    return num1 / den1


# fastmath lets numba vectorise the dot products (reassociating the sums: results differ
# from torch's in the last bits only), and _tanh approximates to 5e-9: the outputs differ
# from torch's by under 1e-7 (a proposal's log-density is computed from the same outputs
# as its draw, so the weights stay exact). It is most of the cost of a guided choice.
@numba.njit(cache=True, fastmath=True)
def network_outputs(x, params):
    """The site network's outputs for the features ``x`` (``params``: :func:`pack_site`'s)."""
    n_raw, n_in, n_hidden, n_out = int(params[0]), int(params[1]), int(params[2]), int(params[3])
    o = _HEAD + 3 * n_raw
    w1 = params[o:o + n_hidden * n_in]
    o += n_hidden * n_in
    b1 = params[o:o + n_hidden]
    o += n_hidden
    w2 = params[o:o + n_out * n_hidden]
    o += n_out * n_hidden
    b2 = params[o:o + n_out]
    h = np.empty(n_hidden)
    for i in range(n_hidden):
        acc = b1[i]
        row = i * n_in
        for j in range(n_in):
            acc += w1[row + j] * x[j]
        h[i] = acc
    for i in range(n_hidden):  # a loop of its own: arithmetic only, so it vectorises
        h[i] = _tanh(h[i])
    out = np.empty(n_out)
    for i in range(n_out):
        acc = b2[i]
        row = i * n_hidden
        for j in range(n_hidden):
            acc += w2[row + j] * h[j]
        out[i] = acc
    return out


@numba.njit(cache=True)
def site_outputs(raw_local, params, target, partial, layout, px, py):
    """Features (:func:`site_features`) -> MLP outputs (:func:`network_outputs`)."""
    x = np.empty(int(params[1]))
    site_features(raw_local, params, target, partial, layout, px, py, x)
    return network_outputs(x, params)


@numba.njit(cache=True, fastmath=True)
def guided_draw(kind, k, c0, s0, base, u, z, raw_local, params, target, partial, layout, px, py):
    """One guided choice in one call: features -> MLP -> a draw from the proposal.

    ``kind`` 0: real (mixture of ``k`` Gaussians around ``c0`` with unit ``s0``),
    1: Bernoulli (prior logit ``base[0]``), 2: categorical (prior log-probabilities
    ``base``). ``u`` (uniform) and ``z`` (standard normal) come from the caller's
    generator. Returns (value, log q): the value is the real number, 1.0/0.0, or the
    category index.
    """
    out = site_outputs(raw_local, params, target, partial, layout, px, py)
    if kind == 0:
        return mixture_draw(out, k, c0, s0, _LOG_SCALE_MIN, _LOG_SCALE_MAX, u, z)
    if kind == 1:
        logit = base[0] + out[0]
        # log sigmoid(+-logit), computed stably
        log_on = -(max(-logit, 0.0) + math.log1p(math.exp(-abs(logit))))
        log_off = -(max(logit, 0.0) + math.log1p(math.exp(-abs(logit))))
        if u < math.exp(log_on):
            return 1.0, log_on
        return 0.0, log_off
    n = out.shape[0]
    top = base[0] + out[0]
    for j in range(1, n):
        top = max(top, base[j] + out[j])
    total = 0.0
    for j in range(n):
        total += math.exp(base[j] + out[j] - top)
    log_norm = top + math.log(total)
    acc = 0.0
    for j in range(n):
        lp = base[j] + out[j] - log_norm
        acc += math.exp(lp)
        if u < acc:
            return float(j), lp
    return float(n - 1), base[n - 1] + out[n - 1] - log_norm


@numba.njit(cache=True)
def mixture_draw(out, k, centre0, scale0, log_scale_min, log_scale_max, u, z):
    """Draw from the mixture the outputs set (component by uniform ``u``, then ``centre +
    sd * z``); returns (x, log density of x) in the mixture's own space."""
    top = out[0]
    for j in range(1, k):
        if out[j] > top:
            top = out[j]
    total = 0.0
    for j in range(k):
        total += math.exp(out[j] - top)
    log_norm = top + math.log(total)
    chosen = k - 1
    acc = 0.0
    for j in range(k):
        acc += math.exp(out[j] - log_norm)
        if u < acc:
            chosen = j
            break
    ls = min(max(out[2 * k + chosen], log_scale_min), log_scale_max)
    x = centre0 + scale0 * out[k + chosen] + scale0 * math.exp(ls) * z
    # log density: logsumexp over components
    best = -np.inf
    terms = np.empty(k)
    for j in range(k):
        lsj = min(max(out[2 * k + j], log_scale_min), log_scale_max)
        sd = scale0 * math.exp(lsj)
        d = (x - (centre0 + scale0 * out[k + j])) / sd
        terms[j] = out[j] - log_norm - 0.5 * d * d - math.log(sd)
        if terms[j] > best:
            best = terms[j]
    s = 0.0
    for j in range(k):
        s += math.exp(terms[j] - best)
    return x, best + math.log(s) - _LOG_SQRT_2PI
