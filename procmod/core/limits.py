"""Sizes a machine cannot hold, refused before the work starts.

A count from the command line or an input file (samples, particles, pixels, voxels,
network widths) can ask for more memory or disk than the machine has. Allocating it
fails late, with a ``MemoryError`` traceback, or never fails and swaps the machine to a
halt. The checks here compare what a request needs (a lower bound: the part procmod can
count before doing the work) with what the machine has, and refuse with a
:class:`ResourceLimitError` that names the request and both figures.
"""

from __future__ import annotations

import contextlib
import gc
import os
import shutil
import threading

from .errors import InvalidArgumentError

# Refuse requests above this share of the machine's physical memory: the rest is the
# interpreter, the libraries, and whatever else runs.
MEMORY_SHARE = 0.8

# Coordinates and lengths an input file may give (targets, part libraries): beyond these,
# squares and ratios of them overflow or vanish in float64 (a voxel of 1e-300 divided by
# zero, an eye at 1e300 read as a zero view direction); a model's parts are metres or
# centimetres, not light years.
MAX_COORDINATE = 1e12
MIN_LENGTH = 1e-12


class ResourceLimitError(InvalidArgumentError):
    """A request (a count, an image size) that needs more memory or disk than the machine has."""


def physical_memory() -> int | None:
    """Bytes of physical memory of this machine (None where the system does not say)."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (AttributeError, ValueError, OSError):  # not a POSIX system
        return None


def format_bytes(n: float) -> str:
    """``1536`` -> ``"1.5 KB"`` (powers of 1000); beyond petabytes ``"2.0e+21 bytes"``."""
    value = float(n)
    for unit in ("B", "KB", "MB", "GB", "TB", "PB"):
        if abs(value) < 1000:
            return f"{value:.0f} {unit}" if unit == "B" else f"{value:.1f} {unit}"
        value /= 1000.0
    return f"{float(n):.1e} bytes"


def check_memory(what: str, needed: float, advice: str = "") -> None:
    """Refuse ``what`` if it needs more than :data:`MEMORY_SHARE` of physical memory.

    ``needed`` is a lower bound in bytes; ``advice`` (e.g. "use fewer particles") ends
    the message.
    """
    total = physical_memory()
    if total is not None and needed > MEMORY_SHARE * total:
        raise ResourceLimitError(f"{what} would need at least {format_bytes(needed)} of memory; this machine "
                                 f"has {format_bytes(total)}" + (f"; {advice}" if advice else ""))


def check_disk(what: str, needed: float, folder: str | os.PathLike, advice: str = "") -> None:
    """Refuse ``what`` if it needs more disk than is free where ``folder`` (or its nearest
    existing parent) lies."""
    path = os.path.abspath(folder)
    while not os.path.exists(path):
        parent = os.path.dirname(path)
        if parent == path:
            return
        path = parent
    try:
        free = shutil.disk_usage(path).free
    except OSError:
        return  # cannot tell: the write itself will say
    if needed > free:
        raise ResourceLimitError(f"{what} would need at least {format_bytes(needed)} of disk; {path} has "
                                 f"{format_bytes(free)} free" + (f"; {advice}" if advice else ""))


__all__ = ["MEMORY_SHARE", "ResourceLimitError", "check_disk", "check_memory", "format_bytes", "physical_memory",
           "relaxed_gc"]


@contextlib.contextmanager
def relaxed_gc(threshold: int = 100_000):
    """Run the cyclic garbage collector rarely while an engine runs or a large file is
    parsed.

    Engines allocate and drop many small acyclic objects (contexts, nodes, copies) that
    reference counting frees at once; the default collector thresholds would scan the
    whole, growing heap of live particles over and over for nothing (a third of an SMC
    run's time; a third of reading a million-face OBJ's faces). Collection still happens,
    just every ``threshold`` allocations.

    Nested and concurrent blocks (engines run in threads) share one relaxation: the
    threshold the first block found is put back when the last one ends (each block put
    back what it found, and a block that found another's left 100,000 for good).
    """
    global _relaxed_count, _threshold_before
    with _RELAXED_LOCK:
        if _relaxed_count == 0:
            _threshold_before = gc.get_threshold()
            gc.set_threshold(threshold, _threshold_before[1], _threshold_before[2])
        _relaxed_count += 1
    try:
        yield
    finally:
        with _RELAXED_LOCK:
            _relaxed_count -= 1
            if _relaxed_count == 0:
                gc.set_threshold(*_threshold_before)


_RELAXED_LOCK = threading.Lock()
_relaxed_count = 0  # blocks of relaxed_gc running now, in any thread
_threshold_before = gc.get_threshold()


def _new_lock_in_child() -> None:
    # a worker forked while another thread held the lock inherited it held, and waited forever
    global _RELAXED_LOCK
    _RELAXED_LOCK = threading.Lock()


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_new_lock_in_child)
