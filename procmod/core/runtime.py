"""The runtime: rule calls, derivation trees and the operations every engine uses.

A run of a model is a :class:`Derivation`, a tree of rule calls (:class:`Node`). It is
built one rule call at a time: spawned calls are *futures* (:class:`Future`) kept in a
pending list, and the caller decides which pending future runs next (program order, or
uniformly at random for stochastically-ordered SMC).

Design notes
------------
* **Cheap copies.** Expanded nodes are immutable and shared between copies: a derivation
  keeps them in a persistent linked list, so :meth:`Derivation.copy` copies only the
  pending list, the output accumulator and a few numbers.
* **Pausing at emits.** :func:`step` returns after a rule call has emitted geometry, so
  SMC can score and resample there. A paused call is resumed by re-executing its rule
  with the choices it already made replayed and its earlier emits skipped; that keeps a
  paused call copyable (a Python frame is not) at the cost of re-running the rule's
  cheap prefix. The pause is taken lazily, just before the call's next random choice or
  emit, so a call that ends with its emit is never re-executed. Rules must therefore be
  deterministic given their arguments and choice values.
* **Addresses** are structural: the spawn-site names from the root to a call, plus the
  choice name (see :mod:`procmod.core.choicemap`).
* **Choice policies.** How a fresh choice is made is a policy object the derivation holds
  (``Derivation.policy``), in the manner of Pyro's effect handlers: ``None`` is the prior
  (handled inline, the hot path), :class:`ReplayPolicy` reuses a choice map's values and
  keeps the reuse bookkeeping, :class:`GuidedPolicy` asks a proposer (a neural guide) and
  keeps its log-density sum and cache. The derivation itself holds only the run.
"""

from __future__ import annotations

import functools
import inspect
import math
import os
import re
from collections.abc import Mapping
from dataclasses import dataclass
from functools import lru_cache
from typing import Any, Callable, NamedTuple

import numpy as np

from .choicemap import ChoiceMap, format_address
from .distributions import Bernoulli, Distribution
from .errors import DistributionError, InvalidArgumentError, ModelError, cut_text
from .model import Model, check_model
from .random import BlockGenerator, LazyGenerator


def rule_function(rule):
    """The function a rule runs: ``rule`` itself, or a ``functools.partial``'s function."""
    while isinstance(rule, functools.partial):
        rule = rule.func
    return rule


def _geometry_text(geometry) -> str:
    """A part for a message, on one line: a named tuple's fields with numbers to 6
    significant digits (``Disc(x=12.8034, y=-10.9612, radius=-0.00312)``), anything else
    its repr; cut to 160 characters. (Cut at 60 characters of the full repr, the value at
    fault could end mid-number: ``radius=-0.``, read as a radius of zero.)"""
    fields = getattr(geometry, "_fields", None)
    if fields:
        def shown(value):
            if isinstance(value, float):
                return f"{value:.6g}"
            return " ".join(repr(value).split())  # one line: a numpy array's repr has several
        text = f"{type(geometry).__name__}(" + ", ".join(f"{f}={shown(getattr(geometry, f))}" for f in fields) + ")"
    else:
        text = " ".join(repr(geometry).split())
    return cut_text(text, 160)


def rule_name(rule) -> str:
    """A rule's name, for messages and for the sites of neural guides: its ``__name__``
    (a ``functools.partial``'s function's), or else what it is (a callable object)."""
    rule = rule_function(rule)
    return getattr(rule, "__name__", None) or repr(rule)[:60]


_MISSING = object()
_new_tuple = tuple.__new__  # builds NamedTuples without their Python-level __new__ (hot path)


class _Pause(BaseException):
    """Raised inside a rule call to suspend it (BaseException so user code can't catch it)."""


@lru_cache(maxsize=1024)
def _bernoulli(p: float) -> Bernoulli:
    return Bernoulli(p)


class Choice(NamedTuple):
    """One random choice of a rule call: its value, log-probability and distribution."""

    value: Any
    log_prob: float
    dist: Distribution


class SpawnRecord(NamedTuple):
    """A child rule call requested by ``ctx.spawn`` (probability 1) or ``ctx.maybe``."""

    site: str
    rule: Callable
    args: tuple
    probability: float
    on: bool


class Future:
    """A pending rule call: where it sits in the tree, which rule, with which arguments."""

    __slots__ = ("address", "rule", "args", "position")

    def __init__(self, address: tuple, rule: Callable, args: tuple, position=None):
        self.address = address
        self.rule = rule
        self.args = args
        self.position = position  # the spawning call's ctx.at position when it spawned this

    def __repr__(self) -> str:
        return f"Future({format_address(self.address)}, {rule_name(self.rule)})"


class Node:
    """An expanded rule call; immutable once built and shared between derivation copies.

    Attributes
    ----------
    address : tuple of str
        Spawn-site names from the root call to this one.
    rule : callable
        The rule that ran.
    args : tuple
        Its arguments.
    choices : dict
        ``name -> Choice`` in the order the choices were made (``maybe`` sites included,
        as Bernoulli choices named after the site).
    geometry : tuple
        The geometry the call emitted, in order.
    spawns : tuple of SpawnRecord
        The child calls it requested, in order (``on`` is False for a ``maybe`` that came
        out False).
    """

    __slots__ = ("address", "rule", "args", "choices", "geometry", "spawns")

    def __init__(self, address, rule, args, choices, geometry, spawns):
        self.address = address
        self.rule = rule
        self.args = args
        self.choices = choices
        self.geometry = geometry
        self.spawns = spawns

    @property
    def log_prob(self) -> float:
        """Sum of the log-probabilities of this call's own choices."""
        return sum(c.log_prob for c in self.choices.values())

    def __repr__(self) -> str:
        return f"Node({format_address(self.address)}, {rule_name(self.rule)}, {len(self.choices)} choices)"


class Context:
    """What a rule sees: ``ctx.sample``, ``ctx.emit``, ``ctx.spawn``, ``ctx.maybe``, ``ctx.at``.

    One context exists per execution of one rule call. Choice and spawn-site names share
    one namespace per call and must be unique within it.
    """

    __slots__ = ("_state", "_rng", "address", "_choices", "_sites", "_geometry", "_spawns",
                 "_prefix", "_skip", "_emits", "_pause", "_armed", "_fresh_emit", "rule", "args",
                 "_positions")

    def __init__(self, state, rng, future, prefix, skip, pause):
        self._state = state
        self._rng = rng
        self.address = future.address
        self.rule = future.rule
        self.args = future.args
        self._positions = None  # spawn-site name -> position at spawn time (when ctx.at is used)
        self._choices = {}
        self._sites = None  # names of plain spawn sites (maybe sites are choices)
        self._geometry = []
        self._spawns = []
        self._prefix = prefix
        self._skip = skip
        self._emits = 0
        self._pause = pause
        self._armed = False
        self._fresh_emit = False

    @property
    def depth(self) -> int:
        """Number of spawn sites between the root call and this one."""
        return len(self.address)

    @property
    def derivation(self) -> "Derivation":
        """The derivation this call belongs to, as built so far: what a
        :class:`~procmod.core.protocols.Proposer` (a neural guide) looks at when it
        proposes a choice (``output``, ``position``, ``n_emits``).

        Read it; do not change it. The one exception is ``guide_cache``, the proposer's
        per-derivation cache: copies share it, so a proposer replaces its value, never
        mutates it. Rules do not need it (``ctx.sample``, ``ctx.emit``, ... are theirs).
        """
        return self._state

    def _misuse(self, what: str) -> ModelError:
        return ModelError(f"rule {rule_name(self.rule)!r} at {format_address(self.address)} {what}")

    def _duplicate(self, name: str) -> ModelError:
        return ModelError(
            f"rule {rule_name(self.rule)!r} uses the name {name!r} twice in one call "
            f"(at {format_address(self.address)}); give each choice and spawn site of a call "
            "a distinct name")

    def _not_a_distribution(self, name: str, dist) -> ModelError:
        return self._misuse(f"samples {name!r} from {dist!r:.40}, which is not a distribution (give one of "
                            "procmod.core's: Normal(mu, sigma), Uniform(low, high), ...)")

    def _bad_name(self, what: str, name) -> ModelError:
        # (a derivation is saved with its names as JSON keys: an int name was refused only
        # then, after a whole run)
        return self._misuse(f"names {what} {name!r:.40} ({type(name).__name__}); names of choices and spawn sites "
                            f"must be strings: give str(...) of it, or an f-string such as f\"branch{{i}}\"")

    def sample(self, name: str, dist: Distribution):
        """Make the random choice ``name`` from ``dist`` and return its value."""
        if self._armed:
            raise _Pause()
        if type(name) is not str and not isinstance(name, str):  # (the first test: quick)
            raise self._bad_name("a choice", name)
        choices = self._choices
        if name in choices or (self._sites is not None and name in self._sites):
            raise self._duplicate(name)
        prefix = self._prefix
        if prefix is not None:
            old = prefix.get(name)
            if old is not None:  # already made (and counted) before this call was paused
                choices[name] = old
                return old[0]
        state = self._state
        if len(choices) >= state.model.max_call_choices:
            raise self._misuse(f"makes more than {state.model.max_call_choices:,} random choices in one call; does a "
                               "loop in it ever end? (raise Model(max_call_choices=...) if it should make more)")
        policy = state.policy
        if policy is None:  # the prior, inline
            try:
                value = dist.sample(self._rng)
            except AttributeError:
                if not isinstance(dist, Distribution):
                    raise self._not_a_distribution(name, dist) from None
                raise
            log_prob = dist.log_prob(value)
        else:  # replay under a choice map, or a guide's proposal
            try:
                value, log_prob = policy.choose(self, name, dist)
            except AttributeError:
                if not isinstance(dist, Distribution):
                    raise self._not_a_distribution(name, dist) from None
                raise
        state.log_prior += log_prob
        choices[name] = _new_tuple(Choice, (value, log_prob, dist))
        return value

    def emit(self, geometry) -> None:
        """Draw ``geometry`` into the output; engines may score and resample after it."""
        if self._armed:
            raise _Pause()
        self._geometry.append(geometry)
        index = self._emits
        self._emits = index + 1
        if index < self._skip:  # drawn before this call was paused
            return
        state = self._state
        model = state.model
        if index >= model.max_call_emits:
            raise self._misuse(f"emits more than {model.max_call_emits:,} times in one call; does a loop in it "
                               "ever end? (emit a long run of parts from child calls, or raise "
                               "Model(max_call_emits=...))")
        if self._pause is True and index >= model.max_resumed_emits:  # (a watch never re-runs a call)
            raise self._misuse(f"emits more than {model.max_resumed_emits:,} times in one call under SMC, which "
                               "re-runs a call from its start to resume it after each emit (n^2 / 2 emits for n: "
                               "hours for a loop of thousands); does the loop end? Emit a long run of parts from "
                               "child calls, use the mcmc or ga engine, or raise Model(max_resumed_emits=...)")
        tag = getattr(geometry, "tag", "")
        if not isinstance(tag, str):  # (colours, OBJ groups and GLB names read it: a traceback at the end of a run)
            raise self._misuse(f"emits {_geometry_text(geometry)}, whose tag is {tag!r} ({type(tag).__name__}): a tag "
                               "names the part's kind and must be a string; give str(...) of it, or a Categorical "
                               "with labels=[...]")
        try:
            state.output.add(geometry)
        except (TypeError, ValueError) as exc:  # the output's own word on what it cannot draw
            raise self._misuse(f"emits {_geometry_text(geometry)}, which the model's output cannot draw: "
                               f"{exc}") from exc
        state.n_emits += 1
        self._fresh_emit = True
        pause = self._pause
        if pause is True or (pause and pause(self)):  # every emit (step), or where a watch says (run_until)
            self._armed = True

    def spawn(self, site: str, rule: Callable, *args) -> None:
        """Request the child call ``rule(ctx, *args)`` at spawn site ``site``."""
        if self._armed:
            raise _Pause()
        if self._sites is None:
            self._sites = set()
        if not isinstance(site, str):
            raise self._bad_name("a spawn site", site)
        if site in self._choices or site in self._sites:
            raise self._duplicate(site)
        if not callable(rule):
            raise self._misuse(f"spawns {rule!r:.40} at site {site!r}, which is not a rule (a function "
                               "rule(ctx, ...)); pass the function itself")
        self._sites.add(site)
        state = self._state
        if not state.stopped:
            self._spawns.append(_new_tuple(SpawnRecord, (site, rule, args, 1.0, True)))
            if state.position is not None:
                self._remember_position(site, state.position)

    def maybe(self, site: str, p: float, rule: Callable, *args) -> bool:
        """With probability ``p`` spawn ``rule(ctx, *args)`` at ``site``; return whether it did.

        The coin is a Bernoulli choice named ``site``. After :meth:`stop` nothing is
        drawn and False is returned.
        """
        state = self._state
        if state.stopped:
            return False
        policy = state.policy
        if policy is not None:
            policy.before_maybe(self.address, site)
        try:  # (zero-cost unless it raises)
            p = float(p)
            coin = _bernoulli(p)
        except (ModelError, TypeError, ValueError):  # refused naming the rule and its address
            raise self._misuse(f"calls maybe({site!r:.40}, {p!r:.40}, ...): its probability must be a number from 0 "
                               "to 1") from None
        on = self.sample(site, coin)
        self._spawns.append(_new_tuple(SpawnRecord, (site, rule, args, p, on)))
        if on and state.position is not None:
            self._remember_position(site, state.position)
        return on

    def _remember_position(self, site, position) -> None:
        if self._positions is None:
            self._positions = {}
        self._positions[site] = position

    def at(self, position) -> None:
        """Report the current position (neural guides look at the output around it).

        A spawned call starts at the position its parent had reported when it spawned it.
        """
        self._state.position = position

    def stop(self) -> None:
        """Stop the whole derivation: no pending or later-spawned call will run."""
        self._state.stopped = True


class ChoicePolicy:
    """How a derivation's fresh choices are made when not from the prior (an effect
    handler for ``ctx.sample``), with the bookkeeping that goes with it.

    A derivation holds one in ``Derivation.policy``; ``None`` there is the prior, which the
    runtime handles inline. A policy belongs to one derivation: :meth:`copy` gives the
    copy's (sums and bookkeeping of its own, read-only parts shared). ``guide_cache`` is a
    guide's per-derivation cache (see :attr:`Derivation.guide_cache`).
    """

    __slots__ = ("guide_cache",)

    def choose(self, ctx: Context, name: str, dist: Distribution) -> tuple:
        """``(value, log_prob)`` of the fresh choice ``name`` of the call ``ctx``, whose
        prior is ``dist``; ``log_prob`` is ``dist.log_prob(value)``."""
        raise NotImplementedError

    def before_maybe(self, address: tuple, site: str) -> None:
        """Called by ``ctx.maybe`` before it draws the coin of ``site``."""

    def copy(self) -> "ChoicePolicy":
        raise NotImplementedError


def _proposal_error(proposer, name: str, what: str) -> InvalidArgumentError:
    return InvalidArgumentError(
        f"{type(proposer).__name__}.propose {what} for the choice {cut_text(repr(name), 60)}: a proposer returns "
        "(value, log q), log q the finite log-density (or log-probability) of the value under its proposal "
        "(procmod.core.protocols.Proposer)")


def _checked_log_q(proposer, name: str, log_q) -> float:
    """A proposer's log q as a float, or an InvalidArgumentError: a NaN had made every
    weight and log Z NaN without a word, +inf every weight zero (the note blamed the
    target), None a TypeError inside the runtime."""
    if isinstance(log_q, (bool, np.bool_)) or not isinstance(log_q, (int, float, np.integer, np.floating)):
        raise _proposal_error(proposer, name, f"returned log q {cut_text(repr(log_q), 60)}")
    log_q = float(log_q)
    if not -math.inf < log_q < math.inf:
        raise _proposal_error(proposer, name, f"returned log q = {log_q}")
    return log_q


class GuidedPolicy(ChoicePolicy):
    """Fresh choices come from ``proposer`` (a neural guide; ``None``: the prior);
    ``log_proposal`` sums the log-densities of the values it gave."""

    __slots__ = ("proposer", "log_proposal")

    def __init__(self, proposer=None, log_proposal: float = 0.0, guide_cache=None):
        self.proposer = proposer
        self.log_proposal = log_proposal
        self.guide_cache = guide_cache

    def choose(self, ctx, name, dist):
        proposer = self.proposer
        if proposer is None:
            value = dist.sample(ctx._rng)
        else:  # engines weight by prior / proposal
            proposed = proposer.propose(ctx, name, dist, ctx._rng)
            try:
                value, log_q = proposed
            except (TypeError, ValueError):
                raise _proposal_error(proposer, name, f"returned {cut_text(repr(proposed), 60)}") from None
            if type(log_q) is not float or not -math.inf < log_q < math.inf:  # (a float: the shipped guides')
                log_q = _checked_log_q(proposer, name, log_q)
            self.log_proposal += log_q
            log_prior = dist.log_prob(value)
            if log_prior == -math.inf:  # (h82: every particle then weighed nothing, and the note blamed the target)
                raise _proposal_error(proposer, name, f"returned the value {cut_text(repr(value), 40)}, outside the "
                                      f"support of {cut_text(repr(dist), 60)}")
            return value, log_prior
        return value, dist.log_prob(value)

    def copy(self) -> "GuidedPolicy":
        return GuidedPolicy(self.proposer, self.log_proposal, self.guide_cache)


class ReplayPolicy(ChoicePolicy):
    """Reuse the value ``constraints`` (``(node_address, name) -> value``) holds for a
    choice when it lies in the choice's support, else sample from the prior.

    ``reused`` collects the keys reused; ``log_reused`` and ``log_fresh`` sum the
    log-probabilities of the reused and of the freshly sampled choices.
    ``maybe_default`` (True or False) fixes every ``maybe`` site the map lacks (written
    into ``constraints``, so those count as reused).
    """

    __slots__ = ("constraints", "maybe_default", "reused", "log_reused", "log_fresh")

    def __init__(self, constraints, maybe_default=None):
        self.constraints = constraints
        self.maybe_default = maybe_default
        self.reused = set()
        self.log_reused = 0.0
        self.log_fresh = 0.0
        self.guide_cache = None

    def choose(self, ctx, name, dist):
        key = (ctx.address, name)
        value = self.constraints.get(key, _MISSING)
        if value is not _MISSING:
            if type(value).__module__ == "numpy" and getattr(value, "ndim", None) == 0:
                value = value.item()  # np.True_ from an edited map (arr > 0) was no coin's value: redrawn
            log_prob = dist.log_prob(value)
            if log_prob > -math.inf:
                self.reused.add(key)
                self.log_reused += log_prob
                return value, log_prob
        value = dist.sample(ctx._rng)
        log_prob = dist.log_prob(value)
        self.log_fresh += log_prob
        return value, log_prob

    def before_maybe(self, address, site):
        if self.maybe_default is not None and (address, site) not in self.constraints:
            self.constraints[(address, site)] = self.maybe_default

    def copy(self) -> "ReplayPolicy":
        other = ReplayPolicy.__new__(ReplayPolicy)
        other.constraints = self.constraints  # shared, as the map is
        other.maybe_default = self.maybe_default
        other.reused = self.reused.copy()
        other.log_reused = self.log_reused
        other.log_fresh = self.log_fresh
        other.guide_cache = self.guide_cache
        return other


class Derivation:
    """A partial or complete run of a model.

    Attributes
    ----------
    model : Model
    output : Output
        Everything emitted so far, drawn (e.g. a raster canvas); see
        :class:`procmod.core.protocols.Output`.
    pending : list of Future
        Calls waiting to run. The **last** element is the next one in program order.
    log_prior : float
        Sum of the log-probabilities of all choices made so far.
    stopped : bool
        True once a rule called ``ctx.stop()``.
    position : object
        The last position a rule reported with ``ctx.at``.
    n_emits : int
        Number of emits drawn into ``output``.
    policy : ChoicePolicy or None
        How fresh choices are made: ``None`` for the prior, a :class:`ReplayPolicy` while
        replaying a choice map, a :class:`GuidedPolicy` under a guide.
    proposer : Proposer or None
        Draws the fresh choices instead of the prior when set (a neural guide; see
        :class:`procmod.core.protocols.Proposer`); ``log_proposal`` sums the log-densities
        of the values it gave. Both live in the derivation's :class:`GuidedPolicy`.
    """

    __slots__ = ("model", "output", "pending", "active", "log_prior", "stopped", "position",
                 "n_emits", "n_nodes", "_chain", "policy")

    def __init__(self, model: Model, output=None, constraints=None):
        self.model = model
        self.output = model.new_output() if output is None else output
        self.pending = [Future((), model.root, model.initial_args())]
        self.active = None  # (future, choices made, emits drawn) of a paused call
        self.log_prior = 0.0
        self.stopped = False
        self.position = None
        self.n_emits = 0
        self.n_nodes = 0
        self._chain = None  # persistent list (node, rest) of expanded nodes, newest first
        self.policy = None if constraints is None else ReplayPolicy(dict(constraints))

    @property
    def proposer(self):
        """The guide's proposer that draws the fresh choices, or None (the prior)."""
        policy = self.policy
        return policy.proposer if type(policy) is GuidedPolicy else None

    @proposer.setter
    def proposer(self, proposer) -> None:
        policy = self.policy
        if type(policy) is GuidedPolicy:
            policy.proposer = proposer
        elif policy is None:
            if proposer is not None:
                self.policy = GuidedPolicy(proposer)
        elif proposer is not None:
            raise ModelError("a derivation that replays a choice map takes no proposer")

    @property
    def log_proposal(self) -> float:
        """Sum of the proposer's log-densities of the values it gave."""
        policy = self.policy
        return policy.log_proposal if type(policy) is GuidedPolicy else 0.0

    @property
    def guide_cache(self):
        """A proposer's per-derivation cache: shared by copies, so it is replaced, never
        mutated."""
        policy = self.policy
        return None if policy is None else policy.guide_cache

    @guide_cache.setter
    def guide_cache(self, value) -> None:
        if self.policy is None:
            self.policy = GuidedPolicy()  # the prior, with a cache
        self.policy.guide_cache = value

    @property
    def done(self) -> bool:
        """True when no call is paused and nothing is left to run."""
        return self.active is None and (self.stopped or not self.pending)

    def copy(self) -> "Derivation":
        """A copy that shares every expanded node; only pending calls and output are copied."""
        other = Derivation.__new__(Derivation)
        other.model = self.model
        other.output = self.output.copy()
        other.pending = self.pending.copy()
        other.active = self.active
        other.log_prior = self.log_prior
        other.stopped = self.stopped
        other.position = self.position
        other.n_emits = self.n_emits
        other.n_nodes = self.n_nodes
        other._chain = self._chain
        policy = self.policy
        other.policy = policy if policy is None else policy.copy()
        return other

    def nodes(self) -> list:
        """Expanded nodes in the order they ran."""
        out = []
        chain = self._chain
        while chain is not None:
            out.append(chain[0])
            chain = chain[1]
        out.reverse()
        return out

    def tree(self) -> dict:
        """``node_address -> Node`` for every expanded call."""
        return {node.address: node for node in self.nodes()}

    def choice_map(self) -> ChoiceMap:
        """All choices of the expanded calls, keyed by ``(node_address, name)``."""
        return ChoiceMap({(node.address, name): choice.value
                          for node in self.nodes() for name, choice in node.choices.items()})

    def choice_log_probs(self) -> dict:
        """``(node_address, name) -> log-probability`` of every choice."""
        return {(node.address, name): choice.log_prob
                for node in self.nodes() for name, choice in node.choices.items()}

    def geometry(self) -> list:
        """All emitted geometry of the expanded calls, in the order it was emitted."""
        return [g for node in self.nodes() for g in node.geometry]

    def order(self) -> list:
        """Addresses of the expanded calls in the order they ran (replay them in this order)."""
        return [node.address for node in self.nodes()]

    def __repr__(self) -> str:
        state = "done" if self.done else f"{len(self.pending)} pending"
        return (f"Derivation({self.model.name}, {self.n_nodes} calls, {state}, "
                f"log_prior={self.log_prior:.4f})")


Pick = Callable[[list, np.random.Generator], int]


def program_order(pending: list, rng: np.random.Generator) -> int:
    """Pick the next pending call in program (depth-first) order."""
    return len(pending) - 1


def random_order(pending: list, rng: np.random.Generator) -> int:
    """Pick a pending call uniformly at random (stochastically-ordered SMC)."""
    return int(rng.random() * len(pending))


_KEYWORD_TO_CONTEXT = re.compile(r"^Context\.(spawn|maybe)\(\) got an unexpected keyword argument '([^']*)'$")
_PACKAGE = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))  # procmod's own files


def _call_name(future: Future) -> str:
    """``rule 'r' at /a/b``: a call as messages name it."""
    return f"rule {rule_name(future.rule)!r} at {format_address(future.address)}"


def where_built(future: Future, exc: BaseException) -> str:
    """``rule 'r' at /a/b`` and, where the rule is the user's own code, its file and line
    (the last frame of ``exc``'s traceback outside procmod's package)."""
    where = _call_name(future)
    frame = None
    tb = exc.__traceback__
    while tb is not None:
        if not os.path.abspath(tb.tb_frame.f_code.co_filename).startswith(_PACKAGE + os.sep):
            frame = tb
        tb = tb.tb_next
    if frame is not None:
        where += f" ({os.path.basename(frame.tb_frame.f_code.co_filename)}, line {frame.tb_lineno})"
    return where


def _execute(state: Derivation, future: Future, rng, prefix, skip, pause) -> bool:
    """Run (or resume) one call. Returns True if it drew a new emit."""
    ctx = Context(state, rng, future, prefix, skip, pause)
    if future.position is not None:
        state.position = future.position
    # A call resumed after an emit runs again from its start (prefix: its choices so far).
    # Only the call running can have stopped the derivation, and a paused call is resumed
    # before any other, so a stopped state here is this call's own ctx.stop(), made before
    # its last emit: it takes effect again where the rule calls it again. Acting from the
    # start, it had made a maybe before it return False unreplayed (the rule took the other
    # branch, the coin's log-probability still counted) and dropped spawns made before it.
    stopped_before = prefix is not None and state.stopped
    if stopped_before:
        state.stopped = False
    try:
        returned = future.rule(ctx, *future.args)
    except _Pause:
        if not ctx._armed:  # raised by a context whose call has ended: not this call's own
            raise ctx._misuse("used a context that is not its own (a ctx kept from another call, e.g. "
                              "lambda c, j: rule(ctx, j) for lambda c, j: rule(c, j)); a rule must make its "
                              "choices, emits and spawns with the ctx it is called with") from None
        state.active = (future, ctx._choices, ctx._emits)
        return True
    except TypeError as exc:
        # A wrong argument count is a model bug worth a clear message; other TypeErrors pass.
        where = _call_name(future)
        if exc.__traceback__ is not None and exc.__traceback__.tb_next is None:
            n = len(future.args)
            raise ModelError(f"{where} was called with {n} argument{'' if n == 1 else 's'} after ctx, which it "
                             f"does not take ({exc}: Python counts ctx too)") from exc
        keyword = _KEYWORD_TO_CONTEXT.search(str(exc))
        if keyword is not None:  # ctx.spawn(site, rule, x, scale=0.5): a rule's arguments are positional
            form = "ctx.spawn(site, rule, a, b)" if keyword[1] == "spawn" else "ctx.maybe(site, p, rule, a, b)"
            raise ModelError(f"{where} passes the keyword argument {keyword[2]!r} to ctx.{keyword[1]}, which "
                             f"passes a rule's arguments by position ({form}): give it by position") from exc
        raise
    except DistributionError as exc:  # a Normal(0, -1) the rule built: say which rule, and where
        raise DistributionError(f"{where_built(future, exc)}: {exc}") from exc
    finally:
        ctx._armed = True  # the call has ended: a later use of this ctx is caught above
        if stopped_before:  # (a rule that no longer calls stop is not deterministic: kept stopped)
            state.stopped = True
    if returned is not None and (inspect.isgenerator(returned) or inspect.iscoroutine(returned)):
        returned.close()  # never run: its body is not the rule's
        raise ctx._misuse("returned a generator or coroutine (a def with yield, or async def), so its body never "
                          "ran; a rule is a plain function that calls ctx.sample, ctx.emit and ctx.spawn")
    node = Node(future.address, future.rule, future.args, ctx._choices,
                tuple(ctx._geometry), tuple(ctx._spawns))
    state._chain = (node, state._chain)
    state.n_nodes += 1
    model = state.model
    if state.n_nodes > model.max_calls or len(future.address) > model.max_depth:
        what, limit = (("rule calls in one derivation", "max_calls") if state.n_nodes > model.max_calls
                       else ("levels of spawns deep", "max_depth"))
        raise ModelError(f"model {model.name!r} went more than {getattr(model, limit):,} {what} (rule "
                         f"{rule_name(future.rule)!r}, call {state.n_nodes:,} at depth {len(future.address):,}); "
                         "does it always stop growing? Give its recursion a depth limit or a spawn chance that "
                         f"dies out, or raise Model({limit}=...) for a model this large")
    if state.stopped:
        state.pending.clear()
    else:
        pending = state.pending
        address = future.address
        positions = ctx._positions
        for spawn in reversed(node.spawns):
            if spawn.on:
                position = None if positions is None else positions.get(spawn.site)
                pending.append(Future(address + (spawn.site,), spawn.rule, spawn.args, position))
        if state.n_nodes + len(pending) > model.max_calls:
            # every queued call will run (unless the derivation stops): refused here, not once
            # the last has run. SMC runs one call of each particle a step, so a call queuing
            # 5,001 children under max_calls 5,000 was refused after 5,000 steps of every
            # particle (79 s and 1 GB, where forward sampling took 1 s; past 10 minutes and
            # 2 GB at the default limit), whatever the budget
            raise ModelError(f"model {model.name!r} queued more than {model.max_calls:,} rule calls in one "
                             f"derivation (rule {rule_name(future.rule)!r} at depth {len(future.address):,} left "
                             f"{len(pending):,} calls waiting after {state.n_nodes:,} made; queued calls count "
                             "toward max_calls, even where ctx.stop() would end the derivation first); does it "
                             "always stop growing? Give its recursion a depth limit or a spawn chance that dies out, "
                             "or raise Model(max_calls=...) for a model this large")
    return ctx._fresh_emit


def start(model: Model, output=None, constraints=None) -> Derivation:
    """A new, empty partial derivation of ``model`` (only the root call pending).

    ``output`` replaces the model's fresh output accumulator (e.g. a canvas with a target
    attached). ``constraints`` is a choice map whose values are reused where they fit.
    """
    return Derivation(model, output, constraints)


def _next_future(state: Derivation, rng, pick):
    pending = state.pending
    index = len(pending) - 1 if pick is None else pick(pending, rng)
    return pending.pop(index)


def _next_call(state: Derivation, rng, pick) -> tuple | None:
    """``(future, prefix, skip)`` of the call to run next (a paused call first, resumed), or
    None when the derivation is complete (its pending calls cleared if it stopped)."""
    if state.active is not None:
        call, state.active = state.active, None
        return call
    if state.stopped or not state.pending:
        state.pending.clear()
        return None
    return _next_future(state, rng, pick), None, 0


def step(state: Derivation, rng: np.random.Generator, pick: Pick | None = None) -> bool:
    """Advance a partial derivation in place until its next emit has been drawn.

    Pending calls run one after another (calls that emit nothing run straight through)
    until one draws an emit; that call is left paused just before its next random choice
    or emit, or complete if it has none. ``pick(pending, rng)`` chooses which pending call
    runs next (default: program order; :func:`random_order` for SOSMC); a paused call is
    always resumed first.

    Returns
    -------
    bool
        True if an emit was drawn, False if the derivation finished without one (or was
        already done). The increase of ``state.log_prior`` is the log-prior probability of
        the choices made in this step.
    """
    while True:
        call = _next_call(state, rng, pick)
        if call is None:
            return False
        if _execute(state, call[0], rng, call[1], call[2], True):
            return True


def finish(state: Derivation, rng: np.random.Generator, pick: Pick | None = None) -> Derivation:
    """Run a partial derivation in place to completion, without pausing; returns it."""
    while True:
        call = _next_call(state, rng, pick)
        if call is None:
            return state
        _execute(state, call[0], rng, call[1], call[2], False)


class _Watch:
    """:func:`run_until`'s look at each fresh emit: whether to pause there, and where the
    last one fell (the call that drew it, the calls made, its choices and spawn sites)."""

    __slots__ = ("stop", "fired", "ctx", "nodes", "acts")

    def __init__(self, stop):
        self.stop, self.fired, self.ctx, self.nodes, self.acts = stop, False, None, 0, 0

    def __call__(self, ctx: Context) -> bool:
        self.ctx, self.nodes, self.acts = ctx, ctx._state.n_nodes, _acts(ctx)
        self.fired = bool(self.stop(ctx._state))
        return self.fired


def _acts(ctx: Context) -> int:
    """The choices and spawn sites a call has made so far: each would pause it after an emit."""
    return len(ctx._choices) + (len(ctx._sites) if ctx._sites else 0)


def run_until(state: Derivation, rng: np.random.Generator, pick: Pick | None = None, stop=None) -> tuple:
    """Run a partial derivation on in place as :func:`step` would, emit by emit, but without
    pausing at each emit (so no call re-runs from its start), until ``stop(state)`` is true
    after an emit or the derivation is complete.

    Where ``stop`` fires, the derivation is left as :func:`step` leaves it after that emit
    (the call paused just before its next choice, emit or spawn); the same random numbers
    are drawn as by stepping it. Returns ``(stopped, steps)``: whether ``stop`` fired, and
    the calls of :func:`step` that advancing it so would have taken (an emit each, plus the
    step that finds it complete unless its last emit completed it): an SMC engine's
    particle-steps.
    """
    watch = _Watch(stop or (lambda _: False))
    emits = state.n_emits
    while True:
        call = _next_call(state, rng, pick)
        if call is None:
            break
        _execute(state, call[0], rng, call[1], call[2], watch)
        if watch.fired:
            return True, state.n_emits - emits
    drawn = state.n_emits - emits
    # step() ends at an emit's call pausing at its next act, or completing; the derivation
    # was complete then only if that call was the last to run and made nothing after the emit
    ended_on_emit = drawn and state.n_nodes == watch.nodes + 1 and _acts(watch.ctx) == watch.acts
    return False, drawn + (0 if ended_on_emit else 1)


def run_forward(model: Model, rng: np.random.Generator, pick: Pick | None = None,
                output=None) -> Derivation:
    """Run ``model`` forward with fresh choices (depth-first program order by default).

    Returns
    -------
    Derivation
        Complete. Its ``log_prior`` is the log-weight of this run: the total
        log-probability of every choice made, i.e. ``log p(derivation)`` under the model.
        A model with a ``settle`` step returns what it makes of the run (learned
        programs: the sample set on its examples' ground, :mod:`procmod.learn.ground`);
        with ``output`` given, the run is returned as it ran.
    """
    _check_call(model, rng)
    derivation = finish(start(model, output), rng, pick)
    if model.settle is not None and output is None:
        settled = model.settle(derivation)
        # a model's own settle step is checked where it is used: anything but a complete
        # derivation of this model would fail later, far from the step that made it
        if not isinstance(settled, Derivation) or settled.model is not model or not settled.done:
            got = (f"a derivation of model {settled.model.name!r}" if isinstance(settled, Derivation) and
                   settled.model is not model else "an incomplete derivation" if isinstance(settled, Derivation)
                   else f"{type(settled).__name__} {settled!r:.40}")
            raise ModelError(f"model {model.name!r}: settle must return a complete derivation of the model (the "
                             f"one it is given, or one replayed from it), got {got}")
        derivation = settled
    return derivation


def check_rng(rng, operator: str | None = None) -> None:
    """An InvalidArgumentError unless ``rng`` is a numpy Generator (or procmod's wrappers of
    one, or an object with its ``random`` and ``standard_normal``): None or a seed given as
    the generator had raised an AttributeError deep inside whatever drew first.
    ``operator``: the public function the error names."""
    # procmod's own wrappers pass as they are: a LazyGenerator makes its generator at the
    # first attribute asked of it, which a replay that draws nothing never needs; others
    # (the GA's LazyRng, which forwards through __getattr__, h86) are asked for the methods
    if not isinstance(rng, (np.random.Generator, LazyGenerator, BlockGenerator)) and not (
            callable(getattr(rng, "random", None)) and callable(getattr(rng, "standard_normal", None))):
        raise InvalidArgumentError(f"{operator + ': ' if operator else ''}rng must be a numpy Generator "
                                   f"(np.random.default_rng(seed)), got {type(rng).__name__} {rng!r:.40}")


def _check_call(model, rng, derivation=None, needs_derivation: bool = False) -> None:
    """One-line errors for the public entry points' most likely mistakes: a model's name
    for the model, a seed for the generator, no derivation."""
    check_model(model)
    check_rng(rng)
    if needs_derivation and not isinstance(derivation, Derivation):
        raise InvalidArgumentError(f"derivation must be a procmod Derivation, got {type(derivation).__name__}")


@dataclass
class ReplayResult:
    """A derivation re-run under a choice map, with the split of its log-probability.

    Attributes
    ----------
    derivation : Derivation
        The new, complete derivation.
    log_reused : float
        Sum of log-probabilities (under the new run) of choices taken from the map.
    log_fresh : float
        Sum of log-probabilities of choices the map lacked (or held values outside the
        choice's support) and that were therefore sampled from the prior.
        ``log_reused + log_fresh == derivation.log_prior``.
    unused : list
        Addresses ``(node_address, name)`` of map entries the new run did not use.
    """

    derivation: Derivation
    log_reused: float
    log_fresh: float
    unused: list


def follow_order(order: list) -> Pick:
    """A pick function that expands calls in a recorded order (program order once it ends
    or when the recorded next call is not pending)."""
    position = {address: i for i, address in enumerate(order)}

    def pick(pending, rng):
        best, best_rank = len(pending) - 1, math.inf
        for i, future in enumerate(pending):
            rank = position.get(future.address, math.inf)
            if rank < best_rank:
                best, best_rank = i, rank
        return best

    return pick


def replay(model: Model, choices, rng: np.random.Generator, order: list | None = None,
           output=None, maybe_default: bool | None = None) -> ReplayResult:
    """Run ``model`` reusing the choices in ``choices`` and sampling only the missing ones.

    ``choices`` is a :class:`ChoiceMap` (or a dict with the same keys). A value is reused
    when a call at its address makes a choice of that name and the value lies in the
    choice's support; otherwise the choice is sampled fresh. Entries no call asks for are
    dropped and listed in ``unused``. ``order`` (a list of node addresses, as returned by
    :meth:`Derivation.order`) replays a derivation made in another expansion order;
    program order is the default. ``maybe_default`` (True or False) fixes every ``maybe``
    site the map lacks instead of flipping its coin (False gives the smallest derivation
    that agrees with the map, the GA's "empty chromosome"); those sites count as reused.

    Returns
    -------
    ReplayResult
        ``log_reused`` and ``log_fresh`` are the log-probabilities of the reused and the
        freshly sampled parts; they sum to the new derivation's log-prior.
    """
    _check_call(model, rng)
    if not isinstance(choices, (ChoiceMap, Mapping)):
        raise InvalidArgumentError(f"choices must be a ChoiceMap or a dict of them, got {type(choices).__name__}")
    raw = choices.raw if isinstance(choices, ChoiceMap) else dict(choices)
    return _replay(model, raw, rng, order, output, raw, maybe_default)


def _replay(model, constraints, rng, order, output, previous, maybe_default=None) -> ReplayResult:
    """Replay under ``constraints``; ``unused`` lists the keys of ``previous`` not reused."""
    state = start(model, output)
    policy = state.policy = ReplayPolicy(dict(constraints), None if maybe_default is None else bool(maybe_default))
    finish(state, rng, None if order is None else follow_order(order))
    unused = [key for key in previous if key not in policy.reused]
    state.policy = None
    return ReplayResult(state, policy.log_reused, policy.log_fresh, unused)


def regenerate(model: Model, derivation: Derivation, node_address: tuple,
               rng: np.random.Generator) -> ReplayResult:
    """Resample the subtree rooted at ``node_address`` from the prior, keeping the rest.

    Returns
    -------
    ReplayResult
        ``log_fresh`` is the log-probability of the new subtree's choices (the forward
        proposal density of an RJMCMC jump); ``unused`` lists the old subtree's choices.
    """
    _check_call(model, rng, derivation, needs_derivation=True)
    node_address = tuple(node_address)
    if node_address not in derivation.tree():
        raise ModelError(f"the derivation has no rule call at {format_address(node_address)}")
    old = derivation.choice_map()
    return _replay(model, old.without_subtree(node_address).raw, rng, None, None, old.raw)


def set_maybe(model: Model, derivation: Derivation, node_address: tuple, site: str, on: bool,
              rng: np.random.Generator) -> ReplayResult:
    """Turn the ``maybe`` site ``site`` of the call at ``node_address`` on or off.

    Turning it on grows a fresh subtree from the prior; turning it off cuts the subtree.
    Everything else is reused.

    Returns
    -------
    ReplayResult
        ``log_fresh`` is the log-probability of the grown subtree (0 when cutting);
        ``log_reused`` includes the new value of the site's Bernoulli choice; ``unused``
        lists the cut subtree's choices.
    """
    _check_call(model, rng, derivation, needs_derivation=True)  # as regenerate checks them
    if not isinstance(on, (bool, np.bool_)):  # "no" is truthy: it had grown the subtree
        raise InvalidArgumentError(f"on must be True (grow the subtree) or False (cut it), got {on!r:.40}")
    node_address = tuple(node_address)
    node = derivation.tree().get(node_address)
    if node is None:
        raise ModelError(f"the derivation has no rule call at {format_address(node_address)}")
    if not any(s.site == site and s.probability < 1.0 for s in node.spawns):
        raise ModelError(f"the call at {format_address(node_address)} has no maybe site {site!r}")
    old = derivation.choice_map()
    choices = old.without_subtree(node_address + (site,)).with_value(node_address, site, bool(on))
    return _replay(model, choices.raw, rng, None, None, old.raw)


class _NoOutput:
    """Swallows emits: :func:`replay_reusing` draws the geometry itself, once it knows
    which calls changed."""

    __slots__ = ()

    def add(self, geometry) -> int:
        return 0


_NO_OUTPUT = _NoOutput()


def same_args(a: tuple, b: tuple) -> bool:
    """Whether two rule calls' argument tuples (or emitted geometry) are equal, so a call
    with ``b`` may be taken for the call with ``a`` (:func:`replay_reusing`, the GA's
    crossover). Values that cannot be compared to a plain bool (numpy arrays, a part made
    of them) are never equal."""
    if a is b:
        return True
    try:
        return bool(a == b)
    except (ValueError, TypeError):  # e.g. numpy arrays among the arguments: don't reuse
        return False


def _map_agrees(node: Node, constraints: dict, maybe_default) -> bool:
    """Whether replaying under ``constraints`` would give ``node``'s call exactly its
    choices (a site the map lacks only agrees when it is a ``maybe`` set by
    ``maybe_default`` to the node's value)."""
    address = node.address
    for name, choice in node.choices.items():
        value = constraints.get((address, name), _MISSING)
        if value is _MISSING:
            if maybe_default is None or choice.value != maybe_default or not any(
                    s.site == name for s in node.spawns):  # only maybe sites take the default
                return False
        elif value is not choice.value:
            try:
                if not value == choice.value:
                    return False
            except (ValueError, TypeError):
                return False
    return True


def replay_reusing(model: Model, previous: Derivation, choices, rng: np.random.Generator, output,
                   maybe_default: bool | None = None, changed=None, unused: bool = True,
                   index: dict | None = None) -> ReplayResult:
    """:func:`replay` in program order that reuses the calls of ``previous`` and its drawn output.

    ``output`` must hold exactly ``previous``'s geometry (e.g. ``previous.output.copy()``)
    and support exact removal (``supports_removal``: its ``remove(geometry)`` undoes ``add``
    exactly; :class:`procmod.core.protocols.RemovableOutput`). A call of ``previous`` is
    reused as it is, without running its rule, when the new run reaches its address with
    the same rule and arguments and ``choices`` (with ``maybe_default``) holds exactly the
    values it chose: rules are deterministic given their arguments and choice values, so
    running it again would make the same choices, emits and spawns. Every other call runs
    as in :func:`replay`. The geometry of ``previous``'s calls that were not kept is then
    removed from ``output`` and that of the new calls drawn (a call that ran again and
    emitted exactly its old geometry is left as drawn).

    The result equals ``replay(model, choices, rng, output=<fresh output>,
    maybe_default=maybe_default)`` — same calls in the same order, same choices (reused
    calls draw nothing; calls that run again draw in program order, as ``replay``
    does), same geometry and counts, same log-prior up to rounding. Two differences:
    sums the output keeps (e.g. ``gain_total``) are updated rather than recomputed, so
    scores agree up to rounding in the last bits, and the output's ``extent`` is an upper
    bound (removing a part does not shrink it). Cheap when ``choices`` differs from
    ``previous``'s choice map in few calls: the cost is the changed calls plus a walk
    over ``previous``'s nodes.

    ``changed`` (optional) lists the node addresses whose choices in ``choices`` may
    differ from ``previous``'s; the caller vouches that every other call of ``previous``
    has exactly its values in the map. Subtrees without a changed call are then spliced
    in whole, without checking their choices. ``unused=False`` skips computing
    ``ReplayResult.unused`` (left empty).

    ``choices`` may also be any mapping with ``get``, ``in`` and item assignment (e.g. a
    lazy view of an edited choice map); it is then used as it is, not copied (``maybe``
    defaults are written into it), and ``unused`` must be False. ``index`` (optional)
    is ``{node.address: node for node in previous.nodes()}`` when the caller has it.

    ``previous`` must be complete and not stopped (ModelError otherwise). Positions
    reported with ``ctx.at`` are not restored, so use it without a guide's proposer.
    """
    if not previous.done or previous.stopped:
        raise ModelError("replay_reusing needs a complete derivation that was not stopped")
    if isinstance(choices, (ChoiceMap, dict)):
        raw = choices.raw if isinstance(choices, ChoiceMap) else choices
        constraints = dict(raw)  # maybe defaults are written into it
    else:
        if unused:
            raise ModelError("replay_reusing computes unused only for a ChoiceMap or dict")
        raw = constraints = choices  # a lazy mapping, used as it is
    if index is None:
        index = {node.address: node for node in previous.nodes()}
    old, old_nodes = index, index.values()
    dirty = None
    if changed is not None:  # every call on the path to a changed one
        changed = set(changed)
        dirty = {address[:k] for address in changed for k in range(len(address) + 1)}
    state = start(model, _NO_OUTPUT)
    policy = state.policy = ReplayPolicy(constraints, None if maybe_default is None else bool(maybe_default))
    pending = state.pending
    kept, still_drawn, drawn = set(), set(), []  # ids of reused old nodes / of old nodes whose
    # geometry stays drawn; new geometry to draw
    chain, n_kept, emits_kept = state._chain, 0, 0
    while pending and not state.stopped:
        future = pending.pop()
        address = future.address
        node = old.get(address)
        if node is not None and node.rule is future.rule and same_args(node.args, future.args):
            if dirty is not None and address not in dirty:  # a trusted subtree: splice it in whole
                stack = [node]
                while stack:
                    n = stack.pop()
                    chain = (n, chain)
                    n_kept += 1
                    emits_kept += len(n.geometry)
                    kept.add(id(n))
                    a = n.address
                    for spawn in reversed(n.spawns):
                        if spawn.on:
                            stack.append(old[a + (spawn.site,)])
                continue
            if (address not in changed) if changed is not None else _map_agrees(node, constraints, policy.maybe_default):
                chain = (node, chain)
                n_kept += 1
                emits_kept += len(node.geometry)
                kept.add(id(node))
                for spawn in reversed(node.spawns):
                    if spawn.on:
                        pending.append(Future(address + (spawn.site,), spawn.rule, spawn.args))
                continue
        state._chain = chain
        _execute(state, future, rng, None, 0, False)
        chain = state._chain
        new = chain[0]
        if node is not None and same_args(new.geometry, node.geometry):  # (parts of numpy arrays: redrawn)
            still_drawn.add(id(node))  # the call is replaced, its geometry stays drawn
        else:
            drawn.extend(new.geometry)
    pending.clear()
    log_removed = 0.0
    for node in old_nodes:
        if id(node) not in kept:
            log_removed += node.log_prob
            if id(node) not in still_drawn:
                for geometry in node.geometry:
                    output.remove(geometry)
    for geometry in drawn:
        output.add(geometry)
    state._chain = chain
    state.n_nodes += n_kept
    state.n_emits += emits_kept
    state.output = output
    # log-prior: the previous one, less the calls that were not reused, plus the new ones
    kept_lp = previous.log_prior - log_removed
    state.log_prior += kept_lp
    policy.log_reused += kept_lp
    out_unused = []
    if unused:
        reused = policy.reused
        by_address = {n.address: n.choices for n in old_nodes if id(n) in kept}
        out_unused = [key for key in raw if key not in reused
                      and key[1] not in by_address.get(key[0], ())]
    state.policy = None
    return ReplayResult(state, policy.log_reused, policy.log_fresh, out_unused)


# ---- moving a particle between processes ----------------------------------------------
# A parallel particle method keeps each particle in one process and moves only the few
# that resampling sends elsewhere. A particle's history (its expanded nodes) is what makes
# it expensive to move, and stepping never reads it, so it stays behind: the moved copy
# carries a HistoryRef to it, and the whole derivation is put back together at the end
# (:func:`graft_history`).


class HistoryRef:
    """Stands for the older expanded calls of a derivation, kept by ``owner`` under ``key``.

    It ends the derivation's chain of nodes where ``None`` would; :func:`graft_history`
    replaces it with the nodes it stands for.
    """

    __slots__ = ("owner", "key")

    def __init__(self, owner: int, key: int):
        self.owner = owner
        self.key = key

    def __reduce__(self):
        return HistoryRef, (self.owner, self.key)

    def __repr__(self) -> str:
        return f"HistoryRef({self.owner}, {self.key})"


_PACKED = tuple(s for s in Derivation.__slots__ if s not in ("model", "_chain"))


def pack_particle(state: Derivation, ref: HistoryRef | None) -> tuple:
    """A partial derivation as plain data for another process: its state without the
    model, with its expanded calls replaced by ``ref`` (the caller keeps
    :func:`history` of it under that reference) or, with ``ref=None``, with them listed
    oldest first, ending in whatever reference ended them."""
    if ref is None:
        nodes, tail = history(state)
    else:
        nodes, tail = None, ref
    return tuple(getattr(state, s) for s in _PACKED) + (nodes, tail)


def unpack_particle(model: Model, packed: tuple) -> Derivation:
    """The derivation :func:`pack_particle` packed, for ``model``."""
    state = Derivation.__new__(Derivation)
    state.model = model
    for name, value in zip(_PACKED, packed):
        setattr(state, name, value)
    nodes, tail = packed[-2], packed[-1]
    state._chain = chain_of(nodes or (), tail)
    return state


def history(state: Derivation) -> tuple:
    """``(nodes, tail)``: the derivation's expanded calls held here, oldest first, and what
    ends them (None, or a :class:`HistoryRef` to calls kept elsewhere)."""
    nodes = []
    chain = state._chain
    while chain is not None and not isinstance(chain, HistoryRef):
        nodes.append(chain[0])
        chain = chain[1]
    nodes.reverse()
    return nodes, chain


def chain_of(nodes, tail=None):
    """The persistent list of ``nodes`` (oldest first) on top of ``tail``."""
    chain = tail
    for node in nodes:
        chain = (node, chain)
    return chain


def graft_history(state: Derivation, lookup) -> None:
    """Replace the :class:`HistoryRef` that ends ``state``'s calls, in place, by the calls
    ``lookup(ref) -> (nodes, tail)`` gives for it (oldest first), until none is left."""
    nodes, tail = history(state)
    while tail is not None:
        older, tail = lookup(tail)
        nodes = list(older) + nodes
    state._chain = chain_of(nodes)
