"""Loading numba kernels as set-up, before an engine's clock starts.

numba loads a kernel's machine code from its cache at the kernel's first call: ~0.3 s for
the first kernel of a process (numba sets up its compiler's context), a few milliseconds
for each further one. Left to the first call, that load lands inside the first timed or
budgeted inference run. Each module with kernels on an engine's hot path therefore has a
``load_kernels`` that calls them once with the argument types the hot path passes, and
the object that uses them (the 2D canvas, the voxel scene, the silhouettes, a guided
proposer) calls it when it is made, which engines do before they start their clock.
"""

from __future__ import annotations

import functools
from typing import Callable


def once_per_process(load: Callable[[], None]) -> Callable[[], None]:
    """``load`` (no arguments) made to run at most once per process.

    It counts as done from the moment it starts, so that ``load`` may make the very
    objects whose constructor calls it (a scratch canvas to draw on)."""
    started = False

    @functools.wraps(load)
    def run_once() -> None:
        nonlocal started
        if started:
            return
        started = True
        load()

    return run_once
