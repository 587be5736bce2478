"""MCMC on several cores: groups of chains run side by side in forked processes.

``mcmc(..., chains=C, workers=W)`` splits its ``C`` chains into ``W`` groups. This process
runs the first group and ``W - 1`` forked worker processes run the others, each group as
an :func:`~procmod.infer.mcmc.mcmc` run of its own under the same budget (seconds and
sweeps apply to every group, evaluations are shared out), seeded from ``(seed, group)``;
the first group uses ``seed`` itself, so it is the chain a one-process run of that many
chains would make. The result is the best derivation any group found; its samples are
every chain's final state, in group order.

Chains of different groups never swap states: a swap needs both processes at the same
sweep, a message each way per sweep, which costs about as much as a move. So each group
is a temperature ladder of its own, and with one chain per group (the default: one per
worker) the groups are independent chains. On a likelihood as sharp as an image match a
chain's outcome varies from run to run far more than it gains from being run twice as
long at the end of its budget (docs/vines_smc.md, "MCMC against WebPPL's MH"), so on
idle cores the best of ``W`` chains beats one chain in the same wall time; on one core
it would not (restarts that share the time lose).

What travels back from a worker is small: choice maps (the best derivation's and each
final state's) and the run's history and move counts. This process replays the choice
maps into derivations (a complete map replays to the same derivation, no randomness).
"""

from __future__ import annotations

import multiprocessing
import os

from .common import NO_FINITE_SCORE_NOTE, RULED_OUT_NOTE, Budget, HistoryRow, Result, evaluate
from ..parallel import lost_worker_error, shared_memory_error
from .particles import _pin, split_evenly


class _Group:
    """One group of chains in a forked worker process; :meth:`result` waits for it."""

    def __init__(self, index: int, run):
        context = multiprocessing.get_context("fork")
        self.index = index
        self.conn, child = context.Pipe(duplex=False)
        self.process = context.Process(target=_group_main, args=(child, index, run, os.getpid()),
                                       name=f"procmod-mcmc-group-{index}", daemon=True)
        self.process.start()
        child.close()
        self._reply = None

    def _receive(self) -> tuple:
        if self._reply is None:
            try:
                self._reply = self.conn.recv()
            except (EOFError, ConnectionResetError, OSError):
                self.process.join(timeout=1)
                self._reply = ("error", lost_worker_error(f"MCMC worker process {self.index}", self.process.exitcode))
        return self._reply

    def failed(self) -> bool:
        """Whether the worker has answered with a failure (or died), without waiting."""
        if self._reply is None and not self.conn.poll():
            return False
        return self._receive()[0] == "error"

    def result(self) -> dict:
        status, reply = self._receive()
        if status == "error":
            raise reply
        return reply

    def close(self, at_once: bool = False) -> None:
        """End the worker: wait for it (it has answered) or, ``at_once``, stop it."""
        self.conn.close()
        self.process.join(timeout=0 if at_once else 5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()


def _group_main(conn, index: int, run, parent: int) -> None:
    from ..parallel import _exit_with_parent, portable_error

    _exit_with_parent(parent)
    _pin(index)  # a core of its own (see procmod.infer.particles._pin)
    try:
        reply = ("ok", _packed(run()))
    except BaseException as exc:  # noqa: BLE001 - every failure goes back to the caller
        reply = ("error", portable_error(exc, f"MCMC worker process {index}"))
    try:
        conn.send(reply)
    except Exception as exc:  # e.g. an exception that cannot be pickled
        conn.send(("error", RuntimeError(f"MCMC worker process {index} failed: {reply[1]!r} ({exc})")))
    conn.close()


def _summary(result: Result) -> dict:
    """What the merge reads of every group's result besides its derivations."""
    return {"best_score": result.best_score, "log_weights": result.log_weights,
            "history": [tuple(r) for r in result.history], "evaluations": result.evaluations,
            "moves": result.settings["moves"], "init_evaluations": result.settings["init_evaluations"],
            "notes": result.notes}


def _packed(result: Result) -> dict:
    """What a worker's result needs to travel: its summary, and choice maps, not derivations."""
    return {**_summary(result), "best": None if result.best is None else result.best.choice_map().raw,
            "samples": [s.choice_map().raw for s in result.samples]}


def group_budget(budget: Budget, group: int, groups: int) -> Budget:
    """A group's share of ``budget``: the same seconds and sweeps, its part of the evaluations."""
    evaluations = budget.evaluations
    if evaluations is not None:
        evaluations = max(1, split_evenly(evaluations, groups)[group])
    return Budget(budget.seconds, evaluations, budget.generations)


def merged_history(histories: list, chains: list) -> list:
    """One anytime curve from the groups' curves.

    Rows are taken in the order of each group's own evaluations per chain (groups work
    side by side at about the same rate), not of the clock, so that a seeded run writes
    the same rows every time, as one process does (only ``seconds`` differ; here they are
    the latest row's so far). Each merged row has the evaluations of all groups so far,
    the best score of any, and the mean score over the chains of the groups that have a
    row by then (each group's latest row, weighted by its chains).
    """
    events = sorted((row[1] / chains[g], g, i) for g, rows in enumerate(histories) for i, row in enumerate(rows))
    latest = [None] * len(histories)
    out = []
    seconds = 0.0
    for _, g, i in events:
        row = latest[g] = histories[g][i]
        seconds = max(seconds, row[0])
        seen = [(r, c) for r, c in zip(latest, chains) if r is not None]
        out.append(HistoryRow(seconds, sum(r[1] for r, _ in seen), max(r[2] for r, _ in seen),
                              sum(r[3] * c for r, c in seen) / sum(c for _, c in seen)))
    return out


def run_groups(run_group, model, target, chains: int, workers: int, budget: Budget, progress=None) -> tuple:
    """Run ``workers`` groups of the ``chains`` chains: ``run_group(group, chains, budget,
    progress)`` returns a group's :class:`Result` (group 0 runs here, with ``progress``,
    the others in forked workers).

    A stop requested through ``progress`` (:meth:`Tracker.request_stop`) reaches every
    group, and a group that fails stops the others, each at its next budget check.

    Returns ``(best derivation, best score, samples, log-weights, history, evaluations,
    move counts, evaluations of the SMC starts, notes)`` over all groups."""
    sizes = split_evenly(chains, workers)
    try:
        stop = multiprocessing.get_context("fork").Event()
    except OSError as exc:  # a read-only /dev/shm: a traceback before
        raise shared_memory_error(exc) from None
    remote = []

    def follow(tracker):  # the workers' progress callback: only listens for a stop
        if stop.is_set():
            tracker.request_stop()

    def watch(tracker):  # this process's: the caller's callback, then stops both ways
        if progress is not None:
            progress(tracker)
        if tracker.stop_requested or any(group.failed() for group in remote):
            tracker.request_stop()
            stop.set()

    done = False
    try:
        for g in range(1, workers):
            remote.append(_Group(g, lambda g=g: run_group(g, sizes[g], group_budget(budget, g, workers), follow)))
        local = run_group(0, sizes[0], group_budget(budget, 0, workers), watch)
        packs = [_summary(local)] + [group.result() for group in remote]  # this group's stay whole
        done = True
    finally:
        for group in remote:
            group.close(at_once=not done)  # after a failure here, the others' work is moot
    configured = target.configure(model)

    def rebuilt(choices):
        return evaluate(configured, target, (choices, 0, None)).derivation

    # a group with a best before one without (it had outranked a ruled-out best, which was
    # then lost); of those, a best the target allows before a ruled-out one (Tracker.offer)
    has_best = [local.best is not None] + [pack["best"] is not None for pack in packs[1:]]
    best_group = max(range(workers), key=lambda g: (has_best[g], RULED_OUT_NOTE not in packs[g]["notes"],
                                                    packs[g]["best_score"]))
    best_score = packs[best_group]["best_score"]
    best = local.best if best_group == 0 else (
        None if packs[best_group]["best"] is None else rebuilt(packs[best_group]["best"]))
    samples = list(local.samples)
    for pack in packs[1:]:
        samples += [rebuilt(c) for c in pack["samples"]]
    log_weights = [w for pack in packs for w in pack["log_weights"]]
    history = merged_history([pack["history"] for pack in packs], sizes)
    moves = {}
    for pack in packs:
        for kind, (accepted, proposed) in pack["moves"].items():
            a, p = moves.get(kind, (0, 0))
            moves[kind] = (a + accepted, p + proposed)
    # what the group of the best says of its best holds for the whole result; that a group
    # found no best does not, when another did
    said_of_best = {RULED_OUT_NOTE: RULED_OUT_NOTE in packs[best_group]["notes"],
                    NO_FINITE_SCORE_NOTE: not any(has_best)}
    notes = list(dict.fromkeys(n for pack in packs for n in pack["notes"] if said_of_best.get(n, True)))
    evaluations = sum(pack["evaluations"] for pack in packs)
    init_evaluations = sum(pack["init_evaluations"] for pack in packs)
    if not has_best[best_group]:
        best = None
    return best, best_score, samples, log_weights, history, evaluations, moves, init_evaluations, notes
