"""The process's memory while it measures: resident memory now, the peak of a stretch of work
(sampled, since the kernel's own high-water mark can only be reset for the whole process, and
``/usr/bin/time`` reads it), and the C heap's free pages given back to the system.

Linux reads ``/proc/self``; elsewhere resident memory reads 0 and the peaks follow it.
"""

from __future__ import annotations

import functools
import os
import threading
import time
from contextlib import contextmanager

SAMPLE_SECONDS = 0.01  # how often a PeakWatch samples while it is armed


def resident_bytes() -> int:
    """This process's resident memory now; 0 where ``/proc/self/statm`` is missing."""
    try:
        with open("/proc/self/statm") as f:
            return int(f.read().split()[1]) * os.sysconf("SC_PAGE_SIZE")
    except (OSError, ValueError, IndexError):
        return 0


def peak_resident_bytes() -> int:
    """The whole process's peak resident memory so far (the kernel's high-water mark, what
    ``/usr/bin/time -v`` calls maximum resident set size); 0 where it cannot be read."""
    try:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024  # KiB on Linux
    except (ImportError, OSError):
        return 0


class PeakWatch:
    """The highest resident memory of a stretch of work: ``with watch.watching() as seen:``,
    then ``seen.peak``. A daemon thread samples every SAMPLE_SECONDS while a stretch is
    watched and sleeps otherwise (nothing samples during what the harness times but a
    prepare's and a warm-up's own wall time). A peak shorter than a sample can be missed, so
    the kernel's high-water mark, when it rose during the stretch, stands in for it: then it is
    that stretch's."""

    def __init__(self, read=None):
        self._read = read or resident_bytes
        self._armed = threading.Event()
        self._lock = threading.Lock()
        self._peak = 0
        self._thread: threading.Thread | None = None

    def _sample(self) -> None:
        while True:
            self._armed.wait()
            now = self._read()
            with self._lock:
                if self._armed.is_set():
                    self._peak = max(self._peak, now)
            time.sleep(SAMPLE_SECONDS)

    @contextmanager
    def watching(self):
        if self._thread is None:
            self._thread = threading.Thread(target=self._sample, name="peak-watch", daemon=True)
            self._thread.start()
        seen = _Seen()
        high_before = peak_resident_bytes()
        with self._lock:
            self._peak = self._read()
        self._armed.set()
        try:
            yield seen
        finally:
            with self._lock:
                self._armed.clear()
                peak = max(self._peak, self._read())
            high_after = peak_resident_bytes()
            seen.peak = max(peak, high_after) if high_after > high_before else peak


class _Seen:
    peak: int = 0


def trim_heap() -> None:
    """Give the pages the C heap holds free back to the system: glibc keeps what was freed in
    its heaps and per-thread arenas, resident (``malloc_trim``, where the C library has it;
    elsewhere nothing)."""
    trim = _malloc_trim()
    if trim is not None:
        trim(0)


@functools.cache
def _malloc_trim():
    """The C library's malloc_trim, or None. Found once: ctypes.util.find_library runs
    ldconfig, 4 ms of each of a sweep's batches before."""
    import ctypes
    import ctypes.util

    try:
        return ctypes.CDLL(ctypes.util.find_library("c") or "libc.so.6").malloc_trim
    except (OSError, AttributeError):
        return None
