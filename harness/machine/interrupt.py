"""Ctrl-C (SIGINT) and SIGTERM stop a command within a second, whatever library is running.

Python turns SIGINT into a KeyboardInterrupt, but only when the main thread next runs Python
code, and libraries that catch BaseException swallow it (trimesh does, in its optional imports
and while building and loading meshes): the sweep would run on. So, within
:func:`stop_on_signals`:

- the handler raises KeyboardInterrupt in the main thread and records the request, which
  :func:`raise_if_interrupted` raises again after library calls that may have swallowed it;
- a watcher thread, woken by the signal itself (``signal.set_wakeup_fd``: the interpreter
  writes the signal number there the moment it arrives, even while the main thread waits in
  a library), ends the process ``GRACE_S`` later if it is still running.

Ending hard is safe: results folders are only ever changed by atomic replacement, and the
next run marks the invocation ``interrupted`` and removes its temporary files. The one case
left is a C extension that holds the interpreter lock the whole time: the watcher then runs
when it lets go.

Two exceptions to "within a second": within :func:`finishing` (runs whose frames are all
rendered being scored and stored) the signal waits until the block ends, at most ``HOLD_S``,
and a second signal ends the process at once. And the message says so on its own line, even
after a progress bar left its line open (:func:`line_open`).
"""

from __future__ import annotations

import os
import select
import signal
import threading
import time
from contextlib import contextmanager

GRACE_S = 0.75
HOLD_S = 120.0  # the longest a signal waits for finished runs to be stored
EXIT_CODE = 130
MESSAGE = "shadowbench: interrupted; run the same command again to finish"
HOLDING = "shadowbench: storing the runs that finished; Ctrl-C again to stop at once"
SIGNALS = (signal.SIGINT, signal.SIGTERM)

_requested = threading.Event()
_announced = threading.Event()
_deferring = threading.Event()
_holding = threading.Event()
_line_open = threading.Event()
_STOP_WATCHING = 0  # not a signal number


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a signal came, even if a library swallowed the first one;
    within :func:`deferred` or :func:`finishing` only on leaving it."""
    if _requested.is_set() and not _deferring.is_set():
        raise KeyboardInterrupt


def line_open(is_open: bool) -> None:
    """Whether stderr's last line is unfinished (a terminal's progress bar, redrawn in place):
    then the interrupt message starts with a newline rather than after the bar's text."""
    (_line_open.set if is_open else _line_open.clear)()


def _say(text: str) -> None:
    """A line on stderr, below a bar whose line is open (which then redraws below it)."""
    os.write(2, (("\n" if _line_open.is_set() else "") + text + "\n").encode())


def announce() -> None:
    """Say once, on stderr and on a line of its own, that the command was interrupted."""
    if not _announced.is_set():
        _announced.set()
        _say(MESSAGE)


def _on_signal(signum, frame):
    _requested.set()
    if not _deferring.is_set():
        raise KeyboardInterrupt


def _watch(read_fd: int) -> None:
    """Wait for a signal's byte; then give the command ``GRACE_S`` to stop, and end it."""
    while True:
        received = os.read(read_fd, 64)
        if not received or _STOP_WATCHING in received:
            os.close(read_fd)
            return
        if any(number in SIGNALS for number in received):
            _requested.set()
            _wait_for_main_thread(read_fd)
            announce()
            os._exit(EXIT_CODE)


def _wait_for_main_thread(read_fd: int) -> None:
    """``GRACE_S`` for the main thread to stop; while it is :func:`finishing`, until it leaves
    the block (saying so once ``GRACE_S`` has passed) and ``GRACE_S`` more, at most
    ``HOLD_S`` in all. A further signal ends the wait."""
    began = time.monotonic()
    end, said, readable = began + GRACE_S, False, True
    while (now := time.monotonic()) < end:
        if _holding.is_set() and now < began + HOLD_S:
            end = max(end, min(now + GRACE_S, began + HOLD_S))
            if not said and now >= began + GRACE_S:
                said = True
                _say(HOLDING)
        if readable and select.select([read_fd], [], [], 0.05)[0]:
            received = os.read(read_fd, 64)
            readable = bool(received)  # b"": the block of stop_on_signals was left
            if any(number in SIGNALS for number in received):
                return
        elif not readable:
            time.sleep(0.05)


@contextmanager
def stop_on_signals():
    """Within the block, SIGINT and SIGTERM raise KeyboardInterrupt and are remembered for
    :func:`raise_if_interrupted`; the process ends ``GRACE_S`` after the first one if it still
    runs then, also after the block (a library's exit handlers may hang: Dask's wait 10 s)."""
    if threading.current_thread() is not threading.main_thread():
        yield  # only the main thread may set signal handlers
        return
    read_fd, write_fd = os.pipe2(os.O_NONBLOCK | os.O_CLOEXEC)
    os.set_blocking(read_fd, True)
    previous_fd = signal.set_wakeup_fd(write_fd, warn_on_full_buffer=False)
    previous = {s: signal.signal(s, _on_signal) for s in SIGNALS}
    threading.Thread(target=_watch, args=(read_fd,), name="shadowbench-signals",
                     daemon=True).start()
    try:
        yield
    finally:
        for s, handler in previous.items():
            signal.signal(s, handler)
        signal.set_wakeup_fd(previous_fd)
        os.write(write_fd, bytes([_STOP_WATCHING]))
        os.close(write_fd)


@contextmanager
def finishing():
    """Within the block the main thread stores work already done (runs whose frames are all
    rendered): a signal is only remembered (:func:`raise_if_interrupted` raises it after the
    block), and the watcher waits for the block to end, at most ``HOLD_S``, rather than
    ending the process ``GRACE_S`` after the signal; a second signal ends it at once. Leaving
    the block raises nothing: the caller's next :func:`raise_if_interrupted` does."""
    _deferring.set()
    _holding.set()
    try:
        yield
    finally:
        _holding.clear()
        _deferring.clear()


@contextmanager
def deferred():
    """Within the block a signal is only remembered (the watcher still ends the process
    ``GRACE_S`` later), and raised on leaving it: for library calls that a KeyboardInterrupt
    would leave half done, such as a Dask cluster starting, whose exit handler then fails with
    a traceback."""
    _deferring.set()
    try:
        yield
    finally:
        _deferring.clear()
    raise_if_interrupted()
