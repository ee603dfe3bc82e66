"""``cull: cull`` and ``cull: cc`` for sv (Lloyd, Wendt, Govindaraju, Manocha 2004, "CC shadow
volumes"): the visible receivers' light-space grid that culls the per-triangle volumes, and the
receivers' light depths that clamp the rest (a helper of the ``sv`` technique, not a
technique).

For a directional light, every frame inside the timed ``receivers`` pass: the light-space
(u, v) bounds of the G-buffer's covered samples (one reduction, ``sv_receivers_range``), then
a ``GRID`` x ``GRID`` grid over them holding each cell's deepest receiver along the light
(``sv_receivers_grid``, atomics), then its max pyramid (``sv_receivers_pyramid``). The volume
pass's geometry shader reads it (``sv_receivers.glsl``): a triangle's volume is culled when no
receiver in the cells its footprint touches lies beyond it.

The clamp (``cc``, Lloyd et al.'s second step) keeps each remaining volume to the light depths
from its triangle's nearest corner to the deepest receiver in those cells, per fragment: the
grid pass also stores each pixel's receiver's light depth, and the volume's fragment shader
drops a fragment whose receiver lies outside them. Clamping the geometry instead (finite far
corners, a far cap) cut the fill 2.9x on architecture at 10^4 triangles (128 x 128) but moved
V at tie pixels (1 to 18 a scene, 18 on hard_far_from_origin): a finite far edge rasterises
otherwise than the edge to infinity. Per fragment the rasterisation is the same, and a
fragment dropped is one of a volume its pixel's receiver lies outside, whose fragments there
add up to nothing under z-fail (a capped volume counts whether the receiver is inside it,
wherever the camera is): V stays bit-equal. Under z-pass they add up to one exit where the
camera sits inside the volume, so z-pass is culled only (the clamp changed V by 239 to 4,380
pixels on the camera-in-shadow scenes and hard_dueling_frusta there). It needs the receiver of
each mask pixel, so it applies where the mask has the G-buffer's resolution (``mask_res:
full``); smaller masks are culled only. What it lowers is the fill that reaches the count
(``frags_shadow``), not the rasterised area, and each fragment pays a texel fetch: on
llvmpipe ``cc`` takes longer than ``cull`` (docs/techniques.md has the figures).

Bit-equal where sv's count is exact: the alpha and screen buffers' 8-bit state machine with
``normalize: max`` loses a count under many nested volumes, and there one volume fewer (culled
or clamped) can change a pixel, to the exact answer (terrain_long at 96 x 96, per-triangle
volumes, alpha, z-fail: 1 pixel, 0 with none and 1 with cull, cc, the stencil and the alpha
buffer's rectangles).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from OpenGL import GL

from harness.gl.framebuffer import Texture
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
    """The grid and the programs that build it, and with ``clamp`` the receivers' light depths
    (at the frame's size); :meth:`uniforms` gives the volume pass what ``sv_receivers.glsl``
    and the clamp read."""

    def __init__(self, clamp: bool):
        self.clamp = clamp
        defines = {"GRID_SIZE": GRID, **({"CLAMP": 1} if clamp else {})}
        self.range = CoveredRange(HERE / "sv_receivers_range.comp.glsl")
        self.grid_program = ComputeProgram(HERE / "sv_receivers_grid.comp.glsl", defines)
        self.pyramid_program = ComputeProgram(HERE / "sv_receivers_pyramid.comp.glsl", defines)
        self.buffer = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.buffer)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, CELLS * 4, None, GL.GL_DYNAMIC_COPY)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        self.depth = None  # each pixel's receiver's light depth, at the frame's size
        self.shared = None  # uniforms of the last build, None: no receivers (cull everything)

    def build(self, frame, light) -> None:
        """The grid for ``light`` (directional) over the frame's G-buffer samples."""
        basis = light_basis(light.direction)
        position = frame.gbuffer.position_texture
        bounds = self.range.reduce(position, frame.gbuffer.normal_texture,
                                   light_basis=basis.astype(np.float32))
        low, high = bounds.low[:3].astype(np.float64), bounds.high[:3].astype(np.float64)
        extent = np.maximum(high[:2] - low[:2], 1e-6 * max(np.abs(low).max(), 1.0))
        if self.clamp and self.depth is None:
            self.depth = Texture(frame.width, frame.height, GL.GL_R32F)
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
        if self.clamp:
            GL.glBindImageTexture(0, self.depth.id, 0, GL.GL_FALSE, 0, GL.GL_WRITE_ONLY,
                                  GL.GL_R32F)
        GL.glDispatchCompute(-(-frame.width // 8), -(-frame.height // 8), 1)
        GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT | GL.GL_TEXTURE_FETCH_BARRIER_BIT)
        program = self.pyramid_program.use()
        for level in range(1, LEVELS):
            program.set(level=level)
            size = GRID >> level
            GL.glDispatchCompute(-(-size // 8), -(-size // 8), 1)
            GL.glMemoryBarrier(GL.GL_SHADER_STORAGE_BARRIER_BIT)
        GL.glUseProgram(0)

    def uniforms(self) -> dict:
        """For the volume pass's geometry and fragment shaders (binds the grid to storage
        binding 1 and, when clamping, the receivers' light depths to texture unit 0)."""
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 1, self.buffer)
        if self.clamp:
            self.depth.bind(0)
        return dict(cull_on=True, receiver_depth=0,
                    receiver_margin=float(self.margin), **self.shared)

    @property
    def mem_bytes(self) -> int:
        return CELLS * 4 + (self.depth.nbytes if self.depth else 0)

    def release(self) -> None:
        GL.glDeleteBuffers(1, [self.buffer])
        if self.depth:
            self.depth.release()
        for resource in (self.range, self.grid_program, self.pyramid_program):
            resource.release()
