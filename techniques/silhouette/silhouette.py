"""Shadow silhouette maps (Sen, Cammarano, Hanrahan 2003)."""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Callable

import numpy as np
from OpenGL import GL
from pydantic import Field

from harness.gl.framebuffer import Framebuffer
from harness.gl.shaders import Program
from harness.technique import AlphaPolicy, Frame, ShadowOutput, Technique, TechniqueParams
from harness.scene.transforms import LightFrustum, fit_light

from techniques.common.footprint import light_map_texels_per_pixel
from techniques.common.light_maps import (BIAS_MODE_TUNING, BIAS_TERMS, BIAS_TUNING, MAX_BIAS,
                                          MAX_TEXELS, BiasMode, LightDepthMap, bias_uniforms)
from .silhouette_edges import QUAD_HALF_WIDTH, EdgeAdjacency, EdgeMesh

HERE = Path(__file__).parent

# Clear value of the silhouette map: a texel no silhouette crosses holds its centre.
EMPTY_POINT = (0.5, 0.5, 0.0, 0.0)

# Bytes the paper's bandwidth model charges: one depth value per pixel, and 24 bytes
# (3 silhouette points of 8 bytes, after texture-cache reuse) per silhouette-path pixel.
MODEL_DEPTH_BYTES = 4
MODEL_SILHOUETTE_BYTES = 24
DEPTH_FETCHES = 4
SILHOUETTE_FETCHES = 5


def half_texel_offset(frustum: LightFrustum, res: int) -> LightFrustum:
    """The same light projection moved half a texel in x and y, so that texel (i, j) of a map
    made with it samples the corner (i, j) of texel (i, j) of a map made with ``frustum``."""
    shift = np.eye(4)
    shift[0, 3] = shift[1, 3] = 1.0 / res  # half a texel in NDC, times w
    return dataclasses.replace(frustum, proj=shift @ frustum.proj)


class SilhouetteMap(Technique):
    """A depth map plus a silhouette map: a piecewise-linear shadow boundary instead of the
    piecewise-constant one of a shadow map.

    Per frame: silhouette edges from the light (a light-facing and a back-facing face, or a
    boundary edge of an open mesh) are found on the GPU from an edge mesh built in ``prepare``
    (``silhouette_edges.EdgeMesh``: endpoints and adjacent face normals). Three passes, each
    timed:

    * ``depth_map``: linear light depth, the projection offset half a texel so its samples
      sit at the corners of silhouette-map texels;
    * ``silhouette_map``: one point per edge; the vertex stage keeps the silhouettes and
      projects them, clipped to the light's near plane, the geometry stage emits each one's
      thin quad, and the fragment stage fills a RG32F map of one point per texel (texel-local
      [0,1]^2, empty texels hold the centre): endpoint in the texel, else the diagonal
      intersections (one: it, two: their midpoint, none: discard), enlarged near corners and
      clamped; points farther from the light than all four corner depths (minus ``bias``) are
      discarded as hidden;
    * ``shading``: four corner depth tests; where they disagree, the skewed-quadrant
      reconstruction from the texel's point and its four neighbours' (eight line tests).

    Bias: the four corner depths lie up to a texel from the shaded point in each axis (the
    corner distance), farther than a shadow map's own texel centre, so a constant or a
    one-texel slope bias lets a surface tilted from the light shadow itself at a corner (box
    front face, box_plane at map 256). Each corner test gets ``bias`` (scene units) plus
    ``slope_bias`` times the receiver plane's depth slope per texel times that corner's
    distance from the point (``shadow_map.glsl``, after Isidoro 2006 and Schueler 2006), the
    rule every map technique here shares (``bias_mode`` as sm's: under ``adaptive`` the corner
    tests take neither ``bias`` nor ``slope_bias``). The hidden-silhouette test of pass 2
    compares a silhouette point's own depth with the corners and uses ``bias`` alone, in every
    ``bias_mode``.

    Extra result columns: ``sil_pct`` (percent of shaded pixels that took the silhouette path,
    counted by atomic counters in an untimed repeat of the shading pass), ``model_bytes_per_px``
    (4 + 24 P, the paper's bandwidth model with P = sil_pct / 100), ``silhouette_edges`` (the
    quads the edge pass emits, counted in an untimed repeat with the rasterizer off). The
    paper's P divides its silhouette fill by the scene fill (forward shading: every fragment
    drawn, overdraw included); ``sil_pct`` divides by the covered pixels, each shaded once in
    the deferred pass, so the two agree only where the scene has no overdraw.
    ``fetches_per_px`` = 4 + 5 P; ``mem_bytes`` = depth map (with its depth buffer) +
    silhouette map.

    ==================  ==============================================  =======  ===========
    Parameter           Meaning                                         Default  Range
    ==================  ==============================================  =======  ===========
    ``res``             width and height of both maps, texels           1024     16 .. 8192
    ``bias``            constant depth bias, scene units                0.02     0 .. 1e7
    ``slope_bias``      times the receiver plane's depth slope x each   1.0      0 .. 64
                        corner's distance, texels
    ``bias_mode``       how each read's receiver depth is formed:       slope
                        ``slope``: less ``slope_bias`` x the plane's
                        depth slope x the distance (the bound);
                        ``receiver_plane``: the plane extrapolated
                        to the texel read (Isidoro 2006), times
                        ``slope_bias``; ``adaptive``: where the light
                        ray through the texel's centre meets the
                        tangent plane, less a rounding epsilon, no
                        constant or slope term (Dou et al. 2014)
    ``normal_offset``   moves the shaded point along its light-facing   0.0      0 .. 64
                        normal before its tests, by this many x the
                        texel's world size there x the sine of the
                        light's angle
    ``center_points``   debug: store every silhouette point at its      false
                        texel's centre (the paper's degenerate case,
                        equal to a shadow map on the offset depth map)
    ``alpha``           on a scene with alpha-tested casters:           decline
                        ``decline`` (skipped: its edges are the
                        triangles' edges) or ``ignore`` (run, cut-outs
                        opaque in both maps)
    ==================  ==============================================  =======  ===========
    """

    name = "silhouette"
    colour = "#9467bd"
    summary = "silhouette map: depth map plus one silhouette point per texel, piecewise-linear edges"
    paper = "Sen, Cammarano, Hanrahan 2003, Shadow silhouette maps"
    # quality knob: the map size (the silhouette map has the depth map's), in factor-4 steps
    # that keep make bench within its 10 minutes
    quality_knobs = {"res": (256, 1024, 4096)}
    tunable = {**BIAS_TUNING, **BIAS_MODE_TUNING}
    bias_terms = BIAS_TERMS
    declines_lights = {"point": "it has no cube-map path: its silhouette points and edge "
                                "reconstruction live in one light frustum's texel grid"}

    class Params(TechniqueParams):
        res: int = Field(1024, ge=16, le=8192)
        bias: float = Field(0.02, ge=0, le=MAX_BIAS)
        slope_bias: float = Field(1.0, ge=0, le=MAX_TEXELS)
        bias_mode: BiasMode = "slope"
        normal_offset: float = Field(0.0, ge=0, le=MAX_TEXELS)
        center_points: bool = False
        alpha: AlphaPolicy = "decline"

    def prepare(self, frame: Frame) -> None:
        res = self.params.res
        self.depth_map = LightDepthMap(frame, res, cutouts=False)
        self.silhouette_fbo = Framebuffer(res, res, (GL.GL_RG32F,), depth=False)
        self.edge_mesh = EdgeMesh(EdgeAdjacency(frame.scene))
        self.map_program = Program(HERE / "silhouette_edges.vert.glsl",
                                   HERE / "silhouette_map.frag.glsl",
                                   {"QUAD_HALF_WIDTH": QUAD_HALF_WIDTH},
                                   geometry=HERE / "silhouette_edges.geom.glsl")
        self.shading = Technique.shader(__file__, "fullscreen.vert.glsl",
                                        "silhouette_shading.frag.glsl")
        self.counting_shading = Technique.shader(__file__, "fullscreen.vert.glsl",
                                                 "silhouette_shading.frag.glsl", COUNT_PIXELS=1)
        self.counters = GL.glGenBuffers(1)
        self.edge_count = 0
        self.counted_pixels = (0, 0)
        self.counted_for = None  # (G-buffer arrays, light frustum) the counts were made for

    def update(self, frame: Frame) -> None:
        """The maps for the frame's light and geometry, each step timed: their fit, the depth
        map, and the silhouette map (its edges found on the GPU from the edge mesh)."""
        res = self.params.res
        with frame.measure("light_fit"):
            self.frustum = fit_light(frame.scene, res)
            self.depth_map.frustum = half_texel_offset(self.frustum, res)
        with frame.measure("depth_map"):
            self.depth_map.render(frame)
        with frame.measure("silhouette_map"):
            self.silhouette_fbo.clear(EMPTY_POINT)
            self.edge_mesh.place(frame.part_poses)  # where moving objects are now
            self.draw_edges(frame, self.map_program, self.edge_mesh.draw)

    def draw_edges(self, frame: Frame, program: Program, draw: Callable[[], None]) -> None:
        """Rasterise silhouette quads into the bound silhouette map: ``draw()`` issues them for
        ``program`` (the edge mesh for the edge program; the tests' CPU-built quads for theirs)."""
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_CULL_FACE)
        program.use()
        program.set(**self.depth_map.lookup_uniforms(0, 0.0, frame))
        program.set(bias=self.params.bias, center_points=self.params.center_points,
                    near=self.frustum.near, silhouette_proj=self.frustum.proj,
                    **self.edge_mesh.uniforms(frame.scene.light, self.frustum.view))
        draw()

    def _shade(self, frame: Frame, program: Program) -> None:
        p = self.params
        frame.begin_visibility()
        program.use()
        unit = frame.bind_gbuffer(program)
        program.set(**self.depth_map.lookup_uniforms(unit, p.slope_bias, frame))
        program.set(silhouette_map=self.silhouette_fbo.colors[0].bind(unit + 1), bias=p.bias,
                    normal_offset=p.normal_offset, **bias_uniforms(p.bias_mode))
        frame.draw_fullscreen(covered_only=True)  # V = 1 and nothing counted where no surface

    def _count_diagnostics(self, frame: Frame) -> None:
        """Untimed repeats of the last two passes that count what the result columns report:
        the quads the edge pass emits (two triangles each; the rasterizer off, so the map stays)
        and the pixels the shading pass shades and sends down the silhouette path."""
        query = GL.glGenQueries(1)[0]
        GL.glEnable(GL.GL_RASTERIZER_DISCARD)
        GL.glBeginQuery(GL.GL_PRIMITIVES_GENERATED, query)
        self.draw_edges(frame, self.map_program, self.edge_mesh.draw)
        GL.glEndQuery(GL.GL_PRIMITIVES_GENERATED)
        GL.glDisable(GL.GL_RASTERIZER_DISCARD)
        self.edge_count = int(GL.glGetQueryObjectuiv(query, GL.GL_QUERY_RESULT)) // 2
        GL.glDeleteQueries(1, [query])

        GL.glBindBuffer(GL.GL_ATOMIC_COUNTER_BUFFER, self.counters)
        GL.glBufferData(GL.GL_ATOMIC_COUNTER_BUFFER, 8, np.zeros(2, np.uint32),
                        GL.GL_DYNAMIC_READ)
        GL.glBindBufferBase(GL.GL_ATOMIC_COUNTER_BUFFER, 0, self.counters)
        self._shade(frame, self.counting_shading)
        self.counted_pixels = self._read_counters()

    def _read_counters(self) -> tuple[int, int]:
        """(shaded pixels, pixels that took the silhouette path) of the last shading pass."""
        GL.glMemoryBarrier(GL.GL_BUFFER_UPDATE_BARRIER_BIT)
        GL.glBindBuffer(GL.GL_ATOMIC_COUNTER_BUFFER, self.counters)
        raw = GL.glGetBufferSubData(GL.GL_ATOMIC_COUNTER_BUFFER, 0, 8)
        shaded, silhouette = np.frombuffer(bytes(raw), np.uint32)
        GL.glBindBuffer(GL.GL_ATOMIC_COUNTER_BUFFER, 0)
        return int(shaded), int(silhouette)

    def render(self, frame: Frame) -> ShadowOutput:
        with frame.measure("shading"):
            self._shade(frame, self.shading)
        # the counts change only with the camera's view (its G-buffer) or the light's frustum
        counted_for = (frame.arrays, self.frustum.view, self.frustum.proj)
        if self.counted_for is None or not (
                counted_for[0] is self.counted_for[0]
                and all(np.array_equal(a, b) for a, b in zip(counted_for[1:], self.counted_for[1:]))):
            self._count_diagnostics(frame)
            self.counted_for = counted_for
        shaded, silhouette = self.counted_pixels
        share = silhouette / max(shaded, 1)
        return frame.output(
            mem_bytes=self.depth_map.mem_bytes + self.silhouette_fbo.nbytes,
            fetches_per_px=DEPTH_FETCHES + SILHOUETTE_FETCHES * share,
            nonfinite=self.depth_map.nonfinite,
            extra={"sil_pct": 100.0 * share,
                   "model_bytes_per_px": MODEL_DEPTH_BYTES + MODEL_SILHOUETTE_BYTES * share,
                   "silhouette_edges": self.edge_count,
                   **light_map_texels_per_pixel(frame, self.depth_map)})

    def silhouette_points(self) -> np.ndarray:
        """The silhouette map as (res, res, 2) texel-local points, row j = map row j."""
        # read() returns row 0 at the top; map rows count from the bottom
        return np.ascontiguousarray(self.silhouette_fbo.read(0)[::-1])

    def release(self) -> None:
        # Mesa 22.3 (llvmpipe) keeps a program that draws after a geometry-shader program alive
        # past its deletion, until a geometry-shader program is bound again (a leaked program)
        self.map_program.use()
        for resource in (self.depth_map, self.silhouette_fbo, self.edge_mesh, self.map_program,
                         self.shading, self.counting_shading):
            resource.release()
        GL.glDeleteBuffers(1, [self.counters])
