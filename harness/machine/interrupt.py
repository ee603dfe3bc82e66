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
"""

from __future__ import annotations

import os
import signal
import threading
import time
from contextlib import contextmanager

GRACE_S = 0.75
EXIT_CODE = 130
MESSAGE = "shadowbench: interrupted; run the same command again to finish"
SIGNALS = (signal.SIGINT, signal.SIGTERM)

_requested = threading.Event()
_announced = threading.Event()
_deferring = threading.Event()
_STOP_WATCHING = 0  # not a signal number


def raise_if_interrupted() -> None:
    """Raise KeyboardInterrupt if a signal came, even if a library swallowed the first one."""
    if _requested.is_set():
        raise KeyboardInterrupt


def announce() -> None:
    """Say once, on stderr, that the command was interrupted."""
    if not _announced.is_set():
        _announced.set()
        os.write(2, (MESSAGE + "\n").encode())


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
            time.sleep(GRACE_S)
            announce()
            os._exit(EXIT_CODE)


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
