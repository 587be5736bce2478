"""Background jobs of the Blender add-on: one worker process per job (no bpy here).

A :class:`Job` writes ``job.json`` into a fresh folder, starts ``python -m
procmod.blender.worker FOLDER`` with the Python of procmod's environment, and is polled
(:meth:`Job.poll`, from a modal operator's timer, so Blender's UI stays live) or waited
for (:meth:`Job.wait`, for scripts and background mode). :meth:`Job.stop` asks the worker
to end early and keep its best result; :meth:`Job.kill` ends it at once.
"""

from __future__ import annotations

import atexit
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

JOB_FORMAT = "procmod-blender-job/1"
DEFAULT_PYTHON_FILE = Path(__file__).with_name("default_python.txt")  # written by package.py
KILL_AFTER_STOP = 20.0  # seconds a stopped worker may take to write its run before it is killed
OUTPUT_KEYS = ("out", "target_folder")  # the spec's fields that name folders the worker makes
# the spec's fields that name folders the operator made for this job's worker (a learn
# job's exported examples): removed with its outputs when it ends without a result
PREPARED_KEYS = ("prepared_folder",)

_RUNNING: set = set()


def find_python(preference: str = "") -> str:
    """The Python that runs workers: the add-on preference, else ``$PROCMOD_PYTHON``, else
    the one the installed add-on was packaged with, else this interpreter."""
    for candidate in (preference, os.environ.get("PROCMOD_PYTHON", "")):
        if candidate and candidate.strip():
            return _absolute(candidate.strip())
    if DEFAULT_PYTHON_FILE.exists():
        text = DEFAULT_PYTHON_FILE.read_text(encoding="utf-8").strip()
        if text:
            return _absolute(text)
    return sys.executable


def _absolute(python: str) -> str:
    """A path (``~/env/bin/python``, ``env/bin/python``) made absolute here: a worker starts
    in its job's folder, where a relative one names nothing. A bare name (``python3``) is
    left for the system's search path."""
    if os.sep not in python and not python.startswith("~"):
        return python
    return os.path.abspath(os.path.expanduser(python))


class Job:
    """One worker process and its folder.

    Parameters
    ----------
    command : str
        ``sample``, ``infer`` or ``learn`` (see :mod:`procmod.blender.worker`).
    spec : dict
        The job's fields; files it names are relative to :attr:`folder`.
    python : str
        The interpreter (:func:`find_python`).
    folder : path, optional
        Where the job's files go (a new temporary folder by default, removed by :meth:`cleanup`).
    """

    def __init__(self, command: str, spec: dict, python: str, folder=None):
        self.command = command
        self.spec = dict(spec)
        self.python = python
        self.owns_folder = folder is None
        self.folder = Path(tempfile.mkdtemp(prefix=f"procmod-{command}-")) if folder is None else Path(folder)
        self.folder.mkdir(parents=True, exist_ok=True)
        self.process = None
        self.fraction = None
        self.message = f"{command}: waiting to start"
        self.result = None
        self.started = None
        self._stop_time = None
        self._new_outputs = []

    def start(self) -> "Job":
        # the run folders this job is to make: a job that ends without a result (stopped,
        # killed, failed) removes what it left of them, so that no half-made run or learn
        # checkpoint is left for the next job to step around
        self._new_outputs = [Path(self.spec[key]) for key in OUTPUT_KEYS
                             if self.spec.get(key) and not Path(self.spec[key]).exists()]
        self._new_outputs += [Path(self.spec[key]) for key in PREPARED_KEYS if self.spec.get(key)]
        data = {"format": JOB_FORMAT, "command": self.command, **self.spec}
        (self.folder / "job.json").write_text(json.dumps(data, indent=1), encoding="utf-8")
        log = open(self.folder / "worker.log", "w", encoding="utf-8")
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        try:
            self.process = subprocess.Popen([self.python, "-m", "procmod.blender.worker", str(self.folder)],
                                            stdin=subprocess.DEVNULL, stdout=log, stderr=subprocess.STDOUT,
                                            env=env, cwd=str(self.folder))
        except OSError as exc:
            log.close()
            self._set_result({"ok": False, "error": f"cannot start the procmod worker with {self.python!r} "
                                                    f"({exc.strerror or exc}); set the add-on's Python preference"})
            return self
        finally:
            if self.process is not None:
                log.close()
        self.started = time.monotonic()
        _RUNNING.add(self)
        return self

    @property
    def done(self) -> bool:
        return self.result is not None

    @property
    def seconds(self) -> float:
        return 0.0 if self.started is None else time.monotonic() - self.started

    def poll(self) -> bool:
        """Read the worker's progress; True once the job has ended (then :attr:`result` is set)."""
        if self.result is not None:
            return True
        try:
            progress = json.loads((self.folder / "progress.json").read_text(encoding="utf-8"))
            self.fraction, self.message = progress.get("fraction"), progress.get("message", self.message)
        except (OSError, ValueError):
            pass
        code = self.process.poll()
        if code is None:
            if self._stop_time is not None and time.monotonic() - self._stop_time > KILL_AFTER_STOP:
                self.kill()
                return True
            return False
        _RUNNING.discard(self)
        self._set_result(self._read_result(code))
        return True

    def _set_result(self, result: dict) -> None:
        self.result = result
        if not result.get("ok"):
            for path in self._new_outputs:
                shutil.rmtree(path, ignore_errors=True)

    def _read_result(self, code: int) -> dict:
        try:
            return json.loads((self.folder / "result.json").read_text(encoding="utf-8"))
        except (OSError, ValueError):
            pass
        lines = [line for line in self._log().splitlines() if line.strip()]
        last = lines[-1].strip() if lines else "no output"
        if "No module named" in last and "procmod" in last:
            return {"ok": False, "error": f"{self.python} cannot import procmod ({last}); set the add-on's "
                                          "Python preference to the python of an environment where procmod "
                                          "is installed (pip install procmod)"}
        return {"ok": False, "error": f"the procmod worker ended with status {code} before it finished: {last}"}

    def _log(self) -> str:
        try:
            return (self.folder / "worker.log").read_text(encoding="utf-8", errors="replace")
        except OSError:
            return ""

    def stop(self) -> None:
        """Ask the worker to end early: an engine writes its run with the best result so far;
        other jobs end at once. A worker that has not ended after :data:`KILL_AFTER_STOP`
        seconds is killed by :meth:`poll`."""
        if self.done:
            return
        if self.command != "infer":
            self.kill()
            return
        (self.folder / "stop").touch()
        self._stop_time = time.monotonic()

    def kill(self) -> None:
        """End the worker now; the job ends without a result. A worker that had already
        ended keeps the result it wrote (a stopped Control run read by no one since, whose
        run folder had been deleted as a cancelled job's when Blender quit; h137)."""
        code = self.process.poll() if self.process is not None else None
        if self.process is not None and code is None:
            self.process.kill()
            self.process.wait()
        _RUNNING.discard(self)
        if self.result is None:
            self._set_result(self._read_result(code) if code is not None else
                             {"ok": False, "error": f"{self.command} cancelled", "cancelled": True})

    def wait(self, timeout: float | None = None, interval: float = 0.1, on_progress=None) -> dict:
        """Poll until the job ends (killing it after ``timeout`` seconds); returns the result."""
        while not self.poll():
            if on_progress is not None:
                on_progress(self)
            if timeout is not None and self.seconds > timeout:
                self.kill()
                break
            time.sleep(interval)
        return self.result

    def cleanup(self) -> None:
        """Remove the job's folder if the job made it (keep it to read ``worker.log``)."""
        if self.owns_folder and self.done:
            shutil.rmtree(self.folder, ignore_errors=True)


@atexit.register
def _kill_running() -> None:
    """Blender is quitting: no worker outlives it."""
    for job in list(_RUNNING):
        job.kill()
