"""Progress of a long command on stderr, in the form its reader can use; any long command
(run, reference, report, tune) shows its progress through :class:`Progress`.

- On a terminal: one bar redrawn in place (tqdm): the stage being done, steps done of all,
  the time left, the time elapsed.
- In a log (stderr not a terminal: ``> log 2>&1``, make's output, CI): plain lines and no
  carriage returns: a line as each stage begins (a scene), a count line every ``every`` steps
  (about ``PLAIN_LINES`` of them in all) and after the last, and one at least every
  ``PLAIN_EVERY_S`` while work advances without a step ending (a long batch of rounds).
- ``verbose``: also a line per step (a run), above the bar on a terminal.
- ``quiet``: nothing.

The estimate of the time left comes from work, not steps: ``work`` is the total in any unit
(the sweep counts each run's frames weighted by their pixels), :meth:`Progress.advance` adds
work done within a step (a frame), and :meth:`Progress.step` ends a step with its remaining
work. Without ``work``, each step is one unit.

A command's result (its summary) is not progress: it goes to stdout. While a bar is shown,
the interrupt message is told to start on a line of its own (``interrupt.line_open``).
"""

from __future__ import annotations

import math
import sys
import time

from ..machine import interrupt

QUIET, NORMAL, VERBOSE = "quiet", "normal", "verbose"
PLAIN_LINES = 20
PLAIN_EVERY_S = 30.0
REFRESH_S = 1.0  # advance() redraws the terminal's bar at most this often


def verbosity(quiet: bool = False, verbose: bool = False) -> str:
    """The mode of ``--quiet`` / ``--verbose`` (given both, quiet wins)."""
    return QUIET if quiet else VERBOSE if verbose else NORMAL


def clock(seconds: float) -> str:
    """``1:02:03`` (hours always shown)."""
    seconds = max(round(seconds), 0)
    return f"{seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d}"


class Progress:
    """``total`` steps of ``unit`` (``done`` of them done before this command started), shown
    as ``mode`` says (:func:`verbosity`) on ``stream`` (stderr); ``terminal``: whether it is
    one (default: ``stream.isatty()``)."""

    def __init__(self, total: int, *, done: int = 0, unit: str = "run", work: float | None = None,
                 mode: str = NORMAL, stream=None, terminal: bool | None = None):
        self.stream = stream if stream is not None else sys.stderr
        self.mode, self.unit = mode, unit
        self.terminal = (getattr(self.stream, "isatty", lambda: False)() if terminal is None
                         else terminal)
        self._bar = None
        self.stage_text, self.status_text = "", ""
        self._drawn = self._line_at = time.monotonic()
        self._begin(total, done, work)

    def _begin(self, total: int, done: int, work: float | None) -> None:
        self.total, self.n, self.failed = total, done, 0
        self.left = float(total - done if work is None else work)
        self.done_work = 0.0
        self.clock = time.monotonic()  # elapsed, and the rate of the estimate, count from here
        self.every = max(1, math.ceil(total / PLAIN_LINES))
        self._counted = -1  # the step count of the last count line written
        if self.mode != QUIET and self.terminal:
            from tqdm import tqdm

            if self._bar is not None:
                self._bar.close()
            self._bar = tqdm(total=total, initial=done, file=self.stream, dynamic_ncols=True,
                             bar_format="{desc} | {n_fmt}/{total_fmt} " + self.unit
                             + "s done{postfix} | {elapsed} elapsed")
            self._draw()
            interrupt.line_open(True)

    def reset(self, total: int, work: float | None = None, *, stage: str = "") -> None:
        """Count again from 0 of ``total`` (a second pass: the noisy runs timed again)."""
        self.stage_text, self.status_text = stage, ""
        self._begin(total, 0, work)
        self._plain(self._stage_line())

    # --- what the command tells it -----------------------------------------------------------

    def stage(self, text: str) -> None:
        """A stage begins (a scene and resolution): the bar's description; a line in a log."""
        self.stage_text, self.status_text = text, ""
        self._draw()
        self._plain(self._stage_line())

    def status(self, text: str) -> None:
        """What the stage is doing now (its reference, its rounds): on the bar only."""
        self.status_text = text
        self._draw()

    def advance(self, work: float) -> None:
        """Work done within a step (a frame of a run): the estimate follows it."""
        self._work(work)
        now = time.monotonic()
        if self._bar is not None and now - self._drawn >= REFRESH_S:
            self._draw()
        elif self._bar is None and now - self._line_at >= PLAIN_EVERY_S:
            self._plain(self._count_line())

    def step(self, line: str = "", *, work: float = 1.0, failed: bool = False) -> None:
        """A step ended (a run stored), with its remaining ``work``; ``line`` says how (shown
        with ``verbose``)."""
        self.failed += failed
        self.n += 1
        self._work(work)
        if self._bar is not None:
            self._bar.n = self.n
        if self.mode == VERBOSE and line:
            self.note(f"{line} [{self.n}/{self.total}]")
        if self._bar is not None:
            self._draw()
        elif self.mode != VERBOSE and (self.n % self.every == 0 or self.n == self.total):
            self._plain(self._count_line())  # verbose: the run's line counts it (close: the last)

    def note(self, line: str) -> None:
        """A line of its own (above the bar on a terminal); nothing when quiet."""
        if self.mode == QUIET:
            return
        if self._bar is not None:
            self._bar.write(line, file=self.stream)
        else:
            self._write(line)

    def close(self) -> None:
        """End the bar (its last state stays on screen), or write the last count line."""
        if self._bar is not None:
            self._draw()
            self._bar.close()
            self._bar = None
            interrupt.line_open(False)
        elif self._counted != self.n and self.n:
            self._plain(self._count_line())

    # --- what it shows -----------------------------------------------------------------------

    def postfix(self) -> str:
        """``3 to go, 1 failed, about 0:01:10 left``."""
        to_go = self.total - self.n
        return (f"{to_go} to go" + (f", {self.failed} failed" if self.failed else "")
                + (f", about {clock(self.seconds_left())} left" if to_go and self.done_work
                   else ""))

    def seconds_left(self) -> float:
        elapsed = time.monotonic() - self.clock
        return elapsed / self.done_work * max(self.left, 0.0) if self.done_work else math.nan

    def _work(self, work: float) -> None:
        self.done_work += work
        self.left -= work

    def _description(self) -> str:
        return ": ".join(t for t in (self.stage_text, self.status_text) if t)

    def _draw(self) -> None:
        if self._bar is None:
            return
        self._bar.set_description_str(self._description(), refresh=False)
        self._bar.set_postfix_str(self.postfix(), refresh=False)
        self._bar.refresh()
        self._drawn = time.monotonic()

    def _elapsed(self) -> str:
        return clock(time.monotonic() - self.clock)

    def _stage_line(self) -> str:
        return (f"{self.stage_text or 'start'} ({self.n}/{self.total} {self.unit}s done, "
                f"{self._elapsed()} elapsed)")

    def _count_line(self) -> str:
        self._counted = self.n
        return f"{self.n}/{self.total} {self.unit}s done, {self.postfix()} | {self._elapsed()} elapsed"

    def _plain(self, line: str) -> None:
        if self._bar is None and self.mode != QUIET:
            self._write(line)

    def _write(self, line: str) -> None:
        try:
            self.stream.write(line + "\n")  # one write: a whole line, even if the process ends
            self.stream.flush()
        except (OSError, ValueError):  # stderr closed (a pipe's reader gone): show nothing more
            self.mode = QUIET
        self._line_at = time.monotonic()
