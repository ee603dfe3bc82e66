"""Cascaded (parallel-split) shadow maps, Zhang et al. 2006, with the sample distribution fit
of Lauritzen, Salvi and Lefohn 2010 and the stabilised cascades engines ship."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import Literal

import numpy as np
from pydantic import Field, create_model

from harness.gl.reduction import CoveredRange
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams
from harness.scene.transforms import LightFrustum, any_perpendicular_up, box_corners, look_at

from techniques.common.footprint import texels_per_pixel
from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TERMS, BIAS_TUNING, EMPTY_DEPTH,
                                          MAX_BIAS, MAX_TEXELS, BiasMode, LightDepthMap,
                                          alpha_fetches_per_px, bias_uniforms, depth_precision)

MAX_SPLITS = 4  # csm_shading.frag.glsl's MAX_CASCADES
# Relative margin around a slice's light-space box: its receivers on the box's faces stay
# inside the map after float32 rounding.
FIT_MARGIN = 1.0e-3
# A stabilised cascade's radius is rounded up to a multiple of 2^-RADIUS_STEPS_LOG2 of the
# power of two below it (at most 1/16 more texel size): rounding noise in the slice's corners
# and, under sdsm, small changes of the visible depth range leave the texel size, and so the
# map's texel grid, as it was.
RADIUS_STEPS_LOG2 = 4


def split_depths(near: float, far: float, splits: int, lam: float) -> np.ndarray:
    """The practical split scheme (Zhang et al. 2006): C_i = lam n (f/n)^(i/N) + (1 - lam)
    (n + (f - n) i/N), i = 0..N, a blend of the logarithmic and the uniform split."""
    i = np.arange(splits + 1) / splits
    depths = lam * near * (far / near) ** i + (1 - lam) * (near + (far - near) * i)
    depths[0], depths[-1] = near, far
    return depths


def slice_corners(view: np.ndarray, proj: np.ndarray, near: float, far: float) -> np.ndarray:
    """World positions of the 8 corners of a symmetric perspective view frustum between the
    view depths ``near`` and ``far``."""
    tan_x, tan_y = 1 / proj[0, 0], 1 / proj[1, 1]
    local = np.array([[sx * d * tan_x, sy * d * tan_y, -d, 1.0]
                      for d in (near, far) for sx in (-1, 1) for sy in (-1, 1)])
    return (local @ np.linalg.inv(view).T)[:, :3]


def stable_radius(radius: float) -> float:
    step = 2.0 ** (math.floor(math.log2(max(radius, 1e-30))) - RADIUS_STEPS_LOG2)
    return math.ceil(radius / step) * step


@dataclass(frozen=True)
class Cascade:
    frustum: LightFrustum
    near: float  # the view depths of its slice
    far: float
    texel_world: float  # the longer side of a texel in world units (the same everywhere)


def light_rotation(light_direction) -> np.ndarray:
    """World -> the light's rigid basis (no translation; -z: the light's travel), fixed by the
    light's direction alone."""
    d = np.asarray(light_direction, np.float64)
    d = d / np.linalg.norm(d)
    return look_at(np.zeros(3), d, any_perpendicular_up(d))


def fit_cascade(corners: np.ndarray, light_direction, bounds: np.ndarray, res: int,
                stabilize: bool, near: float, far: float,
                receivers: tuple[np.ndarray, np.ndarray] | None = None) -> Cascade:
    """An orthographic light frustum over the slice with ``corners``, deep enough for every
    caster in the scene ``bounds``; unstabilised, over ``receivers`` instead where given (the
    low and high x, y of the slice's visible receivers in :func:`light_rotation`'s basis).

    Stabilised, it is the square round the slice's bounding sphere (centred on the corners'
    mean; its radius rounded up by :func:`stable_radius`) with its centre snapped to whole
    texels of the light's fixed rotation: while the radius stays, a camera move or turn only
    shifts the map by whole texels, so every world point keeps its texel and its depth test.
    Otherwise it is the light-space box of the corners (of the receivers), the tightest fit,
    which slides and stretches under the texel grid with every camera change."""
    rotation = light_rotation(light_direction)
    if stabilize:
        centre = corners.mean(axis=0)
        radius = stable_radius(float(np.linalg.norm(corners - centre, axis=1).max()))
        half = np.array([radius, radius])
        texel = 2 * radius / res
        middle = np.round((rotation[:2, :3] @ centre) / texel) * texel
    else:
        if receivers is None:
            local = corners @ rotation[:2, :3].T
            lo, hi = local.min(axis=0), local.max(axis=0)
        else:
            lo, hi = receivers
        middle = (lo + hi) / 2
        # float32 receivers: a few units in the last place of their coordinates
        half = (hi - lo) / 2 * (1 + FIT_MARGIN) + 1e-5 * (1 + np.abs(middle).max())
    # depth along the light from just before the scene's first caster to past its last surface,
    # fixed by the scene alone, so the stored depths do not move with the camera either
    depth = -(box_corners(bounds) @ rotation[2, :3])
    pad = 0.01 * float(depth.max() - depth.min()) + 1e-3
    view = rotation.copy()
    view[:3, 3] = [-middle[0], -middle[1], float(depth.min()) - 2 * pad]
    map_near, map_far = pad, float(depth.max() - depth.min()) + 3 * pad
    import pyrender  # here: the registry imports this module for shadowbench list too

    proj = pyrender.OrthographicCamera(xmag=half[0], ymag=half[1], znear=map_near,
                                       zfar=map_far).get_projection_matrix()
    return Cascade(LightFrustum(view, proj, True, map_near, map_far), near, far,
                   float(2 * half.max() / res))


def scene_depth_range(view: np.ndarray, bounds: np.ndarray, near: float,
                      far: float) -> tuple[float, float]:
    """The camera's ``near`` and ``far`` clipped to the view depths of the scene's bounding
    box (its 8 corners): fit frustum's n and f. A far plane set far past the scene (far: 100
    on a scene 15 units deep) put every pixel in the first cascade; the box holds every
    surface the view can show, so no pixel falls outside the slices. Where the box lies wholly
    in front of near or behind far, the camera's planes are kept."""
    depth = -(box_corners(bounds) @ view[2, :3] + view[2, 3])
    # float32 depths of float32 positions: a few 1e-7 of the depth, as sdsm pads
    pad = 1e-3 * float(depth.max() - depth.min()) + 1e-5 * float(np.abs(depth).max())
    low, high = max(float(depth.min()) - pad, near), min(float(depth.max()) + pad, far)
    if not high > low:
        return near, far
    return low, high


def cascade_of(depth: np.ndarray, ends: np.ndarray) -> np.ndarray:
    """Per view depth, the first cascade whose slice ends at or beyond it (the last for any
    beyond all), as csm_shading.frag.glsl chooses."""
    return np.minimum(np.searchsorted(ends, depth, side="left"), len(ends) - 1)


_Params = create_model(
    "Params", __base__=TechniqueParams,
    res=(int, Field(1024, ge=16, le=8192)),
    splits=(int, Field(4, ge=1, le=MAX_SPLITS)),
    # a Python keyword, so a field made by name: the YAML and --set key is ``lambda``
    **{"lambda": (float, Field(0.5, ge=0, le=1))},
    # the visible depths (issue 46; frustum before): at every split count its curve lies below
    # fit frustum's at equal time on the corpus and the shipped scenes (docs/techniques.md)
    fit=(Literal["frustum", "sdsm"], "sdsm"),
    stabilize=(bool, False),
    bias=(float, Field(0.02, ge=0, le=MAX_BIAS)),
    slope_bias=(float, Field(1.0, ge=0, le=MAX_TEXELS)),
    bias_mode=(BiasMode, "slope"),
    normal_offset=(float, Field(0.0, ge=0, le=MAX_TEXELS)),
)


class CascadedShadowMap(Technique):
    """The view frustum cut into ``splits`` slices along view depth, each with its own
    orthographic map of ``res`` x ``res``; a pixel is tested in the map of the slice it lies
    in, with no blending between cascades (the shadow stays hard).

    The slices run from n to f by the practical split scheme (:func:`split_depths`). With
    ``fit: frustum`` n and f are the camera's near and far planes (PSSM) clipped to the view
    depths of the scene's bounding box (:func:`scene_depth_range`: a far plane of 100 on a
    scene 15 units deep put every pixel in the first cascade); with ``fit: sdsm`` (the
    default) they are the nearest and farthest view depth of the visible pixels, from a GPU
    reduction over the G-buffer (fit frustum's where no pixel is covered), and each cascade
    covers, across the light, just the visible receivers of its slice, from one more
    reduction per cascade (Lauritzen et al.'s sample distribution: its depth range and tight
    light-space bounds); otherwise a cascade covers its slice of the view frustum.
    ``stabilize`` fits each cascade to its slice's bounding sphere instead and snaps it to
    whole texels (:func:`fit_cascade`): the map does not shimmer when the camera moves or
    turns, at the price of a larger texel (under sdsm, the default, the slices still follow
    the visible depth range, so the grid holds under fit frustum only). Directional lights
    only: a spot light has one frustum already.

    Bias: ``shadow_map.glsl``'s rule (``bias`` plus ``slope_bias`` times the receiver plane's
    depth slope per texel times the distance to the texel read, and the point first moved by
    ``normal_offset`` texels), in each cascade's own texels; ``bias_mode`` as sm's.
    Columns: ``split_<i>`` the slice bounds (view depths, i = 0..splits) and
    ``cascade_texel_<i>`` each cascade's texel side in world units (orthographic: the same at
    its near end as anywhere). Map ``cascade``: the cascade each pixel used.

    =================  ================================================  ========  ============
    Parameter          Meaning                                           Default   Range
    =================  ================================================  ========  ============
    ``res``            each cascade's map width and height, texels       1024      16 .. 8192
    ``splits``         cascades                                          4         1 .. 4
    ``lambda``         logarithmic share of the split scheme (0 uniform  0.5       0 .. 1
                       slices, 1 logarithmic)
    ``fit``            ``frustum``: near to far (clipped to the scene's  sdsm      frustum, sdsm
                       depth bounds), slices of the view frustum;
                       ``sdsm``: the visible depths and each slice's
                       visible receivers (GPU reductions)
    ``stabilize``      bounding-sphere cascades snapped to whole texels  false     true, false
    ``bias``           constant depth bias, scene units                  0.02      0 .. 1e7
    ``slope_bias``     times the receiver plane's depth slope x the      1.0       0 .. 64
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
    ``normal_offset``  moves the point along its light-facing normal     0.0       0 .. 64
                       before the read: this many x the texel's world
                       size in the pixel's cascade x sin(the light's
                       angle); the cascade stays the unmoved point's
    =================  ================================================  ========  ============
    """

    name = "csm"
    colour = "#d62728"
    summary = "cascaded shadow maps: one map per slice of view depth"
    paper = ("Zhang, Sun, Xu, Lun 2006, Parallel-split shadow maps; Lauritzen, Salvi, Lefohn "
             "2011, Sample distribution shadow maps")
    # quality knob: how many slices share the view depth range (more cascades, more maps)
    quality_knobs = {"splits": (1, 2, 4)}
    # the fit and the split scheme besides the bias terms: where each cascade's texels go
    tunable = {**BIAS_TUNING, **BIAS_MODE_TUNING, "fit": ("choice", ("frustum", "sdsm")),
               "lambda": ("float", 0.0, 1.0)}
    bias_terms = BIAS_TERMS
    Params = _Params
    alpha_casters = True  # each cascade's depth pass cuts them out (light_maps)
    declines_lights = {
        "spot": "cascades split a directional light's map; a spot light has one frustum",
        "point": "cascades split a directional light's map; a point light shines every way, "
                 "past any one light frustum"}

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.maps = [LightDepthMap(frame, p.res) for _ in range(p.splits)]
        sdsm = p.fit == "sdsm"
        self.reduction = CoveredRange() if sdsm else None
        self.bounds = CoveredRange(Path(__file__).parent / "csm_bounds.comp.glsl") \
            if sdsm and not p.stabilize else None
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl",
                                        "csm_shading.frag.glsl")

    def depth_range(self, frame: Frame) -> tuple[float, float]:
        """n and f of the split scheme; under sdsm the visible range, measured on the GPU;
        under frustum the camera's near and far clipped to the scene's depth bounds."""
        camera = frame.scene.config.camera
        if self.reduction is None:
            return scene_depth_range(frame.camera.view, frame.scene.bounds,
                                     float(camera.near), float(camera.far))
        with frame.measure("depth_range"):
            visible = self.reduction.reduce(frame.gbuffer.position_texture,
                                            frame.gbuffer.normal_texture,
                                            camera_view=frame.camera.view)
        if visible.empty:  # fit frustum's range
            return scene_depth_range(frame.camera.view, frame.scene.bounds,
                                     float(camera.near), float(camera.far))
        low, high = float(visible.low[0]), float(visible.high[0])
        # float32 depths of float32 positions: a few 1e-7 of the depth
        pad = 1e-3 * (high - low) + 1e-5 * high
        near = max(low - pad, float(camera.near))
        return near, max(high + pad, near * (1 + 1e-6))

    def receiver_bounds(self, frame: Frame, splits: np.ndarray) -> list:
        """Per cascade, the light-space x, y range of the visible receivers it shades (None for
        one that shades none), measured on the GPU; all None without tight bounds."""
        if self.bounds is None:
            return [None] * (len(splits) - 1)
        rotation = light_rotation(frame.scene.light.direction)
        # the shader's choice: the first slice reaching a pixel's depth, the last beyond all
        ends = [-EMPTY_DEPTH, *splits[1:-1], EMPTY_DEPTH]
        found = []
        with frame.measure("cascade_bounds"):
            for d0, d1 in zip(ends[:-1], ends[1:]):
                r = self.bounds.reduce(frame.gbuffer.position_texture,
                                       frame.gbuffer.normal_texture,
                                       camera_view=frame.camera.view, light_rotation=rotation,
                                       slice_near=d0, slice_far=d1)
                found.append(None if r.empty else (r.low[:2].astype(np.float64),
                                                   r.high[:2].astype(np.float64)))
        return found

    def fit(self, frame: Frame) -> None:
        """The cascades of the frame's camera and light: per-view work (the splits follow the
        camera), so ``render`` does it every frame under either cost policy."""
        p = self.params
        near, far = self.depth_range(frame)
        splits = split_depths(near, far, p.splits, getattr(p, "lambda"))
        receivers = self.receiver_bounds(frame, splits)
        with frame.measure("cascade_fit"):
            self.splits = splits
            light = frame.scene.light.direction
            self.cascades = [
                fit_cascade(slice_corners(frame.camera.view, frame.camera.proj, d0, d1), light,
                            frame.scene.bounds, p.res, p.stabilize, d0, d1, bounds)
                for d0, d1, bounds in zip(splits[:-1], splits[1:], receivers)]
            for cascade, light_map in zip(self.cascades, self.maps):
                light_map.frustum = cascade.frustum

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        self.fit(frame)
        for i, light_map in enumerate(self.maps):
            with frame.measure(f"shadow_map_{i}"):
                light_map.render(frame)
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            uniforms = {}
            for i, (cascade, light_map) in enumerate(zip(self.cascades, self.maps)):
                uniforms[f"cascade_maps[{i}]"] = light_map.fbo.colors[0].bind(unit + i)
                uniforms[f"cascade_views[{i}]"] = cascade.frustum.view
                uniforms[f"cascade_projs[{i}]"] = cascade.frustum.proj
                uniforms[f"cascade_ends[{i}]"] = cascade.far
            precision = max(depth_precision(frame.scene.bounds, c.frustum.view)
                            for c in self.cascades)
            self.shading.set(**uniforms, cascades=len(self.cascades), cascade_res=float(p.res),
                             camera_view=frame.camera.view, bias=p.bias,
                             slope_bias=p.slope_bias, normal_offset=p.normal_offset,
                             depth_precision=precision, **bias_uniforms(p.bias_mode))
            frame.draw_fullscreen(covered_only=True)  # V = 1 where no surface
        cascades = self.cascade_map(frame)
        return frame.output(mem_bytes=sum(m.mem_bytes for m in self.maps),
                            fetches_per_px=1 + alpha_fetches_per_px(frame, *self.maps),
                            nonfinite=sum(m.nonfinite for m in self.maps),
                            extra=self.columns(frame, cascades), maps={"cascade": cascades})

    def columns(self, frame: Frame, cascades: np.ndarray) -> dict:
        """The cascades' columns and the texels per pixel of the cascade each pixel used."""
        used = np.nan_to_num(cascades, nan=-1)
        return {**{f"split_{i}": float(d) for i, d in enumerate(self.splits)},
                **{f"cascade_texel_{i}": c.texel_world for i, c in enumerate(self.cascades)},
                **texels_per_pixel(frame, self.map_grids(), used)}

    def map_grids(self) -> list[tuple[np.ndarray, float]]:
        """(world -> clip matrix, texels per side) of each cascade: what texels_per_pixel
        reads."""
        return [(c.frustum.view_proj, self.params.res) for c in self.cascades]

    def cascade_map(self, frame: Frame) -> np.ndarray:
        """Which cascade each covered pixel used (NaN elsewhere): a diagnostic, untimed."""
        a, view = frame.arrays, frame.camera.view
        depth = -(a.position.astype(np.float64) @ view[2, :3] + view[2, 3])
        ends = np.array([c.far for c in self.cascades])
        return np.where(a.covered, cascade_of(depth, ends), np.nan).astype(np.float32)

    def release(self) -> None:
        # prepare may have stopped early (not applicable, a failed compile)
        for light_map in self.__dict__.pop("maps", []):
            light_map.release()
        for name in ("reduction", "bounds", "shading"):
            resource = self.__dict__.pop(name, None)
            if resource is not None:
                resource.release()
