"""A model file's errors on worker processes and threads: one line, as in one process.

- a traces job's worker whose model raised an exception pickle cannot send back ended in a
  BrokenProcessPool (or PicklingError) traceback;
- two threads of a dask worker loading one model file at once had one find no Model in it;
- a model drawing at 1e300 was told its best had parts that intersect, which a proxy
  target forbids (its out-of-bounds penalty had overflowed to infinity).
"""

import concurrent.futures
import sys
import time

import pytest

from procmod.cli import main

RAISING_MODEL = """
import math
from procmod import Model, Normal
from procmod.geometry import Canvas, Segment

{error_class}

def root(ctx, x, y):
    angle = ctx.sample("angle", Normal(0.0, 1.0))
    ctx.emit(Segment(x, y, x + math.cos(angle), y + math.sin(angle), 0.6))
    {raise_line}

def root_args(p):
    return (0.0, 0.0)

def new_output(p):
    return Canvas((-12, 12, -22, 2), 50)

MODEL = Model("raising", "raises", root, root_args=root_args, new_output_from=new_output)
"""

TWO_ARGUMENTS = """class TwoArgumentError(Exception):
    def __init__(self, angle, limit):  # args is (message,): pickle cannot rebuild it
        super().__init__(f"angle {angle} beyond {limit}")"""

HOLDS_A_LAMBDA = """class HoldsALambda(Exception):
    def __init__(self, message):
        super().__init__(message)
        self.check = lambda: True  # pickle cannot send it"""


@pytest.mark.parametrize("error_class, raise_line, expected", [
    (TWO_ARGUMENTS, "raise TwoArgumentError(1.5, 0)", "TwoArgumentError: angle 1.5 beyond 0"),
    (HOLDS_A_LAMBDA, "raise HoldsALambda('out of range')", "HoldsALambda: out of range"),
])
def test_an_exception_pickle_cannot_send_from_a_traces_worker_is_the_inline_line(error_class, raise_line,
                                                                                  expected, tmp_path, capsys):
    source = RAISING_MODEL.format(error_class=error_class, raise_line=raise_line)
    (tmp_path / "raising.py").write_text(source)
    line = source.splitlines().index(f"    {raise_line}") + 1
    inline = f"procmod: error: raising.py, line {line}, in root: {expected} (an error in the model's own code)"
    for workers in ("1", "2"):
        out = tmp_path / f"traces{workers}"
        code = main(["guide", "traces", str(tmp_path / "raising.py"), "--count", "2", "--particles", "4",
                     "--out", str(out), "--workers", workers])
        err = capsys.readouterr().err
        assert (code, err.strip()) == (2, inline), err[-3000:]
        assert not out.exists()  # nothing made: nothing left


SLOW_MODEL = """
import time
from procmod import Model
from procmod.geometry import Canvas, Segment

time.sleep(0.05)  # a model file whose imports take a while: another thread comes in meanwhile

def root(ctx, x, y):
    ctx.emit(Segment(x, y, x + 1.0, y, 0.6))

def root_args(p):
    return (0.0, 0.0)

def new_output(p):
    return Canvas((-12, 12, -22, 2), 50)

MODEL = Model("slow-loading", "loads slowly", root, root_args=root_args, new_output_from=new_output)
"""


def test_threads_loading_one_model_file_at_once_all_get_its_model(tmp_path):
    """A dask worker's threads run two tasks of one job at once: the second took the module
    the first had registered but not yet run ("defines no Model at its top level")."""
    from procmod.models.from_file import load_model_file

    for attempt in range(3):
        folder = tmp_path / f"attempt{attempt}"
        folder.mkdir()
        path = folder / "slow_model.py"  # a fresh file (and module name) each time
        path.write_text(SLOW_MODEL)
        with concurrent.futures.ThreadPoolExecutor(8) as pool:
            futures = [pool.submit(load_model_file, str(path)) for _ in range(8)]
            models = [future.result() for future in futures]
        assert all(model is models[0] for model in models) and models[0].name == "slow-loading"
        assert sys.path.count(str(folder.resolve())) == 1


def test_a_model_file_whose_import_loads_another_in_a_thread_does_not_hang(tmp_path):
    """One lock for every model file held while one ran: a file whose import started a
    thread that loaded another model file and waited for it waited for ever (h158)."""
    import threading

    from procmod.models.from_file import load_model_file

    (tmp_path / "other.py").write_text(SLOW_MODEL)
    other = str(tmp_path / "other.py")
    (tmp_path / "threaded.py").write_text(
        "import threading\nfrom procmod.models.from_file import load_model_file\nbox = {}\n"
        f"t = threading.Thread(target=lambda: box.setdefault('m', load_model_file({other!r})))\n"
        "t.start()\nt.join()\nMODEL = box['m']\n")
    found = {}
    loader = threading.Thread(target=lambda: found.setdefault("m", load_model_file(str(tmp_path / "threaded.py"))),
                              daemon=True)
    loader.start()
    loader.join(20)
    assert not loader.is_alive() and found["m"].name == "slow-loading"


def test_a_process_forked_while_another_thread_loads_a_model_file_can_load_one(tmp_path):
    """A child forked while a thread of its parent held the loading lock inherited it held,
    by a thread it does not have: its first model file waited for ever (h158)."""
    import multiprocessing
    import threading

    from procmod.models.from_file import load_model_file

    (tmp_path / "slow.py").write_text(SLOW_MODEL.replace("time.sleep(0.05)", "time.sleep(1.5)"))
    (tmp_path / "other.py").write_text(SLOW_MODEL)
    loading = threading.Thread(target=load_model_file, args=(str(tmp_path / "slow.py"),), daemon=True)
    loading.start()
    for _ in range(500):  # until the thread runs slow.py (registered before it runs), holding its lock
        if any(name.startswith("procmod_user_slow_") for name in list(sys.modules)):
            break
        time.sleep(0.01)
    context = multiprocessing.get_context("fork")
    names = context.Queue()
    child = context.Process(target=_put_model_name, args=(str(tmp_path / "other.py"), names))
    child.start()
    child.join(30)
    hung = child.is_alive()
    if hung:
        child.terminate()
    loading.join(30)
    assert not hung and names.get(timeout=10) == "slow-loading"


def _put_model_name(path: str, names) -> None:
    from procmod.models.from_file import load_model_file

    names.put(load_model_file(path).name)


def _far_root(ctx, x, y):
    from procmod import Normal
    from procmod.geometry import Segment

    d = ctx.sample("d", Normal(0.0, 1.0))
    ctx.emit(Segment(1e300, 1e300 + d, -1e300, -1e300, 0.6))


def _far_root_args(p):
    return (0.0, 0.0)


def _far_new_output(p):
    from procmod.geometry import Canvas

    return Canvas((-12, 12, -22, 2), 50)


def test_parts_at_1e300_are_said_to_be_far_outside_not_intersecting():
    """The zero likelihood came from the out-of-bounds penalty, (1e300 / 24)^2 / 1e-6 = inf:
    the only note named parts that intersect, which a proxy target forbids."""
    from procmod import Model
    from procmod.data import target_from_spec
    from procmod.infer import smc
    from procmod.infer.common import RULED_OUT_NOTE

    model = Model("far-away", "draws at 1e300", _far_root, root_args=_far_root_args,
                  new_output_from=_far_new_output)
    result = smc(model, target_from_spec("glyph:a"), particles=10, seed=0)
    assert RULED_OUT_NOTE in result.notes
    assert "out-of-bounds penalty is infinite" in RULED_OUT_NOTE
    far = [note for note in result.notes if "so far outside the canvas" in note]
    assert len(far) == 1 and "coordinate of 1e300" in far[0] and "rule's arithmetic" in far[0], result.notes


def test_parts_beyond_a_canvas_by_a_finite_penalty_get_no_such_note():
    from procmod.geometry import Canvas, Segment
    from procmod.infer.common import far_outside

    canvas = Canvas((-12, 12, -22, 2), 50)
    canvas.add(Segment(0.0, 0.0, 1e6, 0.0, 0.6))
    assert not far_outside(canvas)
    canvas.add(Segment(0.0, 0.0, 1e300, 0.0, 0.6))
    assert far_outside(canvas)
    # where the default penalty (the square over 0.001^2) turns infinite: not only where the square does (h158)
    from procmod.data import target_from_spec

    target = target_from_spec("glyph:a")
    for reach in (1e150, 1e151, 1.3e151, 1.4e151, 1e153, 1e155):
        canvas = Canvas((-12, 12, -22, 2), 50)
        canvas.add(Segment(0.0, 0.0, reach, 0.0, 0.6))
        assert far_outside(canvas) == (target.log_likelihood(canvas) == float("-inf")), reach


def test_a_worker_error_of_procmods_own_code_keeps_its_stand_in():
    """Only the model file's own code's error becomes its one line; one of procmod's keeps
    portable_error's RuntimeError stand-in (a bug keeps its traceback)."""
    from procmod.parallel import portable_model_error

    class Unpicklable(Exception):
        def __init__(self, a, b):
            super().__init__("procmod's own")

    try:
        raise Unpicklable(1, 2)
    except Unpicklable as exc:
        error = portable_model_error(exc, "a test")
    assert type(error) is RuntimeError and "Unpicklable: procmod's own" in str(error)
    ok = ValueError("picklable")
    assert portable_model_error(ok, "a test") is ok


@pytest.mark.parametrize("raise_line, expected", [
    ("raise SystemExit(3)", "the model called sys.exit(3) while it ran; a model cannot end procmod's run: raise an "
                            "exception for an error (an error in the model's own code)"),
    ("raise KeyboardInterrupt", "KeyboardInterrupt (an error in the model's own code)"),
])
def test_a_model_ending_the_run_on_a_dask_worker_is_the_inline_line(raise_line, expected, tmp_path, capsys):
    """sys.exit() or a KeyboardInterrupt in a rule killed the dask worker that ran it, and
    the job ended in a KilledWorker traceback after dask had tried four (h158). sys.exit()
    is one process's line; a KeyboardInterrupt in one process is taken for Ctrl-C
    ("procmod: interrupted"), on a worker for the model's error."""
    distributed = pytest.importorskip("distributed")
    source = RAISING_MODEL.format(error_class="", raise_line=raise_line)
    (tmp_path / "raising.py").write_text(source)
    line = source.splitlines().index(f"    {raise_line}") + 1
    inline = f"procmod: error: raising.py, line {line}, in root: {expected}"
    with distributed.LocalCluster(n_workers=1, threads_per_worker=1, processes=True, host="127.0.0.1",
                                  dashboard_address=None) as cluster:
        runs = [["--scheduler", cluster.scheduler_address]]
        if "SystemExit" in raise_line:
            runs.append(["--workers", "1"])
        for k, where in enumerate(runs):
            out = tmp_path / f"traces{k}"
            code = main(["guide", "traces", str(tmp_path / "raising.py"), "--count", "2", "--particles", "4",
                         "--out", str(out), *where])
            err = capsys.readouterr().err
            assert (code, err.strip().splitlines()[-1:]) == (2, [inline]), err[-3000:]
            assert not out.exists()


def test_a_model_error_of_megabytes_from_pool_workers_ends_the_command(tmp_path):
    """Two workers raising an error of 16 MB each: the first ended the job, and the other,
    ended while it wrote its own, left the pool's thread waiting for the rest for ever,
    and the command hung at exit after printing its line (h158)."""
    import subprocess

    raise_line = 'raise ValueError("x" * 16_000_000)'
    source = RAISING_MODEL.format(error_class="", raise_line=raise_line)
    (tmp_path / "raising.py").write_text(source)
    line = source.splitlines().index(f"    {raise_line}") + 1
    argv = [sys.executable, "-m", "procmod", "guide", "traces", str(tmp_path / "raising.py"), "--count", "2",
            "--particles", "4", "--out", str(tmp_path / "traces"), "--workers", "2"]
    try:
        done = subprocess.run(argv, capture_output=True, text=True, timeout=90)
    except subprocess.TimeoutExpired:
        pytest.fail("the command did not end within 90 s")
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2 and len(lines) == 1, done.stderr[-2000:]
    assert lines[0].startswith(f"procmod: error: raising.py, line {line}, in root: ValueError: xxx")
    assert len(lines[0]) < 1000  # cut for the terminal
    assert not (tmp_path / "traces").exists()
