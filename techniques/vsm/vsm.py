"""Virtual shadow maps (Unreal Engine 5; Sakmary et al., GPU Zen 3, 2024; after Fernando et al.
2001 and Lefohn et al. 2007): pages of a large virtual map marked by what the camera sees,
given tiles of a fixed physical pool, rendered only when not cached."""

from __future__ import annotations

from pathlib import Path
from typing import Literal

import numpy as np
from OpenGL import GL
from pydantic import Field, field_validator
from pydantic_core.core_schema import ValidationInfo

from harness.config import power_of_two
from harness.gl.geometry import cut_out_corners
from harness.gl.shaders import ComputeProgram
from harness.scene.transforms import box_corners
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from techniques.common.footprint import texels_per_pixel
from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TERMS, BIAS_TUNING, MAX_BIAS,
                                          MAX_TEXELS, BiasMode, Sampling, bias_uniforms,
                                          depth_precision, sampling_uniforms)

from .levels import (SLANT_FLOORS, Levels, choose_levels, coarsening_steps, level_chain,
                     light_vector, pixel_angle, sequence_bounds, top_frustum)
from .pages import (ALLOCATED, HITS, JOBS, MARKED, FrameCounts, PagePool, barrier, pool_tiles,
                    spatial_order)

HERE = Path(__file__).parent
MAX_POOL_TEXELS = 16384  # the pool is one square texture (GL_MAX_TEXTURE_SIZE on llvmpipe)
# filter: pcf is Reeves et al.'s filter as pcf's defaults draw it, a 4 x 4 grid over half the
# pixel's footprint in the level's map, at least a quarter texel; the region's side stops at
# 2 PCF_REACH texels, so no read leaves the pages marking requested about the point
PCF_GRID = 4
PCF_RES_FACTOR = 0.5
PCF_MIN_SIZE = 0.25
PCF_REACH = 1.0  # texels


class VirtualShadowMap(Technique):
    """A virtual map of ``virtual_res`` x ``virtual_res`` texels per level, cut into pages of
    ``page`` x ``page``; only the pages visible pixels need get memory, a tile of a physical
    pool of ``pool_pages`` tiles, and only those not already cached are rendered.

    Levels (levels.py): a directional light has ``levels`` clipmap levels, the coarsest over
    the whole scene (the light's map frustum, as sm's), each finer one half as wide about the
    camera and snapped to its own pages, then the coarsest's mips down to one page; a spot
    light its cone's mips, from ``virtual_res`` down to one page (``levels`` does not apply).
    Point lights are declined (six faces of mips each: not built).

    Each frame (all of it in ``render``, timed): page marking (vsm_mark.comp.glsl): every
    pixel whose visible side faces the light takes the level whose texel is the largest not
    above its footprint, both on the receiver's plane (levels.natural_level: distance x pixel
    angle x sqrt(|n.l| / |n.v|), the slant's factor within a floor and levels.SLANT_CEILING),
    so about one texel per pixel (0.5 to 1 but for the camera's off-axis pixels and the
    slant's limits), and requests the page of its texel (with ``filter: pcf`` the pages its
    filter's reads reach, PCF_REACH texels about it);
    allocation (vsm_pages.comp.glsl): if the requests need more tiles than are free, marking
    runs again a step coarser until they fit (levels.coarsening_steps: the slant's floor raised
    from 0.25 to 0.5, then every pixel a level coarser at a time; columns ``slant_floor`` and
    ``pages_coarsened``, the levels); unrequested pages free their tiles to a ring on the GPU,
    requested ones take theirs from it, and a requested page whose depths are not current
    becomes a job; page rendering: per job, the caster clusters (runs of triangles in Z order of
    their centroids, pages.spatial_order) whose box meets the page's column are drawn into its
    tile (one multi-draw of indirect commands made on the GPU); shading (vsm_shading.frag.glsl):
    Williams' test, or percentage-closer filtering over the pixel's footprint (4 x 4 reads over
    half of it, as pcf's defaults; across page borders), through the page table, with
    shadow_map.glsl's bias in the level's texels.

    Caching (``cache: true``): a page keeps its depths while the light and the casters over it
    stay. ``update`` (the work for a changed light or geometry) drops every page's depths when
    the light changed and, for each object that moved since the last frame, those of the pages
    whose column meets its box at its old or its new pose; it boxes the caster clusters again
    where geometry moved. A moving camera over a still scene renders only newly requested
    pages. With ``cache: false`` every requested page is rendered every frame.

    Cut-outs (``alpha_casters``): on a scene with alpha-tested casters the page draws discard
    the cut-out texels by ``alpha_test.glsl``'s rule (``common/cut_out_texel.glsl``, the shared
    depth pass's), so a cut-out texel writes no depth. ``fetches_per_px`` adds four alpha
    texels per alpha test of this frame's page draws (counted in an untimed repeat of them),
    per covered pixel: a frame whose pages all came from the cache adds none.

    Columns: ``pages_marked``, ``pages_allocated`` (new tiles this frame), ``pages_rendered``,
    ``cache_hits``, ``pages_coarsened`` (levels), ``slant_floor``, ``page_draws`` (cluster
    draws), ``pages_invalidated``; ``mem_bytes`` is the pool and the page table.

    =================  ================================================  =======  ============
    Parameter          Meaning                                           Default  Range
    =================  ================================================  =======  ============
    ``virtual_res``    texels per side of a level (a power of two)       16384    4096 .. 16384
    ``page``           texels per side of a page (dividing               128      8 .. 1024
                       ``virtual_res``: 64 or 128 as engines ship)
    ``levels``         clipmap levels of a directional light             8        1 .. 16
    ``pool_pages``     tiles of the physical pool (the pool is a square  256      1 .. 16384
                       texture of at most 16384 texels per side)
    ``filter``         ``none``: Williams' test; ``pcf``: 4 x 4 reads    pcf      none, pcf
                       over half the pixel's footprint (at most 2
                       texels a side), across page borders
    ``cache``          keep pages' depths across frames                  true     true, false
    ``bias``           constant depth bias, scene units                  0.02     0 .. 1e7
    ``slope_bias``     times the receiver plane's depth slope x the      1.0      0 .. 64
                       distance to the texel read, texels
    ``bias_mode``      how each read's receiver depth is formed:         slope
                       ``slope``, ``receiver_plane`` or ``adaptive``
                       (shadow_map.glsl; sm's table)
    ``normal_offset``  moves the point along its light-facing normal     0.0      0 .. 64
                       before the read: this many x the texel's world
                       size in the pixel's level x sin(the light's
                       angle); the level stays the unmoved point's
    =================  ================================================  =======  ============
    """

    name = "vsm"
    colour = "#1b9e77"
    summary = "virtual shadow maps: pages marked by the view, a physical pool, cached pages"
    paper = ("Epic Games, Virtual Shadow Maps (Unreal Engine 5); Sakmary, Ryan, Hall, Lustri "
             "2024, Virtual shadow maps, GPU Zen 3; Lefohn, Sengupta, Owens 2007, "
             "Resolution-matched shadow maps")
    # quality knobs: the pool (a short one coarsens every pixel's level) and the filter
    quality_knobs = {"pool_pages": (64, 256, 1024), "filter": ("none", "pcf")}
    tunable = {**BIAS_TUNING, **BIAS_MODE_TUNING}
    bias_terms = BIAS_TERMS
    rivals = ("csm",)
    alpha_casters = True  # the page draws discard cut-out texels, as the shared depth pass
    declines_lights = {
        "point": "a point light needs six virtual maps (cube faces) with their mips; vsm builds "
                 "a directional light's clipmap and a spot light's mips only"}

    class Params(TechniqueParams):
        virtual_res: int = Field(16384, ge=4096, le=16384)
        page: int = Field(128, ge=8, le=1024)
        levels: int = Field(8, ge=1, le=16)
        # a 512 x 512 view marked 51 to 197 pages of 128 texels on the five families at 10^5 and
        # 10^6 (13 to 108 on the shipped scenes at their sizes): 256 holds them, a 16 MiB pool
        pool_pages: int = Field(256, ge=1, le=16384)
        filter: Literal["none", "pcf"] = "pcf"
        cache: bool = True
        bias: float = Field(0.02, ge=0, le=MAX_BIAS)
        slope_bias: float = Field(1.0, ge=0, le=MAX_TEXELS)
        bias_mode: BiasMode = "slope"
        normal_offset: float = Field(0.0, ge=0, le=MAX_TEXELS)

        _virtual_res = field_validator("virtual_res")(power_of_two)

        @field_validator("page")
        @classmethod
        def _divides(cls, value: int, info: ValidationInfo) -> int:
            res = info.data.get("virtual_res")
            if res is not None and res % value:
                raise ValueError(f"must divide virtual_res {res}, got {value}")
            return value

        @field_validator("pool_pages")
        @classmethod
        def _fits_a_texture(cls, value: int, info: ValidationInfo) -> int:
            page = info.data.get("page")
            if page is not None and pool_tiles(value) * page > MAX_POOL_TEXELS:
                raise ValueError(f"{value} tiles of {page} texels take a pool of "
                                 f"{pool_tiles(value) * page} texels per side, over "
                                 f"{MAX_POOL_TEXELS}")
            return value

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.bounds = sequence_bounds(frame.sequence)
        self.top = top_frustum(frame.scene.light, self.bounds)
        levels = self.chain(frame)
        scene = frame.scene
        vertices, faces = scene.indexed
        if scene.has_alpha:  # the scene mesh's faces: cut-out corners have their own vertices
            vertices, faces, _ = cut_out_corners(vertices, faces, scene.face_mask,
                                                 scene.face_texcoords)
        self.pages = PagePool(p.pool_pages, p.page, levels.table_size, levels.count,
                              spatial_order(vertices, faces), scene.has_alpha)
        self.mark = ComputeProgram(HERE / "vsm_mark.comp.glsl")
        defines = ({"PCF": 1, "MAX_FOOTPRINT": f"{2 * PCF_REACH / PCF_RES_FACTOR:.1f}"}
                   if p.filter == "pcf" else {})
        self.shading = self.shader(__file__, "fullscreen.vert.glsl", "vsm_shading.frag.glsl",
                                   **defines)
        parts = frame.scene.parts
        self.part_bounds = np.array([[p.vertices.min(axis=0), p.vertices.max(axis=0)]
                                     for p in parts], np.float64)
        self.start_poses = frame.part_poses
        self.poses = None  # the poses the pages were last brought up to date for
        self.light = None
        self.geometry = None
        self.counts = FrameCounts()

    def chain(self, frame: Frame) -> Levels:
        p = self.params
        return level_chain(self.top, frame.camera.position, p.virtual_res, p.page, p.levels)

    def level_uniforms(self, frame: Frame, levels: Levels,
                       step: tuple[int, float] = (0, SLANT_FLOORS[0])) -> dict:
        """vsm_levels.glsl's uniforms at coarsening ``step`` (level bias, slant floor)."""
        bias, slant_floor = step
        return dict(level_count=levels.count, nested_levels=levels.nested, level_bias=bias,
                    slant_floor=slant_floor,
                    page_size=levels.page, eye_position=frame.camera.position,
                    pixel_angle=pixel_angle(frame.camera.proj, frame.height),
                    light_vector=light_vector(frame.scene.light))

    def moved_boxes(self, poses: np.ndarray) -> list[tuple[np.ndarray, np.ndarray]]:
        """World boxes of the parts that moved since the last update, at their old and new
        poses."""
        if self.poses is None:
            return []
        boxes = []
        for i in np.flatnonzero(np.any(poses != self.poses, axis=(1, 2))):
            corners = np.c_[box_corners(self.part_bounds[i]), np.ones(8)]
            for pose in (self.poses[i], poses[i]):
                placed = corners @ (pose @ np.linalg.inv(self.start_poses[i])).T
                boxes.append((placed[:, :3].min(axis=0), placed[:, :3].max(axis=0)))
        return boxes

    def update(self, frame: Frame) -> None:
        light = frame.scene.light
        key = (light.type, tuple(np.atleast_1d(light.direction if light.direction is not None
                                               else ())),
               tuple(np.atleast_1d(light.position if light.position is not None else ())),
               getattr(light, "fov_deg", None))
        poses = frame.part_poses
        with frame.measure("page_invalidation"):
            light_moved = key != self.light
            if light_moved:
                self.top = top_frustum(light, self.bounds)
            boxes = self.moved_boxes(poses)
            levels = self.chain(frame)
            if light_moved or boxes:
                self.pages.upload_levels(levels)
                self.counts.invalidated = self.pages.invalidate(
                    self.level_uniforms(frame, levels), light_moved, boxes)
            else:
                self.counts.invalidated = 0
            if frame.geometry is not self.geometry:
                self.pages.box_clusters(frame)
        self.light, self.poses, self.geometry = key, poses.copy(), frame.geometry

    def request_pages(self, frame: Frame, levels: Levels) -> tuple[int, float]:
        """Mark the pages the view needs, coarser until they fit the pool; the coarsening step
        (level bias, slant floor) that fits."""
        reach = PCF_REACH if self.params.filter == "pcf" else 0.0
        for step in coarsening_steps(levels.count):
            uniforms = self.level_uniforms(frame, levels, step)
            self.pages.start_frame()
            self.pages.bind()
            self.mark.use().set(gbuffer_position=frame.gbuffer.position_texture.bind(0),
                                gbuffer_normal=frame.gbuffer.normal_texture.bind(1), reach=reach,
                                **self.map_uniforms(frame, levels), **uniforms)
            GL.glDispatchCompute(-(-frame.width // 8), -(-frame.height // 8), 1)
            barrier()
            fits, _ = self.pages.fits(uniforms)
            if fits:
                return step
        raise RuntimeError("the coarsest level did not fit the pool")  # one page always does

    def map_uniforms(self, frame: Frame, levels: Levels) -> dict:
        """shadow_map.glsl's uniforms other than the map itself."""
        p = self.params
        precision = max(depth_precision(frame.scene.bounds, view) for view in levels.views)
        return dict(light_is_ortho=levels.ortho, slope_bias=p.slope_bias,
                    normal_offset=p.normal_offset, depth_precision=precision,
                    **bias_uniforms(p.bias_mode))

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        counts = self.counts
        with frame.measure("page_marking"):
            levels = self.chain(frame)
            self.pages.upload_levels(levels)
            step = self.request_pages(frame, levels)
            uniforms = self.level_uniforms(frame, levels, step)
        with frame.measure("page_allocation"):
            if not p.cache:
                self.pages.invalidate(uniforms, True, [])
            c = self.pages.allocate(uniforms)
        with frame.measure("page_render"):
            draws = self.pages.render_jobs(frame, int(c[JOBS]), uniforms)
        with frame.measure("shading"):
            frame.begin_visibility()
            self.shading.use()
            unit = frame.bind_gbuffer(self.shading)
            self.pages.bind()
            GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
            GL.glBindTexture(GL.GL_TEXTURE_2D, self.pages.pool)
            sampling = Sampling(grid_n=PCF_GRID, footprint_region=True,
                                res_factor=PCF_RES_FACTOR, min_size=PCF_MIN_SIZE,
                                bias_min=p.bias, bias_max=p.bias,
                                slope_bias=p.slope_bias, bias_mode=p.bias_mode,
                                normal_offset=p.normal_offset)
            pcf = sampling_uniforms(frame, sampling) if p.filter == "pcf" else {}
            self.shading.set(pool=unit, pool_tiles=self.pages.tiles, bias=p.bias,
                             **{**self.map_uniforms(frame, levels), **pcf}, **uniforms)
            frame.draw_fullscreen(covered_only=True)
        counts.marked, counts.allocated = int(c[MARKED]), int(c[ALLOCATED])
        counts.rendered, counts.hits = int(c[JOBS]), int(c[HITS])
        (counts.coarsened, counts.slant_floor), counts.draws = step, draws
        self.levels = levels
        nonfinite = int(sum(np.count_nonzero(~np.isfinite(m)) for m in (levels.views,
                                                                        levels.projs)))
        # the page draws' alpha tests, four texels each, per pixel (untimed repeat)
        alpha_tests = self.pages.alpha_tests(frame, int(c[JOBS]), draws, uniforms)
        covered = int(np.count_nonzero(frame.arrays.covered))
        fetches = (PCF_GRID ** 2 if p.filter == "pcf" else 1) + 4 * alpha_tests / max(covered, 1)
        return frame.output(mem_bytes=self.pages.mem_bytes, fetches_per_px=fetches,
                            nonfinite=nonfinite, extra=self.columns(frame))

    def level_map(self, frame: Frame) -> np.ndarray:
        """The level each covered pixel reads (levels.choose_levels, the shader's choice in
        float64; -1 elsewhere): a diagnostic, untimed."""
        a, levels = frame.arrays, self.levels
        chosen = choose_levels(levels, a.position[a.covered].astype(np.float64),
                               a.normal[a.covered].astype(np.float64), frame.camera.position,
                               light_vector(frame.scene.light),
                               pixel_angle(frame.camera.proj, frame.height), self.counts.coarsened,
                               self.counts.slant_floor)
        used = np.full(a.covered.shape, -1, np.int64)
        used[a.covered] = chosen
        return used

    def columns(self, frame: Frame) -> dict:
        c = self.counts
        # the level map depends on the levels (in their grids), the camera pass and the coarsening
        return {**texels_per_pixel(frame, self.levels.map_grids, lambda: self.level_map(frame),
                                   choice_key=f"{c.coarsened} {c.slant_floor}".encode()),
                "pages_marked": c.marked, "pages_allocated": c.allocated,
                "pages_rendered": c.rendered, "cache_hits": c.hits,
                "pages_coarsened": c.coarsened, "slant_floor": c.slant_floor,
                "page_draws": c.draws,
                "pages_invalidated": c.invalidated}

    def release(self) -> None:
        for name in ("pages", "mark", "shading"):
            resource = self.__dict__.pop(name, None)
            if resource is not None:
                resource.release()
