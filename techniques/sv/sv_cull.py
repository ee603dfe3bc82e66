"""``cull: cc`` for sv (Lloyd, Wendt, Govindaraju, Manocha 2004, "CC shadow volumes"): the
visible receivers' light-space grid that culls the per-triangle volumes (a helper of the ``sv``
technique, not a technique).

For a directional light, every frame inside the timed ``receivers`` pass: the light-space
(u, v) bounds of the G-buffer's covered samples (one reduction, ``sv_receivers_range``), then
a ``GRID`` x ``GRID`` grid over them holding each cell's deepest receiver along the light
(``sv_receivers_grid``, atomics), then its max pyramid (``sv_receivers_pyramid``). The volume
pass's geometry shader reads it (``sv_receivers.glsl``): a triangle's volume is culled when no
receiver in the cells its footprint touches lies beyond it.

Lloyd et al.'s second step, clamping each remaining volume just beyond the deepest receiver it
can reach (finite far corners, a far cap), was built and measured, and is not here: it cut the
fill 2.9x on architecture at 10^4 triangles (128 x 128) with V the same there, but a finite far
edge rasterises otherwise than the edge to infinity, and V moved at tie pixels (1 pixel at
96 x 96 on pins with per-triangle volumes; 1 to 18 with a larger margin, 18 on
hard_far_from_origin): not the bit-equal V this option promises.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from OpenGL import GL

from harness.gl.reduction import CoveredRange
from harness.gl.shaders import ComputeProgram

HERE = Path(__file__).parent
GRID = 64  # cells along each light-space axis (a power of two)
LEVELS = GRID.bit_length()  # GRID, GRID / 2, ..., 1
CELLS = sum((GRID >> k) ** 2 for k in range(LEVELS))
# a volume is kept when a receiver in its footprint lies less than this far in front of its
# triangle's nearest corner, relative to the receivers' depth range (rounding, never a shadow)
MARGIN = 1e-3


def light_basis(direction: np.ndarray) -> np.ndarray:
    """Rows: two unit axes across the light's direction, then the direction (3, 3)."""
    d = np.asarray(direction, np.float64) / np.linalg.norm(direction)
    helper = np.array([1.0, 0.0, 0.0]) if abs(d[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = np.cross(helper, d)
    u /= np.linalg.norm(u)
    return np.stack([u, np.cross(d, u), d])


class ReceiverGrid:
    """The grid and the programs that build it; :meth:`uniforms` gives the volume pass what
    ``sv_receivers.glsl`` reads."""

    def __init__(self):
        defines = {"GRID_SIZE": GRID}
        self.range = CoveredRange(HERE / "sv_receivers_range.comp.glsl")
        self.grid_program = ComputeProgram(HERE / "sv_receivers_grid.comp.glsl", defines)
        self.pyramid_program = ComputeProgram(HERE / "sv_receivers_pyramid.comp.glsl", defines)
        self.buffer = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.buffer)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, CELLS * 4, None, GL.GL_DYNAMIC_COPY)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        self.mem_bytes = CELLS * 4
        self.shared = None  # uniforms of the last build, None: no receivers (cull everything)

    def build(self, frame, light) -> None:
        """The grid for ``light`` (directional) over the frame's G-buffer samples."""
        basis = light_basis(light.direction)
        position = frame.gbuffer.position_texture
        bounds = self.range.reduce(position, frame.gbuffer.normal_texture,
                                   light_basis=basis.astype(np.float32))
        low, high = bounds.low[:3].astype(np.float64), bounds.high[:3].astype(np.float64)
        extent = np.maximum(high[:2] - low[:2], 1e-6 * max(np.abs(low).max(), 1.0))
        self.shared = dict(light_basis=basis.astype(np.float32),
                           grid_low=low[:2].astype(np.float32),
                           grid_scale=(GRID / extent).astype(np.float32))
        self.margin = MARGIN * max(float(high[2] - low[2]), 1e-6) if not bounds.empty else 0.0
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.buffer)
        GL.glClearBufferData(GL.GL_SHADER_STORAGE_BUFFER, GL.GL_R32UI, GL.GL_RED_INTEGER,
                             GL.GL_UNSIGNED_INT, None)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 1, self.buffer)
        program = self.grid_program.use()
        program.set(gbuffer_position=position.bind(0), **self.shared)
        GL.glDispatchCompute(-(-frame.width // 8), -(-frame.height // 8), 1)
        GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT)
        program = self.pyramid_program.use()
        for level in range(1, LEVELS):
            program.set(level=level)
            size = GRID >> level
            GL.glDispatchCompute(-(-size // 8), -(-size // 8), 1)
            GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT)
        GL.glUseProgram(0)

    def uniforms(self) -> dict:
        """For the volume pass's geometry shader (binds the grid to storage binding 1)."""
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 1, self.buffer)
        return dict(cull_on=True, receiver_margin=float(self.margin), **self.shared)

    def release(self) -> None:
        GL.glDeleteBuffers(1, [self.buffer])
        for resource in (self.range, self.grid_program, self.pyramid_program):
            resource.release()
