"""Per-pass time, fragments (GL_SAMPLES_PASSED) and pipeline work counters.

Two clocks: ``clock`` brackets the pass with glFinish and reads a monotonic clock (the only
choice on OSMesa, where timer queries do not load through PyOpenGL); ``query`` uses a
GL_TIME_ELAPSED timer query, the GPU's own time for the pass (used on a hardware GPU).

Work counters come from GL_ARB_pipeline_statistics_query (core in GL 4.6): vertex shader
invocations, fragment shader invocations, primitives entering clipping and compute shader
invocations (the GPU reductions), per pass. What a
driver counts as a fragment invocation is its own: llvmpipe counts 16 per 4x4 pixel block a
triangle touches (partly covered blocks whole, a block on the edge shared by two triangles
twice); a GPU counts pixels, helper invocations included. Where the driver lacks the extension
the counters are None (:func:`pipeline_statistics_missing` says why).
"""

from __future__ import annotations

import ctypes
import os
import time
from contextlib import contextmanager
from dataclasses import dataclass

from OpenGL import GL
from OpenGL.GL.ARB import pipeline_statistics_query as psq

from ..machine.timing import contention, is_software_renderer, median_interval

TIMERS = ("clock", "query")
PIPELINE_STATISTICS_EXTENSION = "GL_ARB_pipeline_statistics_query"
COUNTER_TARGETS = {
    "vertex_invocations": psq.GL_VERTEX_SHADER_INVOCATIONS_ARB,
    "fragment_invocations": psq.GL_FRAGMENT_SHADER_INVOCATIONS_ARB,
    "primitives": psq.GL_CLIPPING_INPUT_PRIMITIVES_ARB,
    "compute_invocations": psq.GL_COMPUTE_SHADER_INVOCATIONS_ARB,
}
COUNTERS = tuple(COUNTER_TARGETS)


@dataclass(frozen=True)
class PassStats:
    name: str
    ms: float  # median over measured frames
    ms_ci_low: float  # a 95% interval of that median (harness.machine.timing.median_interval)
    ms_ci_high: float
    fragments: int  # samples that passed, from the last frame
    # pipeline statistics of the last frame; None where the driver cannot count them
    vertex_invocations: int | None = None
    fragment_invocations: int | None = None
    primitives: int | None = None
    compute_invocations: int | None = None


def default_timer(renderer: str) -> str:
    """``$SHADOWBENCH_TIMER`` if set; timer queries on a hardware GPU; else the clock."""
    chosen = os.environ.get("SHADOWBENCH_TIMER")
    if chosen:
        if chosen not in TIMERS:
            raise ValueError(f"SHADOWBENCH_TIMER must be one of {TIMERS}, got {chosen!r}")
        return chosen
    return "clock" if is_software_renderer(renderer) else "query"


def pipeline_statistics_missing() -> str:
    """Why the current GL context cannot count pipeline statistics; '' where it can."""
    major = GL.glGetIntegerv(GL.GL_MAJOR_VERSION)
    minor = GL.glGetIntegerv(GL.GL_MINOR_VERSION)
    if (int(major), int(minor)) >= (4, 6):
        return ""
    count = int(GL.glGetIntegerv(GL.GL_NUM_EXTENSIONS))
    if any(GL.glGetStringi(GL.GL_EXTENSIONS, i).decode() == PIPELINE_STATISTICS_EXTENSION
           for i in range(count)):
        return ""
    return (f"the GL driver ({GL.glGetString(GL.GL_RENDERER).decode()}, GL {major}.{minor}) "
            f"lacks {PIPELINE_STATISTICS_EXTENSION}")


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
    """Collects the passes of each frame. ``measuring`` is False during warm-up frames.

    ``counters``: also count pipeline statistics per pass (the driver must have them).
    :meth:`add_load` attributes to the current measured frame the CPU time other processes
    used while it ran, and the time the machine had (see :mod:`harness.machine.timing`)."""

    def __init__(self, timer: str = "clock", counters: bool = False):
        if timer not in TIMERS:
            raise ValueError(f"timer must be one of {TIMERS}, got {timer!r}")
        self.timer = timer
        # per measured frame: (name, ms, fragments, counter values or None) per pass
        self._frames: list[list[tuple[str, float, int, tuple[int, ...] | None]]] = []
        self._others_s = self._capacity_s = 0.0
        self.measuring = False
        self._queries = [int(q) for q in GL.glGenQueries(2 + (len(COUNTERS) if counters else 0))]
        self._samples, self._elapsed = self._queries[:2]
        self._counters = dict(zip(COUNTERS, self._queries[2:]))

    @property
    def counts(self) -> bool:
        return bool(self._counters)

    def new_frame(self, measuring: bool) -> None:
        self.measuring = measuring
        if measuring:
            self._frames.append([])

    def add_load(self, others_s: float, capacity_s: float) -> None:
        self._others_s += others_s
        self._capacity_s += capacity_s

    @property
    def cpu_contention(self) -> float | None:
        """Share of the machine's CPU time other processes used over the measured frames."""
        return contention(self._others_s, self._capacity_s)

    @contextmanager
    def measure(self, name: str):
        if self.timer == "clock":
            GL.glFinish()
        else:
            GL.glBeginQuery(GL.GL_TIME_ELAPSED, self._elapsed)
        GL.glBeginQuery(GL.GL_SAMPLES_PASSED, self._samples)
        for counter, query in self._counters.items():
            GL.glBeginQuery(COUNTER_TARGETS[counter], query)
        start = time.perf_counter_ns()
        try:
            yield
        finally:
            for counter in self._counters:
                GL.glEndQuery(COUNTER_TARGETS[counter])
            GL.glEndQuery(GL.GL_SAMPLES_PASSED)
            if self.timer == "clock":
                GL.glFinish()
                ms = (time.perf_counter_ns() - start) / 1e6
            else:
                GL.glEndQuery(GL.GL_TIME_ELAPSED)
                ms = _query_result_ui64(self._elapsed) / 1e6
        # 32-bit result: PyOpenGL 3.1.10 has no array mapping for the 64-bit variant
        fragments = int(GL.glGetQueryObjectuiv(self._samples, GL.GL_QUERY_RESULT))
        counts = (tuple(_query_result_ui64(q) for q in self._counters.values())
                  if self._counters else None)
        if self.measuring:
            self._frames[-1].append((name, ms, fragments, counts))

    @property
    def frame_totals_ms(self) -> list[float]:
        return [sum(p[1] for p in frame) for frame in self._frames]

    def passes(self, statistics: str = "order") -> list[PassStats]:
        """Each pass of the last frame: its median time with the interval that
        ``statistics`` (harness.machine.timing.STATISTICS) gives, its fragments and counters."""
        if not self._frames:
            return []
        out = []
        for i, (name, _, fragments, counts) in enumerate(self._frames[-1]):
            times = [frame[i][1] for frame in self._frames if len(frame) > i]
            ms, low, high = median_interval(times, method=statistics)
            out.append(PassStats(name, ms, low, high, fragments,
                                 **dict(zip(COUNTERS, counts or (None,) * len(COUNTERS)))))
        return out

    def release(self) -> None:
        GL.glDeleteQueries(len(self._queries), self._queries)
