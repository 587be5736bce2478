"""Worker processes the machine will not start or takes away, and user errors raised on a
worker: one line each, never a hang (an adversarial pass with a process limit, kill -9
and a user's rule that fails only on a worker found each)."""

import concurrent.futures
import logging
import multiprocessing
import os
import signal
import subprocess
import sys
import textwrap
import threading

import pytest

from procmod import parallel
from procmod.parallel import WorkerError, open_executor


def _fail_to_start(parent):
    raise RuntimeError("can't start new thread")  # what a worker's initializer met under pids.max


def _die():
    os.kill(os.getpid(), signal.SIGKILL)  # what the OOM killer sends


class _TwoArgumentError(Exception):
    def __init__(self, angle, limit):  # args is (message,): pickle cannot rebuild it
        super().__init__(f"angle {angle} beyond {limit}")


def _raise_two_argument_error():
    raise _TwoArgumentError(1.5, 0)


def test_workers_that_cannot_start_are_one_line_not_a_hang(monkeypatch):
    """Under a process limit some workers started and waited for work forever, and the
    command with them, after a traceback (BlockingIOError)."""
    monkeypatch.setattr(parallel, "_exit_with_parent", _fail_to_start)
    with pytest.raises(WorkerError, match="cannot start 2 worker processes .*give fewer workers, or workers=1"):
        with open_executor(2):
            pass
    assert not multiprocessing.active_children()


def test_a_worker_killed_mid_job_is_one_line():
    with pytest.raises(WorkerError, match="a worker process ended unexpectedly \\((killed by signal 9: from|killed from) outside, "
                                          "or by the system when memory ran out\\); rerun, with fewer workers"):
        with open_executor(2) as pool:
            pool.submit(_die).result()
    assert not multiprocessing.active_children()


def test_a_result_the_caller_cannot_unpickle_is_not_a_lost_worker():
    """A pool that cannot rebuild a task's exception is 'broken' too, though nothing died:
    it was reported as a worker killed by the system."""
    # (alone, the pool breaks on it; in the whole suite it came back whole once, some library
    # loaded earlier having registered its own pickling of exceptions: either is no lost worker)
    with pytest.raises((concurrent.futures.process.BrokenProcessPool, _TwoArgumentError)) as raised:
        with open_executor(2) as pool:
            pool.submit(_raise_two_argument_error).result()
    assert not isinstance(raised.value, WorkerError)
    assert "_TwoArgumentError" in f"{type(raised.value).__name__} {raised.value.__cause__}"
    assert not multiprocessing.active_children()


@pytest.mark.parametrize("engine, str_fails", [("smc", False), ("mcmc", False), ("smc", True)])
def test_a_users_rule_failing_on_an_engine_worker_is_one_line_naming_it(engine, str_fails, tmp_path):
    """The worker's traceback travels in a note; the one line read only a process pool's.
    An exception whose own __str__ fails had its stand-in's making raise in the worker,
    which printed a 57-line traceback before the one line (h146)."""
    source = textwrap.dedent("""
        import math, multiprocessing
        from procmod import Model, Normal
        from procmod.geometry import Canvas, Segment

        class AngleError(Exception):
            def __init__(self, angle, limit):
                super().__init__("boom only in a worker")

        def chain(ctx, x, y, angle):
            angle = ctx.sample("angle", Normal(angle, math.pi / 8))
            if multiprocessing.current_process().name != "MainProcess":
                raise AngleError(angle, 0)  # its __init__ takes two: it does not come back through pickle
            x1, y1 = x + 2 * math.cos(angle), y + 2 * math.sin(angle)
            ctx.emit(Segment(x, y, x1, y1, 0.6))
            ctx.maybe("next", 0.7, chain, x1, y1, angle)

        M = Model("my-chain", "a chain", chain, root_args=lambda p: (0.0, 0.0, -math.pi / 2),
                  new_output_from=lambda p: Canvas((-12, 12, -22, 2), 50))
        """)
    if str_fails:  # (its __str__ reads what its __init__ never set)
        source = source.replace('        super().__init__("boom only in a worker")',
                                '        super().__init__("boom only in a worker")\n\n'
                                '    def __str__(self):\n        return self.missing')
        assert "self.missing" in source
    (tmp_path / "mine.py").write_text(source)
    options = ["--particles", "8"] if engine == "smc" else ["--engine", "mcmc", "--budget", "40evals",
                                                            "--init-particles", "0"]
    run = subprocess.run([sys.executable, "-m", "procmod.cli", "infer", "mine.py:M", "--target", "glyph:a",
                          *options, "--workers", "2", "--out", "run"], cwd=tmp_path, capture_output=True,
                         text=True, timeout=300)
    assert run.returncode == 2, run.stderr[-2000:]
    line = 16 if str_fails else 13
    message = "(its message could not be shown: its __str__ raised an error)" if str_fails else "boom only in a worker"
    assert run.stderr.strip() == (f"procmod: error: mine.py, line {line}, in chain: RuntimeError: AngleError: "
                                  f"{message} (an error in the model's own code)"), run.stderr[-2000:]


def _slow(seconds):
    import time
    time.sleep(seconds)
    return seconds


def test_a_dask_scheduler_lost_mid_job_is_one_line(capfd, caplog):
    """A cluster that went away mid-job ended in a CancelledError traceback, and then in
    distributed's own ERROR lines (a traceback of its own) above procmod's one line."""
    distributed = pytest.importorskip("distributed")
    from procmod.parallel import SchedulerError
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    try:
        with pytest.raises(SchedulerError, match="lost the dask scheduler at .* mid-job .*rerun"):
            with open_executor(scheduler=cluster.scheduler_address) as executor:
                future = executor.submit(_slow, 3)
                cluster.close()
                future.result()
    finally:
        cluster.close()
    err = capfd.readouterr().err
    assert "ERROR" not in err and "Traceback" not in err, err
    assert not [r for r in caplog.records if r.name.startswith("distributed") and r.levelno >= logging.ERROR]


def _raise_value_error():
    raise ValueError("a task's own error")


def test_a_tasks_error_leaves_no_worker_behind():
    """The workers were terminated but the pool's thread could fork a replacement for one
    of them before it saw the shutdown, left running after the block."""
    for _ in range(5):
        with pytest.raises(ValueError, match="a task's own error"):
            with open_executor(2) as pool:
                pool.submit(_raise_value_error).result()
        assert not multiprocessing.active_children()


@pytest.mark.parametrize("engine", ["pool", "mcmc"])
def test_a_read_only_dev_shm_is_one_line(engine, monkeypatch):
    """multiprocessing's locks live in /dev/shm; a container that mounts it read-only made
    --workers a traceback (mcmc, guide traces, learn)."""
    import multiprocessing.synchronize

    def refuse(self, *args, **kwargs):
        raise OSError(30, "Read-only file system")

    monkeypatch.setattr(multiprocessing.synchronize.SemLock, "__init__", refuse)
    with pytest.raises(WorkerError, match=r"their locks cannot be made \(Read-only file system\).*writable /dev/shm"):
        if engine == "pool":
            with open_executor(2):
                pass
        else:
            from procmod.data import target_from_spec
            from procmod.infer import Budget, mcmc
            from procmod.models import get_model
            mcmc(get_model("chain"), target_from_spec("glyph:a"), workers=2, budget=Budget(evaluations=20))


def test_a_dask_scheduler_without_workers_is_noted():
    """A job sent to a scheduler with no workers waited for ever, without a word."""
    distributed = pytest.importorskip("distributed")
    notes = []
    cluster = distributed.LocalCluster(n_workers=0, processes=False, dashboard_address=None)
    try:
        with open_executor(scheduler=cluster.scheduler_address, note=notes.append):
            pass
        assert len(notes) == 1 and "has no workers yet: the job waits until one joins" in notes[0]
        cluster.scale(1)
        cluster.wait_for_workers(1)
        with open_executor(scheduler=cluster.scheduler_address, note=notes.append) as executor:
            assert executor.submit(abs, -3).result() == 3
        assert len(notes) == 1  # a worker there: no note
    finally:
        cluster.close()


def test_overlapping_relaxed_gc_blocks_put_the_users_threshold_back():
    # engines run in threads: a block that began inside another's saved the relaxed
    # threshold as "the old one" and, ending last, left 100,000 for the rest of the process
    import gc

    from procmod.core.limits import relaxed_gc
    before = gc.get_threshold()
    first, second = relaxed_gc(), relaxed_gc()
    first.__enter__()
    second.__enter__()
    assert gc.get_threshold()[0] == 100_000
    first.__exit__(None, None, None)  # the first to begin ends first
    assert gc.get_threshold()[0] == 100_000  # the other still runs
    second.__exit__(None, None, None)
    assert gc.get_threshold() == before


def test_a_worker_forked_while_the_gc_lock_is_held_does_not_wait_for_it():
    # another thread inside relaxed_gc when a worker was forked: the child inherited the lock
    # held, and its first relaxed_gc waited forever (an MCMC worker group hung)
    import time

    import procmod.core.limits as limits
    limits._RELAXED_LOCK.acquire()
    try:
        pid = os.fork()
        if pid == 0:  # the child: as a forked worker starts
            try:
                with limits.relaxed_gc():
                    pass
            finally:
                os._exit(0)
    finally:
        limits._RELAXED_LOCK.release()
    for _ in range(200):
        done, status = os.waitpid(pid, os.WNOHANG)
        if done:
            break
        time.sleep(0.05)
    else:
        os.kill(pid, 9)
        os.waitpid(pid, 0)
        pytest.fail("the forked child still waited for the lock after 10 s")
    assert os.WEXITSTATUS(status) == 0


def test_every_task_of_a_dask_job_first_checks_its_workers_procmod():
    """A worker that joined an adaptive cluster after the connect's check ran a learn or
    strings job on another procmod without a word (h62)."""
    import concurrent.futures

    from procmod.parallel import CheckedExecutor, SchedulerError

    with concurrent.futures.ThreadPoolExecutor(1) as pool:
        checked = CheckedExecutor(pool)
        assert checked.submit(pow, 2, 5).result() == 32 and list(checked.map(abs, [-1, 2])) == [1, 2]
        checked.expected = "0" * 16  # as a worker of another version sees it
        with pytest.raises(SchedulerError, match="runs another version of procmod's code than this command"):
            checked.submit(pow, 2, 5).result()


def test_a_lost_worker_is_said_with_the_command_lines_flags():
    """The command line said 'workers=1', the API's spelling (h62)."""
    from procmod.cli import CLI_SPELLING
    from procmod.core.errors import spelled
    from procmod.parallel import lost_worker_error

    assert "workers=1" in str(lost_worker_error("SMC worker process 1", -9))
    with spelled(CLI_SPELLING):
        assert "--workers 1" in str(lost_worker_error("SMC worker process 1", -9))


def _wait_for(condition, seconds=20.0):
    import time
    deadline = time.monotonic() + seconds
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail("the condition did not hold in time")
        time.sleep(0.05)


def test_a_dask_cluster_whose_workers_all_go_mid_job_is_noted(monkeypatch):
    """A job whose dask workers all went (killed, or an adaptive cluster scaled to none)
    waited without a word (h59); a worker that joins again finishes it."""
    distributed = pytest.importorskip("distributed")
    import procmod.parallel as parallel
    monkeypatch.setattr(parallel, "WORKER_WATCH_SECONDS", 0.1)
    notes = []
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    try:
        with open_executor(scheduler=cluster.scheduler_address, note=notes.append) as executor:
            assert executor.submit(abs, -2).result() == 2 and notes == []
            cluster.scale(0)
            _wait_for(lambda: notes)
            assert len(notes) == 1 and "has no workers left: the job waits until one joins" in notes[0], notes
            future = executor.submit(abs, -3)
            cluster.scale(1)
            assert future.result(timeout=30) == 3
            assert len(notes) == 1  # one note each time the workers are gone
    finally:
        cluster.close()


_STARTED = threading.Event()


def _start_then_sleep(seconds):
    _STARTED.set()  # an in-process worker: the test sees it
    return _slow(seconds)


def _another_procmod():
    return (("parallel.py", "0" * 16),)


def _no_code_check():
    raise AttributeError("module 'procmod.parallel' has no attribute 'procmod_code_files'")


@pytest.mark.parametrize("worker_files, message", [
    (_another_procmod, r"runs another version of procmod's code \(procmod/\S+ only here, and \d+ more\)"),
    (_no_code_check, r"does not run this procmod: it cannot run its code check \(another version, or no procmod: "
                     "AttributeError"),
])
def test_a_worker_of_another_procmod_joining_mid_job_ends_it(monkeypatch, worker_files, message):
    """A worker older than the per-task check that joined mid-job could not read its tasks
    (dask logged an AttributeError on the worker) and the job waited for ever, as with no
    workers (h59): the job's watch checks each worker that joins, and refuses it."""
    distributed = pytest.importorskip("distributed")
    import procmod.parallel as parallel
    from procmod.parallel import SchedulerError
    monkeypatch.setattr(parallel, "WORKER_WATCH_SECONDS", 0.1)
    cluster = distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=False, dashboard_address=None)
    try:
        _STARTED.clear()
        with pytest.raises(SchedulerError, match=r"dask worker \S+://\S+ of '\S+' " + message):
            with open_executor(scheduler=cluster.scheduler_address) as executor:
                future = executor.submit(_start_then_sleep, 3)
                assert _STARTED.wait(20)  # its worker's check passed: the task runs
                # the worker that joins now answers the check as another procmod would
                monkeypatch.setattr(parallel, "procmod_code_files", worker_files)
                cluster.scale(2)
                future.result(timeout=30)
    finally:
        cluster.close()


class _ClusterSeen:
    """A dask client as the job's watch sees it: its workers now and the scheduler's events."""

    def __init__(self):
        self.workers, self.events = {}, []

    def scheduler_info(self):
        return {"workers": dict(self.workers)}

    def get_events(self, topic):
        assert topic == "all"
        return list(self.events)


def test_a_worker_that_joins_and_closes_between_two_looks_is_named():
    """A worker of a procmod older than the per-task check closes as soon as it gets a
    task (it cannot read it), often between two of the watch's looks; the job then waited
    with no word of it (h59)."""
    from procmod.parallel import CheckedExecutor, _WorkerWatch

    client, notes = _ClusterSeen(), []
    client.events = [(1.0, {"action": "add-client", "client": "c"})]
    watch = _WorkerWatch(client, "tcp://s:8786", CheckedExecutor(concurrent.futures.ThreadPoolExecutor(1)), set(),
                         notes.append)
    watch.look()
    assert notes == []  # no workers yet, and none gone: the connect's note said so
    client.events.append((2.0, {"action": "add-worker", "worker": "tcp://w:1"}))
    watch.look()
    assert len(notes) == 1 and "no workers left (tcp://w:1 joined and closed before its code check could run" in notes[0], notes
    watch.look()
    assert len(notes) == 1  # said once
