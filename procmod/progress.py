"""Progress of long commands on stderr.

On a terminal, a tqdm bar redrawn in place. Anywhere else (a log file, a pipe, a job
runner, the Blender add-on's log) a redrawn bar would be noise and tqdm hides it, which
left a twenty-minute ``strings train`` or ``learn`` silent until it ended: there a plain
line is written at most every :data:`LOG_INTERVAL` seconds instead, so a log shows that
the run is alive and how far it has got.
"""

from __future__ import annotations

import sys
import time

LOG_INTERVAL = 30.0
"""Seconds between progress lines when stderr is not a terminal."""


def _is_terminal(stream) -> bool:
    try:
        return stream.isatty()
    except (AttributeError, ValueError):  # a closed or stand-in stream
        return False


class _LogLines:
    """The part of tqdm's interface procmod's commands use (``n``, ``update``,
    ``set_postfix``, ``refresh``, ``close``), writing a plain line at most every
    ``interval`` seconds."""

    def __init__(self, total, unit: str, desc: str, stream, interval: float):
        self.total, self.unit, self.desc = total, unit, desc
        self.stream, self.interval = stream, interval
        self.n = 0
        self._postfix = ""
        self._last = time.monotonic()

    def update(self, n=1) -> None:
        self.n += n
        self.refresh()

    def set_postfix(self, ordered_dict=None, refresh: bool = True, **kwargs) -> None:
        items = dict(ordered_dict or {}, **kwargs)
        self._postfix = ", ".join(f"{k}={v}" for k, v in items.items())
        if refresh:
            self.refresh()

    def refresh(self) -> None:
        now = time.monotonic()
        if now - self._last < self.interval:
            return
        self._last = now
        done = f"{self.n:g}" if self.total is None else f"{self.n:g}/{self.total:g}"
        head = f"{self.desc}: " if self.desc else ""
        tail = f" ({self._postfix})" if self._postfix else ""
        print(f"progress: {head}{done}{self.unit}{tail}", file=self.stream, flush=True)

    def close(self) -> None:
        pass


def progress_bar(total=None, unit: str = "it", desc: str = "", stream=None, interval: float = LOG_INTERVAL):
    """A progress bar on ``stream`` (default stderr): tqdm on a terminal, else plain lines
    at most every ``interval`` seconds (see the module docstring)."""
    stream = sys.stderr if stream is None else stream
    if _is_terminal(stream):
        from tqdm import tqdm
        return tqdm(total=total, unit=unit, desc=desc or None, leave=False, file=stream)
    return _LogLines(total, unit, desc, stream, interval)


def progress_lines(stream=None, interval: float = LOG_INTERVAL):
    """A callback for commands that report progress as one line of text: on a terminal it
    redraws the line in place; elsewhere it prints it at most every ``interval`` seconds.
    Call ``.end()`` on it when the work is done (ends the terminal's line)."""
    stream = sys.stderr if stream is None else stream
    return _Lines(stream, _is_terminal(stream), interval)


class _Lines:
    def __init__(self, stream, terminal: bool, interval: float):
        self.stream, self.terminal, self.interval = stream, terminal, interval
        self._last = time.monotonic()
        self._drawn = False

    def __call__(self, line: str) -> None:
        if self.terminal:
            print(f"\r{line:<78}", end="", file=self.stream, flush=True)
            self._drawn = True
            return
        now = time.monotonic()
        if now - self._last >= self.interval:
            self._last = now
            print(f"progress: {line}", file=self.stream, flush=True)

    def end(self) -> None:
        if self._drawn:
            print(file=self.stream)
