"""The shared camera pass: world position, flat normal, albedo, depth and coverage per pixel.

Textures: position (w = 1 where a surface is, else 0) and normal (w = albedo; undefined where
no surface is: test coverage first, as ``gbuffer_fetch`` does). In a scene with alpha-tested
surfaces the pass cuts them out by the rule of ``glsl/alpha_test.glsl``: the camera sees what is
behind a hole, as the light does."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from OpenGL import GL

from .alpha import AlphaTextures
from .framebuffer import Framebuffer
from .shaders import HARNESS_GLSL, Program


@dataclass
class GBufferArrays:
    position: np.ndarray  # (H, W, 3) float32 world position
    normal: np.ndarray  # (H, W, 3) float32 flat normal
    albedo: np.ndarray  # (H, W) float32
    covered: np.ndarray  # (H, W) bool


class GBuffer:
    """Renders the camera view once; techniques read it as textures, metrics as arrays."""

    def __init__(self, width: int, height: int, alpha: AlphaTextures | None = None):
        """``alpha``: the scene's cut-outs (None in an opaque scene: no alpha test, no extra
        fetch). The geometry drawn then carries their texture coordinates (SceneMesh's
        ``cutouts``)."""
        self.fbo = Framebuffer(width, height, (GL.GL_RGBA32F, GL.GL_RGBA32F), depth=True)
        self.alpha = alpha
        self.program = Program(HARNESS_GLSL / "gbuffer.vert.glsl",
                               HARNESS_GLSL / "gbuffer.frag.glsl",
                               None if alpha is None else {"ALPHA_TEST": 1})

    @property
    def position_texture(self):
        return self.fbo.colors[0]

    @property
    def normal_texture(self):
        return self.fbo.colors[1]

    @property
    def depth_texture(self):
        return self.fbo.depth

    def render(self, geometry, view_proj: np.ndarray) -> None:
        # The normal texture keeps whatever it held where no surface is drawn: every reader
        # tests coverage (position w, gbuffer_fetch) first, and read() zeroes it there. Not
        # clearing it saves 0.9 of the clear's 2.3 ms CPU on llvmpipe at 512^2.
        self.fbo.clear((0, 0, 0, 0))
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDisable(GL.GL_CULL_FACE)
        self.program.use().set(view_proj=view_proj,
                               face_attributes=geometry.bind_face_attributes(0))
        if self.alpha is not None:
            self.alpha.bind(self.program, 1)
        geometry.draw()

    def read(self) -> GBufferArrays:
        """The arrays; normal and albedo 0 where no surface is."""
        p = self.fbo.read(0)
        covered = p[..., 3] > 0.5
        n = np.where(covered[..., None], self.fbo.read(1), 0.0).astype(np.float32)
        return GBufferArrays(p[..., :3].copy(), n[..., :3].copy(), n[..., 3].copy(), covered)

    def release(self) -> None:
        self.fbo.release()
        self.program.release()
