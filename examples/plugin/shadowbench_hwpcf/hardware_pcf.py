"""2x2 hardware-compare percentage-closer filtering, with a normal-offset bias."""

from __future__ import annotations

from OpenGL import GL
from pydantic import Field

from harness.gl.framebuffer import Framebuffer
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams
from harness.scene.transforms import fit_light


class HardwarePCF(Technique):
    """A depth-texture shadow map read through a ``sampler2DShadow`` with ``GL_LINEAR``
    filtering: the texture unit compares the 4 texels around the point and blends the outcomes
    bilinearly, so V ramps over one texel at a shadow edge for the price of one fetch
    instruction (the "hardware PCF" engines use as their cheapest filter).

    The map is the light's ordinary depth buffer (orthographic over the scene bounds for a
    directional light, perspective over the cone for a spot light). Instead of a slope-scaled
    bias the point moves along its normal by ``normal_offset`` map texels before it is
    projected (the normal-offset bias), which keeps a plane lit at every angle to the light
    from 1.5 texels up (``hardware_pcf.frag.glsl`` says why), and ``bias`` scene units toward
    the light for the depth buffer's rounding. What the offset costs: it moves the lookup up to
    1.5 texels sideways, so shadows shift (sphere_plane at 512 px, map 1024: edge_mae 0.071,
    sm 0.044); and castle at 512 px keeps acne_pct 0.13 and leak_pct 0.036 (sm 0.003 and
    0.0007), its acne mostly within 2 px of a reference shadow (not analysed further).

    =================  ============================================  =======  ===========
    Parameter          Meaning                                       Default  Range
    =================  ============================================  =======  ===========
    ``res``            map width and height, texels                  1024     16 .. 8192
    ``normal_offset``  move along the normal, map texels             1.5      0 .. 16
    ``bias``           move toward the light, scene units            0.002    >= 0
    =================  ============================================  =======  ===========
    """

    name = "hwpcf"
    summary = "hardware PCF: one GL_LINEAR depth-compare fetch (2x2 texels) per pixel"
    paper = "Reeves, Salesin, Cook 1987 (PCF), in the 2x2 form depth-compare texture units filter"
    quality_knobs = {"res": (256, 1024, 4096)}

    class Params(TechniqueParams):
        res: int = Field(1024, ge=16, le=8192)
        normal_offset: float = Field(1.5, ge=0, le=16)
        bias: float = Field(0.002, ge=0)

    def prepare(self, frame: Frame) -> None:
        res = self.params.res
        self.map = Framebuffer(res, res, colors=(), depth=True)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.map.depth.id)
        for key, value in ((GL.GL_TEXTURE_MIN_FILTER, GL.GL_LINEAR),
                           (GL.GL_TEXTURE_MAG_FILTER, GL.GL_LINEAR),
                           (GL.GL_TEXTURE_COMPARE_MODE, GL.GL_COMPARE_REF_TO_TEXTURE),
                           (GL.GL_TEXTURE_COMPARE_FUNC, GL.GL_LEQUAL)):
            GL.glTexParameteri(GL.GL_TEXTURE_2D, key, value)
        self.light_pass = self.shader(__file__, "light_depth.vert.glsl", "light_depth.frag.glsl")
        self.shading = self.shader(__file__, "fullscreen.vert.glsl", "hardware_pcf.frag.glsl")

    def update(self, frame: Frame) -> None:
        """The light's fit and depth map: they depend on the light and the geometry only."""
        with frame.measure("light_fit"):
            self.frustum = fit_light(frame.scene, self.params.res)
        with frame.measure("shadow_map"):
            self.map.clear()
            GL.glEnable(GL.GL_DEPTH_TEST)
            GL.glDepthFunc(GL.GL_LESS)
            self.light_pass.use().set(light_view=self.frustum.view, light_proj=self.frustum.proj)
            frame.draw_scene()

    def render(self, frame: Frame) -> ShadowOutput:
        f, light = self.frustum, frame.scene.light
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            position = light.position if light.position is not None else (0.0, 0.0, 0.0)
            self.shading.set(shadow_map=self.map.depth.bind(unit), light_view=f.view,
                             light_proj=f.proj, light_is_ortho=f.is_ortho,
                             light_direction=light.direction, light_position=position,
                             map_res=float(self.params.res),
                             normal_offset=self.params.normal_offset, bias=self.params.bias)
            frame.draw_fullscreen(covered_only=True)
        return frame.output(mem_bytes=self.map.nbytes, fetches_per_px=4)

    def release(self) -> None:
        for resource in (self.map, self.light_pass, self.shading):
            resource.release()
