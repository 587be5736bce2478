"""Trace-generation jobs: resuming after SIGKILL, and running on a real dask cluster."""

import json
import signal
import subprocess
import sys
import time

import pytest

from procmod.guide import GuideError
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


@pytest.mark.parametrize("answer", [b"HTTP/1.1 400 Bad Request\r\nContent-Length: 11\r\n\r\nBad Request", None])
def test_a_server_that_is_no_dask_scheduler_is_one_line_in_bounded_time(answer, monkeypatch):
    """An error page was read as a frame length (a MemoryError traceback for 3 EiB); a
    server that took the connection and answered nothing dask reads (python -m
    http.server) kept the command waiting in silence for ever (h59)."""
    import socket
    import threading
    import time

    import procmod.parallel
    from procmod.parallel import SchedulerError

    server = socket.socket()
    server.bind(("127.0.0.1", 0))
    server.listen(4)
    held = []

    def serve():
        while True:
            try:
                conn, _ = server.accept()
            except OSError:
                return
            held.append(conn)  # kept open: a silent server
            if answer is not None:
                conn.recv(4096)
                conn.sendall(answer)

    threading.Thread(target=serve, daemon=True).start()
    monkeypatch.setattr(procmod.parallel, "HANDSHAKE_GRACE", 1.0)
    began = time.perf_counter()
    try:
        with pytest.raises(SchedulerError, match="scheduler at 'tcp://127.0.0.1:.*(another server|handshake)"):
            with open_executor(scheduler=f"tcp://127.0.0.1:{server.getsockname()[1]}", connect_timeout=1.0):
                pass
    finally:
        server.close()
        for conn in held:
            conn.close()
    assert time.perf_counter() - began < 20


def test_a_worker_running_other_code_refuses_to_make_a_trace():
    """A dask worker on an older checkout made traces unlike the job's, recorded under the
    job's code digest without a word (h59)."""
    from procmod.guide.traces import generate_trace, job_code
    from procmod.models import get_model

    ours = job_code(get_model("vines"), None)
    made = generate_trace("vines", "scribble:3", 10, 0, 0, ours)
    assert made["derivation"]["model"] == "vines"
    with pytest.raises(GuideError, match="runs other code than this traces job"):
        generate_trace("vines", "scribble:3", 10, 0, 0, (ours[0], "0" * 16))


def test_a_worker_of_an_older_procmod_is_one_line_and_leaves_nothing(tmp_path):
    """A worker whose generate_trace predates the code check takes five arguments: the
    TypeError came back as a traceback (h61)."""
    import concurrent.futures

    def old_generate_trace(model_spec, target_spec, particles, seed, index):
        return {}

    class OlderWorkers(concurrent.futures.ThreadPoolExecutor):
        def submit(self, fn, *args):
            return super().submit(lambda: old_generate_trace(*args))

    with OlderWorkers(1) as executor:
        with pytest.raises(GuideError, match="a worker runs other code than this traces job .an older procmod"):
            generate_traces("vines", "scribble", 2, tmp_path / "t", particles=10, seed=0, executor=executor)
    assert not (tmp_path / "t").exists()


def test_the_code_digest_passes_over_unreadable_and_editor_files(monkeypatch):
    """An editor's lock file (.#parallel.py, a link to nothing) made the digest a traceback."""
    from pathlib import Path

    from procmod.parallel import procmod_code_files

    clean = procmod_code_files.__wrapped__()
    read_bytes = Path.read_bytes

    def failing(path):
        if path.name == "parallel.py":
            raise OSError(13, "Permission denied")
        return read_bytes(path)

    monkeypatch.setattr(Path, "read_bytes", failing)
    assert procmod_code_files.__wrapped__() != clean  # said "unreadable", not a traceback


def test_dask_workers_of_another_procmod_are_refused_at_connect():
    """learn and strings augment ran on workers of an older checkout without a word (h59)."""
    from procmod.parallel import SchedulerError, _check_worker_code, procmod_code_files

    class Cluster:
        def __init__(self, answers):
            self.answers = answers

        def run(self, function, on_error="raise"):
            assert function is procmod_code_files
            return self.answers

    ours = procmod_code_files()
    edited = tuple((name, "0" * 16 if name == "models/vines.py" else digest) for name, digest in ours)
    _check_worker_code(Cluster({"tcp://a:1": ours}), "tcp://s:8786")  # the same code: fine
    _check_worker_code(Cluster({}), "tcp://s:8786")  # no workers yet: none to ask
    for answer, said in ((edited, r"runs another version of procmod's code \(procmod/models/vines.py differs\)"),
                         (ours + (("scratch.py", "1" * 16),), r"procmod/scratch.py only on the worker"),
                         (AttributeError("Can't get attribute 'procmod_code_files'"), "cannot run its code check")):
        with pytest.raises(SchedulerError, match=f"dask worker tcp://b:2 of 'tcp://s:8786' .*{said}"):
            _check_worker_code(Cluster({"tcp://a:1": ours, "tcp://b:2": answer}), "tcp://s:8786")
