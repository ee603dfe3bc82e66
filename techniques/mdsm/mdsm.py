"""Multiple-depth shadow maps and PCF(k, n) (Pagot, Comba, Oliveira).

Shaders: mdsm_select.frag.glsl (selection pass), mdsm_shading.frag.glsl (PCF(k, n) shading,
built on pcf_samples.glsl and shadow_map.glsl like pcf).
"""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from OpenGL import GL
from pydantic import Field, ValidationError, field_validator, model_serializer, model_validator

from harness.config import SquareInt
from harness.gl.framebuffer import Framebuffer
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TERMS, BIAS_TUNING, MAX_BIAS,
                                          MAX_TEXELS, BiasMode, FilteredShadowMap, Sampling)

SHADING = Path(__file__).with_name("mdsm_shading.frag.glsl")

DEPTH_COUNTS = (1, 2, 3, 4)
WINDOW_SAMPLES = (4, 9, 16, 25)
KERNEL_SAMPLES = tuple(i * i for i in range(1, 9))  # the square grids pcf accepts


def base_channel(p) -> int:
    """The channel of the selected texel that holds the cell's own (base) depth, as
    mdsm_select.frag.glsl stores it; -1 where it is not fixed (sort)."""
    if p.n == 1:
        return 0
    if p.select == "sort":
        return -1
    return 0 if (p.n == 2 and p.extra == "min") else 1


class DepthSelection:
    """The selection pass: a res x res RGBA32F map whose texel holds a cell's n depths, chosen
    from the q = window^2 base-map samples around the cell (mdsm_select.frag.glsl)."""

    def __init__(self, res: int, n: int, q: int, select: str, extra: str):
        self.fbo = Framebuffer(res, res, (GL.GL_RGBA32F,), depth=False)
        side = math.isqrt(q)
        # texel offsets the window spans (odd sides centred, even ones one further right)
        self.window = (-((side - 1) // 2), side - 1 - (side - 1) // 2)
        self.program = Technique.shader(
            __file__, "fullscreen.vert.glsl", "mdsm_select.frag.glsl", N_DEPTHS=n,
            WINDOW=math.isqrt(q), SELECT_SORT=int(select == "sort"),
            EXTRA_MAX=int(extra == "max"))

    @property
    def texture(self):
        return self.fbo.colors[0]

    @property
    def mem_bytes(self) -> int:
        return self.fbo.nbytes

    def render(self, frame: Frame, base_map) -> None:
        self.fbo.bind()
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_BLEND)
        self.program.use().set(base_map=base_map.bind(0))
        frame.draw_fullscreen()

    def release(self) -> None:
        self.fbo.release()
        self.program.release()


class MultipleDepthShadowMap(Technique):
    """An n-SM stores n depths per shadow-map cell in one RGBA32F texel, so one fetch reads all
    of them; PCF(k, n) filters n-shadow tests on pcf's regular k-sample grid (spacing one texel,
    centred on the point), giving up to nk + 1 outcomes (the paper's Table 1).

    Passes: ``shadow_map`` (the standard linear-depth map, as sm and pcf), ``mdsm_select`` (one
    fragment per cell reading q samples of the square window around it: the cell's own depth is
    always kept; ``minmax`` adds the window's maximum (``extra: max``, the default) or minimum
    (``extra: min``) for n = 2 and both for n = 3; ``sort`` sorts the q samples into n groups and
    keeps each group's middle sample, the base depth replacing its own group's), ``shading``
    (k fetches per pixel). For n = 1 the n-SM is the standard map: no selection pass runs and V
    equals pcf's with ``region: fixed``, ``res_factor: 1`` and the same k, res and bias (the
    paper's regular kernel, not pcf's default footprint region). ``extra`` applies to n = 2 with minmax only:
    setting it otherwise is an error, and there it is left out of the stored parameters (so
    they validate again).

    The n-shadow test returns the fraction of the cell's n depths that are not closer to the
    light than the point after bias (1 = lit): n + 1 equally spaced outcomes, exactly Williams'
    test for n = 1. The paper's printed rule for the shadow coverage (sc = 1 if d > Z_n, else
    (i - 1)/n with Z_i the largest stored depth smaller than d) is inconsistent with its own
    descending order Z_1 >= ... >= Z_n: Z_n is the smallest depth, so d > Z_n holds whenever any
    stored depth is in front of the point and the rule returns full shadow for every partly
    shadowed point, while its "otherwise" case (d <= every Z_i) has no Z_i smaller than d. The
    counting definition here is what the text around it and the 2-SM decision tree (Figure 4:
    0, 0.5, 1) describe.

    Bias: every depth read gets ``bias`` (scene units) plus ``slope_bias`` times the receiver
    plane's depth slope per texel times the distance in texels from the point to the texel the
    depth came from (``shadow_map.glsl``, after the receiver plane of Isidoro 2006 and Schueler
    2006). The cell's own (base) depth comes from the texel read, so it gets that texel's
    distance, as in pcf and sm; a depth chosen from the window may come from any of its
    texels, so it gets the distance to the window's farthest texel: the sample's offset plus
    the window radius ((sqrt(q) - 1) / 2 texels each way, one more to the right and top for
    even windows). ``sort`` does not keep the base depth in a fixed channel (it replaces its
    own group's representative), so there every depth gets the window's distance. Giving the
    base depth the window's reach too (as before) let grazing receivers pass tests of real
    occluders: on architecture at 10^5 triangles (512 x 512, map 1024) the default's
    edge_mae 0.131 -> 0.117 and mae 0.059 -> 0.052 with the own reach, acne 0.006 -> 0.009 %;
    ``extra: min``'s leak 0.36 -> 0.18 %. For n = 1 it is pcf's and sm's term. ``bias_mode``
    picks how a read's receiver depth is formed (``shadow_map.glsl``): that bound (``slope``),
    the plane extrapolated (``receiver_plane``) or the tangent plane's depth on the light ray
    through the texel's centre (``adaptive``: no constant and no slope term); for a window
    depth the two plane modes take the most lenient of the window's corners.

    Empty map cells hold the clear depth 3e38 (lit); representatives are picked, never averaged,
    so no depth overflows. Extra result columns: ``select_fetches`` (q x res^2, 0 for n = 1),
    ``select_fetches_per_cell`` (q or 0), ``shaded_px`` (covered pixels f) and
    ``shading_fetches`` (f x k), the two terms of the paper's equation 4.

    =================  ================================================  =======  ================
    Parameter          Meaning                                           Default  Range
    =================  ================================================  =======  ================
    ``res``            map width and height, texels                      1024     16 .. 8192
    ``n``              depths per cell (n-SM)                            2        1, 2, 3, 4
    ``k``              PCF samples on the regular grid, a square         4        1, 4, 9 .. 64
    ``q``              selection window samples, a square                4        4, 9, 16, 25
    ``select``         ``minmax`` (n <= 3) or ``sort``                   minmax
    ``extra``          n = 2 with minmax only: ``max`` or ``min``        max      max, min
    ``bias``           constant depth bias, scene units                  0.02     0 .. 1e7
    ``slope_bias``     times the receiver plane's depth slope x the      1.0      0 .. 64
                       distance to the farthest texel a depth may come
                       from
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
                       before the samples: this many x the texel's
                       world size there x sin(the light's angle)
    =================  ================================================  =======  ================
    """

    name = "mdsm"
    colour = "#2ca02c"
    summary = "multiple-depth shadow map: n depths per cell, PCF(k, n) with up to nk + 1 levels"
    paper = "Pagot, Comba, Oliveira, Multiple-Depth Shadow Maps"
    # quality knobs: the map size (to 2048: at 4096 the selection pass alone costs make bench a
    # tenth of its time), the depths and the samples per cell
    quality_knobs = {"res": (256, 1024, 2048), "n": (1, 2, 3), "k": (1, 4, 9)}
    # the selection window besides the bias terms: how far a depth may come from its cell
    tunable = {**BIAS_TUNING, **BIAS_MODE_TUNING, "q": ("choice", WINDOW_SAMPLES)}
    bias_terms = BIAS_TERMS
    declines_lights = {"point": "it has no cube-map path: its selection pass and PCF(k, n) read "
                                "square windows of one light frustum's map"}

    class Params(TechniqueParams):
        res: int = Field(1024, ge=16, le=8192)
        n: Literal[1, 2, 3, 4] = 2
        # a 2 x 2 kernel over a 2 x 2 window (were 3 x 3 and 3 x 3, issue 46): the soft edge
        # reaches the kernel plus the window past the shadow boundary, in texels, so where a
        # texel covers pixels (map 256 under a 512 x 384 view) the 3 x 3 pair put 0.3 to
        # 1.2 % of the lit pixels of the real corpus in false shadow beyond the edge band,
        # under the spot lights too; the 2 x 2 pair at most 0.19 % there (docs/techniques.md)
        k: SquareInt = Field(4, le=64)
        q: Literal[4, 9, 16, 25] = 4
        select: Literal["minmax", "sort"] = "minmax"
        # meaningful for n = 2 with minmax only; a concrete default so one configuration has
        # one run id
        extra: Literal["max", "min"] = "max"
        bias: float = Field(0.02, ge=0, le=MAX_BIAS)
        slope_bias: float = Field(1.0, ge=0, le=MAX_TEXELS)
        bias_mode: BiasMode = "slope"
        normal_offset: float = Field(0.0, ge=0, le=MAX_TEXELS)

        @field_validator("n", "k", "q", mode="wrap")
        @classmethod
        def _name_allowed_values(cls, value, handler, info):
            """The annotations say what is allowed (``shadowbench list`` shows it); the error
            lists every allowed value."""
            try:
                return handler(value)
            except ValidationError:
                what = {"n": ("n must be one of", DEPTH_COUNTS),
                        "k": ("k must be a square number, one of", KERNEL_SAMPLES),
                        "q": ("q must be a square window, one of", WINDOW_SAMPLES)}
                text, allowed = what[info.field_name]
                raise ValueError(f"{text} {list(allowed)}; got {value!r}") from None

        @model_validator(mode="after")
        def _combination(self):
            if "extra" in self.model_fields_set and not self.uses_extra:
                raise ValueError(f"extra ({self.extra}) applies only to n=2 with "
                                 f"select=minmax; got n={self.n}, select={self.select}")
            if self.select == "minmax" and self.n == 4:
                raise ValueError("select=minmax allows n in [1, 2, 3] (base, max and/or min); "
                                 "n=4 needs select=sort")
            return self

        @model_serializer(mode="wrap")
        def _without_unused_extra(self, handler):
            """``extra`` only where it applies, so the dumped parameters validate again."""
            data = handler(self)
            if not self.uses_extra:
                data.pop("extra", None)
            return data

        @property
        def uses_extra(self) -> bool:
            return self.n == 2 and self.select == "minmax"

        @property
        def extra_depth(self) -> str:
            """The window extreme kept besides the base depth for n = 2 with minmax."""
            return self.extra

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.passes = FilteredShadowMap(frame, p.res, SHADING, N_DEPTHS=p.n,
                                        BASE_CHANNEL=base_channel(p))
        self.selection = (DepthSelection(p.res, p.n, p.q, p.select, p.extra_depth)
                          if p.n > 1 else None)

    def update(self, frame: Frame) -> None:
        """The base map and its depth selection: they depend on the light and geometry only."""
        self.passes.update(frame)
        if self.selection:
            with frame.measure("mdsm_select"):
                self.selection.render(frame, self.passes.map.fbo.colors[0])

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        base = self.passes.map
        self.passes.shade(frame, Sampling(grid_n=math.isqrt(p.k), bias_min=p.bias,
                                          bias_max=p.bias, slope_bias=p.slope_bias,
                                          normal_offset=p.normal_offset,
                                          bias_mode=p.bias_mode,
                                          window=self.selection.window if self.selection else (0, 0)),
                          texture=self.selection.texture if self.selection else None)
        q = p.q if self.selection else 0
        shaded = int(frame.arrays.covered.sum())
        return frame.output(
            mem_bytes=base.mem_bytes + (self.selection.mem_bytes if self.selection else 0),
            fetches_per_px=p.k, nonfinite=base.nonfinite,
            extra={"select_fetches": q * p.res * p.res, "select_fetches_per_cell": q,
                       "shaded_px": shaded, "shading_fetches": shaded * p.k})

    def release(self) -> None:
        self.passes.release()
        if self.selection:
            self.selection.release()
