"""Killed jobs leave nothing running and resume exactly (issue 28.4): pool workers end
when their parent is SIGKILLed; a resumed guide training ends with the loss history of an
uninterrupted one."""

import os
import signal
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from procmod.guide.traces import generate_traces
from procmod.guide.train import train_guide
from procmod.models import get_model

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="POSIX signals and process states")


def _alive(pid: int) -> bool:
    """True while ``pid`` runs (a zombie, exited but not reaped by its new parent, is gone)."""
    try:
        with open(f"/proc/{pid}/status") as handle:
            return not any(line.startswith("State:") and "Z" in line.split()[1] for line in handle)
    except FileNotFoundError:
        return False
    except OSError:
        try:
            os.kill(pid, 0)
        except ProcessLookupError:
            return False
        return True


# A parent that opens a pool, has each worker report its pid and then block for a minute
# (a long task), prints the worker pids and waits to be killed.
PARENT = textwrap.dedent("""
    import concurrent.futures, os, sys, time
    from procmod import parallel

    def task(i):
        time.sleep(60)
        return i

    if __name__ == "__main__":
        mode = sys.argv[1]
        if mode == "open_executor":
            pools = parallel.open_executor(workers=2)
            pool = pools.__enter__()
        else:  # the watcher thread alone, without prctl
            pool = concurrent.futures.ProcessPoolExecutor(
                2, initializer=parallel._exit_with_parent, initargs=(os.getpid(), False))
            pool.submit(os.getpid).result()
        for i in range(2):
            pool.submit(task, i)
        while len(pool._processes) < 2:
            time.sleep(0.01)
        print(" ".join(map(str, sorted(pool._processes))), flush=True)
        time.sleep(120)
""")


@pytest.mark.parametrize("mode", ["open_executor", "watcher_only"])
def test_pool_workers_exit_when_their_parent_is_killed(tmp_path, mode):
    script = tmp_path / "parent.py"
    script.write_text(PARENT)
    env = dict(os.environ, PYTHONPATH=str(Path(__file__).resolve().parents[1]))
    parent = subprocess.Popen([sys.executable, str(script), mode], stdout=subprocess.PIPE, text=True, env=env)
    workers = []
    try:
        workers = [int(p) for p in parent.stdout.readline().split()]
        assert len(workers) == 2 and all(_alive(p) for p in workers)
        time.sleep(0.5)  # the tasks are running
        parent.send_signal(signal.SIGKILL)
        parent.wait()
        deadline = time.monotonic() + 10
        while any(_alive(p) for p in workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert not [p for p in workers if _alive(p)], "workers outlived their killed parent"
    finally:
        if parent.poll() is None:
            parent.kill()
        for pid in workers:  # never leave one behind, even when the check failed
            if _alive(pid):
                os.kill(pid, signal.SIGKILL)


def test_resumed_training_ends_with_the_loss_history_of_an_uninterrupted_run(tmp_path):
    model = get_model("lightning")
    traces = tmp_path / "traces"
    generate_traces("lightning", "scribble", 4, traces, particles=20, seed=2)
    _, whole = train_guide(model, traces, tmp_path / "whole", iterations=300, checkpoint_every=100)

    class Killed(Exception):
        pass

    def kill_at_300(step, loss):
        if step == 300:  # the progress report of the last step: resumed from the checkpoint at 200
            raise Killed()

    with pytest.raises(Killed):
        train_guide(model, traces, tmp_path / "resumed", iterations=300, checkpoint_every=100,
                    progress=kill_at_300)
    _, resumed = train_guide(model, traces, tmp_path / "resumed", iterations=300, checkpoint_every=100)
    assert [s for s, _ in resumed["curve"]] == [s for s, _ in whole["curve"]] == [100, 200, 300]
    # one process, the same arithmetic in the same order: equal up to the last bits
    for (_, a), (_, b) in zip(resumed["curve"], whole["curve"]):
        assert a == pytest.approx(b, rel=1e-12, abs=0)


@pytest.mark.parametrize("command, signum, code, line", [
    (["sample", "vines", "-n", "20000", "--size", "256"], signal.SIGTERM, 143, "procmod: terminated"),
    (["infer", "vines", "--target", "glyph:a", "--particles", "40", "--workers", "2", "--budget", "60s"],
     signal.SIGTERM, 143, "procmod: terminated"),
    (["infer", "vines", "--target", "glyph:a", "--particles", "40", "--workers", "2", "--budget", "60s"],
     signal.SIGINT, 130, "procmod: interrupted")])
def test_terminated_or_interrupted_runs_leave_nothing_behind(tmp_path, command, signum, code, line):
    """SIGTERM (kill, timeout, a scheduler) left a run's hidden .OUT.*.tmp folder, which no
    later run removed; Ctrl-C, sent to the whole process group, printed the SMC workers'
    KeyboardInterrupt tracebacks. Both now stop as Ctrl-C did in the coordinator: one
    line, nothing left, no worker running."""
    out = tmp_path / "run"
    job = subprocess.Popen([sys.executable, "-m", "procmod.cli", *command, "--out", str(out)], cwd=tmp_path,
                           stderr=subprocess.PIPE, text=True, start_new_session=True,
                           preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
    deadline = time.time() + 60
    while time.time() < deadline and not any(p.name.startswith(".run.") for p in tmp_path.iterdir()) \
            and "infer" not in command:
        time.sleep(0.05)  # sample: until its temporary folder exists
    time.sleep(4 if "infer" in command else 0.5)
    workers = subprocess.run(["pgrep", "-g", str(job.pid)], capture_output=True, text=True).stdout.split()
    os.killpg(job.pid, signum)
    err = job.communicate(timeout=60)[1]
    assert job.returncode == code and err.strip() == line, err
    assert sorted(p.name for p in tmp_path.iterdir()) == []
    time.sleep(0.5)
    assert not [pid for pid in map(int, workers) if _alive(pid)]


def _sleep(seconds):
    time.sleep(seconds)
    return seconds


def test_an_interrupted_pool_ends_its_tasks_and_says_nothing(capfd):
    """Leaving an executor block by an exception (Ctrl-C, SIGTERM, an error) waited for the
    tasks running (a SIGTERM'd trace job took 24 s to stop); now its workers end at once,
    even when the caller has cancelled futures first (Python 3.11's pool thread printed a
    traceback for those), and none is left behind."""
    from procmod.parallel import open_executor

    t0 = time.perf_counter()
    with pytest.raises(ValueError, match="the real error"):
        with open_executor(workers=2) as pool:
            futures = [pool.submit(_sleep, 30) for _ in range(8)]
            pids = list(pool._processes)
            time.sleep(0.5)
            for f in futures[4:]:
                f.cancel()
            raise ValueError("the real error")
    assert time.perf_counter() - t0 < 20  # not the 30 s a running task takes
    time.sleep(0.5)
    assert not [pid for pid in pids if _alive(pid)]
    assert "Traceback" not in capfd.readouterr().err
