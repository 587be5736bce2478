"""``mcmc``: reversible-jump MCMC on derivations, with parallel tempering, annealing and
optional delayed rejection (Metropolis procedural modeling, Talton et al. 2011; seed 002
section 7).

Moves, all built from replay under a modified choice map:

* **diffusion** — pick a call with continuous choices uniformly, perturb all of them
  with a Gaussian random walk (``step_scale`` x each distribution's scale);
* **regenerate** (jump) — pick a call uniformly and resample its subtree from the prior;
* **toggle** (jump) — pick a ``maybe`` site uniformly and flip it: grow a fresh subtree
  from the prior or cut the existing one.

Acceptance. Replaying a map reuses some choices and samples the rest from the prior, so
for every move the forward proposal density is (selection probability) x (symmetric
kernel, diffusion only) x (prior of the freshly sampled choices), and the reverse move
resamples exactly the choices that were dropped. The Metropolis-Hastings ratio for the
tempered target ``prior x likelihood^beta`` therefore reduces to::

    log alpha = log p(reused choices of the new derivation)
              - log p(old choices that were reused)
              + beta (log L(new) - log L(old))
              + log n_candidates(old) - log n_candidates(new)

which includes the dimension-matching terms of reversible jump (the prior of a grown
subtree cancels against its proposal density).

Parallel tempering uses seed 002's ladder: temperatures spaced geometrically so that a
move accepted 70% of the time in the hottest chain is accepted 1% of the time in the
coldest (likelihood ratio ``r`` with ``r^(1/T_hot) = 0.7`` and ``r^(1/T_cold) = 0.01``,
so ``T_hot / T_cold = ln 0.01 / ln 0.7``); after each sweep a random adjacent pair
proposes to swap states. Annealing multiplies every chain's inverse temperature by 1.1
every ``anneal_every`` sweeps. Delayed rejection (optional): when a regenerate jump is
rejected, a second independent regeneration of the same call is tried and accepted with
the Tierney-Mira two-stage probability.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core import InvalidArgumentError, is_within
from .common import (Budget, Evaluation, Result, Scored, Tracker, check_positive,
                     evaluate_all, new_seed, relaxed_gc)

HOTTEST_ACCEPTANCE = 0.7
COLDEST_ACCEPTANCE = 0.01
T_MAX = math.log(COLDEST_ACCEPTANCE) / math.log(HOTTEST_ACCEPTANCE)  # ~12.9


def temperature_ladder(chains: int) -> np.ndarray:
    """Inverse temperatures of seed 002's ladder, coldest (beta = 1) first."""
    if chains == 1:
        return np.ones(1)
    return 1.0 / T_MAX ** (np.arange(chains) / (chains - 1))


def diffusion_candidates(derivation) -> list:
    """Calls with at least one continuous choice."""
    return [n for n in derivation.nodes()
            if any(not c.dist.discrete for c in n.choices.values())]


def maybe_sites(derivation) -> list:
    """``(node_address, site)`` of every ``maybe`` site, on or off."""
    return [(n.address, s.site) for n in derivation.nodes() for s in n.spawns if s.probability < 1.0]


@dataclass
class Proposal:
    kind: str
    choices: dict
    n_before: int
    address: tuple = ()
    perturbed: tuple = ()


def _counter(kind: str):
    if kind == "diffusion":
        return lambda d: len(diffusion_candidates(d))
    if kind == "toggle":
        return lambda d: len(maybe_sites(d))
    return lambda d: d.n_nodes


def propose(state: Scored, rng: np.random.Generator, p_diffusion: float, step_scale: float) -> Proposal:
    """Build one move's choice map from a chain state."""
    d = state.derivation
    old = d.choice_map().raw
    kind = "diffusion" if rng.random() < p_diffusion else "jump"
    if kind == "diffusion":
        candidates = diffusion_candidates(d)
        if not candidates:
            kind = "jump"
        else:
            node = candidates[int(rng.random() * len(candidates))]
            choices = dict(old)
            perturbed = []
            for name, c in node.choices.items():
                if not c.dist.discrete:
                    choices[(node.address, name)] = c.value + step_scale * c.dist.scale * rng.standard_normal()
                    perturbed.append((node.address, name))
            return Proposal("diffusion", choices, len(candidates), node.address, tuple(perturbed))
    sites = maybe_sites(d)
    if sites and rng.random() < 0.5:
        address, site = sites[int(rng.random() * len(sites))]
        child = address + (site,)
        choices = {k: v for k, v in old.items() if not is_within(k[0], child)}
        choices[(address, site)] = not old[(address, site)]
        return Proposal("toggle", choices, len(sites), address)
    nodes = d.nodes()
    node = nodes[int(rng.random() * len(nodes))]
    choices = {k: v for k, v in old.items() if not is_within(k[0], node.address)}
    return Proposal("regenerate", choices, len(nodes), node.address)


def _kept_log_prob(state: Scored, proposal: Proposal, ev: Evaluation) -> float:
    """Log-probability, under the old derivation, of the old choices the new one reused."""
    old = state.derivation.choice_log_probs()
    unused = set(ev.unused)
    return sum(old[k] for k in proposal.choices if k not in unused and k in old)


def log_acceptance(state: Scored, proposal: Proposal, ev: Evaluation, beta: float) -> float:
    """The reversible-jump log acceptance ratio (see the module docstring)."""
    if ev.log_reused == -math.inf or ev.log_likelihood == -math.inf:
        return -math.inf
    if proposal.perturbed and not set(proposal.perturbed).isdisjoint(ev.unused):
        return -math.inf  # a random-walk step left the choice's support: zero target density
    n_after = _counter(proposal.kind)(ev.derivation)
    if n_after == 0:
        return -math.inf
    return (ev.log_reused - _kept_log_prob(state, proposal, ev)
            + beta * (ev.log_likelihood - state.log_likelihood)
            + math.log(proposal.n_before) - math.log(n_after))


def _log_q_regenerate(src, dst, address) -> float:
    """Log density of proposing ``dst`` by regenerating ``address`` in ``src``."""
    if address not in src.tree():
        return -math.inf
    old = src.choice_map().raw
    total = -math.log(src.n_nodes)
    for node in dst.nodes():
        inside = is_within(node.address, address)
        for name, c in node.choices.items():
            key = (node.address, name)
            if inside or old.get(key, _NOTHING) != c.value:
                total += c.log_prob
    return total


_NOTHING = object()


def _log_pi(state: Scored, beta: float) -> float:
    return state.log_prior + beta * state.log_likelihood


def _log_alpha1(src: Scored, dst: Scored, address, beta) -> float:
    return min(0.0, _log_pi(dst, beta) - _log_pi(src, beta)
               + _log_q_regenerate(dst.derivation, src.derivation, address)
               - _log_q_regenerate(src.derivation, dst.derivation, address))


def _log1m_exp(x: float) -> float:
    return -math.inf if x >= 0 else math.log1p(-math.exp(x))


def delayed_rejection_log_alpha(x: Scored, y1: Scored, y2: Scored, address, beta) -> float:
    """Tierney-Mira second-stage acceptance for an independent second regeneration."""
    num = (_log_pi(y2, beta) + _log_q_regenerate(y2.derivation, y1.derivation, address)
           + _log_q_regenerate(y2.derivation, x.derivation, address)
           + _log1m_exp(_log_alpha1(y2, y1, address, beta)))
    den = (_log_pi(x, beta) + _log_q_regenerate(x.derivation, y1.derivation, address)
           + _log_q_regenerate(x.derivation, y2.derivation, address)
           + _log1m_exp(_log_alpha1(x, y1, address, beta)))
    if num == -math.inf:
        return -math.inf
    return min(0.0, num - den)


def mcmc(model, target, chains: int = 8, seed: int = 0, budget: Budget | None = None,
         p_diffusion: float = 0.5, step_scale: float = 0.1, tempering: bool = True,
         annealing: float | None = 1.1, anneal_every: int = 50, delayed_rejection: bool = False,
         executor=None, progress=None) -> Result:
    """Reversible-jump MCMC with parallel tempering and annealing.

    Parameters
    ----------
    chains : int
        Number of chains; with ``tempering`` they form one temperature ladder (coldest
        first), otherwise they are independent chains at temperature 1.
    budget : Budget
        Default: 200 sweeps (generations). One sweep proposes one move per chain.
    p_diffusion : float
        Probability of a diffusion move (otherwise a jump).
    step_scale : float
        Diffusion step as a fraction of each choice distribution's scale.
    annealing : float or None
        Factor by which every inverse temperature grows every ``anneal_every`` sweeps
        (turns sampling into optimisation); None samples the tempered posterior.
    delayed_rejection : bool
        Try a second regeneration when a regenerate jump is rejected.
    executor : concurrent.futures.Executor, optional
        Evaluates the chains' proposals of a sweep (default: in-process).
    """
    check_positive("chains", chains)
    if not 0.0 <= p_diffusion <= 1.0:
        raise InvalidArgumentError(f"p_diffusion must be in [0, 1], got {p_diffusion!r}")
    if annealing is not None and not annealing >= 1.0:
        raise InvalidArgumentError(f"annealing must be >= 1 (or None), got {annealing!r}")
    budget = budget or Budget(generations=200)
    model = target.configure(model)
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    betas = temperature_ladder(chains) if tempering else np.ones(chains)
    accepted = {"diffusion": 0, "regenerate": 0, "toggle": 0, "swap": 0, "delayed": 0}
    proposed = dict.fromkeys(accepted, 0)
    with relaxed_gc():
        states = [Scored.from_evaluation(ev) for ev in
                  evaluate_all(executor, model, target, [({}, new_seed(rng), None) for _ in range(chains)])]
        tracker.evaluations += chains
        for s in states:
            tracker.offer(s.derivation, s.score)
        while not tracker.spent():
            proposals = [propose(s, rng, p_diffusion, step_scale) for s in states]
            evaluations = evaluate_all(executor, model, target,
                                       [(p.choices, new_seed(rng), None) for p in proposals])
            tracker.evaluations += chains
            second = []
            for c, (s, p, ev) in enumerate(zip(states, proposals, evaluations)):
                proposed[p.kind] += 1
                tracker.offer(ev.derivation, ev.score)
                if math.log(rng.random() + 1e-300) < log_acceptance(s, p, ev, betas[c]):
                    states[c] = Scored.from_evaluation(ev)
                    accepted[p.kind] += 1
                elif delayed_rejection and p.kind == "regenerate":
                    second.append((c, p, ev))
            if second:
                retries = evaluate_all(executor, model, target,
                                       [(p.choices, new_seed(rng), None) for _, p, _ in second])
                tracker.evaluations += len(second)
                for (c, p, ev1), ev2 in zip(second, retries):
                    proposed["delayed"] += 1
                    tracker.offer(ev2.derivation, ev2.score)
                    y1, y2 = Scored.from_evaluation(ev1), Scored.from_evaluation(ev2)
                    if math.log(rng.random() + 1e-300) < delayed_rejection_log_alpha(
                            states[c], y1, y2, p.address, betas[c]):
                        states[c] = y2
                        accepted["delayed"] += 1
            if chains > 1 and tempering:
                i = int(rng.random() * (chains - 1))
                proposed["swap"] += 1
                log_swap = (betas[i] - betas[i + 1]) * (states[i + 1].log_likelihood - states[i].log_likelihood)
                if math.log(rng.random() + 1e-300) < log_swap:
                    states[i], states[i + 1] = states[i + 1], states[i]
                    accepted["swap"] += 1
            tracker.generations += 1
            if annealing is not None and tracker.generations % anneal_every == 0:
                betas = betas * annealing
            if tracker.due():
                tracker.record(float(np.mean([s.score for s in states])))
        tracker.record(float(np.mean([s.score for s in states])))
    rates = {k: (accepted[k] / proposed[k] if proposed[k] else None) for k in accepted}
    return Result("mcmc", tracker.best, tracker.best_score, [s.derivation for s in states],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={"chains": chains, "seed": seed, "budget": budget.describe(),
                            "p_diffusion": p_diffusion, "step_scale": step_scale,
                            "tempering": tempering, "annealing": annealing,
                            "anneal_every": anneal_every, "delayed_rejection": delayed_rejection,
                            "acceptance_rates": rates},
                  log_weights=[s.log_likelihood for s in states])
