"""The light depth map shared by the map-based techniques (a helper, not a technique)."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness.gl.framebuffer import Framebuffer, Texture
from harness.technique import Frame, Technique
from harness.transforms import LightFrustum, fit_light

# Clear value of the map: "no occluder in this texel", so every receiver there is lit.
EMPTY_DEPTH = 3.0e38


class LightDepthMap:
    """A res x res linear-depth map (R32F) rendered from the scene's light."""

    def __init__(self, frame: Frame, res: int, frustum: LightFrustum | None = None):
        self.res = res
        self.frustum = frustum or fit_light(frame.scene, res)
        self.fbo = Framebuffer(res, res, (GL.GL_R32F,), depth=True)
        self.program = Technique.shader(__file__, "light_depth.vert.glsl", "light_depth.frag.glsl")

    @property
    def mem_bytes(self) -> int:
        return self.fbo.nbytes

    @property
    def nonfinite(self) -> int:
        f = self.frustum
        return int(sum(np.count_nonzero(~np.isfinite(m)) for m in (f.view, f.proj)))

    def render(self, frame: Frame) -> None:
        self.fbo.clear((EMPTY_DEPTH,) * 4)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        self.program.use().set(light_view=self.frustum.view, light_proj=self.frustum.proj)
        frame.draw_scene()

    def lookup_uniforms(self, unit: int, slope_bias: float, frame: Frame,
                        texture: Texture | None = None) -> dict:
        """Uniforms of shadow_map.glsl, with the map bound to texture ``unit``.

        ``texture`` replaces the depth map by another res x res texture on the same frustum
        (e.g. one holding several depths per cell)."""
        light = frame.scene.light
        vector = (np.append(light.direction, 0.0) if light.type == "directional"
                  else np.append(light.position, 1.0))
        f = self.frustum
        texture = texture or self.fbo.colors[0]
        return dict(shadow_map=texture.bind(unit), light_view=f.view,
                    light_proj=f.proj, map_res=float(self.res), light_is_ortho=f.is_ortho,
                    texel_world=f.texel_world, light_vector=vector, slope_bias=slope_bias)

    def release(self) -> None:
        self.fbo.release()
        self.program.release()


class FilteredShadowMap:
    """Two passes: the light depth map, then full-screen PCF shading into V.

    The shading shader is ``pcf.frag.glsl`` unless ``fragment`` names another one built on
    ``pcf_samples.glsl`` (same grid, its own per-sample test; ``defines`` go to it)."""

    def __init__(self, frame: Frame, res: int, fragment: str = "pcf.frag.glsl", **defines):
        self.map = LightDepthMap(frame, res)
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl", fragment, **defines)

    def update(self, frame: Frame) -> None:
        """Fit the map to the frame's light: an engine refits it every frame (timed)."""
        with frame.measure("light_fit"):
            self.map.frustum = fit_light(frame.scene, self.map.res)

    def render(self, frame: Frame, *, grid_n: int, spacing: float, bias_min: float,
               bias_max: float, slope_bias: float, jitter: bool, seed: int) -> None:
        with frame.measure("shadow_map"):
            self.map.render(frame)
        self.shade(frame, grid_n=grid_n, spacing=spacing, bias_min=bias_min, bias_max=bias_max,
                   slope_bias=slope_bias, jitter=jitter, seed=seed)

    def shade(self, frame: Frame, *, grid_n: int, spacing: float, bias_min: float,
              bias_max: float, slope_bias: float, jitter: bool, seed: int,
              texture: Texture | None = None) -> None:
        """The shading pass alone, on the map already rendered (or on ``texture``)."""
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            self.shading.set(**self.map.lookup_uniforms(unit, slope_bias, frame, texture))
            self.shading.set(grid_n=grid_n, spacing=spacing, bias_min=bias_min,
                             bias_max=bias_max, jitter=jitter)
            GL.glUniform1ui(self.shading.location("seed"), seed)
            frame.draw_fullscreen()

    def release(self) -> None:
        self.map.release()
        self.shading.release()
