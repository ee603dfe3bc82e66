"""The technique shared by psm, lispsm and gmnpr: a light's depth map under a perspective warp,
with its aliasing and coverage columns; the helpers' public names are re-exported here.

The papers' formulas are in ``warp_equations``, the body the warps fit and the space they are
made in in ``warp_body``, the warps and their unit-cube fit in ``warp_fit``, the aliasing and
coverage measurements in ``warp_diagnostics``.
"""

from __future__ import annotations

import math

import numpy as np
from OpenGL import GL
from pydantic import Field

from harness.truth import metrics
from harness.config import SquareInt
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from techniques.common.footprint import light_map_texels_per_pixel
from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TERMS, BIAS_TUNING, MAX_BIAS,
                                          MAX_TEXELS, BiasMode, LightDepthMap,
                                          alpha_fetches_per_px, bias_uniforms)
from .warp_body import (LightSpace, ReceiverPoints, Receivers, ViewSetup, caster_body,
                        convex_vertices, homogeneous, light_space, padded_bounds, project,
                        receiver_body, receiver_points, space_depth_range, space_theta,
                        view_setup)
from .warp_receivers import ReceiverReduction
from .warp_diagnostics import (ALIAS_MIN_COS, NEAR_FRACTION, alias_map, alias_statistics,
                               map_coordinates, outside_unit_cube)
from .warp_equations import (LAMBDA_MAX, EyeDistance, aliasing_F, gmnpr_eye_distance,
                             lambda_gmnpr, lambda_lispsm, lambda_minimum_norm,
                             lispsm_eye_distance, n_opt)
from .warp_fit import (CUBE_MARGIN, PostPerspective, Warp, cube_fit, frustum_from_clip,
                       light_space_warp, local_light_view, oriented_basis, post_perspective_warp,
                       unwarped_clip, warp_axis, warp_columns)

__all__ = [
    # warp_equations
    "LAMBDA_MAX", "EyeDistance", "aliasing_F", "gmnpr_eye_distance", "lambda_gmnpr",
    "lambda_lispsm", "lambda_minimum_norm", "lispsm_eye_distance", "n_opt",
    # warp_body
    "LightSpace", "ReceiverPoints", "Receivers", "ViewSetup", "caster_body", "convex_vertices",
    "homogeneous", "light_space", "padded_bounds", "project", "receiver_body", "receiver_points",
    "space_depth_range", "space_theta", "view_setup",
    # warp_receivers
    "ReceiverReduction",
    # warp_fit
    "CUBE_MARGIN", "PostPerspective", "Warp", "cube_fit", "frustum_from_clip", "light_space_warp",
    "local_light_view", "oriented_basis", "post_perspective_warp", "unwarped_clip", "warp_axis",
    "warp_columns",
    # warp_diagnostics
    "ALIAS_MIN_COS", "NEAR_FRACTION", "alias_map", "alias_statistics", "map_coordinates",
    "outside_unit_cube",
    # this module
    "PARAMETER_TABLE", "WarpParams", "WarpedShadowMap",
]


PARAMETER_TABLE = """
    =================  ================================================  =======  ===========
    Parameter          Meaning                                           Default  Range
    =================  ================================================  =======  ===========
    ``res``            map width and height, texels                      1024     16 .. 8192
    ``bias``           constant depth bias, scene units                  0.02     0 .. 1e7
    ``slope_bias``     times the receiver plane's depth slope x each     1.0      0 .. 64
                       read's distance, in the warped map's texels
                       (shadow_map.glsl)
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
                       before its reads: this many x the warped map's
                       texel's world size there x sin(the light's angle)
    ``k``              PCF samples per pixel, a square grid of texels    1        1 .. 49
    =================  ================================================  =======  ===========
    """


class WarpParams(TechniqueParams):
    res: int = Field(1024, ge=16, le=8192)
    bias: float = Field(0.02, ge=0, le=MAX_BIAS)
    slope_bias: float = Field(1.0, ge=0, le=MAX_TEXELS)
    bias_mode: BiasMode = "slope"
    normal_offset: float = Field(0.0, ge=0, le=MAX_TEXELS)
    k: SquareInt = Field(1, le=49)


class WarpedShadowMap(Technique):
    """A light's depth map under a warp chosen by ``warp(setup, res)`` (which returns a
    :class:`Warp` or :class:`PostPerspective` and the technique's extra columns, or raises
    NotApplicable for a light the technique does not treat), looked up by
    ``warp_shading.frag.glsl``. Columns of every warp: ``theta_deg``, ``alias_mean``,
    ``alias_max``, ``alias_near`` (see :func:`alias_statistics`), ``outside_pct``."""

    Params = WarpParams
    tunable = {**BIAS_TUNING, **BIAS_MODE_TUNING}
    bias_terms = BIAS_TERMS
    alpha_casters = True  # the depth pass cuts them out (light_maps)
    declines_lights = {"point": "its warp reparameterises one light frustum, and a point light "
                                "shines every way"}

    def warp(self, setup: ViewSetup, res: int) -> tuple[Warp | PostPerspective, dict]:
        raise NotImplementedError

    def prepare(self, frame: Frame) -> None:
        self.map = LightDepthMap(frame, self.params.res)
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl", "warp_shading.frag.glsl")
        self.receivers = ReceiverReduction()
        self.diagnosed = None  # (G-buffer arrays, warp clip) the diagnostics were made for
        self.fit(frame)  # a warp that does not treat the scene's light says so here

    def fit(self, frame: Frame) -> None:
        """The warp of the frame's camera, light and visible receivers, timed (``warp_fit``:
        an engine fits it every frame); then its aliasing and coverage diagnostics, untimed.
        It depends on the camera, so it is per-view work: ``render`` does it, and nothing is
        left for ``update``."""
        res = self.params.res
        with frame.measure("warp_fit"):
            self.transform, columns = self.warp(view_setup(frame, self.receivers.find), res)
            self.map.frustum = self.transform.frustum
        self.diagnose(frame, columns)

    def diagnose(self, frame: Frame, columns: dict) -> None:
        """The aliasing map and the result columns of the fitted warp, from the CPU copy of
        the G-buffer (untimed: no renderer computes them). Made again only when the warp or
        the G-buffer changed: on a still scene every frame's fit is the same, and at ~0.1 s
        a frame (256^2, NumPy) they would outweigh the frames themselves."""
        arrays, clip = frame.arrays, self.transform.clip
        if (self.diagnosed is not None and self.diagnosed[0] is arrays
                and np.array_equal(self.diagnosed[1], clip)):
            return
        self.diagnosed = (arrays, clip)
        alias = alias_map(clip, self.params.res, arrays.position, arrays.normal, arrays.covered)
        reached = arrays.covered
        if frame.scene.light.type == "spot":  # outside its cone no receiver needs the map
            reached = reached & frame.scene.light.inside_cone(arrays.position)
        outside = outside_unit_cube(clip, arrays.position, reached)
        with np.errstate(divide="ignore", invalid="ignore"):
            self.alias_log2 = np.log2(alias)
        self.columns = dict(
            theta_deg=math.degrees(self.transform.theta),
            **alias_statistics(alias, arrays.normal, arrays.position, arrays.covered,
                               frame.scene.light, frame.camera.view),
            outside_pct=100.0 * float(np.count_nonzero(outside))
            / max(np.count_nonzero(reached), 1),
            **columns)

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        self.fit(frame)
        with frame.measure("shadow_map"):
            # casters nearer the light than the fitted range still occlude: depth clamp puts them
            # on the near plane instead of clipping them (past the far plane, where the clamped
            # depth equals the cleared one, lie no receivers to shadow)
            GL.glEnable(GL.GL_DEPTH_CLAMP)
            self.map.render(frame)
            GL.glDisable(GL.GL_DEPTH_CLAMP)
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            self.shading.set(**self.map.lookup_uniforms(unit, p.slope_bias, frame),
                             grid_n=math.isqrt(p.k), bias=p.bias, normal_offset=p.normal_offset,
                             **bias_uniforms(p.bias_mode))
            frame.draw_fullscreen(covered_only=True)  # V = 1 where no surface
        warnings = []
        if self.columns["outside_pct"] > 0:
            warnings.append(f"{self.columns['outside_pct']:.2f}% of visible receivers fall "
                            "outside the warped map")
        return frame.output(mem_bytes=self.map.mem_bytes,
                            fetches_per_px=p.k + alpha_fetches_per_px(frame, self.map),
                            nonfinite=self.map.nonfinite + metrics.nonfinite(self.transform.clip),
                            extra={**self.columns,
                                   **light_map_texels_per_pixel(frame, self.map)},
                            warnings=warnings,
                            maps={"pixels_per_texel_log2": self.alias_log2})

    def release(self) -> None:
        # prepare may have stopped early (a failed compile)
        for name in ("map", "shading", "receivers"):
            resource = self.__dict__.pop(name, None)
            if resource is not None:
                resource.release()
