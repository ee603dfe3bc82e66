"""GPU reductions over a G-buffer: the minimum and maximum of a per-pixel quantity over the
covered pixels, read back as a few floats.

A quantity is a compute shader that defines ``bool quantity(vec3 position, vec3 normal,
out vec4 value)`` and includes ``covered_range.glsl`` (``view_depth_range.comp.glsl`` is one);
its own uniforms go to :meth:`CoveredRange.reduce`. One dispatch of 16 x 16 work groups, each
merged into eight integers by atomics, so the read-back is 32 bytes whatever the image size."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
from OpenGL import GL

from .framebuffer import Texture
from .shaders import HARNESS_GLSL, ComputeProgram

# the quantity: each covered pixel's view depth (uniform camera_view, world -> camera view)
VIEW_DEPTH = HARNESS_GLSL / "view_depth_range.comp.glsl"
GROUP_SIZE = 16
ROWS_PER_INVOCATION = 16  # each invocation merges a column of this many pixels before its atomics
_EMPTY = np.array([0xFFFFFFFF] * 4 + [0] * 4, np.uint32)  # low: largest, high: smallest


@dataclass(frozen=True)
class Range:
    """Per component, the smallest and largest value; +inf and -inf where no pixel counted."""

    low: np.ndarray  # float32 (4,)
    high: np.ndarray

    @property
    def empty(self) -> bool:
        return bool(self.low[0] > self.high[0])


def decode(ordered: np.ndarray) -> np.ndarray:
    """Floats from covered_range.glsl's order-preserving unsigned integers."""
    ordered = np.asarray(ordered, np.uint32)
    negative = (ordered & 0x80000000) == 0
    bits = np.where(negative, ~ordered, ordered & 0x7FFFFFFF).astype(np.uint32)
    return bits.view(np.float32)


class CoveredRange:
    """The range of the quantity computed by the compute shader ``shader`` (a path; see the
    module docstring) over the pixels of a G-buffer's position texture whose w is 1."""

    def __init__(self, shader: Path = VIEW_DEPTH):
        self.program = ComputeProgram(Path(shader), {"ROWS_PER_INVOCATION": ROWS_PER_INVOCATION})
        self.buffer = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.buffer)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, _EMPTY.nbytes, None, GL.GL_DYNAMIC_READ)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def reduce(self, position: Texture, normal: Texture, **uniforms) -> Range:
        """One dispatch over ``position`` (w = 1 where covered) and ``normal``; ``uniforms`` go
        to the quantity. Waits for the result (a read-back of eight integers)."""
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.buffer)
        GL.glBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, _EMPTY.nbytes, _EMPTY)
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 0, self.buffer)
        self.program.use().set(gbuffer_position=position.bind(0), gbuffer_normal=normal.bind(1),
                               **uniforms)
        GL.glDispatchCompute(-(-position.width // GROUP_SIZE),
                             -(-position.height // (GROUP_SIZE * ROWS_PER_INVOCATION)), 1)
        GL.glMemoryBarrier(GL.GL_BUFFER_UPDATE_BARRIER_BIT)
        result = np.asarray(GL.glGetBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, _EMPTY.nbytes))
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        GL.glUseProgram(0)
        ordered = result.view(np.uint32)
        # a component no pixel reached keeps its start value, which decodes to NaN: it is
        # +inf (low) or -inf (high), so that an empty range says so (low > high)
        values = np.where(ordered == _EMPTY, np.float32(np.inf) * np.where(_EMPTY > 0, 1, -1),
                          decode(ordered)).astype(np.float32)
        return Range(values[:4], values[4:])

    def release(self) -> None:
        GL.glDeleteBuffers(1, [self.buffer])
        self.program.release()
