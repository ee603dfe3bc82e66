"""Shadow volumes (Crow 1977) counted in the stencil, alpha or screen buffer (Roettger et al.)."""

from __future__ import annotations

from typing import Literal

import numpy as np
from OpenGL import GL

from harness.gl.framebuffer import Framebuffer
from harness.gl.geometry import VertexArray
from harness.technique import Frame, ShadowOutput, Technique, TechniqueParams

from . import sv_volumes

# Everitt and Kilgard's epsilon: points at infinity (w = 0) land just inside the far plane.
INFINITE_FAR_EPSILON = 2.0 ** -20
# Mask channel and the level between shadow and lit that the normalised mask is snapped at.
CHANNEL = {"stencil": 0, "alpha": 3, "screen": 0}
COLOUR_MASK = {"alpha": (False, False, False, True), "screen": (True, True, True, False)}


def infinite_far(proj: np.ndarray, epsilon: float = INFINITE_FAR_EPSILON) -> np.ndarray:
    """The camera's perspective projection with its far plane moved to infinity."""
    p = np.array(proj, dtype=np.float64)
    near = p[2, 3] / (p[2, 2] - 1.0)
    p[2, 2] = epsilon - 1.0
    p[2, 3] = near * (epsilon - 2.0)
    return p


def count_fragments(draw) -> int:
    """Samples that pass the current state while ``draw()`` runs (an untimed query)."""
    query = GL.glGenQueries(1)[0]
    GL.glBeginQuery(GL.GL_SAMPLES_PASSED, query)
    draw()
    GL.glEndQuery(GL.GL_SAMPLES_PASSED)
    count = int(GL.glGetQueryObjectuiv(query, GL.GL_QUERY_RESULT))
    GL.glDeleteQueries(1, [query])
    return count


class ShadowVolumes(Technique):
    """Per-pixel exact hard shadows: count the shadow-volume faces along each camera ray.

    Volumes are extruded to infinity (w = 0) and drawn with an infinite-far projection, so no
    volume is clipped at the far plane. ``zpass`` counts the faces in front of the visible
    surface and is wrong when the camera sits inside a volume; ``zfail`` (Carmack's reverse)
    counts those behind it and closes each volume with caps, so it is right there too.

    The count lives in the ``stencil`` buffer (two-sided, wrapping increment/decrement), or,
    without a stencil buffer (Roettger et al. 2002), in the ``alpha`` channel or the RGB of the
    ``screen`` buffer as a blending state machine: start at 1/4, the faces that enter a volume
    double, those that leave halve, so a lit pixel ends at 1/4 and a shadowed one at 1/2 or 1.
    ``normalize: rectangles`` turns that into 0/1 with three full-window rectangles (double,
    invert, double; section 4.3); ``normalize: max`` starts at 1 with halve/double swapped and
    lifts everything to at least 1/2 with one max-blended rectangle (section 4.4). The state
    machine is right only for volumes a ray enters at most once, each drawn front faces before
    back faces (section 4.2): one silhouette volume per convex closed mesh, one volume per
    triangle otherwise (``volumes: auto``). The screen buffer needs the scene drawn again after
    the mask (timed as ``scene_redraw``). ``mask_res: half`` computes the mask from a half-
    resolution depth pass and magnifies it bilinearly (section 4.5).

    Volume fragments are counted once, untimed, with the depth test off: they are the row's
    ``frags_shadow``, so ``overdraw`` = that / scene fragments is the silhouette-map paper's O.

    ===============  =====================================================  ==========  =====
    Parameter        Meaning                                                Default     Range
    ===============  =====================================================  ==========  =====
    ``buffer``       where the count lives: ``stencil``, ``alpha``,         stencil
                     ``screen``
    ``method``       ``zpass`` or ``zfail`` (capped, camera may be inside)  zfail
    ``mask_res``     ``full`` or ``half`` (bilinear magnification)          full
    ``normalize``    alpha/screen: ``rectangles`` (3, section 4.3) or       rectangles
                     ``max`` (1, section 4.4)
    ``volumes``      ``auto``, ``silhouette`` (one per closed mesh, even    auto
                     non-convex) or ``polygon`` (one per triangle)
    ===============  =====================================================  ==========  =====
    """

    name = "sv"
    summary = "shadow volumes: stencil, alpha or screen buffer; z-pass or z-fail; half-res mask"
    paper = ("Crow 1977, Shadow algorithms for computer graphics; Roettger, Irion, Ertl 2002, "
             "Shadow volumes revisited")
    # quality knobs: buffer and method trade cost for robustness, mask_res accuracy for time
    # (mask_res quarter and method nearclip join these when they exist)
    quality_knobs = {"buffer": ("stencil", "alpha", "screen"), "method": ("zpass", "zfail"),
                     "mask_res": ("half", "full")}

    class Params(TechniqueParams):
        buffer: Literal["stencil", "alpha", "screen"] = "stencil"
        method: Literal["zpass", "zfail"] = "zfail"
        mask_res: Literal["full", "half"] = "full"
        normalize: Literal["rectangles", "max"] = "rectangles"
        volumes: Literal["auto", "silhouette", "polygon"] = "auto"

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.view_proj = infinite_far(frame.camera.proj) @ frame.camera.view
        zfail = p.method == "zfail"
        stencil = p.buffer == "stencil"
        volumes = sv_volumes.build(frame.scene.parts, frame.scene.light, caps=zfail,
                                   one_pass_count=stencil, grouping=p.volumes)
        self.volume_set = volumes
        self.warnings = list(volumes.warnings)
        self.front_increments = not zfail
        triangles = (volumes.triangles if stencil else
                     sv_volumes.draw_order(volumes, self.view_proj, self.front_increments))
        self.volumes = VertexArray(triangles.reshape(-1, 4), (4,))
        half = p.mask_res == "half"
        self.mask = Framebuffer((frame.width + 1) // 2 if half else frame.width,
                                (frame.height + 1) // 2 if half else frame.height,
                                (GL.GL_RGBA8,), depth=True)
        self.depth_program = self.shader(__file__, "sv_volume.vert.glsl", "sv_fill.frag.glsl")
        self.volume_program = self.shader(__file__, "sv_volume.vert.glsl", "sv_volume.frag.glsl")
        self.fill_program = self.shader(__file__, "fullscreen.vert.glsl", "sv_fill.frag.glsl")
        self.visibility_program = self.shader(__file__, "fullscreen.vert.glsl",
                                              "sv_visibility.frag.glsl")
        self.fill = self._count_fill(frame)

    # ---- untimed fill-rate counts -------------------------------------------------------

    def _count_fill(self, frame: Frame) -> dict:
        GL.glColorMask(False, False, False, False)
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_CULL_FACE)
        self.mask.clear((0, 0, 0, 0))
        GL.glDisable(GL.GL_DEPTH_TEST)
        self.volume_program.use().set(view_proj=self.view_proj)
        volume_frags = count_fragments(self.volumes.draw)
        GL.glColorMask(True, True, True, True)
        triangles = len(self.volume_set.triangles)
        return {"volume_frags": volume_frags,
                "volume_triangles": triangles, "volume_vertices": 3 * triangles,
                "volume_count": self.volume_set.volume_count,
                "silhouette_edges": self.volume_set.silhouette_edges,
                "mask_width": self.mask.width, "mask_height": self.mask.height}

    # ---- passes ---------------------------------------------------------------------------

    def _start_value(self) -> float:
        if self.params.buffer == "stencil" or self.params.normalize == "max":
            return 1.0
        return 0.25

    def _depth_pass(self, frame: Frame) -> None:
        self.mask.clear((self._start_value(),) * 4)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthMask(True)
        GL.glColorMask(False, False, False, False)
        self.depth_program.use().set(view_proj=self.view_proj)
        frame.draw_scene()

    def _volume_pass(self) -> None:
        p = self.params
        GL.glDepthMask(False)
        # z-fail counts the faces behind the surface: stencil has a depth-fail operation,
        # blending only sees passing fragments, so there the test is reversed. Either way a
        # face at equal depth counts (a near cap on its own surface).
        reversed_test = p.method == "zfail" and p.buffer != "stencil"
        GL.glDepthFunc(GL.GL_GEQUAL if reversed_test else GL.GL_LESS)
        program = self.volume_program.use().set(view_proj=self.view_proj)
        if p.buffer == "stencil":
            GL.glColorMask(False, False, False, False)
            GL.glEnable(GL.GL_STENCIL_TEST)
            GL.glStencilMask(0xFF)
            GL.glStencilFunc(GL.GL_ALWAYS, 0, 0xFF)
            keep, incr, decr = GL.GL_KEEP, GL.GL_INCR_WRAP, GL.GL_DECR_WRAP
            if p.method == "zpass":
                GL.glStencilOpSeparate(GL.GL_FRONT, keep, keep, incr)
                GL.glStencilOpSeparate(GL.GL_BACK, keep, keep, decr)
            else:
                GL.glStencilOpSeparate(GL.GL_FRONT, keep, decr, keep)
                GL.glStencilOpSeparate(GL.GL_BACK, keep, incr, keep)
        else:
            GL.glColorMask(*COLOUR_MASK[p.buffer])
            GL.glEnable(GL.GL_BLEND)
            GL.glBlendEquation(GL.GL_FUNC_ADD)
            GL.glBlendFunc(GL.GL_DST_COLOR, GL.GL_SRC_COLOR)
            double, halve = (1.0,) * 4, (0.25,) * 4
            increment, decrement = (halve, double) if p.normalize == "max" else (double, halve)
            program.set(front_increments=self.front_increments, increment_colour=increment,
                        decrement_colour=decrement)
        self.volumes.draw()

    def _rectangle(self, frame: Frame, colour: float) -> None:
        self.fill_program.use().set(fill_colour=(colour,) * 4)
        frame.draw_fullscreen()

    def _normalize_pass(self, frame: Frame) -> None:
        """Turn the count into a 0/1 (stencil, rectangles) or 1/2 / 1 (max) mask."""
        p = self.params
        GL.glDisable(GL.GL_DEPTH_TEST)
        if p.buffer == "stencil":
            GL.glColorMask(True, True, True, True)
            GL.glDisable(GL.GL_BLEND)
            GL.glEnable(GL.GL_STENCIL_TEST)
            GL.glStencilFunc(GL.GL_NOTEQUAL, 0, 0xFF)
            GL.glStencilOp(GL.GL_KEEP, GL.GL_KEEP, GL.GL_KEEP)
            self._rectangle(frame, 0.0)
            GL.glDisable(GL.GL_STENCIL_TEST)
            return
        GL.glColorMask(*COLOUR_MASK[p.buffer])
        GL.glEnable(GL.GL_BLEND)
        if p.normalize == "max":
            GL.glBlendEquation(GL.GL_MAX)
            self._rectangle(frame, 0.5)
            GL.glBlendEquation(GL.GL_FUNC_ADD)
            return
        GL.glBlendEquation(GL.GL_FUNC_ADD)
        for source, destination in ((GL.GL_DST_COLOR, GL.GL_ONE),  # double
                                    (GL.GL_ONE_MINUS_DST_COLOR, GL.GL_ZERO),  # invert
                                    (GL.GL_DST_COLOR, GL.GL_ONE)):  # double
            GL.glBlendFunc(source, destination)
            self._rectangle(frame, 1.0)

    def _scene_redraw_pass(self, frame: Frame) -> None:
        """The screen-buffer method's extra scene pass: the scene multiplied onto the mask
        (glBlendFunc(GL_DST_COLOR, GL_ZERO)). Its colour is white: V, not an image, is what
        the benchmark reads, and the cost is the same rasterisation, depth test and blend."""
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_EQUAL)
        GL.glDepthMask(False)
        GL.glColorMask(*COLOUR_MASK["screen"])
        GL.glEnable(GL.GL_BLEND)
        GL.glBlendFunc(GL.GL_DST_COLOR, GL.GL_ZERO)
        self.depth_program.use().set(view_proj=self.view_proj, fill_colour=(1.0,) * 4)
        frame.draw_scene()
        GL.glDisable(GL.GL_BLEND)
        GL.glDepthFunc(GL.GL_LESS)

    def _visibility_pass(self, frame: Frame) -> None:
        GL.glColorMask(True, True, True, True)
        frame.begin_visibility()
        program = self.visibility_program.use()
        unit = frame.bind_gbuffer(program)
        p = self.params
        lit_threshold = 0.75 if p.buffer != "stencil" and p.normalize == "max" else 0.5
        program.set(shadow_mask=self.mask.colors[0].bind(unit), mask_channel=CHANNEL[p.buffer],
                    lit_threshold=lit_threshold, magnify=p.mask_res == "half")
        frame.draw_fullscreen()

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        with frame.measure("depth"):
            self.mask.bind()
            self._depth_pass(frame)
        with frame.measure("volumes"):
            self._volume_pass()
        with frame.measure("stencil_mask" if p.buffer == "stencil" else "normalize"):
            self._normalize_pass(frame)
        if p.buffer == "screen" and p.mask_res == "full":
            with frame.measure("scene_redraw"):
                self._scene_redraw_pass(frame)
        with frame.measure("visibility"):
            self._visibility_pass(frame)
        fill = dict(self.fill)
        return frame.output(mem_bytes=self.mask.nbytes,
                            fetches_per_px=4 if p.mask_res == "half" else 1,
                            shadow_fragments=fill.pop("volume_frags"), extra=fill,
                            warnings=self.warnings)

    def release(self) -> None:
        for resource in (self.volumes, self.mask, self.depth_program, self.volume_program,
                         self.fill_program, self.visibility_program):
            resource.release()
