"""Per-pass time and fragments (GL_SAMPLES_PASSED).

Two clocks: ``clock`` brackets the pass with glFinish and reads a monotonic clock (the only
choice on OSMesa, where timer queries do not load through PyOpenGL); ``query`` uses a
GL_TIME_ELAPSED timer query, the GPU's own time for the pass (used on a hardware GPU).
"""

from __future__ import annotations

import ctypes
import os
import statistics
import time
from contextlib import contextmanager
from dataclasses import dataclass

from OpenGL import GL

TIMERS = ("clock", "query")


@dataclass(frozen=True)
class PassStats:
    name: str
    ms: float  # median over measured frames
    fragments: int  # samples that passed, from the last frame


def default_timer(renderer: str) -> str:
    """``$SHADOWBENCH_TIMER`` if set; timer queries on a hardware GPU; else the clock."""
    chosen = os.environ.get("SHADOWBENCH_TIMER")
    if chosen:
        if chosen not in TIMERS:
            raise ValueError(f"SHADOWBENCH_TIMER must be one of {TIMERS}, got {chosen!r}")
        return chosen
    software = any(s in renderer.lower() for s in ("llvmpipe", "softpipe", "swrast"))
    return "clock" if software else "query"


_query_ui64 = None


def _query_result_ui64(query: int) -> int:
    """glGetQueryObjectui64v through ctypes: PyOpenGL 3.1.10 cannot allocate its output."""
    global _query_ui64
    if _query_ui64 is None:
        from OpenGL import platform

        address = platform.PLATFORM.getExtensionProcedure(b"glGetQueryObjectui64v")
        if not address:
            raise RuntimeError("the GL driver has no glGetQueryObjectui64v")
        _query_ui64 = ctypes.CFUNCTYPE(None, ctypes.c_uint, ctypes.c_uint,
                                       ctypes.POINTER(ctypes.c_uint64))(address)
    result = ctypes.c_uint64(0)
    _query_ui64(query, GL.GL_QUERY_RESULT, ctypes.byref(result))
    return int(result.value)


class PassMeter:
    """Collects the passes of each frame. ``measuring`` is False during warm-up frames."""

    def __init__(self, timer: str = "clock"):
        if timer not in TIMERS:
            raise ValueError(f"timer must be one of {TIMERS}, got {timer!r}")
        self.timer = timer
        self._frames: list[list[tuple[str, float, int]]] = []
        self.measuring = False
        self._samples, self._elapsed = GL.glGenQueries(2)

    def new_frame(self, measuring: bool) -> None:
        self.measuring = measuring
        if measuring:
            self._frames.append([])

    @contextmanager
    def measure(self, name: str):
        if self.timer == "clock":
            GL.glFinish()
        else:
            GL.glBeginQuery(GL.GL_TIME_ELAPSED, self._elapsed)
        GL.glBeginQuery(GL.GL_SAMPLES_PASSED, self._samples)
        start = time.perf_counter_ns()
        try:
            yield
        finally:
            GL.glEndQuery(GL.GL_SAMPLES_PASSED)
            if self.timer == "clock":
                GL.glFinish()
                ms = (time.perf_counter_ns() - start) / 1e6
            else:
                GL.glEndQuery(GL.GL_TIME_ELAPSED)
                ms = _query_result_ui64(self._elapsed) / 1e6
        # 32-bit result: PyOpenGL 3.1.10 has no array mapping for the 64-bit variant
        fragments = int(GL.glGetQueryObjectuiv(self._samples, GL.GL_QUERY_RESULT))
        if self.measuring:
            self._frames[-1].append((name, ms, fragments))

    @property
    def frame_totals_ms(self) -> list[float]:
        return [sum(ms for _, ms, _ in frame) for frame in self._frames]

    def passes(self) -> list[PassStats]:
        if not self._frames:
            return []
        names = [name for name, _, _ in self._frames[-1]]
        out = []
        for i, name in enumerate(names):
            times = [frame[i][1] for frame in self._frames if len(frame) > i]
            out.append(PassStats(name, statistics.median(times), self._frames[-1][i][2]))
        return out

    def release(self) -> None:
        GL.glDeleteQueries(2, [self._samples, self._elapsed])
