"""Percentage-closer filtering (Reeves, Salesin, Cook 1987)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal

from pydantic import Field, model_validator

from harness.config import SquareInt
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TUNING, MAX_BIAS, MAX_TEXELS, BiasMode,
                                          FilteredShadowMap, Sampling)

SHADING = Path(__file__).with_name("pcf_shading.frag.glsl")


class PercentageCloserFiltering(Technique):
    """Compare first, then filter: the fraction of k map samples closer to the light than
    the shaded point (the paper's Figure 4), so V takes at most k + 1 values.

    Sample region (``region: footprint``, the paper's section 3.2 and Figure 4): the pixel's
    footprint in the map, times ``res_factor``, each side at least ``min_size`` texels (by
    default half the footprint's bounding box, at least a quarter texel: the filter
    antialiases the pixel, it does not blur the map; the paper's MinSize of one texel blurred
    edges past sm's where a texel covers pixels, and read across creases). The
    footprint is the bounding box in the map of the pixel's square on its receiver plane (the
    plane through the G-buffer position with its normal, cut by the camera rays through the
    pixel's sides), so neighbouring pixels on other surfaces do not widen it; a pixel seeing its
    plane edge-on stops at 64 texels. ``k`` and ``sampling`` change only where the samples fall
    inside the region: ``grid`` puts sqrt(k) x sqrt(k) samples evenly from one side to the
    other (so the region alone, not k, sets how wide a shadow edge is); ``jitter`` puts one
    seeded uniform sample in each of sqrt(k) x sqrt(k) sub-regions (stratified jitter, the
    paper's method c). The paper fits ns x nt samples to the box's aspect; here the grid is
    square. ``region: fixed`` is the earlier region, independent of the pixel: sqrt(k) x sqrt(k)
    sub-regions of ``res_factor`` texels, sampled at their centres or jittered inside them (the
    regular kernel MDSM's paper compares with).

    Bias: each sample draws a constant from [``bias_min``, ``bias_max``] (the paper's Bias0,
    Bias1, scene units), plus ``slope_bias`` times the receiver plane's depth slope per texel
    times the distance in texels from the point to the centre of the texel the sample reads
    (``shadow_map.glsl``, after Isidoro 2006 and Schueler 2006): samples far out in a large
    region get the bias their distance needs,
    which one constant cannot give for every region, scene size and map size (Reeves et al.
    tune Bias per scene). ``bias_mode`` picks how each sample's receiver depth is formed
    (``shadow_map.glsl``): that bound (``slope``), the plane extrapolated (``receiver_plane``)
    or the tangent plane's depth on the light ray through the texel's centre (``adaptive``:
    no constant and no slope term). Points behind the light or outside the map count as lit. A point
    light gets sm's cube of six faces, each face's 90 degrees over ``res`` texels and 32 more
    texels of its neighbours' directions on every side (half the largest region), so no
    sample of a point near a face's edge falls off its face.

    =================  ===============================================  =========  ===============
    Parameter          Meaning                                          Default    Range
    =================  ===============================================  =========  ===============
    ``res``            map width and height, texels                     1024       16 .. 8192
    ``k``              samples per pixel (NumSamples), a square         16         1 .. 64
    ``sampling``       ``grid`` or ``jitter`` (stratified)              grid
    ``region``         ``footprint`` (pixel footprint) or ``fixed``     footprint
    ``res_factor``     footprint: times the footprint (ResFactor);      0.5        (0, 64]
                       fixed: sub-region side, texels
    ``min_size``       footprint: smallest region side, texels          0.25       (0, 64]
                       (MinSize)
    ``bias_min``       smallest per-sample bias, scene units (Bias0)    0.02       0 .. 1e7
    ``bias_max``       largest per-sample bias, scene units (Bias1)     0.04       bias_min .. 1e7
    ``slope_bias``     times the receiver plane's depth slope x each    1.0        0 .. 64
                       sample's distance to its texel, texels
    ``bias_mode``      how each read's receiver depth is formed:        slope
                       ``slope``: less ``slope_bias`` x the plane's
                       depth slope x the distance (the bound);
                       ``receiver_plane``: the plane extrapolated
                       to the texel read (Isidoro 2006), times
                       ``slope_bias``; ``adaptive``: where the light
                       ray through the texel's centre meets the
                       tangent plane, less a rounding epsilon, no
                       constant or slope term (Dou et al. 2014)
    ``normal_offset``  moves the point along its light-facing normal    0.0        0 .. 64
                       before the samples: this many x the texel's
                       world size there x sin(the light's angle)
    ``seed``           seed of the jitter and bias draws                0          >= 0
    =================  ===============================================  =========  ===============
    """

    name = "pcf"
    colour = "#ff7f0e"
    summary = "percentage-closer filtering: k depth comparisons averaged"
    paper = "Reeves, Salesin, Cook 1987, Rendering antialiased shadows with depth maps"
    # quality knobs: the map size (factor-4 steps keep make bench within its 10 minutes), and
    # the samples
    quality_knobs = {"res": (256, 1024, 4096), "k": (1, 4, 16, 36)}
    # its constant bias is a range [bias_min, bias_max] (Reeves et al. tune Bias0 and Bias1 per
    # scene), its filter a region of the footprint times res_factor, at least min_size texels
    tunable = {"bias_min": BIAS_TUNING["bias"], "bias_max": BIAS_TUNING["bias"],
               "slope_bias": BIAS_TUNING["slope_bias"],
               "normal_offset": BIAS_TUNING["normal_offset"], **BIAS_MODE_TUNING,
               "region": ("choice", ("footprint", "fixed")),
               "res_factor": ("log", 0.125, 4.0), "min_size": ("log", 0.125, 4.0)}
    bias_terms = ("bias_min", "bias_max", "slope_bias", "normal_offset")
    declines_lights = {}  # a point light gets a cube map: six faces

    class Params(TechniqueParams):
        res: int = Field(1024, ge=16, le=8192)
        k: SquareInt = Field(16, le=64)
        sampling: Literal["grid", "jitter"] = "grid"
        region: Literal["footprint", "fixed"] = "footprint"
        # half the footprint's bounding box, at least a quarter texel (were 1 and 1 texel):
        # the box of a slanted footprint is wider than the footprint, and a region of one
        # texel where a texel covers several pixels blurs the edge past a pixel and reads
        # the next face of a crease (docs/techniques.md, "pcf's region")
        res_factor: float = Field(0.5, gt=0, le=64)
        min_size: float = Field(0.25, gt=0, le=64)
        bias_min: float = Field(0.02, ge=0, le=MAX_BIAS)
        bias_max: float = Field(0.04, ge=0, le=MAX_BIAS)
        slope_bias: float = Field(1.0, ge=0, le=MAX_TEXELS)
        bias_mode: BiasMode = "slope"
        normal_offset: float = Field(0.0, ge=0, le=MAX_TEXELS)
        seed: int = Field(0, ge=0, lt=2**32)

        @model_validator(mode="after")
        def _bias_range(self):
            if self.bias_max < self.bias_min:
                raise ValueError(f"bias_max ({self.bias_max}) < bias_min ({self.bias_min})")
            return self

    def prepare(self, frame: Frame) -> None:
        self.passes = FilteredShadowMap(frame, self.params.res, SHADING)

    def update(self, frame: Frame) -> None:
        self.passes.update(frame)

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        self.passes.render(frame, Sampling(
            grid_n=math.isqrt(p.k), footprint_region=p.region == "footprint",
            res_factor=p.res_factor, min_size=p.min_size, spacing=p.res_factor,
            jitter=p.sampling == "jitter", seed=p.seed, bias_min=p.bias_min,
            bias_max=p.bias_max, slope_bias=p.slope_bias, normal_offset=p.normal_offset,
            bias_mode=p.bias_mode))
        return frame.output(mem_bytes=self.passes.map.mem_bytes, fetches_per_px=p.k,
                            nonfinite=self.passes.map.nonfinite)

    def release(self) -> None:
        self.passes.release()
