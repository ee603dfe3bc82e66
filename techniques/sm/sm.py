"""Williams' shadow map (1978)."""

from __future__ import annotations

from pathlib import Path

from pydantic import Field

from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from techniques.common.footprint import light_map_texels_per_pixel
from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TERMS, BIAS_TUNING, MAX_BIAS,
                                          MAX_TEXELS, BiasMode, MapShading, alpha_fetches_per_px,
                                          bias_uniforms)

SHADING = Path(__file__).with_name("sm_shading.frag.glsl")


class ShadowMap(Technique):
    """One depth map from the light, one depth comparison per shaded pixel.

    Orthographic map fitted to the scene bounds for a directional light, perspective over the
    cone for a spot light, and for a point light a cube: six 90-degree perspective faces of
    ``res`` x ``res`` texels, each point tested in the face its direction falls in (one timed
    pass per face; ``mem_bytes`` counts all six). Map depths are linear light-space distances
    (along the face's axis, for a cube), so ``bias`` is in scene units. The comparison reads
    the centre of the point's texel, up to half a texel away from the point in each axis; the
    bias is ``bias`` plus ``slope_bias`` times the receiver plane's depth slope per texel
    times that distance (``shadow_map.glsl``, after the receiver plane of Isidoro 2006 and
    Schueler 2006), the rule every map technique here shares. ``bias_mode`` picks how the
    read's receiver depth is formed (``shadow_map.glsl``): that bound (``slope``, the default),
    the receiver plane extrapolated to the texel's centre (``receiver_plane``), or the depth
    where the light ray through the texel's centre meets the point's tangent plane
    (``adaptive``, Dou et al. 2014: no constant and no slope term, a rounding epsilon only).
    Alpha-tested casters are cut out in the depth pass (``light_maps``: a cut-out texel writes
    no depth), whose alpha texels ``fetches_per_px`` counts per shaded pixel.

    =================  ================================================  =======  ===========
    Parameter          Meaning                                           Default  Range
    =================  ================================================  =======  ===========
    ``res``            map (a cube face's) width and height, texels      1024     16 .. 8192
    ``bias``           constant depth bias, scene units                  0.02     0 .. 1e7
    ``slope_bias``     times the receiver plane's depth slope x the      1.0      0 .. 64
                       distance to the texel read, texels
    ``bias_mode``      how each read's receiver depth is formed:         slope
                       ``slope``: less ``slope_bias`` x the plane's
                       depth slope x the distance (the bound);
                       ``receiver_plane``: the plane extrapolated
                       to the texel read (Isidoro 2006), times
                       ``slope_bias``; ``adaptive``: where the light
                       ray through the texel's centre meets the
                       tangent plane, less a rounding epsilon, no
                       constant or slope term (Dou et al. 2014)
    ``normal_offset``  moves the point along its light-facing normal     0.0      0 .. 64
                       before the read: this many x the texel's world
                       size there x the sine of the light's angle
    =================  ================================================  =======  ===========
    """

    name = "sm"
    colour = "#1f77b4"
    summary = "shadow map: one depth comparison per pixel"
    paper = "Williams 1978, Casting curved shadows on curved surfaces"
    # quality knob: the map size (the one way Williams' map buys accuracy with time), in
    # factor-4 steps that keep make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}
    tunable = {**BIAS_TUNING, **BIAS_MODE_TUNING}
    bias_terms = BIAS_TERMS
    # the oldest and simplest map: the others' cost is read as a multiple of its
    baseline = True
    declines_lights = {}  # a point light gets a cube map: six faces
    alpha_casters = True  # the depth pass cuts them out (light_maps)

    class Params(TechniqueParams):
        res: int = Field(1024, ge=16, le=8192)
        bias: float = Field(0.02, ge=0, le=MAX_BIAS)
        slope_bias: float = Field(1.0, ge=0, le=MAX_TEXELS)
        bias_mode: BiasMode = "slope"
        normal_offset: float = Field(0.0, ge=0, le=MAX_TEXELS)

    def prepare(self, frame: Frame) -> None:
        self.passes = MapShading(frame, self.params.res, SHADING)

    def update(self, frame: Frame) -> None:
        self.passes.update(frame)

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        self.passes.render(frame, p.slope_bias, bias=p.bias, normal_offset=p.normal_offset,
                           **bias_uniforms(p.bias_mode))
        # one depth read per pixel, and the depth pass's alpha texels where casters are cut out
        fetches = 1 + alpha_fetches_per_px(frame, self.passes.map)
        return frame.output(mem_bytes=self.passes.map.mem_bytes, fetches_per_px=fetches,
                            nonfinite=self.passes.map.nonfinite,
                            extra=light_map_texels_per_pixel(frame, self.passes.map))

    def release(self) -> None:
        self.passes.release()
