"""Trace-generation jobs: resuming after SIGKILL, and running on a real dask cluster."""

import json
import os
import signal
import subprocess
import sys
import time

import pytest

from procmod.guide.traces import generate_traces, load_traces
from procmod.parallel import open_executor


def _derivations(folder):
    return {t["index"]: (t["target"], t["derivation"]) for t in load_traces(folder)[1]}


def test_trace_job_killed_with_sigkill_resumes_without_losing_traces(tmp_path):
    out = tmp_path / "traces"
    argv = [sys.executable, "-m", "procmod.cli", "guide", "traces", "vines", "--count", "8", "--particles", "60",
            "--seed", "5", "--workers", "1", "--out", str(out)]
    job = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    deadline = time.monotonic() + 120
    while len(list(out.glob("trace_*.json"))) < 2:
        assert job.poll() is None, "the job ended before it could be killed"
        assert time.monotonic() < deadline, "no trace appeared within two minutes"
        time.sleep(0.05)
    job.send_signal(signal.SIGKILL)
    job.wait()
    finished = {p.name: p.read_bytes() for p in out.glob("trace_*.json")}
    assert 2 <= len(finished) < 8
    # no half-written trace: every file under a trace name is whole (a kill that lands while
    # a trace is written leaves only the atomic write's hidden temporary file)
    assert all(json.loads(data) for data in finished.values())
    done = subprocess.run(argv, capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert not [p for p in out.iterdir() if p.name.startswith(".")]  # the resumed job cleared them
    assert f"{len(finished)} already there" in done.stdout
    for name, data in finished.items():
        assert (out / name).read_bytes() == data  # finished traces were kept, not redone
    # and the result is the job an uninterrupted run makes
    reference = tmp_path / "reference"
    generate_traces("vines", "scribble", 8, reference, particles=60, seed=5)
    assert _derivations(out) == _derivations(reference)


def test_traces_through_a_real_dask_local_cluster(tmp_path):
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        assert cluster.scheduler_address.startswith("tcp://127.0.0.1:")
        with open_executor(scheduler=cluster.scheduler_address) as executor:
            summary = generate_traces("vines", "scribble", 4, tmp_path / "dask", particles=40, seed=9,
                                      executor=executor)
    assert summary["made"] == 4
    generate_traces("vines", "scribble", 4, tmp_path / "inline", particles=40, seed=9)
    # distinct seeds per task: four different traces, identical to the inline run's
    got = _derivations(tmp_path / "dask")
    assert got == _derivations(tmp_path / "inline")
    assert len({json.dumps(d) for _, d in got.values()}) == 4


def test_unreachable_scheduler_is_a_clear_error():
    from procmod.parallel import SchedulerError
    with pytest.raises(SchedulerError, match="cannot reach the dask scheduler"):
        with open_executor(scheduler="tcp://127.0.0.1:1", connect_timeout=1.0):
            pass
