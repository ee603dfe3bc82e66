"""Percentage-closer filtering (Reeves, Salesin, Cook 1987)."""

from __future__ import annotations

import math
from typing import Literal

from pydantic import Field, model_validator

from harness.config import SquareInt
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from .shadowmap import FilteredShadowMap


class PercentageCloserFiltering(Technique):
    """Compare first, then filter: the fraction of k map samples closer to the light than
    the shaded point (the paper's Figure 4), so V takes at most k + 1 values.

    The sample region is a square of ``sqrt(k) * res_factor`` texels centred on the point,
    split into sqrt(k) x sqrt(k) sub-regions: ``grid`` samples each sub-region's centre,
    ``jitter`` a seeded uniform point inside it (stratified jitter, the paper's method c).
    The paper sizes the region from the pixel's footprint clamped to a minimum; these scenes
    magnify the map, so the minimum (one texel per sub-region, times ``res_factor``) applies.
    Each sample draws its bias uniformly from [``bias_min``, ``bias_max``]. Points behind the
    light or outside the map count as lit.

    ==============  ===============================================  ========  ===========
    Parameter       Meaning                                          Default   Range
    ==============  ===============================================  ========  ===========
    ``res``         map width and height, texels                     1024      16 .. 8192
    ``k``           samples per pixel (NumSamples), a square         16        1 .. 64
    ``sampling``    ``grid`` or ``jitter`` (stratified)              grid
    ``res_factor``  sub-region side in texels (ResFactor)            1.0       (0, 64]
    ``bias_min``    smallest per-sample bias, scene units (Bias0)    0.02      >= 0
    ``bias_max``    largest per-sample bias, scene units (Bias1)     0.04      >= bias_min
    ``slope_bias``  slope-scaled bias, texels x tan(incidence)       0.0       >= 0
    ``seed``        seed of the jitter and bias draws                0         >= 0
    ==============  ===============================================  ========  ===========
    """

    name = "pcf"
    summary = "percentage-closer filtering: k depth comparisons averaged"
    paper = "Reeves, Salesin, Cook 1987, Rendering antialiased shadows with depth maps"
    # quality knobs: map size, and samples (k = 9 left out to keep make bench in its time)
    quality_knobs = {"res": (256, 512, 1024, 2048, 4096), "k": (1, 4, 16, 36)}

    class Params(TechniqueParams):
        res: int = Field(1024, ge=16, le=8192)
        k: SquareInt = Field(16, le=64)
        sampling: Literal["grid", "jitter"] = "grid"
        res_factor: float = Field(1.0, gt=0, le=64)
        bias_min: float = Field(0.02, ge=0)
        bias_max: float = Field(0.04, ge=0)
        slope_bias: float = Field(0.0, ge=0)
        seed: int = Field(0, ge=0, lt=2**32)

        @model_validator(mode="after")
        def _bias_range(self):
            if self.bias_max < self.bias_min:
                raise ValueError(f"bias_max ({self.bias_max}) < bias_min ({self.bias_min})")
            return self

    def prepare(self, frame: Frame) -> None:
        self.passes = FilteredShadowMap(frame, self.params.res)

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        self.passes.render(frame, grid_n=math.isqrt(p.k), spacing=p.res_factor,
                           bias_min=p.bias_min, bias_max=p.bias_max, slope_bias=p.slope_bias,
                           jitter=p.sampling == "jitter", seed=p.seed)
        return frame.output(mem_bytes=self.passes.map.mem_bytes, fetches_per_px=p.k,
                            nonfinite=self.passes.map.nonfinite)

    def release(self) -> None:
        self.passes.release()
