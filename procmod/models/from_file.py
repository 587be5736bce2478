"""A model written in a user's own Python file, for the command line: ``FILE.py:NAME``.

``procmod infer mymodels.py:PLANT --target glyph:a`` runs the :class:`~procmod.core.Model`
named ``PLANT`` at the top level of ``mymodels.py`` (``FILE.py`` alone: the file's one
model). The file is run as a module, as ``python mymodels.py`` would run it minus its
``if __name__ == "__main__":`` block: it is the user's own code, named on their own command
line. It is registered in ``sys.modules`` under a name of its own, so that its rules pickle
by reference to the worker processes SMC and MCMC fork (``--workers``).

Every way the file can fail (missing, a syntax error, an exception while it runs, no such
name, not a Model) is one :class:`UnknownModelError` line naming the file.
"""

from __future__ import annotations

import hashlib
import importlib.machinery
import importlib.util
import os
import re
import sys
import threading
import traceback
from pathlib import Path

from ..core import Model, UnknownModelError
from ..core.errors import exception_message
from ..core.paths import remember_file_read

_SPEC = re.compile(r"^(?P<file>.+\.py)(?::(?P<name>[^:]*))?$", re.IGNORECASE)
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_]*$")


def is_model_file_spec(spec: str) -> bool:
    """Whether ``spec`` names a Python file's model (``FILE.py`` or ``FILE.py:NAME``)."""
    return isinstance(spec, str) and _SPEC.match(spec) is not None


def load_model_file(spec: str) -> Model:
    """The model ``spec`` (``FILE.py:NAME`` or ``FILE.py``) names; see the module docstring."""
    match = _SPEC.match(spec)
    if match is None:
        raise UnknownModelError(f"{spec!r} is not FILE.py or FILE.py:NAME (NAME: a Model at the file's top level)")
    path, name = Path(match["file"]), match["name"]
    if name is not None and not _NAME.match(name):
        raise UnknownModelError(f"{spec!r}: {name!r} is not a Python name; give FILE.py:NAME, NAME a Model at the "
                                "file's top level")
    if not path.is_file():
        raise UnknownModelError(f"model file {path} does not exist" if not path.exists()
                                else f"model file {path} is not a regular file")
    module = _run_module(path)
    models = {key: value for key, value in vars(module).items() if isinstance(value, Model) and not key.startswith("_")}
    if name is None:
        if not models:
            raise UnknownModelError(f"{path} defines no Model at its top level (a name bound to a procmod Model, "
                                    "e.g. MODEL = Model('mine', root)); add one")
        if len(models) != 1:
            raise UnknownModelError(f"{path} defines {len(models)} Model objects at its top level "
                                    f"({', '.join(sorted(models))}); name one: {path}:NAME")
        return next(iter(models.values()))
    value = getattr(module, name, None)
    if value is None:
        found = ", ".join(sorted(models)) or "none"
        raise UnknownModelError(f"{path} has no {name!r} at its top level (its Model objects: {found})")
    if not isinstance(value, Model):
        raise UnknownModelError(f"{path}:{name} is a {type(value).__name__}, not a procmod Model (build one with "
                                "procmod.Model(name, description, root_rule, root_args=..., new_output_from=...))")
    return value


def absolute_spec(spec: str) -> str:
    """``spec`` (``FILE.py`` or ``FILE.py:NAME``) with the file's absolute path: the same
    model from another working directory, or in a worker process started elsewhere."""
    match = _SPEC.match(spec)
    if match is None:
        raise UnknownModelError(f"{spec!r} is not FILE.py or FILE.py:NAME (NAME: a Model at the file's top level)")
    path = str(Path(match["file"]).resolve())
    return path if match["name"] is None else f"{path}:{match['name']}"


def named_spec(spec: str) -> str:
    """``spec`` as :func:`absolute_spec` gives it, with the name of the Model it means
    (``/abs/plant.py:PLANT`` for ``plant.py`` when PLANT is its one Model): two specs of
    one model read the same (its file is run once a process)."""
    spec = absolute_spec(spec)
    if _SPEC.match(spec)["name"] is not None:
        return spec
    model = load_model_file(spec)
    module = _run_module(Path(spec))
    names = [key for key, value in vars(module).items() if value is model and not key.startswith("_")]
    return f"{spec}:{names[0]}" if names else spec


_USER_FILES: set = set()  # resolved paths of the model files this process has run


def user_code_error(exc: BaseException) -> str | None:
    """One line for an exception raised in a user's model file while its model runs
    (``FILE.py, line N, in RULE: Type: message``), or None when no frame of the traceback
    lies in such a file (then it is procmod's own bug, and keeps its traceback)."""
    if (isinstance(exc, RuntimeError) and isinstance(exc.__cause__, StopIteration)
            and "raised StopIteration" in str(exc.args[:1])):
        # PEP 479: a StopIteration from the user's rule, turned into a RuntimeError by the
        # engine's generator it passed through; the user's frames are the cause's
        exc = exc.__cause__
    frames = [(f.filename, f.lineno, f.name) for f in traceback.extract_tb(exc.__traceback__)]
    remote = getattr(exc.__cause__, "tb", None)  # a process pool's worker: its traceback, as text
    # an SMC or MCMC worker's: in a note (procmod.parallel.note_worker_traceback)
    notes = [n for n in getattr(exc, "__notes__", ()) if isinstance(n, str)]
    for text in ([remote] if isinstance(remote, str) else []) + notes:
        frames += [(m[1], int(m[2]), m[3]) for m in _FRAME_LINE.finditer(text)]
    frames = [f for f in frames if f[0] in _USER_FILES or str(Path(f[0]).resolve()) in _USER_FILES]
    if not frames:
        return None
    filename, line, function = frames[-1]
    if isinstance(exc, SystemExit):  # sys.exit() in a rule had ended the run with no word, with its status
        return (f"{Path(filename).name}, line {line}, in {function}: the model called sys.exit({_shown(exc.code)}) "
                "while it ran; a model cannot end procmod's run: raise an exception for an error (an error in the "
                "model's own code)")
    message = exception_message(exc)
    return (f"{Path(filename).name}, line {line}, in {function}: {type(exc).__name__}"
            f"{': ' + message if message else ''} (an error in the model's own code)")


def _shown(value) -> str:
    """``repr(value)``, or its type's name where the value's own ``__repr__`` fails."""
    try:
        return repr(value)
    except Exception:  # noqa: BLE001 - the user's class
        return f"<a {type(value).__name__}>"


_FRAME_LINE = re.compile(r'^\s*File "(.+)", line (\d+), in (\S+)$', re.MULTILINE)


# A lock per model file, held while it is looked up and run: a dask worker runs tasks in
# threads, and two tasks of one job loading one file at once had the second take the
# module the first had registered but not yet run (no Model in it: "defines no Model at
# its top level"), or lose it when the first's run failed. One lock per file, not one for
# all: a model file whose import starts a thread that loads another file and waits for it
# would wait for ever (h158). Reentrant: a model file may load itself.
_FILE_LOCKS: dict = {}
_FILE_LOCKS_GUARD = threading.Lock()  # over _FILE_LOCKS and sys.path's edits; never held while user code runs


def _forget_locks_after_fork() -> None:
    """A child forked while another thread held a lock holds it for ever (no thread of its
    own will let go of it): a process pool's worker then hung at its first model file
    (h158). The child starts with none."""
    global _FILE_LOCKS_GUARD
    _FILE_LOCKS.clear()
    _FILE_LOCKS_GUARD = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_forget_locks_after_fork)


def _run_module(path: Path):
    """``path`` run as a module of its own (once per process and file; one thread at a
    time per file, :data:`_FILE_LOCKS`)."""
    resolved = path.resolve()
    with _FILE_LOCKS_GUARD:
        lock = _FILE_LOCKS.setdefault(resolved, threading.RLock())
    with lock:
        return _run_module_locked(path)


def _run_module_locked(path: Path):
    resolved = path.resolve()
    digest = hashlib.sha256(os.fsencode(resolved)).hexdigest()[:12]  # (a name's non-UTF-8 bytes too)
    module_name = f"procmod_user_{re.sub(r'[^0-9A-Za-z_]', '_', path.stem)}_{digest}"
    if module_name in sys.modules:
        return sys.modules[module_name]
    # read as Python source whatever its suffix ("Plant.PY": no loader is found for it by name)
    loader = importlib.machinery.SourceFileLoader(module_name, str(resolved))
    spec = importlib.util.spec_from_file_location(module_name, resolved, loader=loader)
    module = importlib.util.module_from_spec(spec)
    sys.modules[module_name] = module  # before running it: its dataclasses and pickles look it up
    with _FILE_LOCKS_GUARD:
        if str(resolved.parent) not in sys.path:  # as python FILE.py does: it imports its neighbours
            sys.path.insert(0, str(resolved.parent))
    _USER_FILES.add(str(resolved))
    remember_file_read(resolved)  # an output folder that holds it is never replaced (--overwrite)
    try:
        spec.loader.exec_module(module)
    except SyntaxError as exc:
        del sys.modules[module_name]
        where = f", line {exc.lineno}" if exc.lineno is not None else ""  # (a NUL byte in the file: no line)
        raise UnknownModelError(f"{path}{where}: {exc.msg}; fix the model file") from None
    except BaseException as exc:  # the user's code: anything it raises is its own error
        del sys.modules[module_name]
        if isinstance(exc, KeyboardInterrupt):
            raise
        frames = [f for f in traceback.extract_tb(exc.__traceback__) if Path(f.filename).resolve() == resolved]
        where = f", line {frames[-1].lineno}" if frames else ""
        message = exception_message(exc)
        shadowed = _shadowed_neighbour(exc, resolved.parent)
        fix = (f"{shadowed} beside it is hidden by Python's own module {shadowed.removesuffix('.py')}: rename it, "
               "and the imports of it" if shadowed else "fix the model file")
        raise UnknownModelError(f"{path}{where}: running it raised {type(exc).__name__}"
                                f"{': ' + message if message else ''}; {fix}") from None
    return module


def _shadowed_neighbour(exc: BaseException, folder: Path) -> str | None:
    """The name of a file or package beside a model file that a failed import meant but
    Python's standard library module of the same name hid (``from types import LENGTH`` with
    a ``types.py`` beside the model: the standard library's ``types`` is imported, and had
    been blamed without a word on the model file), or None."""
    if not isinstance(exc, ImportError) or not isinstance(exc.name, str):
        return None
    top = exc.name.split(".", 1)[0]
    if top not in getattr(sys, "stdlib_module_names", ()):
        return None
    for candidate in (f"{top}.py", top):
        if (folder / candidate).exists():
            return candidate
    return None


__all__ = ["absolute_spec", "is_model_file_spec", "load_model_file", "user_code_error"]
