"""A particle population split into shards, stepped in one process or in several.

SMC spends nearly all of its time stepping particles, and particles step independently
between two resampling points, so the population can be split among processes: each
process (a *shard*) steps its own particles, the coordinator gathers their weights,
resamples the whole population, and tells each shard which of its particles to keep and
how often. Only the offspring that would leave a shard with more active particles than
its share move to another process, and a moved particle travels without its history (its
expanded calls stay where they were and come back only at the end; see
:func:`procmod.core.runtime.pack_particle`), so a generation costs one small message per
worker plus, usually, one or two moved particles.

:class:`ParticleShard` is one shard in this process (the coordinator's own, or the only
one); :class:`WorkerShard` drives a shard in a forked worker process over a pipe. Objects
every process already holds (the model, its rules, the target, a guide, the arrays the
outputs share) are sent by reference, never copied (:class:`_SharedObjects`).

Which particles a run ends with, and which it returns as best, depend on the number of
shards (each shard draws its own random numbers); with the same seed and the same number
of workers a run is the same, bit for bit.
"""

from __future__ import annotations

import io
from array import array
import math
import multiprocessing
import os
import pickle
import signal

from ..core.errors import ModelError, ProcmodError, argument
from ..core.runtime import HistoryRef, history, pack_particle, run_until, start, step, unpack_particle
from .common import best_first, checked_value, mean_of
from ..parallel import lost_worker_error

_ATOMS = (int, float, str, bytes, bool, type(None))


class ParticleShard:
    """Some of a population's particles, with their weights since the last resampling.

    Parameters
    ----------
    index : int
        This shard's number (0 for the coordinator's own).
    template : Output
        An empty output of the configured model; every particle starts from a copy.
    rng : numpy.random.Generator
        This shard's random numbers.
    pick : callable or None
        Which pending call runs next (None: program order).
    proposer : Proposer or None
        A guide's proposer: each step also weighs by prior / proposal.
    offer : callable
        ``offer(derivation, score)`` for every particle that completes.
    """

    def __init__(self, index, model, target, template, rng, pick, proposer, offer):
        self.index = index
        self.model, self.target, self.template = model, target, template
        self.rng, self.pick, self.proposer, self.offer = rng, pick, proposer, offer
        self.states, self.log_lik, self.log_w, self.log_ratio, self.finished = [], [], [], None, []
        self.exported = {}  # key -> history chain of a particle sent elsewhere
        self._next_key = 0

    def reset(self, count: int) -> None:
        """``count`` fresh particles (the root call pending), weights zero."""
        self.states = []
        for _ in range(count):
            state = start(self.model, self.template.copy())
            state.proposer = self.proposer
            self.states.append(state)
        self.log_lik = [0.0] * count
        self.log_w = [0.0] * count
        self.log_ratio = [0.0] * count if self.proposer is not None else None
        self.finished = [False] * count
        self.exported = {}

    def step(self) -> tuple:
        """Step every unfinished particle to its next emit and reweigh it.

        Returns ``(log-weights since the last resampling, finished flags, particles
        stepped, particles still active)``.
        """
        rng, pick, finished, reweigh = self.rng, self.pick, self.finished, self._reweigh
        active = stepped = 0
        for i, state in enumerate(self.states):
            if finished[i]:
                continue
            stepped += 1
            step(state, rng, pick)
            if not reweigh(i, state):
                active += 1
        return self.log_w, finished, stepped, active

    def run_through(self, looked_at=None) -> int:
        """Run every unfinished particle to its end without pausing at its emits, and
        reweigh it once; returns the particle-steps that stepping it emit by emit would have
        counted (:func:`procmod.core.runtime.run_until`).

        For a population that no resampling can change (one particle, or an ESS
        threshold no population of this size can fall below; see :func:`procmod.infer.smc.smc`):
        the same derivations, without re-running a call from its start after each emit.
        The likelihood is still looked at after each emit, as stepping does: a particle whose
        weight becomes zero pauses there, and where every particle's has, the run ends
        where stepping them together would have ended it (unfinished, as :meth:`step` leaves
        them); otherwise the paused ones run on to their ends. ``looked_at(state)``, if
        given, is called after each emit (the engine's history rows and progress, which
        stepping updates between its steps)."""
        rng, pick, states, finished, zero = self.rng, self.pick, self.states, self.finished, self._zero_weight
        if looked_at is None:
            go_on = None
        else:
            def zero(state, zero_weight=zero):
                looked_at(state)
                return zero_weight(state)

            def go_on(state):
                looked_at(state)
                return False
        stepped = 0
        paused = {}  # index -> steps taken, of particles paused where their weight became zero
        last = 0  # the step at which the last particle's weight became zero (all have: see below)
        alive = False
        for i, state in enumerate(states):
            if finished[i]:
                continue
            halted, steps = run_until(state, rng, pick, zero)
            stepped += steps
            if not self._reweigh(i, state) and halted:
                paused[i] = steps
            if self.log_w[i] != -math.inf:
                alive = True
            else:
                last = max(last, steps)
        for i, steps in paused.items():
            state = states[i]
            if alive:  # a particle the target allows keeps the run going: the others run to their ends
                stepped += run_until(state, rng, pick, go_on)[1]
                self._reweigh(i, state)
                continue
            # every weight is zero: stepped SMC stops once the last of them is (each particle
            # stepped as far as that, or to its end)
            while steps < last:
                steps += 1
                stepped += 1
                step(state, rng, pick)
                if self._reweigh(i, state):
                    break
        return stepped

    def _zero_weight(self, state) -> bool:
        """Whether a particle's weight is zero for good (the target rules its output out, or a
        guide proposed outside the prior's support); raises as :meth:`_reweigh` does on a
        likelihood that is no number."""
        if self._log_likelihood(state) == -math.inf:
            return True
        return self.log_ratio is not None and state.log_prior == -math.inf

    def _log_likelihood(self, state) -> float:
        """The target's log-likelihood of a particle's output, checked."""
        target = self.target
        new = target.log_likelihood(state.output)
        if not isinstance(new, float) or new != new or new == math.inf:  # NaN, +inf, not a float
            new = checked_value(new, target, "log_likelihood")
        return new

    def _reweigh(self, i: int, state) -> bool:
        """Reweigh particle ``i`` after it ran (its likelihood now, and for a guided run its
        prior / proposal); offer it if it is complete. Returns whether it is."""
        target = self.target
        new = self._log_likelihood(state)
        log_w, log_ratio = self.log_w, self.log_ratio
        old = self.log_lik[i]
        if new == -math.inf or old == -math.inf:
            # zero likelihood stays zero weight (-inf - -inf would be NaN); a particle left
            # so by a skipped resampling (ess_threshold) must not poison the weights
            log_w[i] = -math.inf
        else:
            log_w[i] += new - old
        self.log_lik[i] = new
        if log_ratio is not None:  # guided: weigh by prior / proposal of this step's choices
            ratio = state.log_prior - state.policy.log_proposal  # the GuidedPolicy reset() installed
            if ratio == -math.inf or log_ratio[i] == -math.inf:
                # a proposal outside the prior's support (a real head on a half-normal): zero
                # weight for good; -inf - -inf at its next step was NaN, and log Z with it
                log_w[i] = -math.inf
            else:
                log_w[i] += ratio - log_ratio[i]
            log_ratio[i] = ratio
        if not state.done:
            return False
        self.finished[i] = True
        score = target.score(state.output)
        if not isinstance(score, float) or score != score or score == math.inf:
            score = checked_value(score, target, "score")
        self.offer(state, score, new)
        return True

    def regroup(self, keep: list, incoming: list) -> None:
        """The shard's particles after resampling: the particles at local indices ``keep``
        (an index repeated for each offspring, in order), then ``count`` copies of each
        packed particle in ``incoming`` (``(count, packed, log_lik, log_ratio)``).
        Weights restart at zero."""
        states, old_lik, old_ratio, old_finished = self.states, self.log_lik, self.log_ratio, self.finished
        new_states, taken = [], set()
        for a in keep:
            # The first offspring of an ancestor takes it over; the rest are copies. A
            # finished particle is never changed again, so its offspring share it.
            if a in taken and not old_finished[a]:
                new_states.append(states[a].copy())
            else:
                taken.add(a)
                new_states.append(states[a])
        log_lik = [old_lik[a] for a in keep]
        log_ratio = None if old_ratio is None else [old_ratio[a] for a in keep]
        finished = [old_finished[a] for a in keep]
        for count, packed, lik, ratio in incoming:
            state = unpack_particle(self.model, packed)
            state.proposer = self.proposer
            for k in range(count):
                new_states.append(state if k == 0 else state.copy())
                log_lik.append(lik)
                finished.append(False)
                if log_ratio is not None:
                    log_ratio.append(ratio)
        self.states, self.log_lik, self.log_ratio, self.finished = new_states, log_lik, log_ratio, finished
        self.log_w = [0.0] * len(new_states)

    def export(self, indices: list) -> list:
        """The particles at ``indices``, packed to move to another shard: ``(packed,
        log_lik, log_ratio)`` each. Their histories stay here, under keys in
        :attr:`exported`."""
        out = []
        for i in indices:
            state = self.states[i]
            key = self._next_key
            self._next_key += 1
            nodes, tail = history(state)
            self.exported[key] = (nodes, tail)
            out.append((pack_particle(state, HistoryRef(self.index, key)), self.log_lik[i],
                        None if self.log_ratio is None else self.log_ratio[i]))
        return out

    def histories(self, keys: list) -> list:
        """The exported histories under ``keys``: ``(nodes oldest first, tail)`` each."""
        return [self.exported[k] for k in keys]

    def score_mean(self) -> tuple[float, int]:
        """``(mean, count)`` of the target's score over the shard's particles (for history
        rows; a mean, not a sum: scores near the end of the float range, a target's
        -sys.float_info.max, had summed to -inf)."""
        target = self.target
        scores = [checked_value(target.score(s.output), target, "score") for s in self.states]
        return (mean_of(scores), len(scores)) if scores else (0.0, 0)

    def packed_states(self) -> list:
        """Every particle packed with the history held here (for the coordinator)."""
        return [pack_particle(s, None) for s in self.states]


# ---- shards in worker processes --------------------------------------------------------

class _SharedObjects:
    """Objects every process holds from before the fork, sent by reference.

    A worker is forked after these exist, so each sits at the same place in every
    process and its ``id`` names it everywhere. Everything else is pickled by value.
    """

    def __init__(self, objects):
        self.by_id = {}
        for obj in objects:
            if obj is not None and not isinstance(obj, _ATOMS):
                self.by_id[id(obj)] = obj

    def dumps(self, message) -> bytes:
        """``message`` pickled, shared objects by reference. What plain pickle cannot send
        (a rule that is a closure, a lambda or a bound method, in a moved particle's
        pending calls) goes by value through cloudpickle (a dask dependency): the worker is
        a fork of this process, so the code it rebuilds is the same."""
        try:
            return self._dumps(message, pickle.Pickler)
        except (pickle.PicklingError, TypeError, AttributeError):
            pass
        import cloudpickle

        try:
            return self._dumps(message, cloudpickle.CloudPickler)
        except Exception as exc:  # noqa: BLE001 -- whatever the object's own pickling raises
            raise ModelError(f"a particle's state cannot be sent to the worker processes ({type(exc).__name__}: "
                             f"{str(exc)[:120]}); keep the model's rules and their arguments to plain functions and "
                             f"values, or run in one process ({argument('workers')}=1)") from None

    def _dumps(self, message, pickler_class) -> bytes:
        buffer = io.BytesIO()
        pickler = pickler_class(buffer, protocol=pickle.HIGHEST_PROTOCOL)
        by_id = self.by_id
        pickler.persistent_id = lambda obj: id(obj) if id(obj) in by_id else None
        pickler.dump(message)
        return buffer.getvalue()

    def loads(self, data: bytes):
        unpickler = pickle.Unpickler(io.BytesIO(data))
        unpickler.persistent_load = self.by_id.__getitem__
        return unpickler.load()


def shared_objects(model, target, template, proposer) -> _SharedObjects:
    """What a forked worker already has: model, rules, target, proposer, the root call's
    arguments, and the parts of an output that its copies share (e.g. a canvas's gains)."""
    objects = [model, target, proposer, model.root, *model.rules, *model.initial_args()]
    # a rule that is a bound method is a new object at each look-up; its instance is not
    objects += [getattr(rule, "__self__", None) for rule in (model.root, *model.rules)]
    copy = template.copy()
    names = getattr(type(template), "__slots__", ()) or tuple(getattr(template, "__dict__", {}))
    for name in names:
        value = getattr(template, name, None)
        if value is not None and getattr(copy, name, None) is value:
            objects.append(value)
    return _SharedObjects(objects)


def _worker_main(conn, shard: ParticleShard, shared: _SharedObjects, parent: int) -> None:
    from ..parallel import _exit_with_parent, portable_error

    _exit_with_parent(parent)
    # the coordinator answers Ctrl-C (a terminal sends it to the whole process group) and
    # closes the shards; a shard that also raised KeyboardInterrupt printed its traceback
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    _pin(shard.index)
    best = [-math.inf, None, False]  # score, derivation, whether the target allows it (Tracker.offer)

    def offer(derivation, score, log_likelihood=0.0):
        allowed, _ = key = best_first(score, log_likelihood)
        if score != -math.inf and key > (best[2], best[0]):  # a score of -inf is no best, as Tracker.offer has it
            best[:] = [score, derivation, allowed]

    shard.offer = offer
    while True:
        try:
            data = conn.recv_bytes()
        except EOFError:
            return
        command, *args = shared.loads(data)
        if command == "stop":
            return
        try:
            if command == "regroup":  # no answer: the next request comes after it
                shard.regroup(*args)
                continue
            if command == "reset":
                shard.reset(*args)
                best[:] = [-math.inf, None, False]
                continue
            if command == "step":
                log_w, finished, stepped, active = shard.step()
                # flat arrays: one object each for the pickler, not one per particle
                reply = (array("d", log_w), bytes(finished), stepped, active, (best[0], best[2]))
            elif command == "export":
                reply = shard.export(*args)
            elif command == "histories":
                reply = shard.histories(*args)
            elif command == "scores":
                reply = shard.score_mean()
            elif command == "collect":
                reply = shard.packed_states()
            elif command == "best":
                reply = None if best[1] is None else (pack_particle(best[1], None), best[0])
            else:  # pragma: no cover - the coordinator sends only the commands above
                raise ValueError(f"unknown command {command!r}")
            message = ("ok", reply)
        except BaseException as exc:  # raised again in the coordinator at its next answer
            message = ("error", portable_error(exc, f"SMC worker process {shard.index}"))
        try:
            conn.send_bytes(shared.dumps(message))
        except ProcmodError as exc:  # a reply that cannot be sent (dumps says what): said in the coordinator
            conn.send_bytes(shared.dumps(("error", exc)))
        except (pickle.PicklingError, TypeError, AttributeError):
            error = message[1]
            conn.send_bytes(shared.dumps(("error", RuntimeError(f"{type(error).__name__}: {error}"))))


def _pin(index: int) -> None:
    """Keep worker ``index`` on one core of its own (Linux), apart from the coordinator.

    The coordinator wakes a worker by writing to its pipe, and Linux runs a task woken
    that way on the waker's core, ahead of the waker, when it can: unpinned, a worker
    stepped its shard on the coordinator's core while the coordinator waited, and the two
    took turns instead of running together (traced on the 2-core bench machine).
    """
    try:
        cores = sorted(os.sched_getaffinity(0))
    except AttributeError:  # not Linux
        return
    if len(cores) > 1:
        os.sched_setaffinity(0, {cores[index % len(cores)]})


class WorkerShard:
    """A :class:`ParticleShard` in a forked worker process, driven over a pipe.

    Requests are sent first and answered later (:meth:`send` / :meth:`receive`) so that
    the coordinator steps its own shard while the workers step theirs.
    """

    def __init__(self, shard: ParticleShard, shared: _SharedObjects):
        context = multiprocessing.get_context("fork")
        self.index = shard.index
        self.shared = shared
        self.conn, child = context.Pipe()
        self.process = context.Process(target=_worker_main, args=(child, shard, shared, os.getpid()),
                                       name=f"procmod-smc-shard-{shard.index}", daemon=True)
        self.process.start()
        child.close()

    def send(self, *message) -> None:
        self.conn.send_bytes(self.shared.dumps(message))

    def receive(self):
        try:
            data = self.conn.recv_bytes()
        except (EOFError, ConnectionResetError) as exc:
            self.process.join(timeout=1)
            raise lost_worker_error(f"SMC worker process {self.index}", self.process.exitcode) from exc
        status, reply = self.shared.loads(data)
        if status == "error":
            raise reply
        return reply

    def call(self, *message):
        self.send(*message)
        return self.receive()

    def close(self) -> None:
        try:
            self.send("stop")
        except (BrokenPipeError, OSError):
            pass
        self.conn.close()
        self.process.join(timeout=5)
        if self.process.is_alive():
            self.process.kill()
            self.process.join()


def fork_available() -> bool:
    """Whether worker shards can be forked here (they need the ``fork`` start method)."""
    return "fork" in multiprocessing.get_all_start_methods()


def split_evenly(total: int, shards: int) -> list:
    """``total`` in ``shards`` near-equal parts (the first ones one larger)."""
    return [total // shards + (1 if s < total % shards else 0) for s in range(shards)]


def plan_offspring(ancestors: list, sizes: list, finished: list) -> tuple:
    """Where each offspring of a resampling lives.

    Global particle indices run shard by shard, in local order; shard ``s`` holds
    ``sizes[s]`` particles. ``ancestors`` are the global indices of the new population's
    parents (sorted), ``finished[g]`` whether particle ``g`` has finished. Offspring stay
    with their ancestor's shard, except that a shard left with more *active* (unfinished)
    offspring than its share sends the surplus — its last ones — to the shards below
    their share: finished particles cost nothing to step, so only active ones are balanced.

    Returns ``(keep, sends)``: ``keep[s]`` the local indices shard ``s`` keeps, in order,
    one per offspring; ``sends[s]`` a list of ``(local index, destination, count)``.
    """
    shards = len(sizes)
    offsets = [0] * shards
    owner = []
    for s, size in enumerate(sizes):
        offsets[s] = len(owner)
        owner.extend([s] * size)
    kept = [[] for _ in range(shards)]
    active = [0] * shards
    for a in ancestors:
        s = owner[a]
        kept[s].append(a)
        if not finished[a]:
            active[s] += 1
    quota = split_evenly(sum(active), shards)
    deficits = [[s, quota[s] - active[s]] for s in range(shards) if active[s] < quota[s]]
    sends = [[] for _ in range(shards)]
    for s in range(shards):
        surplus = active[s] - quota[s]
        mine = kept[s]
        moving = {}  # ancestor -> offspring to send, taken from the end of the shard's list
        position = len(mine) - 1
        while surplus > 0:
            a = mine[position]
            if not finished[a]:
                moving[a] = moving.get(a, 0) + 1
                del mine[position]
                surplus -= 1
            position -= 1
        for a in sorted(moving):
            count = moving[a]
            while count > 0:
                destination = deficits[0]
                n = min(count, destination[1])
                sends[s].append((a - offsets[s], destination[0], n))
                count -= n
                destination[1] -= n
                if destination[1] == 0:
                    deficits.pop(0)
    keep = [[a - offsets[s] for a in kept[s]] for s in range(shards)]
    return keep, sends
