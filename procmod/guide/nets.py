"""The training side of guide networks (torch): the site network module and the
proposal log-density as differentiable tensors. The inference side, in plain numpy and
numba, is :mod:`procmod.guide.network` and :mod:`procmod.guide.fast`; it needs only
each network's weights (:meth:`SiteNet.numpy_weights`), so running a saved guide does
not import torch.
"""

from __future__ import annotations

import math

import numpy as np
import torch

from .network import EDGE, LOG_SCALE_MAX, LOG_SCALE_MIN, LOGISTIC_SD


class SiteNet(torch.nn.Module):
    """The network of one site: n_in -> tanh(n_in / 2) -> n_out (or a constant vector)."""

    def __init__(self, n_in: int, n_out: int, bias: np.ndarray, generator: torch.Generator):
        super().__init__()
        self.n_in = n_in
        if n_in > 0:
            hidden = max(n_in // 2, 1)
            self.hidden = torch.nn.Linear(n_in, hidden, dtype=torch.float64)
            self.out = torch.nn.Linear(hidden, n_out, dtype=torch.float64)
            with torch.no_grad():
                bound = 1.0 / math.sqrt(n_in)
                self.hidden.weight.uniform_(-bound, bound, generator=generator)
                self.hidden.bias.uniform_(-bound, bound, generator=generator)
                self.out.weight.normal_(0.0, 0.01, generator=generator)
                self.out.bias.copy_(torch.as_tensor(bias))
        else:
            self.constant = torch.nn.Parameter(torch.as_tensor(bias, dtype=torch.float64).clone())

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        if self.n_in > 0:
            return self.out(torch.tanh(self.hidden(x)))
        return self.constant.expand(x.shape[0], -1)

    def numpy_weights(self) -> tuple:
        """(W1, b1, W2, b2) as numpy arrays; a constant network has no hidden units
        (empty W1, b1, W2) and its vector as b2."""
        if self.n_in > 0:
            return tuple(np.ascontiguousarray(t.detach().numpy()).copy() for t in
                         (self.hidden.weight, self.hidden.bias, self.out.weight, self.out.bias))
        constant = self.constant.detach().numpy().copy()
        return np.zeros((0, 0)), np.zeros(0), np.zeros((len(constant), 0)), constant

    def set_numpy_weights(self, weights: tuple) -> None:
        """Take the weights :meth:`numpy_weights` returns (its inverse)."""
        w1, b1, w2, b2 = weights
        with torch.no_grad():
            if self.n_in > 0:
                for t, v in ((self.hidden.weight, w1), (self.hidden.bias, b1), (self.out.weight, w2), (self.out.bias, b2)):
                    t.copy_(torch.as_tensor(v))
            else:
                self.constant.copy_(torch.as_tensor(b2))


def _mixture_parts(out: torch.Tensor, k: int):
    logits = out[:, :k]
    means = out[:, k:2 * k]
    log_scales = out[:, 2 * k:3 * k].clamp(LOG_SCALE_MIN, LOG_SCALE_MAX)
    return torch.log_softmax(logits, dim=1), means, log_scales


def log_q_torch(kind: str, mixture: int, out: torch.Tensor, base: torch.Tensor, value: torch.Tensor) -> torch.Tensor:
    """Log-density (or mass) of each row's value under the proposal the outputs set."""
    if kind == "bernoulli":
        logit = base[:, 0] + out[:, 0]
        return -torch.nn.functional.softplus(torch.where(value > 0.5, -logit, logit))
    if kind.startswith("categorical"):
        log_p = torch.log_softmax(base + out, dim=1)
        return log_p.gather(1, value.long().unsqueeze(1)).squeeze(1)
    log_w, m, l = _mixture_parts(out, mixture)
    if kind == "real":
        mu0, s0 = base[:, 0:1], base[:, 1:2]
        x = value.unsqueeze(1)
        centre, log_sd = mu0 + s0 * m, torch.log(s0) + l
        jacobian = 0.0
    else:
        low, high, c = base[:, 0], base[:, 1], base[:, 2:3]
        frac = ((value - low) / (high - low)).clamp(EDGE, 1.0 - EDGE)
        x = torch.log(frac / (1.0 - frac)).unsqueeze(1)
        centre, log_sd = c + LOGISTIC_SD * m, math.log(LOGISTIC_SD) + l
        jacobian = -torch.log(frac) - torch.log1p(-frac) - torch.log(high - low)
    z = (x - centre) * torch.exp(-log_sd)
    comp = log_w - 0.5 * z * z - log_sd - 0.5 * math.log(2 * math.pi)
    return torch.logsumexp(comp, dim=1) + jacobian
