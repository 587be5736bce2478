"""Incremental replay for MCMC: a proposal costs what it changes, not the whole derivation.

A chain state is a :class:`Traced` derivation: besides the derivation it keeps, for the
calls in program order, *checkpoints* — the output drawn so far, the pending calls and
the running log-prior just before each call ran. A move edits the choices of one call
``X`` (and maybe drops its subtree); in program order every call before ``X`` makes the
same choices with the same arguments, so :func:`replay_traced` restores the checkpoint
before ``X`` instead of running those calls again. From there it goes on in program
order as :func:`procmod.core.replay` would, except that a call whose address, rule,
arguments and choice values are those of a call of the old derivation is not run again:
its recorded choices, geometry and spawns are taken as they are (rules are deterministic
given their arguments and choice values — the same contract that lets the runtime
resume a paused call by re-execution), and only its geometry is drawn, in program order.

The result is the derivation a full replay gives, bit for bit: the same calls in the same
order, the same choices, and the output, the log-prior and the likelihood summed in the
same order from the same values (``tests/test_mcmc_incremental.py`` checks it). What a
move then costs is a copy of one checkpoint, the changed calls run again, and for the
calls after them a draw of their geometry: on vines about the second half of the
derivation drawn and the edited subtree run, where a full replay ran every call.

Checkpoints take memory (one output copy per call), so they are kept every ``stride``
calls, with ``stride`` chosen from the output's size (every call for a 50x50 canvas;
a 3D output keeps fewer and draws the calls between them again).
"""

from __future__ import annotations

import math
from typing import NamedTuple

from ..core.runtime import Derivation, Future, ReplayPolicy, _execute, _map_agrees, same_args, start
from .common import Scored, output_bytes, scored

_MISSING = object()
DROP = _MISSING  # an override that drops a choice: the replay samples it afresh

# Calls between checkpoints, at least: a checkpoint (an output copy, ~2-3 us for a 50x50
# canvas) is made for every call a replay passes after the edited one (~40 on a
# 100-call vine), while a restore from a checkpoint k calls before the edited call draws
# those k calls again (~5-8 us each on vines): every 4th call balances the two (an
# estimate from those per-call costs; the load on the machine hid the difference).
MIN_STRIDE = 4
# Memory of checkpoints per chain state, about: fewer of them for outputs larger than this
# / 256 bytes (a 50x50 canvas is 2.5 kB).
CHECKPOINT_BYTES = 4 << 20


def checkpoint_stride(output) -> int:
    """Calls between checkpoints for an output like ``output`` (MIN_STRIDE, more where
    CHECKPOINT_BYTES requires). Results do not depend on it, only time and memory do."""
    return max(MIN_STRIDE, math.ceil(256 * (output_bytes(output) + 512) / CHECKPOINT_BYTES))


class Checkpoint(NamedTuple):
    """A partial derivation just before a call ran (program order)."""

    output: object  # never drawn into: restored by copying it
    pending: tuple
    log_prior: float
    n_emits: int
    chain: object


class Traced(Scored):
    """A chain state: a complete derivation with its checkpoints (module docstring).

    Attributes
    ----------
    nodes : list
        The calls in program order.
    marks : list
        ``marks[i]``: :class:`Checkpoint` before ``nodes[i]`` ran, or None between
        checkpoints (``marks[0]`` is always one).
    stride : int
        Calls between checkpoints.
    cum : tuple of three lists
        Running counts over ``nodes`` (``n + 1`` entries each, from 0) of the calls with a
        continuous choice, of ``maybe`` sites and of choices (:func:`node_counts`): what
        MCMC picks its moves from, and what the reverse move's probability needs.
    """

    def __init__(self, derivation, log_prior, log_likelihood, score, nodes, marks, stride, cum):
        super().__init__(derivation, log_prior, log_likelihood, score)
        self.nodes, self.marks, self.stride, self.cum = nodes, marks, stride, cum
        self._index = None

    @property
    def index(self) -> dict:
        """``address -> position`` of the calls in ``nodes`` (built on first use)."""
        if self._index is None:
            self._index = {n.address: i for i, n in enumerate(self.nodes)}
        return self._index


class EditedChoices:
    """The choice map of a derivation with one move's edits, without building it.

    ``get((address, name))`` answers ``overrides`` first (a value, or ``_MISSING`` for a
    dropped choice), then nothing inside the dropped subtree ``removed``, then the old
    derivation's value.
    """

    __slots__ = ("nodes", "index", "overrides", "removed")

    def __init__(self, traced: Traced, overrides: dict, removed: tuple | None):
        self.nodes, self.index = traced.nodes, traced.index
        self.overrides, self.removed = overrides, removed

    def get(self, key, default=None):
        value = self.overrides.get(key, _MISSING)
        if value is not _MISSING:
            return value
        if key in self.overrides:  # dropped
            return default
        address, name = key
        removed = self.removed
        if removed is not None and address[: len(removed)] == removed:
            return default
        i = self.index.get(address)
        if i is None:
            return default
        choice = self.nodes[i].choices.get(name)
        return default if choice is None else choice.value

    def __contains__(self, key) -> bool:
        return self.get(key, _MISSING) is not _MISSING


def node_counts(node) -> tuple:
    """(1 if the call has a continuous choice else 0, its ``maybe`` sites, its choices)."""
    cont = 0
    for c in node.choices.values():
        if not c.dist.discrete:
            cont = 1
            break
    maybe = 0
    for s in node.spawns:
        if s.probability < 1.0:
            maybe += 1
    return cont, maybe, len(node.choices)


class TracedReplay(NamedTuple):
    """What :func:`replay_traced` returns: the new state, the calls that ran again (new
    nodes) and, of their choices, the keys taken from the map (what the acceptance ratio
    needs: :func:`procmod.infer.mcmc.log_acceptance_traced`)."""

    state: Traced
    ran: list
    reused: set
    first: int  # position in both states' ``nodes`` from which they may differ


def replay_traced(model, target, previous: Traced | None, choices, rng, edited: tuple | None = None,
                  stride: int | None = None) -> TracedReplay:
    """Replay ``choices`` in program order from ``previous``'s checkpoint before the call
    at ``edited`` (module docstring); from the start when ``previous`` is None.

    ``choices`` is any mapping with ``get`` and ``in`` (an :class:`EditedChoices`, a
    dict). The caller vouches that it holds exactly ``previous``'s values for every call
    outside the subtree at ``edited`` (calls inside it are compared value by value).
    ``stride`` (calls between checkpoints) defaults to ``previous``'s, or
    :func:`checkpoint_stride` of the target's output.
    """
    old_nodes = previous.nodes if previous is not None else []
    old_index = previous.index if previous is not None else {}
    if previous is None or edited is None or edited not in old_index:
        first = 0
    else:
        first = old_index[edited]
    if previous is not None:
        stride = previous.stride
        j = first - first % stride
        mark = previous.marks[j]
        state = Derivation.__new__(Derivation)
        state.model = model
        state.output = mark.output.copy()
        state.pending = list(mark.pending)
        state.active = None
        state.log_prior = mark.log_prior
        state.stopped = False
        state.position = None
        state.n_emits = mark.n_emits
        state.n_nodes = j
        state._chain = mark.chain
        state.policy = policy = ReplayPolicy(choices)
        nodes = old_nodes[:j]
        marks = previous.marks[:j]
        old_d, old_m, old_k = previous.cum
        cum_d, cum_m, cum_k = old_d[: j + 1], old_m[: j + 1], old_k[: j + 1]
        stopper = old_nodes[-1] if previous.derivation.stopped else None
    else:
        output = target.new_output(model)
        if output.supports_part_cache:
            output.use_part_cache()
        if stride is None:
            stride = checkpoint_stride(output)
        state = start(model, output)
        state.policy = policy = ReplayPolicy(choices)
        j, nodes, marks, stopper = 0, [], [], None
        cum_d, cum_m, cum_k = [0], [0], [0]
    pending = state.pending
    ran = []
    output = state.output
    draw = output.add
    copy_output = output.copy
    # The state's running fields live in locals while calls are taken over (this loop is
    # the cost of a move) and are written back around each call that runs.
    lp_prior, n_emits, n_nodes, chain = state.log_prior, state.n_emits, state.n_nodes, state._chain
    depth = None if edited is None else len(edited)
    stopped = False
    while pending:
        marks.append(Checkpoint(copy_output(), tuple(pending), lp_prior, n_emits, chain)
                     if n_nodes % stride == 0 else None)
        future = pending.pop()
        address = future.address
        i = old_index.get(address)
        if i is not None:
            node = old_nodes[i]
            if (node.rule is future.rule and same_args(node.args, future.args)
                    and (depth is None or address[:depth] != edited or _map_agrees(node, choices, None))):
                # take the call over (module docstring): what running it again would do,
                # the same log-probabilities added in the same order, the same geometry
                # drawn, the same spawns pending (their ctx.at positions, read only by
                # guides, are not kept)
                for choice in node.choices.values():
                    lp_prior += choice[1]
                for geometry in node.geometry:
                    draw(geometry)
                n_emits += len(node.geometry)
                chain = (node, chain)
                n_nodes += 1
                nodes.append(node)
                cum_d.append(cum_d[-1] + old_d[i + 1] - old_d[i])
                cum_m.append(cum_m[-1] + old_m[i + 1] - old_m[i])
                cum_k.append(cum_k[-1] + old_k[i + 1] - old_k[i])
                if node is stopper:
                    stopped = True
                    break
                for spawn in reversed(node.spawns):
                    if spawn.on:
                        pending.append(Future(address + (spawn.site,), spawn.rule, spawn.args))
                continue
        state.log_prior, state.n_emits, state.n_nodes, state._chain = (
            lp_prior, n_emits, n_nodes, chain)
        _execute(state, future, rng, None, 0, False)
        lp_prior, n_emits, n_nodes, chain = state.log_prior, state.n_emits, state.n_nodes, state._chain
        node = chain[0]
        nodes.append(node)
        ran.append(node)
        d, m, k = node_counts(node)
        cum_d.append(cum_d[-1] + d)
        cum_m.append(cum_m[-1] + m)
        cum_k.append(cum_k[-1] + k)
        if state.stopped:
            stopped = True
            break
    state.log_prior, state.n_emits, state.n_nodes, state._chain = (
        lp_prior, n_emits, n_nodes, chain)
    state.stopped = stopped
    pending.clear()
    state.policy = None
    traced = Traced(state, state.log_prior, *scored(target, output), nodes, marks, stride, (cum_d, cum_m, cum_k))
    return TracedReplay(traced, ran, policy.reused, j)


def trace(model, target, choices, rng) -> Traced:
    """A :class:`Traced` state from a choice map (e.g. ``{}``: a fresh forward run)."""
    return replay_traced(model, target, None, choices, rng).state
