"""procmod on machines unlike the development one (sweep 33): read-only installs, homes
that cannot be written."""

import os
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

# Runs procmod's command line with every folder outside TMPDIR unwritable to tempfile, the
# way numba tests a cache folder: as a read-only install run with an unwritable home folder
# is (root writes anywhere, so chmod cannot show it in a test run as root).
READ_ONLY_ELSEWHERE = """
import os, runpy, sys, tempfile
allowed = os.path.realpath(os.environ["TMPDIR"])
real = tempfile.TemporaryFile

def refuse(*args, dir=None, **kwargs):
    if dir is not None and not os.path.realpath(dir).startswith(allowed + os.sep):
        raise PermissionError(13, "Permission denied", dir)
    return real(*args, dir=dir, **kwargs)

tempfile.TemporaryFile = refuse
sys.argv = ["procmod", *sys.argv[1:]]
runpy.run_module("procmod", run_name="__main__")
"""


def test_a_read_only_install_with_an_unwritable_home_runs_and_leaves_no_cache_behind(tmp_path):
    """numba found no folder to cache procmod's kernels in (neither the install's
    __pycache__ nor ~/.cache/numba writable) and importing procmod raised a RuntimeError:
    a traceback for every command. The kernels now go to a temporary folder, removed at exit."""
    temp = tmp_path / "tmp"
    temp.mkdir()
    env = {k: v for k, v in os.environ.items() if not k.startswith("NUMBA_")}
    env.update(TMPDIR=str(temp), HOME=str(tmp_path / "home"), PYTHONPATH=str(ROOT))
    env.pop("XDG_CACHE_HOME", None)
    done = subprocess.run([sys.executable, "-c", READ_ONLY_ELSEWHERE, "sample", "chain", "-n", "1", "--size", "16",
                           "--out", str(tmp_path / "s")], env=env, cwd=tmp_path, capture_output=True, text=True,
                          timeout=600)
    assert done.returncode == 0, done.stderr
    assert "Traceback" not in done.stderr
    assert (tmp_path / "s" / "sample_000.json").exists()
    assert list(temp.iterdir()) == []  # the temporary kernel cache went with the process


def test_a_ctrl_c_that_a_library_dropped_ends_the_command_as_an_interrupt(tmp_path, monkeypatch, capsys):
    """Ctrl-C while numba compiled a kernel (a first run: no cached machine code) arrived in
    a ctypes callback, which printed the KeyboardInterrupt and dropped it; the compile then
    failed with a RuntimeError of its own, and the command ended with a 60-line traceback
    and status 1 in place of "procmod: interrupted" (seen on a 1-core machine)."""
    import ctypes
    import signal

    import procmod.cli as cli

    def compiling(args):
        ctypes.CFUNCTYPE(None)(lambda: signal.raise_signal(signal.SIGINT))()  # numba's object-cache callback
        raise RuntimeError("no compiled object yet for <Library '_part_count'>")

    monkeypatch.setitem(cli._COMMANDS, "sample", compiling)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)  # Python's own, as a command starts with
    try:
        code = cli.main(["sample", "chain", "-n", "1", "--out", str(tmp_path / "s")])
        assert signal.getsignal(signal.SIGINT) is signal.default_int_handler  # back after the command
    finally:
        signal.signal(signal.SIGINT, before)
    err = capsys.readouterr().err
    assert code == 130 and err == "procmod: interrupted\n", err  # (nor ctypes's "Exception ignored")
    assert not (tmp_path / "s").exists()


def test_a_ctrl_c_that_a_library_dropped_still_stops_the_command(tmp_path, monkeypatch, capsys):
    """The same dropped Ctrl-C where the library's work then went on: the command ran to the
    end of its budget (a minute of infer's --budget 60s) as if no key had been pressed."""
    import ctypes
    import signal
    import time

    import procmod.cli as cli

    def compiling(args):
        ctypes.CFUNCTYPE(None)(lambda: signal.raise_signal(signal.SIGINT))()
        deadline = time.monotonic() + 5
        while time.monotonic() < deadline:  # the run the budget allows
            time.sleep(0.01)
        print("finished")

    monkeypatch.setitem(cli._COMMANDS, "sample", compiling)
    before = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        code = cli.main(["sample", "chain", "-n", "1", "--out", str(tmp_path / "s")])
    finally:
        signal.signal(signal.SIGINT, before)
    out, err = capsys.readouterr()
    assert code == 130 and err == "procmod: interrupted\n" and "finished" not in out, (code, out, err)


def test_commands_in_threads_leave_the_unraisable_hook_alone(tmp_path, monkeypatch):
    """Two commands run in threads, overlapping: each had put back the hook it found, and
    the later left the earlier's installed for good (review h174). Signals reach the main
    thread only: a command in another changes nothing global."""
    import threading
    import time

    import procmod.cli as cli

    monkeypatch.setitem(cli._COMMANDS, "sample", lambda args: time.sleep(float(args.out.rsplit("_", 1)[1])))
    hook = sys.unraisablehook
    seen = []
    first = threading.Thread(target=lambda: seen.append(cli.main(["sample", "chain", "--out", f"{tmp_path}/a_0.6"])))
    second = threading.Thread(target=lambda: seen.append(cli.main(["sample", "chain", "--out", f"{tmp_path}/b_1.0"])))
    first.start()
    time.sleep(0.2)
    assert sys.unraisablehook is hook  # (not even while they run)
    second.start()
    first.join()
    second.join()
    assert seen == [0, 0] and sys.unraisablehook is hook
