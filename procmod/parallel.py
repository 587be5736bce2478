"""Executors for embarrassingly parallel work: one interface, local or on a cluster.

Everything procmod parallelises (SMC training traces, GA fitness batches, independent
inference runs, parallel structure searches) goes through a
:class:`concurrent.futures.Executor`. :func:`open_executor` picks one:

- ``workers <= 1`` and no scheduler: :class:`InlineExecutor` (runs in the caller; the
  default for library calls, and what tests use);
- ``workers = W > 1``: a local :class:`concurrent.futures.ProcessPoolExecutor` with W
  processes;
- ``scheduler = "tcp://host:8786"``: a dask.distributed cluster through
  ``Client.get_executor(pure=False)``. ``pure=False`` matters: dask otherwise keys a task
  by its function and arguments and would run two identical stochastic calls once. Callers
  still pass each task its own seed, so results do not depend on where a task ran.

Tasks must be module-level functions fed picklable arguments.

Local pool workers end when the process that opened the pool dies, even by SIGKILL
(which runs no clean-up): each worker watches its parent (:func:`_exit_with_parent`), so
a killed ``procmod guide traces --workers 2`` or ``procmod learn`` leaves no process
behind.
"""

from __future__ import annotations

import concurrent.futures
import contextlib
import functools
import ctypes
import logging
import os
import re
import signal
import sys
import threading
from pathlib import Path
from typing import Iterator

from .core.errors import InvalidArgumentError, ProcmodError, argument


class SchedulerError(ProcmodError):
    """A dask scheduler that cannot be reached or used."""


class WorkerError(ProcmodError):
    """Worker processes that cannot be started, or one that ended before its work did
    (killed by the system when memory ran out, or from outside): the machine's doing,
    not the command's; one line says so and what to try."""


def lost_worker_error(what: str, exitcode) -> WorkerError:
    """The one line for a worker process ``what`` that ended with ``exitcode`` mid-job
    (None: not known). Only SIGKILL is blamed on the outside or on memory (the OOM
    killer's signal); a crash or an exit of its own is said as it is."""
    if exitcode is None:
        how = " (killed from outside, or by the system when memory ran out)"
    elif exitcode == -signal.SIGKILL:
        how = f" (killed by signal {signal.SIGKILL}: from outside, or by the system when memory ran out)"
    elif exitcode < 0:
        how = f" (killed by signal {-exitcode})"
    else:
        how = f" (exit code {exitcode})"
    return WorkerError(f"{what} ended unexpectedly{how}; rerun, with fewer workers, or with "
                       f"{argument('workers=1')} (in one process, where a crash shows its cause)")


class InlineExecutor(concurrent.futures.Executor):
    """An executor that runs each task at once in the calling thread."""

    def submit(self, fn, /, *args, **kwargs):
        future = concurrent.futures.Future()
        try:
            future.set_result(fn(*args, **kwargs))
        except BaseException as exc:  # delivered through the future, as executors do
            future.set_exception(exc)
        return future


def default_workers() -> int:
    """The number of CPU cores this process may use."""
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


# Worker processes per core a command may start: a few per core can hide waits, far more
# only adds memory and start-up (and --workers 100000 would be a fork bomb).
MAX_WORKERS_PER_CORE = 4


def check_worker_limit(workers: int) -> int:
    """``workers`` if this machine can sensibly run that many processes, else an
    InvalidArgumentError naming the limit (:data:`MAX_WORKERS_PER_CORE` per core)."""
    limit = MAX_WORKERS_PER_CORE * default_workers()
    if workers > limit:
        raise InvalidArgumentError(f"{argument('workers')} {workers:,} is more processes than this machine's "
                                   f"{default_workers()} cores can use (at most {limit}); give fewer")
    return workers


_ADDRESS = re.compile(r"^(?:(?:tcp|tls|ucx|ws|wss)://)?(?:\[[0-9A-Fa-f:.]+\]|[A-Za-z0-9_.-]+):\d{1,5}$"
                      r"|^inproc://\S+$")


def check_scheduler(address: str) -> str:
    """``address`` if it reads as a dask scheduler address (``tcp://host:8786``,
    ``host:8786``, ``tls://...``), else a SchedulerError; checked before any work."""
    if not isinstance(address, str) or not _ADDRESS.match(address.strip()):
        shown = repr(address) if len(repr(address)) <= 60 else repr(address)[:57] + "..."
        raise SchedulerError(f"{argument('scheduler')} {shown} is not a dask scheduler address; give one like "
                             "tcp://host:8786 (the address 'dask scheduler' prints)")
    return address.strip()


# ---- workers that end with their parent ---------------------------------------------

PR_SET_PDEATHSIG = 1  # linux/prctl.h
WATCH_INTERVAL = 0.25  # seconds between checks of the fallback watcher


def note_worker_traceback(exc: BaseException, where: str) -> BaseException:
    """Add the traceback of ``exc``, raised in a worker process, to it as a note (notes
    travel with the pickled exception): raised again in the parent, its traceback ends in
    procmod's code, and the user's line that raised it would otherwise be lost."""
    import traceback

    if exc.__traceback__ is not None and hasattr(exc, "add_note"):
        text = "".join(traceback.format_exception(type(exc), exc, exc.__traceback__)).rstrip()
        exc.add_note(f"--- raised in {where}:\n{text}")
    return exc


def portable_error(exc: BaseException, where: str) -> BaseException:
    """``exc``, raised in worker process ``where``, made ready to send to the coordinator:
    its traceback as a note (:func:`note_worker_traceback`), and, if it would not come
    back through pickle (an exception class whose ``__init__`` takes other arguments
    than its ``args``: the coordinator's unpickling raised a TypeError of its own), a
    RuntimeError naming it that carries the same notes."""
    import pickle

    note_worker_traceback(exc, where)
    try:
        pickle.loads(pickle.dumps(exc))
        return exc
    except Exception:  # noqa: BLE001 - whatever the user's class does on the way
        from .core.errors import exception_message

        stand_in = RuntimeError(f"{type(exc).__name__}: {exception_message(exc)}")
        for note in getattr(exc, "__notes__", ()):
            stand_in.add_note(note)
        return stand_in


def portable_model_error(exc: BaseException, where: str) -> BaseException:
    """``exc``, raised in worker process ``where`` by a task that runs a model of the user's
    own file (a traces job's), made ready to send back: as :func:`portable_error` makes it,
    except that one pickle would not bring back, raised by the model file's own code, becomes
    a :class:`~procmod.core.errors.ModelCodeError` holding the one line a run in one process
    gives (``FILE.py, line N, in RULE: Type: message``). A process pool's coordinator that
    could not rebuild it had ended in a BrokenProcessPool traceback, and a worker that could
    not pickle it (an exception holding a lambda) in a PicklingError's. So does a
    ``sys.exit()`` or a ``KeyboardInterrupt`` the model's code raised: pickle sends them, but
    a dask worker whose task raises one dies (a KilledWorker traceback once dask had tried
    four)."""
    from .core.errors import ModelCodeError
    from .models.from_file import user_code_error

    portable = portable_error(exc, where)
    if portable is exc and isinstance(exc, Exception):
        return exc
    line = user_code_error(exc)  # (this worker ran the model file: its frames are known as the user's)
    if line is None:  # procmod's own code raised it: the stand-in, with the worker's traceback
        return portable
    error = ModelCodeError(line)
    for note in getattr(exc, "__notes__", ()):
        if isinstance(note, str):  # (add_note takes strings only: another note had made a TypeError the line, h158)
            error.add_note(note)
    return error


def _exit_with_parent(parent: int, use_prctl: bool = True) -> None:
    """Pool worker initializer: end this worker as soon as process ``parent`` (the one
    that opened the pool) is gone.

    On Linux the kernel sends the worker SIGKILL when its parent dies
    (``prctl(PR_SET_PDEATHSIG)``, through ctypes). Everywhere, and in case prctl is not
    available, a daemon thread checks every :data:`WATCH_INTERVAL` seconds: a worker
    forked by ``parent`` sees its parent pid change when it is re-parented; a worker
    started by a fork server checks that ``parent`` still exists.
    """
    try:
        # the coordinator answers Ctrl-C (a terminal sends it to the whole process group)
        # and ends its workers (open_executor): a worker raising KeyboardInterrupt itself
        # printed its own lines; and the coordinator's SIGTERM handler (procmod.cli) is
        # not a worker's
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
    except ValueError:  # not this process's main thread: leave its handlers alone
        pass
    direct = os.getppid() == parent
    if use_prctl and direct and sys.platform.startswith("linux"):
        try:
            libc = ctypes.CDLL(None, use_errno=True)
            libc.prctl(PR_SET_PDEATHSIG, signal.SIGKILL, 0, 0, 0)
        except (OSError, AttributeError):  # no libc prctl: the thread below still watches
            pass
    if direct and os.getppid() != parent:  # the parent died before prctl took effect
        os._exit(1)
    threading.Thread(target=_watch_parent, args=(parent, direct), name="procmod-parent-watch",
                     daemon=True).start()


def _parent_alive(parent: int, direct: bool) -> bool:
    if direct:
        return os.getppid() == parent
    try:
        os.kill(parent, 0)
    except ProcessLookupError:
        return False
    except PermissionError:  # exists, owned by someone else (the pid was reused): treat as gone
        return False
    return True


def _watch_parent(parent: int, direct: bool) -> None:
    import time

    while _parent_alive(parent, direct):
        time.sleep(WATCH_INTERVAL)
    os._exit(1)  # no clean-up to do: results go to the parent, which is gone


def _ready() -> int:
    return os.getpid()


@contextlib.contextmanager
def _quiet_distributed():
    """distributed logs ERROR lines of its own (a lost scheduler, a closed connection)
    above the one line procmod prints for the same event: quiet while a job runs."""
    loggers = [logging.getLogger(name) for name in ("distributed", "distributed.client", "distributed.comm")]
    levels = [logger.level for logger in loggers]
    for logger in loggers:
        logger.setLevel(logging.CRITICAL)
    try:
        yield
    finally:
        for logger, level in zip(loggers, levels):
            logger.setLevel(level)


def _has_workers(client) -> bool:
    """Whether a dask client's scheduler has a worker now (True when it cannot tell)."""
    try:
        return bool(client.scheduler_info().get("workers"))
    except Exception:  # noqa: BLE001 - a note's check must never fail the job
        return True


def shared_memory_error(exc: OSError) -> WorkerError:
    """The error for worker processes whose locks cannot be made: Python's multiprocessing
    keeps its semaphores in /dev/shm, which a container may mount read-only or tiny."""
    return WorkerError(f"cannot set up worker processes: their locks cannot be made ({exc.strerror or exc}); "
                       "Python's multiprocessing needs a writable /dev/shm (a container may mount it read-only or "
                       f"too small): mount it writable, or use {argument('workers=1')}")


@functools.lru_cache(maxsize=1)
def procmod_code_files() -> tuple:
    """``(path within the package, digest)`` of each of procmod's own source files (once a
    process): what the workers of a job must share with it (:func:`_check_worker_code`)."""
    from .core.io import fingerprint

    package = Path(__file__).resolve().parent
    files = []
    for path in sorted(package.rglob("*.py")):
        relative = path.relative_to(package)
        if any(part.startswith(".") for part in relative.parts):
            continue  # an editor's lock or backup file (.#parallel.py: a link to nothing), not procmod's code
        try:
            files.append((relative.as_posix(), fingerprint(path.read_bytes())))
        except OSError:
            files.append((relative.as_posix(), "unreadable"))
    return tuple(files)


def procmod_code_digest() -> str:
    """One digest of :func:`procmod_code_files` (a traces job compares each trace's:
    :func:`procmod.guide.traces.job_code`)."""
    from .core.io import fingerprint

    return fingerprint(" ".join(f"{name}={digest}" for name, digest in procmod_code_files()))


def _first_difference(ours: tuple, theirs: tuple) -> str:
    """Which of procmod's files differ between two :func:`procmod_code_files`, in words."""
    mine, other = dict(ours), dict(theirs)
    for name in sorted(set(mine) | set(other)):
        if mine.get(name) != other.get(name):
            where = ("only here" if name not in other else "only on the worker" if name not in mine
                     else "differs")
            count = sum(mine.get(n) != other.get(n) for n in set(mine) | set(other))
            return f"procmod/{name} {where}" + (f", and {count - 1} more" if count > 1 else "")
    return "the same files"


def _worker_code_refusal(scheduler: str, found: dict, ours: tuple) -> SchedulerError | None:
    """The refusal for the first of ``found`` (``client.run(procmod_code_files)``'s answer:
    worker address -> its files, or the error it raised) that does not run ``ours``; None
    when every worker runs it."""
    for worker, files in sorted(found.items()):
        if isinstance(files, BaseException) or not isinstance(files, (tuple, list)):
            return SchedulerError(f"dask worker {worker} of {scheduler!r} does not run this procmod: it cannot run "
                                  f"its code check (another version, or no procmod: {type(files).__name__}: "
                                  f"{str(files)[:120]}); give the workers the procmod this command runs (their "
                                  "PYTHONPATH or installed package) and rerun")
        files = tuple(tuple(f) for f in files)
        if files != ours:
            return SchedulerError(f"dask worker {worker} of {scheduler!r} runs another version of procmod's code "
                                  f"({_first_difference(ours, files)}); give the workers the procmod this command "
                                  "runs (their PYTHONPATH or installed package) and rerun")
    return None


def _check_worker_code(client, scheduler: str) -> set:
    """Refuse, in one line, a dask cluster whose workers run another procmod than this
    process (an older checkout on their PYTHONPATH, or none): their results would be
    another version's, without a word. Workers that join later are checked by
    :class:`_WorkerWatch` and by each task (:func:`_checked_call`). Returns the workers
    checked."""
    try:
        found = client.run(procmod_code_files, on_error="return")
    except Exception as exc:  # noqa: BLE001 - the cluster's own failure: said in one line
        raise SchedulerError(f"cannot ask the dask workers at {scheduler!r} which procmod they run "
                             f"({type(exc).__name__}: {str(exc)[:160]})") from None
    refusal = _worker_code_refusal(scheduler, found, procmod_code_files())
    if refusal is not None:
        raise refusal
    return set(found)


def _checked_call(expected: str, fn, *args, **kwargs):
    """``fn(*args, **kwargs)`` on a dask worker whose procmod is the client's (``expected``:
    its :func:`procmod_code_digest`), else a :class:`SchedulerError` in one line: a worker
    that joined after the connect's check (an adaptive cluster starts empty) is checked
    by its first task."""
    if procmod_code_digest() != expected:
        import socket
        raise SchedulerError(f"a dask worker (on {socket.gethostname()}, procmod at {Path(__file__).resolve().parent}) "
                             "runs another version of procmod's code than this command; give the workers the "
                             "procmod this command runs (their PYTHONPATH or installed package) and rerun")
    return fn(*args, **kwargs)


class CheckedExecutor(concurrent.futures.Executor):
    """A dask cluster's executor whose every task first checks its worker's procmod
    (:func:`_checked_call`)."""

    def __init__(self, inner: concurrent.futures.Executor):
        self.inner = inner
        self.expected = procmod_code_digest()
        self.refusal: SchedulerError | None = None  # set by _WorkerWatch when a late worker is refused

    def submit(self, fn, /, *args, **kwargs):
        return self.inner.submit(_checked_call, self.expected, fn, *args, **kwargs)

    def map(self, fn, *iterables, timeout=None, chunksize=1):
        return self.inner.map(functools.partial(_checked_call, self.expected, fn), *iterables, timeout=timeout)

    def shutdown(self, wait=True, *, cancel_futures=False):
        self.inner.shutdown(wait=wait)


WORKER_WATCH_SECONDS = 2.0  # seconds between a dask job's looks at its cluster's workers


class _WorkerWatch:
    """Watches a dask job's workers from a thread of its own, while the job waits on them.

    - A worker that joins after the connect's check runs the check too. A worker older
      than :func:`_checked_call` cannot even read its tasks (dask logs an AttributeError on
      the worker and the job waited, as with no workers): one of another procmod is
      refused, the job's tasks cancelled, and ``executor.refusal`` says why.
    - A cluster whose every worker has gone (killed, or an adaptive cluster scaled to
      none) left the job waiting without a word: ``note`` says so, once each time, naming
      the workers that closed before their check could run (an older procmod's close as
      soon as they get a task, often between two looks: the scheduler's event log has them).
    """

    def __init__(self, client, scheduler: str, executor: CheckedExecutor, checked: set, note=None):
        self.client, self.scheduler, self.executor, self.note = client, scheduler, executor, note
        self.ours = procmod_code_files()
        self.checked = set(checked)  # the workers the connect's check saw
        self.unanswered: set = set()  # workers whose connection closed before their check answered
        self.had_workers = bool(self.checked)
        self.since = float("-inf")  # the scheduler's time of the last event seen (its own clock)
        self._joined()
        self.stopped = threading.Event()
        self.thread = threading.Thread(target=self._run, name="procmod-dask-workers", daemon=True)

    def __enter__(self):
        self.thread.start()
        return self

    def __exit__(self, *exc):
        self.stopped.set()
        self.thread.join(timeout=5)

    def _workers(self) -> set | None:
        try:
            try:  # every worker: distributed 2025.4 to 2026.6 listed 5 unless asked for all
                info = self.client.scheduler_info(n_workers=-1)
            except TypeError:  # a distributed before n_workers: it lists all
                info = self.client.scheduler_info()
            return set(info.get("workers", {}))
        except Exception:  # noqa: BLE001 - a look that fails (the scheduler going) is no finding
            return None

    def _joined(self) -> set:
        """The workers that joined since the last look, from the scheduler's event log: one
        that joins and closes between two looks (a worker of an older procmod, which
        cannot read the job's tasks, closes at once) is not in the workers of either."""
        try:
            events = list(self.client.get_events("all"))
        except Exception:  # noqa: BLE001 - a look that fails is no finding
            return set()
        fresh = [message for stamp, message in events if stamp > self.since]
        self.since = max([self.since] + [stamp for stamp, _ in events])
        return {message.get("worker") for message in fresh
                if isinstance(message, dict) and message.get("action") == "add-worker"} - {None}

    def look(self) -> None:
        """One look at the workers (what the thread does every :data:`WORKER_WATCH_SECONDS`)."""
        workers = self._workers()
        if workers is None:
            return
        joined = self._joined()
        if not workers:
            if (self.had_workers or joined) and self.note is not None:
                closed = sorted((self.unanswered | joined) - self.checked)
                why = (f" ({', '.join(closed)} joined and closed before its code check could run: stopped, or a worker "
                       "of an older procmod, which closes as soon as it gets this job's tasks)" if closed else "")
                self.note(f"the dask scheduler at {self.scheduler} has no workers left{why}: the job waits until one "
                          f"joins (start one with `dask worker {self.scheduler}`), or stop it (Ctrl-C): a resumable "
                          "job keeps what it finished")
            self.had_workers = False
            self.unanswered.clear()
            return
        self.had_workers = True
        new = sorted(workers - self.checked)
        if not new:
            return
        try:
            found = self.client.run(procmod_code_files, workers=new, on_error="return")
        except Exception:  # noqa: BLE001 - gone again before it answered: looked at again next time
            return
        # a worker whose connection closed (it left, or it could not read a task and closed
        # itself) has said nothing of its procmod: looked at again while it stays
        gone = {worker for worker, answer in found.items() if isinstance(answer, (OSError, TimeoutError))}
        self.unanswered.update(gone)
        found = {worker: answer for worker, answer in found.items() if worker not in gone}
        self.checked.update(found)
        refusal = _worker_code_refusal(self.scheduler, found, self.ours)
        if refusal is not None and self.executor.refusal is None:
            self.executor.refusal = refusal
            futures = list(getattr(self.executor.inner, "_futures", ()))  # the dask futures of the job's tasks
            try:
                self.client.cancel(futures)  # their waiters then see a CancelledError: open_executor says why
            except Exception:  # noqa: BLE001 - the scheduler going: said as its loss
                pass

    def _run(self) -> None:
        while not self.stopped.wait(WORKER_WATCH_SECONDS):
            self.look()
            if self.executor.refusal is not None:
                return


HANDSHAKE_GRACE = 5.0  # seconds beyond the connect timeout for the scheduler to answer dask's handshake


def _connect(client_class, scheduler: str, timeout: float):
    """A dask client of ``scheduler``, or a :class:`SchedulerError` in one line.

    dask bounds the connection by ``timeout`` but not the handshake after it: a server that
    accepts the connection and answers something else (``python -m http.server``) kept the
    command waiting in silence for ever; one that answers with an error page had its reply
    read as a frame length (a MemoryError for 3 EiB, a traceback). The client is made in a
    thread of its own, given ``timeout`` + :data:`HANDSHAKE_GRACE` seconds."""
    made = {}

    def connect():
        try:
            made["client"] = client_class(scheduler, timeout=timeout)
        except BaseException as exc:  # noqa: BLE001 - whatever the peer's reply made of dask: said below
            made["error"] = exc

    thread = threading.Thread(target=connect, name="procmod-dask-connect", daemon=True)
    thread.start()
    thread.join(timeout + HANDSHAKE_GRACE)
    if thread.is_alive():
        raise SchedulerError(f"the dask scheduler at {scheduler!r} did not answer dask's handshake within "
                             f"{timeout + HANDSHAKE_GRACE:g} s: is a dask scheduler listening there (`dask scheduler`), "
                             "or another server?")
    exc = made.get("error")
    if isinstance(exc, (KeyboardInterrupt, SystemExit)):
        raise exc
    if exc is not None:
        hint = ("check the address and that `dask scheduler` is running"
                if isinstance(exc, (OSError, TimeoutError)) else "is a dask scheduler listening there, or another server?")
        raise SchedulerError(f"cannot reach the dask scheduler at {scheduler!r} ({type(exc).__name__}: "
                             f"{str(exc)[:200]}); {hint}") from None
    return made["client"]


@contextlib.contextmanager
def open_executor(workers: int | None = None, scheduler: str | None = None,
                  connect_timeout: float = 10.0, note=None) -> Iterator[concurrent.futures.Executor]:
    """Open an executor for the duration of a ``with`` block.

    Parameters
    ----------
    workers : int, optional
        Local worker processes; ``None`` or 1 runs inline, 0 means one per core.
    scheduler : str, optional
        Address of a dask.distributed scheduler (``tcp://host:8786``); overrides
        ``workers``.
    connect_timeout : float
        Seconds to wait for the scheduler before giving up with a :class:`SchedulerError`.
    note : callable, optional
        ``note(text)`` is told when the scheduler has no workers yet, or none left mid-job
        (the job then waits for one to join, however long: an adaptive cluster starts
        them for the work). A worker that joins mid-job running another procmod ends the
        job with a :class:`SchedulerError`.
    """
    if workers is not None and workers < 0:
        raise InvalidArgumentError(f"workers must be >= 0, got {workers}; use 0 for one per core")
    if scheduler:
        scheduler = check_scheduler(scheduler)
        try:
            from distributed import Client
        except ImportError as exc:  # pragma: no cover - dask is a dependency
            raise SchedulerError("dask.distributed is not installed; pip install 'dask[distributed]'") from exc
        with _quiet_distributed():
            client = _connect(Client, scheduler, connect_timeout)
            try:
                if note is not None and not _has_workers(client):
                    note(f"the dask scheduler at {scheduler} has no workers yet: the job waits until one joins "
                         f"(start one with `dask worker {scheduler}`)")
                checked = _check_worker_code(client, scheduler)
            except BaseException:
                client.close()
                raise
            executor = CheckedExecutor(client.get_executor(pure=False))
            try:
                with _WorkerWatch(client, scheduler, executor, checked, note):
                    yield executor
            except (concurrent.futures.CancelledError, OSError, TimeoutError) as exc:
                if executor.refusal is not None:  # a worker that joined mid-job, of another procmod
                    raise executor.refusal from None
                if client.status == "running":  # the scheduler is there: not its loss
                    raise
                raise SchedulerError(f"lost the dask scheduler at {scheduler!r} mid-job ({type(exc).__name__}); "
                                     "start it again and rerun: a resumable job keeps what it finished") from None
            finally:
                client.close()
        return
    if workers is not None:
        check_worker_limit(workers)
    if workers == 0:
        workers = default_workers()
    if workers is None or workers <= 1:
        yield InlineExecutor()
        return
    try:
        pool = concurrent.futures.ProcessPoolExecutor(max_workers=workers, initializer=_exit_with_parent,
                                                      initargs=(os.getpid(),))
    except OSError as exc:  # its queues' semaphores live in /dev/shm
        raise shared_memory_error(exc) from None
    try:
        # start the workers now, from this thread: the kernel's parent-death signal follows
        # the thread that forked a worker, and this one outlives the pool
        pool.submit(_ready).result()
        started = list((pool._processes or {}).values())  # a broken pool forgets them
    except (OSError, concurrent.futures.process.BrokenProcessPool) as exc:
        # under a process limit (ulimit -u, a container's pids.max) the workers that did
        # start waited for work forever, and the command with them
        _stop_now(pool)
        raise WorkerError(f"cannot start {workers} worker processes ({getattr(exc, 'strerror', None) or exc}); if "
                          "the machine limits its processes (ulimit -u, a container's pids limit), give fewer "
                          f"workers, or {argument('workers=1')}") from None
    with pool:
        try:
            yield pool
        except concurrent.futures.process.BrokenProcessPool as exc:
            if exc.__cause__ is not None:  # the pool's own failure (a result it could not unpickle): nothing died
                _stop_now(pool)
                raise
            # the one that died: not one the pool's own clean-up terminated (SIGTERM) before this
            lost = next((p.exitcode for p in started if p.exitcode not in (None, 0, -signal.SIGTERM)), None)
            _stop_now(pool)
            raise lost_worker_error("a worker process", lost) from None
        except BaseException:
            _stop_now(pool)
            raise


def _stop_now(pool: concurrent.futures.ProcessPoolExecutor) -> None:
    """End a pool's tasks now, rather than wait for them as leaving its block does: an
    interrupted command (Ctrl-C, SIGTERM) waited up to a task's length (24 s for traces).

    Its workers are terminated; the pool then marks its pending futures broken. Python
    3.11 raises (and prints, from the pool's thread) for a future already cancelled, as a
    caller's clean-up may have done: such a work item gets a fresh future of its own to
    be marked instead (the pool's thread still looks the item up, so it stays)."""
    workers = pool._processes or {}  # shutdown() forgets them, and the pool's thread
    thread = getattr(pool, "_executor_manager_thread", None)
    processes = list(workers.values())
    results = getattr(pool, "_result_queue", None)  # shutdown() forgets it too
    pool.shutdown(wait=False, cancel_futures=False)
    pending = getattr(pool, "_pending_work_items", None)
    if isinstance(pending, dict):
        for item in list(pending.values()):
            if item.future.cancelled():
                item.future = concurrent.futures.Future()
    for process in processes:
        process.terminate()
    for process in processes:
        process.join(timeout=5)
    # A worker ended while it wrote a large result (a model's error with a message of
    # megabytes) left the pool's thread waiting for the rest for ever, and the command hung
    # at exit, which joins that thread. With the workers gone, this process's copy of the
    # results pipe's writing end is the last: closed, the thread reads an end of file.
    writer = getattr(results, "_writer", None)
    if writer is not None:
        writer.close()
    # The pool's thread ends a broken pool's workers itself, and may fork a replacement for
    # one that died (CPython does so even under fork) before it sees the shutdown: wait for
    # it, then end what it left.
    if thread is not None:
        thread.join(timeout=5)
    for process in list(workers.values()):
        if process.is_alive():
            process.terminate()
            process.join(timeout=5)
