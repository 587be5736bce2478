"""Progress of long commands when stderr is not a terminal (procmod.progress): plain lines
at an interval, never a redrawn bar, never silence for the whole run."""

import io

from procmod import progress


class _Clock:
    def __init__(self):
        self.now = 0.0

    def __call__(self):
        return self.now


def test_a_log_gets_a_plain_line_per_interval_and_no_carriage_returns(monkeypatch):
    clock = _Clock()
    monkeypatch.setattr(progress.time, "monotonic", clock)
    log = io.StringIO()  # not a terminal
    bar = progress.progress_bar(total=200, unit=" strings", desc="held-out", stream=log, interval=30.0)
    for step in range(200):
        clock.now = step * 1.0  # one string a second: 200 s in all
        bar.set_postfix({"accuracy": f"{step / 200:.2f}"}, refresh=False)
        bar.update(1)
    bar.close()
    lines = log.getvalue().splitlines()
    assert "\r" not in log.getvalue()
    assert len(lines) == 6  # at 30, 60, ..., 180 s
    assert lines[0] == "progress: held-out: 31/200 strings (accuracy=0.15)"

    lines_log = io.StringIO()
    clock.now = 1000.0
    report = progress.progress_lines(stream=lines_log, interval=30.0)
    for step in range(100):
        clock.now = 1000.0 + step
        report(f"round {step}")
    report.end()
    assert lines_log.getvalue().splitlines() == ["progress: round 30", "progress: round 60", "progress: round 90"]


def test_a_terminal_gets_the_line_redrawn_in_place():
    class Terminal(io.StringIO):
        def isatty(self):
            return True

    screen = Terminal()
    report = progress.progress_lines(stream=screen)
    report("round 1")
    report("round 2")
    report.end()
    assert screen.getvalue().count("\r") == 2 and screen.getvalue().endswith("\n")
