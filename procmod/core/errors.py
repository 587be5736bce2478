"""The error types procmod raises for problems a user can cause.

Every user-caused error is a :class:`ProcmodError`; its message says what was wrong and
how to fix it, so the command-line tool can print it as one line and exit with status 2.

Messages name the Python API's arguments (``out``, ``overwrite=True``), never
command-line flags: only the command line speaks of flags. Where a message names an
argument a front end sets for its user, it goes through :func:`argument`, and the front
end says how its user knows that argument (:func:`spelled`): ``procmod.cli.main`` spells
``out`` as ``--out`` while it runs a command, so the same check reads right from Python
and from the shell.
"""

import contextlib
import json
import numbers
import re
from contextvars import ContextVar
from types import MappingProxyType
from typing import Callable

_SPELLING: ContextVar = ContextVar("procmod_argument_spelling", default=MappingProxyType({}))


def cut_text(text: str, limit: int = 200) -> str:
    """``text`` cut to ``limit`` characters for a message (an input may hold a 100 KB string)."""
    return text if len(text) <= limit else text[:limit - 3] + "..."


_CONTROL = re.compile(r"[\x00-\x1f\x7f-\x9f]")


def printable(text: str) -> str:
    """``text`` with control characters (a line break, a terminal's escape codes, a CR
    that would overwrite the line) shown as escapes (``\\n``, ``\\x1b``): names from
    input files printed on one line of output stay one line."""
    return _CONTROL.sub(lambda m: m.group().encode("unicode_escape").decode("ascii"), str(text))


def whole_number(value) -> int | None:
    """``value`` as a plain ``int`` when it is a whole number of an integer type (numpy's
    too, e.g. from ``np.arange``; never a bool), else None. Argument checks take their
    counts and seeds through it, so that what they record (settings.json) is plain JSON."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        return None
    return int(value)


def checked_count(name: str, value, least: int = 1, most: int | None = None) -> int:
    """``value`` as a plain int if it is a whole number (numpy's too) from ``least`` to
    ``most``, else an InvalidArgumentError naming the argument ``name``."""
    count = whole_number(value)
    if count is None or count < least or (most is not None and count > most):
        span = f"from {least:,} to {most:,}" if most is not None else f"{least:,} or more"
        raise InvalidArgumentError(f"{argument(name)} must be a whole number {span}, got {shown_value(value)}")
    return count


def check_real(name: str, value, expected: str, holds: Callable[[float], bool]) -> float:
    """``value`` as a plain float if it is a real number (numpy's too) for which
    ``holds`` is true, else an InvalidArgumentError "``name`` must be ``expected``".
    A numpy float kept as given would turn up in settings.json (and, as a step size,
    make the choices it moves numpy floats)."""
    try:  # a Python or numpy number, a 0-d array, a Decimal: what float() reads as a number
        number = None if isinstance(value, (bool, str, bytes)) else float(value)
    except (TypeError, ValueError, OverflowError):  # 10**400 is past any float
        number = None
    if number is None or not holds(number):
        shown = shown_value(value) if number is None or isinstance(value, numbers.Real) else \
            f"{type(value).__name__} {shown_value(value)}"
        raise InvalidArgumentError(f"{name} must be {expected}, got {shown}")
    return number


def plain_value(value):
    """A numpy number or array as the Python number or list it holds, and a list or tuple
    (a namedtuple too) as a list of such; anything else as it is. What the API records
    (settings, parameters, configs) is JSON."""
    if type(value).__module__ == "numpy" and callable(getattr(value, "tolist", None)):
        return value.tolist()
    if isinstance(value, (list, tuple)):
        return [plain_value(item) for item in value]
    return value


def plain_fields(config) -> None:
    """Each numpy number in a dataclass ``config``'s fields as the Python one (a grid
    search's ``epochs=np.int64(8)``), in place."""
    for name, value in vars(config).items():
        if type(value).__module__ == "numpy":
            setattr(config, name, plain_value(value))


def exception_message(exc: BaseException) -> str:
    """``str(exc)``, or a stand-in where the exception's own ``__str__`` fails (a user's
    exception class may)."""
    try:
        return str(exc)
    except Exception:  # noqa: BLE001 - whatever the user's class does
        return "(its message could not be shown: its __str__ raised an error)"


def shown_value(value, limit: int = 60) -> str:
    """A value from an input file or argument as its user wrote it, for a message: JSON
    where it is a JSON value (``null``, ``true``, ``"wing"``, ``[1, 2]``; a message about a
    file shows what the file says, not Python's ``None``), else its ``repr``; cut to
    ``limit`` characters."""
    if hasattr(value, "item") and getattr(value, "ndim", None) == 0:
        value = value.item()  # a numpy scalar: its number
    if isinstance(value, (list, tuple)) and len(value) > limit:
        value = list(value[:limit])  # the part that shows (cut below), not a huge dump
    try:
        text = json.dumps(value, ensure_ascii=False)
    except (TypeError, ValueError, RecursionError):
        text = repr(value)
    return cut_text(text, limit)


def argument(name: str) -> str:
    """How an error message names the API argument ``name`` (e.g. ``"out"``, or
    ``"overwrite=True"`` for a flag to set): as written, or as the front end running the
    library spells it (see :func:`spelled`)."""
    return _SPELLING.get().get(name, name)


@contextlib.contextmanager
def spelled(spelling: dict):
    """Within the block, :func:`argument` spells the API arguments in ``spelling`` (API
    name -> what the user typed, e.g. ``{"out": "--out", "overwrite=True": "--overwrite"}``);
    nested blocks add to the outer spelling."""
    token = _SPELLING.set(MappingProxyType({**_SPELLING.get(), **spelling}))
    try:
        yield
    finally:
        _SPELLING.reset(token)


class ProcmodError(Exception):
    """Base class of every error a user of procmod can cause."""


class ModelError(ProcmodError):
    """A model (its rules) broke a rule of the runtime, e.g. reused a choice name."""


class DistributionError(ModelError):
    """A distribution built with parameters it cannot take (a Normal's sigma <= 0, a
    Bernoulli's p > 1); raised out of a rule, it names the rule, its address and the line."""


class ModelCodeError(ProcmodError):
    """An exception a model file's own code raised on a worker process that pickle could
    not send back as it was (a class whose ``__init__`` takes other arguments than its
    ``args``, one holding a lambda): the one line a run in one process gives for it
    (``FILE.py, line N, in RULE: Type: message``; :func:`procmod.parallel.portable_model_error`)."""


class UnknownModelError(ProcmodError):
    """A model name that no registry knows."""


class DerivationFormatError(ProcmodError):
    """A derivation file that cannot be read, is malformed, or does not match its model."""


class InvalidArgumentError(ProcmodError):
    """A bad value for an option or argument (negative count, unknown format, ...)."""
