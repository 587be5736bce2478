"""``mcmc``: reversible-jump MCMC on derivations, with parallel tempering, annealing and
optional delayed rejection (Metropolis procedural modeling, Talton et al. 2011; seed 002
section 7).

Moves, all built from replay under a modified choice map:

* **diffusion** — pick a call with continuous choices uniformly, perturb all of them
  with a Gaussian random walk (``step_scale`` x each distribution's scale);
* **regenerate** (jump) — pick a call uniformly and resample its subtree from the prior;
* **toggle** (jump) — pick a ``maybe`` site uniformly and flip it: grow a fresh subtree
  from the prior or cut the existing one;
* **resample** (single-site) — pick one choice uniformly among all the state's choices
  and draw it afresh from its prior, keeping every other value (WebPPL's single-site MH
  move): the move that flips one coin, e.g. a vine's ``terminate``, growing the vine
  from its last segment on, which a regenerate jump reaches only with the call's other
  choices redrawn too. It drops the choice from the map, so it is a jump like the
  others: the reverse move drops the same choice in the new state. A discrete choice's
  new value is drawn when the move is proposed: when it is the old value the move leaves
  the state as it is and is accepted without a replay (WebPPL's MH does the same; half
  the redraws of a fair coin), otherwise the replay takes it as an override and the
  acceptance ratio leaves out its prior, which its proposal density cancels.

Move selection depends on what the state offers. With ``D`` calls that have a continuous
choice, ``M`` ``maybe`` sites (on or off), ``K`` choices and ``N`` calls,
:func:`propose` picks::

    P(kind)     diffusion: p_diffusion if D > 0, else 0
                resample:  p_resample if K > 0, else 0
                toggle:    (1 - P(diffusion) - P(resample)) / 2 if M > 0, else 0
                regenerate: the rest, 1 - P(diffusion) - P(resample) - P(toggle)
    P(move)  =  P(kind) / (D, K, M or N respectively)

(:func:`log_select`). States differ in ``D`` and ``M`` — a vine whose root terminates
has no ``maybe`` site, a derivation may have no continuous choice at all — so both the
kind's probability and the count enter the ratio, evaluated in the old state for the
move and in the new state for its reverse (the same kind at the same site).

Jump sites are chosen uniformly among the calls: Talton et al.'s basic jump (every rule
call is a nonterminal of the derivation). Their *nonterminal selection* optimisation
reweights that choice; seed 002 describes it only as "altering the probability with
which the mutations choose genes", without the weights, so it is not implemented here.
Any site distribution would fit the acceptance below, with :func:`log_select` returning
its probability of the site in each state.

Acceptance. Replaying a map reuses some choices and samples the rest from the prior, so
for every move the forward proposal density is P(move | old) x (symmetric kernel,
diffusion only) x (prior of the freshly sampled choices), and the reverse move resamples
exactly the choices that were dropped. The Metropolis-Hastings ratio for the tempered
target ``prior x likelihood^beta`` therefore reduces to::

    log alpha = log p(reused choices of the new derivation)
              - log p(old choices that were reused)
              + beta (log L(new) - log L(old))
              + log P(move | new) - log P(move | old)

which includes the dimension-matching terms of reversible jump (the prior of a grown
subtree cancels against its proposal density). ``P(move | new)`` is zero, and the move
rejected, when the new state does not offer the reverse move. The diffusion kernel is
symmetric only where each choice's scale is the same in both states; where a scale
follows another choice (``y ~ Normal(0, x)``, perturbed with ``x``) the ratio adds its
Gaussian steps' log q(old | new) - log q(new | old) (:func:`diffusion_log_ratio`).

Two cases where a choice the map offered is not reused (:func:`support_log_factor`):

* a choice that the new derivation makes, but whose offered value lies outside its new
  support (``y ~ Uniform(0, x)`` after ``x`` moved below ``y``), is drawn afresh. The
  reverse move offers that fresh value back, and reuses it unless it lies outside the old
  support: then it too draws afresh and the ratio above holds; otherwise the reverse move
  cannot return to the old value, so the move is rejected. (Counting such a redraw as a
  plain fresh choice had halved E[x] in that two-choice model.) A diffusion step whose
  own perturbed value leaves its support is rejected outright: the target density there
  is zero;
* a choice the new derivation no longer makes (``y`` is drawn only while ``x > 0``, and
  the step took ``x`` below 0) simply drops out, like any choice a jump removes: the
  reverse move draws it afresh. (Rejecting it as though the step had left ``y``'s
  support had made P(x > 0) 0.74 where it is 0.5.)

Parallel tempering uses seed 002's ladder: temperatures spaced geometrically so that a
move accepted 70% of the time in the hottest chain is accepted 1% of the time in the
coldest (likelihood ratio ``r`` with ``r^(1/T_hot) = 0.7`` and ``r^(1/T_cold) = 0.01``,
so ``T_hot / T_cold = ln 0.01 / ln 0.7``); after each sweep a random adjacent pair
proposes to swap states. Annealing multiplies every chain's inverse temperature by 1.1
every ``anneal_every`` sweeps. Delayed rejection (optional): when a regenerate jump is
rejected, a second independent regeneration of the same call is tried and accepted with
the Tierney-Mira two-stage probability, in which the site's selection probability enters
once per first-stage move (the second stage reuses the site, so it has no selection
factor of its own; see :func:`delayed_rejection_log_alpha`).

Cost. By default each move is replayed incrementally (:mod:`procmod.infer.traced`):
from a checkpoint before the edited call, taking over the unchanged calls after it
without running them — the same chain, bit for bit, as replaying the whole derivation
(``incremental=False``, and always with an executor or delayed rejection), at a cost
that grows with what the move changes.

Start. Chains start from the best complete derivations of one SMC run of
``init_particles`` (100) particles on the target, not from forward samples: on an image
target a forward sample is mostly a vine that stops after a segment or two, and a chain
spends its first thousands of moves, often its whole budget, growing what SMC finds in a
fraction of a second (on development glyphs +0.09 to +0.2 of mean similarity at equal
CPU time, on scribbles about even; docs/vines_smc.md). The stationary distribution is the
same from any start. ``init_particles=0`` keeps the forward start.
"""

from __future__ import annotations

import math
import time
from bisect import bisect_right
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ..core import InvalidArgumentError, Model, is_within
from ..core.errors import argument, check_real, shown_value, whole_number
from ..core.protocols import Target
from ..core.limits import relaxed_gc
from ..core.random import LazyGenerator
from .common import (RULED_OUT_NOTE, Budget, Evaluation, Result, Scored, Tracker, check_population, check_positive,
                     check_run, configured_model, evaluate_all, mean_of, new_seed, recorded_seed)
from .mcmc_workers import run_groups
from .particles import fork_available
from .traced import DROP, EditedChoices, Traced, TracedReplay, node_counts, replay_traced, trace

HOTTEST_ACCEPTANCE = 0.7
COLDEST_ACCEPTANCE = 0.01
T_MAX = math.log(COLDEST_ACCEPTANCE) / math.log(HOTTEST_ACCEPTANCE)  # ~12.9
TOGGLE_SHARE = 0.5  # of the jumps, where the state has a maybe site
# SMC particles whose best derivations the chains start from (mcmc's init_particles)
INIT_PARTICLES = 100

MOVES = ("diffusion", "resample", "regenerate", "toggle")


def temperature_ladder(chains: int) -> np.ndarray:
    """Inverse temperatures of seed 002's ladder, coldest (beta = 1) first."""
    if chains == 1:
        return np.ones(1)
    return 1.0 / T_MAX ** (np.arange(chains) / (chains - 1))


def _has_continuous(node) -> bool:
    for c in node.choices.values():
        if not c.dist.discrete:
            return True
    return False


class MoveCounts(NamedTuple):
    """What a state offers each move: calls, calls with a continuous choice, maybe sites,
    choices."""

    calls: int
    diffusion: int
    maybe: int
    choices: int


def move_counts(derivation) -> MoveCounts:
    """:class:`MoveCounts` of a derivation (one walk over its calls)."""
    return _counts_of(derivation.nodes())


def _counts_of(nodes) -> MoveCounts:
    diffusion = maybe = choices = 0
    for node in nodes:
        c, m, k = node_counts(node)
        diffusion += c
        maybe += m
        choices += k
    return MoveCounts(len(nodes), diffusion, maybe, choices)


def log_select(counts: MoveCounts, kind: str, p_diffusion: float, p_resample: float = 0.0) -> float:
    """Log-probability that :func:`propose` picks one given move of ``kind`` (one call,
    site or choice) in a state with ``counts``; -inf where the state does not offer the
    move."""
    p_diff = p_diffusion if counts.diffusion else 0.0
    p_res = p_resample if counts.choices else 0.0
    if kind == "diffusion":
        p, n = p_diff, counts.diffusion
    elif kind == "resample":
        p, n = p_res, counts.choices
    else:
        toggle = (1.0 - p_diff - p_res) * (TOGGLE_SHARE if counts.maybe else 0.0)
        if kind == "toggle":
            p, n = toggle, counts.maybe
        else:
            p, n = 1.0 - p_diff - p_res - toggle, counts.calls
    return math.log(p / n) if p > 0.0 and n > 0 else -math.inf


@dataclass
class Proposal:
    """One move: the edit of the choice map to replay, and where and how likely the move
    was picked.

    The edited map is the old one without the subtree at ``removed`` (None: nothing
    dropped), with ``overrides`` applied (a value, or :data:`DROP` for a choice dropped
    so that the replay samples it afresh); every edit lies within the call at
    ``address``. ``choices`` is that map as a dict where :func:`propose` built it (from a
    plain :class:`Scored` state; None from a :class:`~procmod.infer.traced.Traced` one,
    which replays the edit without building it). ``log_select`` is :func:`log_select`
    in the old state; ``perturbed`` the choices a diffusion moved."""

    kind: str
    choices: dict | None
    log_select: float
    p_diffusion: float
    address: tuple = ()
    perturbed: tuple = ()
    p_resample: float = 0.0
    overrides: dict | None = None
    removed: tuple | None = None
    # a single-site resample of a discrete choice: log p(new value) - log p(old value),
    # which the ratio leaves out (the value was drawn from that prior); None otherwise
    log_redrawn: float | None = None
    unchanged: bool = False  # the redrawn value is the old one: the move keeps the state
    step_scale: float = 0.0  # a diffusion's step, in units of each choice's scale (diffusion_log_ratio)




def traced_counts(state: Traced) -> MoveCounts:
    """:class:`MoveCounts` of a traced state, from its running counts."""
    cum_d, cum_m, cum_k = state.cum
    return MoveCounts(len(state.nodes), cum_d[-1], cum_m[-1], cum_k[-1])


class _Picks:
    """The ``i``-th call with a continuous choice, ``maybe`` site or choice of a state, in
    program order: from lists built from the derivation (a :class:`Scored` state) or by
    bisecting a traced state's running counts (no walk over its calls)."""

    def __init__(self, state: Scored):
        if isinstance(state, Traced):
            self.nodes, self.cum = state.nodes, state.cum
            self.counts = traced_counts(state)
        else:
            nodes = state.derivation.nodes()
            self.nodes, self.cum = nodes, None
            self.candidates = [n for n in nodes if _has_continuous(n)]
            self.sites = [(n, s.site) for n in nodes for s in n.spawns if s.probability < 1.0]
            self.keys = [(n, name) for n in nodes for name in n.choices]
            self.counts = MoveCounts(len(nodes), len(self.candidates), len(self.sites), len(self.keys))

    def _locate(self, which: int, i: int) -> tuple:
        """``(node, j)``: the traced state's call holding the ``i``-th item counted by
        running count ``which``, and the item's position within that call."""
        cum = self.cum[which]
        k = bisect_right(cum, i) - 1
        return self.nodes[k], i - cum[k]

    def candidate(self, i: int):
        if self.cum is None:
            return self.candidates[i]
        return self._locate(0, i)[0]

    def site(self, i: int) -> tuple:
        """``(node, site name)`` of the ``i``-th maybe site."""
        if self.cum is None:
            return self.sites[i]
        node, j = self._locate(1, i)
        return node, [s.site for s in node.spawns if s.probability < 1.0][j]

    def key(self, i: int) -> tuple:
        """``(node, choice name)`` of the ``i``-th choice."""
        if self.cum is None:
            return self.keys[i]
        node, j = self._locate(2, i)
        return node, list(node.choices)[j]


def _edited_dict(derivation, overrides: dict, removed) -> dict:
    old = derivation.choice_map().raw
    if removed is not None:
        choices = {k: v for k, v in old.items() if not is_within(k[0], removed)}
    else:
        choices = dict(old)
    for key, value in overrides.items():
        if value is DROP:
            choices.pop(key, None)
        else:
            choices[key] = value
    return choices


def propose(state: Scored, rng: np.random.Generator, p_diffusion: float, step_scale: float,
            p_resample: float = 0.0) -> Proposal:
    """Build one move's edit of the choice map from a chain state (selection as in the
    module docstring)."""
    picks = _Picks(state)
    counts = picks.counts
    log_redrawn = None
    u = rng.random()
    if u < p_diffusion and counts.diffusion:
        node = picks.candidate(int(rng.random() * counts.diffusion))
        overrides = {}
        perturbed = []
        for name, c in node.choices.items():
            if not c.dist.discrete:
                overrides[(node.address, name)] = c.value + step_scale * c.dist.scale * rng.standard_normal()
                perturbed.append((node.address, name))
        kind, address, removed = "diffusion", node.address, None
    elif p_diffusion <= u < p_diffusion + p_resample and counts.choices:
        node, name = picks.key(int(rng.random() * counts.choices))
        kind, address, removed, perturbed = "resample", node.address, None, ()
        old = node.choices[name]
        overrides = {(address, name): DROP}
        if old.dist.discrete:  # drawn now, so that redrawing the old value costs no replay
            value = old.dist.sample(rng)
            if value == old.value:
                return Proposal(kind, None, log_select(counts, kind, p_diffusion, p_resample), p_diffusion,
                                address, perturbed, p_resample, {}, removed, 0.0, True)
            log_redrawn = old.dist.log_prob(value) - old.log_prob
            if math.isfinite(log_redrawn):  # (else a distribution that samples what it scores
                overrides = {(address, name): value}  # impossible: the replay draws it afresh)
            else:
                log_redrawn = None
    elif counts.maybe and rng.random() < TOGGLE_SHARE:
        node, site = picks.site(int(rng.random() * counts.maybe))
        address = node.address
        overrides, perturbed = {(address, site): not node.choices[site].value}, ()
        kind, removed = "toggle", address + (site,)
    else:
        node = picks.nodes[int(rng.random() * counts.calls)]
        overrides, perturbed = {}, ()
        kind, address, removed = "regenerate", node.address, node.address
    choices = None if isinstance(state, Traced) else _edited_dict(state.derivation, overrides, removed)
    return Proposal(kind, choices, log_select(counts, kind, p_diffusion, p_resample), p_diffusion,
                    address, tuple(perturbed), p_resample, overrides, removed, log_redrawn,
                    step_scale=step_scale if perturbed else 0.0)


def _kept_log_prob(state: Scored, proposal: Proposal, ev: Evaluation) -> float:
    """Log-probability, under the old derivation, of the old choices the new one reused."""
    old = state.derivation.choice_log_probs()
    unused = set(ev.unused)
    return sum(old[k] for k in proposal.choices if k not in unused and k in old)


def support_log_factor(redrawn, perturbed, old_choice) -> float:
    """0.0, or -inf when the move must be rejected because of choices the map offered
    that the new derivation makes but drew afresh, their offered value outside their new
    support (module docstring): ``redrawn`` yields ``(key, new value)``; ``old_choice(key)``
    is the old state's :class:`~procmod.core.runtime.Choice` there (None if it had none)."""
    for key, value in redrawn:
        if key in perturbed:
            return -math.inf  # a random-walk step left the choice's support: zero target density
        old = old_choice(key)
        if old is not None and old.dist.log_prob(value) > -math.inf:
            return -math.inf  # the reverse move would keep the fresh value: it cannot return
    return 0.0


def diffusion_log_ratio(proposal: Proposal, old_node, new_node) -> float:
    """log q(old | new) - log q(new | old) of a diffusion's Gaussian steps: each perturbed
    choice stepped with sd ``step_scale`` x its distribution's scale in the state it left,
    and the reverse step from the new state with the new scale. Zero where the scales
    agree (a scale that depends on no other choice); a choice one of the two states does
    not make drops out (module docstring). A scale that follows an earlier choice
    (``y ~ Uniform(0, x)``, perturbed with ``x``) made the kernel asymmetric, and the
    ratio without this term sampled P(x < 1/4) 0.2 where it is 0.25."""
    total = 0.0
    for key in proposal.perturbed:
        name = key[1]
        old, new = old_node.choices.get(name), new_node.choices.get(name)
        if old is None or new is None:
            continue
        s_old, s_new = proposal.step_scale * old.dist.scale, proposal.step_scale * new.dist.scale
        if s_old == s_new:
            continue
        if not (s_new > 0.0 and math.isfinite(s_new)):
            return -math.inf  # the reverse step cannot be taken
        d = new.value - old.value
        total += math.log(s_old / s_new) - 0.5 * d * d * (1.0 / (s_new * s_new) - 1.0 / (s_old * s_old))
    return total


def _node_at(derivation, address):
    """The call at ``address`` of ``derivation`` (None if it has none)."""
    return next((node for node in derivation.nodes() if node.address == address), None)


def _old_choice(derivation):
    """``key -> Choice`` of ``derivation`` (None where it has none), its tree built on first use."""
    tree = {}

    def choice(key):
        if not tree:
            tree.update(derivation.tree())
        node = tree.get(key[0])
        return None if node is None else node.choices.get(key[1])
    return choice


def log_acceptance(state: Scored, proposal: Proposal, ev: Evaluation, beta: float) -> float:
    """The reversible-jump log acceptance ratio (see the module docstring)."""
    if ev.log_reused == -math.inf or ev.log_likelihood == -math.inf:
        return -math.inf
    if ev.unused:  # offered values not reused: dropped out, or drawn afresh (support_log_factor)
        made = ev.derivation.choice_map().raw
        redrawn = [(key, made[key]) for key in ev.unused if key in made]
        if redrawn and support_log_factor(redrawn, set(proposal.perturbed),
                                          _old_choice(state.derivation)) == -math.inf:
            return -math.inf
    log_back = log_select(move_counts(ev.derivation), proposal.kind, proposal.p_diffusion, proposal.p_resample)
    if log_back == -math.inf:
        return -math.inf  # the new state does not offer the reverse move
    if proposal.perturbed:  # (a node made again at the same address: the diffusion's call)
        log_back += diffusion_log_ratio(proposal, _node_at(state.derivation, proposal.address),
                                        _node_at(ev.derivation, proposal.address))
    return (ev.log_reused - _kept_log_prob(state, proposal, ev) - (proposal.log_redrawn or 0.0)
            + beta * (ev.log_likelihood - state.log_likelihood)
            + log_back - proposal.log_select)


def log_acceptance_traced(state: Traced, proposal: Proposal, replayed: TracedReplay, beta: float) -> float:
    """:func:`log_acceptance` of a move replayed by
    :func:`~procmod.infer.traced.replay_traced`.

    The same ratio, summed over what differs: a call the replay took over unchanged
    contributes the same log-probabilities to both states, so the prior term is the sum,
    over the choices that the calls run again took from the map, of their new less their
    old log-probability; the new state's move counts are its running counts' totals.
    """
    new = replayed.state
    if new.log_likelihood == -math.inf:
        return -math.inf
    reused, old_nodes, old_index = replayed.reused, state.nodes, state.index
    offered = EditedChoices(state, proposal.overrides, proposal.removed)
    redrawn = [((node.address, name), c.value) for node in replayed.ran for name, c in node.choices.items()
               if (node.address, name) not in reused and (node.address, name) in offered]
    if redrawn:  # (support_log_factor)

        def old_choice(key):
            i = old_index.get(key[0])
            return None if i is None else old_nodes[i].choices.get(key[1])

        if support_log_factor(redrawn, set(proposal.perturbed), old_choice) == -math.inf:
            return -math.inf
    log_prior = 0.0
    for node in replayed.ran:
        address = node.address
        for name, c in node.choices.items():
            if (address, name) in reused:
                log_prior += c.log_prob - old_nodes[old_index[address]].choices[name].log_prob
    log_back = log_select(traced_counts(new), proposal.kind, proposal.p_diffusion, proposal.p_resample)
    if log_back == -math.inf:
        return -math.inf  # the new state does not offer the reverse move
    if proposal.perturbed:
        log_back += diffusion_log_ratio(proposal, old_nodes[old_index[proposal.address]],
                                        new.nodes[new.index[proposal.address]])
    log_prior -= proposal.log_redrawn or 0.0  # a redrawn value's prior cancels its proposal density
    return log_prior + beta * (new.log_likelihood - state.log_likelihood) + log_back - proposal.log_select


def _log_fresh_regenerate(src, dst, address) -> float:
    """Log density of the choices that regenerating ``address`` in ``src`` samples to give
    ``dst`` (the site's selection probability not included)."""
    if address not in src.tree():
        return -math.inf
    old = src.choice_map().raw
    total = 0.0
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


def _log_alpha1(src: Scored, dst: Scored, address, beta, select_src, select_dst) -> float:
    """First-stage acceptance of regenerating ``address`` from ``src`` to ``dst``."""
    return min(0.0, _log_pi(dst, beta) + select_dst + _log_fresh_regenerate(dst.derivation, src.derivation, address)
               - _log_pi(src, beta) - select_src - _log_fresh_regenerate(src.derivation, dst.derivation, address))


def _log1m_exp(x: float) -> float:
    return -math.inf if x >= 0 else math.log1p(-math.exp(x))


def delayed_rejection_log_alpha(x: Scored, y1: Scored, y2: Scored, address, beta,
                                p_diffusion: float, p_resample: float = 0.0) -> float:
    """Tierney-Mira second-stage acceptance for an independent second regeneration.

    The path ``x -> y1`` (rejected) ``-> y2`` has density ``pi(x) s(x) g(x, y1) (1 -
    alpha1(x, y1)) g(x, y2)``, where ``s`` is the probability of selecting the regenerate
    move at ``address`` (:func:`log_select`) and ``g`` the density of the freshly sampled
    choices; the second stage regenerates the same call, so it has no selection factor.
    ``alpha2`` balances it against the reverse path ``y2 -> y1 -> x``.
    """
    s_x, s_y1, s_y2 = (log_select(move_counts(s.derivation), "regenerate", p_diffusion, p_resample)
                       for s in (x, y1, y2))
    if s_y2 == -math.inf or _log_pi(y2, beta) == -math.inf:
        return -math.inf  # y2 has zero target density or does not offer the reverse move
    num = (_log_pi(y2, beta) + s_y2 + _log_fresh_regenerate(y2.derivation, y1.derivation, address)
           + _log_fresh_regenerate(y2.derivation, x.derivation, address)
           + _log1m_exp(_log_alpha1(y2, y1, address, beta, s_y2, s_y1)))
    den = (_log_pi(x, beta) + s_x + _log_fresh_regenerate(x.derivation, y1.derivation, address)
           + _log_fresh_regenerate(x.derivation, y2.derivation, address)
           + _log1m_exp(_log_alpha1(x, y1, address, beta, s_x, s_y1)))
    if num == -math.inf:
        return -math.inf
    return min(0.0, num - den)


class Chains:
    """The chains of one :func:`mcmc` run and their sweep (the engine's loop body).

    ``states[c]`` is chain ``c``'s state at inverse temperature ``betas[c]``. Each
    :meth:`sweep` proposes one move per chain (evaluated through ``executor`` as one
    batch), accepts or rejects it, tries delayed rejection for rejected regenerate jumps,
    and then proposes one swap of adjacent chains when ``tempering``.
    """

    def __init__(self, model: Model, target: Target, states: list, betas, rng: np.random.Generator,
                 p_diffusion: float = 0.5, step_scale: float = 0.1, tempering: bool = True,
                 delayed_rejection: bool = False, executor=None, tracker: Tracker | None = None,
                 p_resample: float = 0.0, incremental: bool = False):
        if incremental and (executor is not None or delayed_rejection):
            raise InvalidArgumentError("incremental MCMC runs in process and without delayed rejection; "
                                       "pass incremental=False for an executor or delayed_rejection")
        self.model, self.target, self.states = model, target, states
        self.p_resample, self.incremental = p_resample, incremental
        self.betas = np.asarray(betas, dtype=np.float64)
        self.rng, self.executor = rng, executor
        self.p_diffusion, self.step_scale = p_diffusion, step_scale
        self.tempering, self.delayed_rejection = tempering, delayed_rejection
        self.tracker = tracker or Tracker(None)
        self.accepted = dict.fromkeys(MOVES + ("swap", "delayed"), 0)
        self.proposed = dict.fromkeys(self.accepted, 0)

    def _evaluate(self, maps: list) -> list:
        rng = self.rng
        evaluations = evaluate_all(self.executor, self.model, self.target,
                                   [(choices, new_seed(rng), None) for choices in maps])
        self.tracker.evaluations += len(maps)
        return evaluations

    def _accept(self, log_alpha: float) -> bool:
        return math.log(self.rng.random() + 1e-300) < log_alpha

    def _sweep_traced(self) -> None:
        """The chains' moves of one sweep, each replayed from its state's checkpoints.

        Random numbers are drawn in the order of the full-replay sweep (every proposal,
        then one seed per replay, then the acceptances), so both give the same chain."""
        rng, states, betas, tracker = self.rng, self.states, self.betas, self.tracker
        model, target = self.model, self.target
        for c, s in enumerate(states):
            if not isinstance(s, Traced):  # e.g. a state handed in by a caller
                states[c] = trace(model, target, s.derivation.choice_map().raw, np.random.default_rng(0))
        proposals = [propose(s, rng, self.p_diffusion, self.step_scale, self.p_resample) for s in states]
        replays = [None if p.unchanged else
                   replay_traced(model, target, s, EditedChoices(s, p.overrides, p.removed),
                                 LazyGenerator(new_seed(rng)), edited=p.address)
                   for s, p in zip(states, proposals)]
        tracker.evaluations += len(states)
        for c, (s, p, replayed) in enumerate(zip(states, proposals, replays)):
            self.proposed[p.kind] += 1
            if p.unchanged:  # the state proposed itself: accepted, nothing to replay
                self.accepted[p.kind] += 1
                continue
            new = replayed.state
            tracker.offer(new.derivation, new.score, new.log_likelihood)
            if self._accept(log_acceptance_traced(s, p, replayed, betas[c])):
                states[c] = new
                self.accepted[p.kind] += 1

    def sweep(self) -> None:
        """One move per chain, then one proposed swap."""
        rng, states, betas, tracker = self.rng, self.states, self.betas, self.tracker
        accepted, proposed = self.accepted, self.proposed
        if self.incremental:
            self._sweep_traced()
            self._swap()
            return
        proposals = [propose(s, rng, self.p_diffusion, self.step_scale, self.p_resample) for s in states]
        evaluations = iter(self._evaluate([p.choices for p in proposals if not p.unchanged]))
        tracker.evaluations += sum(p.unchanged for p in proposals)
        second = []
        for c, (s, p) in enumerate(zip(states, proposals)):
            proposed[p.kind] += 1
            if p.unchanged:  # the state proposed itself: accepted, nothing to evaluate
                accepted[p.kind] += 1
                continue
            ev = next(evaluations)
            tracker.offer(ev.derivation, ev.score, ev.log_likelihood)
            if self._accept(log_acceptance(s, p, ev, betas[c])):
                states[c] = Scored.from_evaluation(ev)
                accepted[p.kind] += 1
            elif self.delayed_rejection and p.kind == "regenerate":
                second.append((c, p, ev))
        if second:
            retries = self._evaluate([p.choices for _, p, _ in second])
            for (c, p, ev1), ev2 in zip(second, retries):
                proposed["delayed"] += 1
                tracker.offer(ev2.derivation, ev2.score, ev2.log_likelihood)
                y1, y2 = Scored.from_evaluation(ev1), Scored.from_evaluation(ev2)
                if self._accept(delayed_rejection_log_alpha(states[c], y1, y2, p.address, betas[c],
                                                            self.p_diffusion, self.p_resample)):
                    states[c] = y2
                    accepted["delayed"] += 1
        self._swap()

    def _swap(self) -> None:
        rng, states, betas, proposed = self.rng, self.states, self.betas, self.proposed
        chains = len(states)
        if chains > 1 and self.tempering:
            i = int(rng.random() * (chains - 1))
            proposed["swap"] += 1
            log_swap = (betas[i] - betas[i + 1]) * (states[i + 1].log_likelihood - states[i].log_likelihood)
            if self._accept(log_swap):
                states[i], states[i + 1] = states[i + 1], states[i]
                self.accepted["swap"] += 1

    def acceptance_rates(self) -> dict:
        """Accepted / proposed per move kind (None where none was proposed)."""
        return {k: (self.accepted[k] / self.proposed[k] if self.proposed[k] else None) for k in self.accepted}


def mcmc(model: Model, target: Target, chains: int | None = None, seed: int = 0, budget: Budget | None = None,
         p_diffusion: float = 0.3, step_scale: float = 0.1, tempering: bool = True,
         annealing: float | None = 1.1, anneal_every: int = 50, delayed_rejection: bool = False,
         executor=None, progress=None, p_resample: float = 0.3, incremental: bool | None = None,
         workers: int = 1, init_particles: int = INIT_PARTICLES) -> Result:
    """Reversible-jump MCMC with parallel tempering and annealing.

    The defaults (one chain; diffusion 0.3, single-site resample 0.3, jumps the rest)
    are what did best on vines at equal wall time (docs/vines_smc.md, "MCMC"): every
    chain of a ladder costs as much as the coldest, and on a likelihood as sharp as an
    image match the hot chains' states are rarely swapped down, so 8 chains gave the
    cold one an eighth of the moves for nothing. Pass ``chains=8`` for seed 002's ladder.

    Parameters
    ----------
    chains : int, optional
        Number of chains (default: one per worker, so 1); with ``tempering`` (and more
        than one) they form one temperature ladder (coldest first), otherwise they are
        independent chains at temperature 1. Split over ``workers``, each worker's chains
        form a ladder of their own.
    budget : Budget
        Default: 1,600 sweeps (generations), as many moves as the 200 sweeps of the eight
        chains this engine used to default to. One sweep proposes one move per chain.
        Annealing counts sweeps, so with more chains it is slower per move.
    p_diffusion : float
        Probability of a diffusion move where the state has a continuous choice
        (otherwise a jump; see the module docstring).
    step_scale : float
        Diffusion step as a fraction of each choice distribution's scale.
    annealing : float or None
        Factor by which every inverse temperature grows every ``anneal_every`` sweeps
        (turns sampling into optimisation); None samples the tempered posterior.
    delayed_rejection : bool
        Try a second regeneration when a regenerate jump is rejected.
    executor : concurrent.futures.Executor, optional
        Evaluates the chains' proposals of a sweep (default: in-process).
    p_resample : float
        Probability of a single-site move: one choice, uniform among all the state's
        choices, drawn afresh from its prior (discrete ones included: the move that
        flips one coin). ``p_diffusion + p_resample`` must be at most 1.
    incremental : bool or None
        Replay each move from the state's checkpoints (:mod:`procmod.infer.traced`):
        the same chain, bit for bit, at a cost proportional to what the move changes.
        Default: on, unless an ``executor`` or ``delayed_rejection`` is given (both
        replay whole derivations).
    init_particles : int
        Where the chains start: the best complete derivations of one SMC run of this many
        particles on the same target (default 100; chain ``c`` takes the ``c``-th best), or,
        with 0, forward samples from the prior (Talton et al.'s and WebPPL's MH start). A
        chain started from a forward sample spends its first moves, often all of them on an
        image target, growing what SMC finds in a fraction of a second (docs/vines_smc.md).
        The SMC run's time counts against the budget, its particle-steps do not (an MCMC
        evaluation is one proposal; they are in ``settings["init_evaluations"]``); the
        stationary distribution is the same either way.
    workers : int
        Processes that run chains (default 1: this one). With ``W > 1`` the chains are
        split into ``W`` groups run side by side, this process running the first and
        forked workers the others, each under the same budget in seconds and sweeps
        (evaluations are shared out); chains of different groups never swap, and the best
        derivation of any group is returned (:mod:`procmod.infer.mcmc_workers`). With one
        chain per worker that is the best of ``W`` independent chains in the wall time of
        one: worth it where the cores are idle. The first group is the chain a one-process
        run would make; each worker's group is seeded from ``(seed, worker)``.
    """
    workers = check_positive("workers", workers)
    from ..parallel import check_worker_limit
    check_worker_limit(workers)
    if whole_number(init_particles) is None or init_particles < 0:
        raise InvalidArgumentError(f"init_particles must be a non-negative integer, got {shown_value(init_particles)}")
    init_particles = int(init_particles)
    if not fork_available():
        workers = 1  # groups are forked processes; elsewhere the run stays in this one
    if chains is None:
        chains = workers
    chains = check_positive("chains", chains)  # a plain int: numpy's too, for settings.json
    p_diffusion = check_real("p_diffusion", p_diffusion, "in [0, 1]", lambda v: 0.0 <= v <= 1.0)
    p_resample = check_real("p_resample", p_resample, "in [0, 1 - p_diffusion]",
                            lambda v: 0.0 <= v <= 1.0 - p_diffusion)
    if incremental is None:
        incremental = executor is None and not delayed_rejection
    if annealing is not None:
        annealing = check_real("annealing", annealing, "a finite number >= 1 (or None)", lambda v: 1.0 <= v < math.inf)
    anneal_every = check_positive("anneal_every", anneal_every)
    step_scale = check_real("step_scale", step_scale, "a positive finite number (the random walk's step, times "
                            "each choice's scale)", lambda v: 0.0 < v < math.inf)
    budget = budget or Budget(generations=1600)
    check_run(model, target, seed, budget)
    unconfigured, model = model, configured_model(target, model)
    # refuse what memory cannot hold: an incremental chain holds its state's output, the
    # first of its checkpoints (procmod.infer.traced) and a proposal's output, at least
    check_population("chains", chains, target.new_output(model), copies=3 if incremental else 1)
    settings = {"chains": chains, "seed": recorded_seed(seed), "budget": budget.describe(),
                "p_diffusion": p_diffusion, "step_scale": step_scale,
                "tempering": tempering, "annealing": annealing,
                "anneal_every": anneal_every, "delayed_rejection": delayed_rejection,
                "p_resample": p_resample, "incremental": incremental, "init_particles": init_particles}
    workers = min(workers, chains)
    if init_particles:  # each group's SMC start holds its particles at once, all groups together
        check_population("init_particles", init_particles, target.new_output(model), copies=workers)
    if workers > 1:
        if executor is not None:
            raise InvalidArgumentError("pass either an executor (proposals evaluated in a pool) or workers > 1 "
                                       "(chains in processes of their own), not both")
        return _mcmc_on_workers(unconfigured, target, chains, workers, seed, budget, settings, progress)
    rng = np.random.default_rng(seed)
    tracker = Tracker(budget, progress)
    betas = temperature_ladder(chains) if tempering else np.ones(chains)
    with relaxed_gc():
        starts, init_evaluations, start_cut = (([{}] * chains, 0, False) if not init_particles else
                                               _smc_starts(unconfigured, target, init_particles, new_seed(rng), chains,
                                                           tracker))
        if incremental:  # the same initial states as evaluate_all's runs
            states = [trace(model, target, starts[c], np.random.default_rng(new_seed(rng))) for c in range(chains)]
        else:
            states = [Scored.from_evaluation(ev) for ev in
                      evaluate_all(executor, model, target, [(starts[c], new_seed(rng), None) for c in range(chains)])]
        tracker.evaluations += chains
        for s in states:
            tracker.offer(s.derivation, s.score, s.log_likelihood)
        run = Chains(model, target, states, betas, rng, p_diffusion, step_scale, tempering,
                     delayed_rejection, executor, tracker, p_resample, incremental)
        while not tracker.spent():
            run.sweep()
            tracker.generations += 1
            if annealing is not None and tracker.generations % anneal_every == 0:
                run.betas = run.betas * annealing
            if tracker.due():
                tracker.record(mean_of([s.score for s in run.states]))
        tracker.record(mean_of([s.score for s in run.states]))
    moves = {kind: (run.accepted[kind], run.proposed[kind]) for kind in run.accepted}
    return Result("mcmc", tracker.best, tracker.best_score, [s.derivation for s in run.states],
                  tracker.rows, tracker.seconds, tracker.evaluations,
                  settings={**settings, "workers": 1, "acceptance_rates": run.acceptance_rates(), "moves": moves,
                            "init_evaluations": init_evaluations},
                  log_weights=[s.log_likelihood for s in run.states],
                  notes=([f"{START_CUT_NOTE}; give a longer budget or a smaller {argument('init_particles')}"]
                         if start_cut else []) + tracker.notes())


# MCMC's note when its SMC start was stopped by the time budget (smc's deadline)
START_CUT_NOTE = ("the SMC start was stopped by the time budget before it was complete: the chains began from what "
                  "it had completed, or from the prior")


def _smc_starts(model, target, particles: int, seed: int, chains: int, tracker: Tracker) -> tuple:
    """``(choice maps, evaluations, cut)``: the maps ``chains`` chains start from, the best
    complete derivations of one SMC run of ``particles`` particles, best first, repeated if
    there are fewer distinct ones than chains; the particle-steps the run took; and whether
    the run was cut: it ends where the tracker's time budget does.

    Its best is offered to ``tracker``; its evaluations are not counted there, because an
    MCMC evaluation is one proposal (a budget in evaluations is one in moves); its time
    is, as every second of the run is."""
    from .smc import smc  # (smc imports nothing of mcmc; imported here to keep start-up light)

    # under a time budget the start stops with it: a slow target's start had run 24 s of a
    # 0.5 s budget (h149); a start stopped before any particle was complete starts the
    # chains from the prior, as init_particles=0 does
    seconds = tracker.budget.seconds if tracker.budget is not None else None
    result = smc(model, target, particles=particles, seed=seed,
                 deadline=None if seconds is None else tracker.t0 + seconds)
    from .smc import DEADLINE_NOTE

    cut = DEADLINE_NOTE in result.notes
    if result.best is None:
        return [{}] * chains, result.evaluations, cut
    tracker.offer(result.best, result.best_score, -math.inf if RULED_OUT_NOTE in result.notes else 0.0)
    score = target.score
    # complete particles only (a run where every particle reached zero likelihood ends early)
    ranked = [result.best] + sorted((s for s in result.samples if s.done), key=lambda s: -score(s.output))
    maps, seen = [], set()
    for derivation in ranked:
        choices = derivation.choice_map().raw
        key = tuple(sorted(choices.items(), key=repr))
        if key not in seen:
            seen.add(key)
            maps.append(choices)
        if len(maps) == chains:
            break
    return [maps[c % len(maps)] for c in range(chains)], result.evaluations, cut


def _mcmc_on_workers(model, target, chains: int, workers: int, seed, budget: Budget, settings: dict,
                     progress) -> Result:
    """:func:`mcmc` with its chains in ``workers`` groups (:mod:`procmod.infer.mcmc_workers`)."""
    options = {k: settings[k] for k in ("p_diffusion", "step_scale", "tempering", "annealing", "anneal_every",
                                        "delayed_rejection", "p_resample", "incremental", "init_particles")}

    def run_group(group: int, group_chains: int, group_budget: Budget, group_progress) -> Result:
        return mcmc(model, target, chains=group_chains, seed=seed if group == 0 else [seed, group],
                    budget=group_budget, progress=group_progress, **options)

    t0 = time.perf_counter()
    best, best_score, samples, log_weights, history, evaluations, moves, init_evaluations, notes = run_groups(
        run_group, model, target, chains, workers, budget, progress)
    rates = {kind: (accepted / proposed if proposed else None) for kind, (accepted, proposed) in moves.items()}
    return Result("mcmc", best, best_score, samples, history, time.perf_counter() - t0, evaluations,
                  settings={**settings, "workers": workers, "acceptance_rates": rates, "moves": moves,
                            "init_evaluations": init_evaluations},
                  log_weights=log_weights, notes=notes)
