"""Per-pass time (glFinish-bracketed monotonic clock) and fragments (GL_SAMPLES_PASSED)."""

from __future__ import annotations

import statistics
import time
from contextlib import contextmanager
from dataclasses import dataclass

from OpenGL import GL


@dataclass(frozen=True)
class PassStats:
    name: str
    ms: float  # median over measured frames
    fragments: int  # samples that passed, from the last frame


class PassMeter:
    """Collects the passes of each frame. ``measuring`` is False during warm-up frames."""

    def __init__(self):
        self._frames: list[list[tuple[str, float, int]]] = []
        self.measuring = False
        self._query = GL.glGenQueries(1)[0]

    def new_frame(self, measuring: bool) -> None:
        self.measuring = measuring
        if measuring:
            self._frames.append([])

    @contextmanager
    def measure(self, name: str):
        GL.glFinish()
        GL.glBeginQuery(GL.GL_SAMPLES_PASSED, self._query)
        start = time.perf_counter_ns()
        try:
            yield
        finally:
            GL.glEndQuery(GL.GL_SAMPLES_PASSED)
            GL.glFinish()
            ms = (time.perf_counter_ns() - start) / 1e6
        # 32-bit result: PyOpenGL 3.1.10 has no array mapping for the 64-bit variant
        fragments = int(GL.glGetQueryObjectuiv(self._query, GL.GL_QUERY_RESULT))
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
        GL.glDeleteQueries(1, [self._query])
