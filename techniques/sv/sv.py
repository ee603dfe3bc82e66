"""Shadow volumes (Crow 1977) counted in the stencil, alpha or screen buffer (Roettger et al.)."""

from __future__ import annotations

from typing import Literal

from pydantic import model_validator

import numpy as np
from OpenGL import GL

from harness.gl.framebuffer import Framebuffer
from harness.technique import AlphaPolicy, Frame, ShadowOutput, Technique, TechniqueParams
from techniques.common.mask import mask_visibility_program

from . import sv_cpu, sv_volumes
from .sv_cull import ReceiverGrid
from .sv_gpu import GpuVolumes

# Mask channel and the level between shadow and lit that the normalised mask is snapped at.
CHANNEL = {"stencil": 0, "alpha": 3, "screen": 0}
COLOUR_MASK = {"alpha": (False, False, False, True), "screen": (True, True, True, False)}
# mask_res -> image pixels along each axis per mask texel
MASK_DIVISOR = {"full": 1, "half": 2, "quarter": 4}


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

    As in Roettger et al., the scene is drawn first and the volumes are depth-tested against
    its depth: here that first pass is the G-buffer's, the scene pass every technique gets, so
    a full-resolution mask draws the scene no second time. A smaller mask needs the scene's
    depth at its own resolution, one more scene pass (section 4.5), and the screen buffer draws
    the scene again after the mask (timed as ``scene_redraw``). ``scene_passes`` counts a
    frame's scene passes, the G-buffer's included: stencil 1, alpha 1, screen 2 (Table 1),
    and 2 with a smaller mask.

    ``method``: ``zpass`` counts the faces between the near plane and the visible surface
    (section 3.2) and is wrong wherever the near plane lies inside a volume (the camera in a
    shadow). ``nearclip`` is the paper's fix for that (section 3.2): every volume is clipped
    at the near plane and the clip polygon drawn as a front face (computed per light-facing
    triangle in double precision, ``sv_volumes.near_clip_polygons``). ``zfail`` counts the
    faces behind the surface instead and closes each volume with a near cap (the light-facing
    triangles) and, for a spot or point light, a far cap (the others pushed to infinity), so
    it is right wherever the camera is; it is later work, not the paper's: Carmack's reverse (2000), made
    robust by Everitt and Kilgard (2002). Volumes are extruded to infinity (w = 0); z-fail
    draws them with depth clamping (one of Everitt and Kilgard's two ways; their infinite far
    plane would give depths other than the G-buffer's), so what lies beyond the far plane
    counts at the far plane's depth instead of being clipped, and with a one-unit polygon
    offset, so a near cap never lands in front of the surface it copies.

    The count lives in the ``stencil`` buffer (two-sided, wrapping increment/decrement: counts
    modulo 256), or, without a stencil buffer (Roettger et al. 2002), in the ``alpha`` channel
    or the RGB of the ``screen`` buffer as a blending state machine: start at 1/4, the faces
    that enter a volume double, those that leave halve, so a lit pixel ends at 1/4 and a
    shadowed one at 1/2 or 1. ``normalize: rectangles`` turns that into 0/1 with three
    full-window rectangles (double, invert, double; section 4.3); the state machine tells 0
    from "at least 1" only, so it is right only for volumes a ray enters at most once, each
    drawn front faces before back faces (section 4.2): one silhouette volume per convex closed
    mesh, one volume per triangle otherwise (``volumes: auto``). ``normalize: max`` starts at 1
    with halve/double swapped and lifts everything to at least 1/2 with one max-blended
    rectangle (section 4.4); its counter holds several entries per ray (1, 1/2, 1/4 ...), so,
    as with the stencil, ``auto`` makes every closed mesh one silhouette volume. Its depth
    limit is 7 entries in the 8-bit channel on llvmpipe (each blend product is rounded, so
    halving stops at 2/255 after 7 halvings; rounding their sum once would allow 8): entries
    beyond 7 are lost, so a count that reaches 8 or more on the way (faces are drawn volume by
    volume, increments first) ends too low, and a pixel still inside a volume can read as lit.
    ``mask_res: half`` or ``quarter`` computes the mask at 1/2 or 1/4 of the image's
    resolution along each axis and magnifies it bilinearly (section 4.5; the paper's "quarter
    of the screen size" took 10.2 to 23.6 Hz at 1024^2, beyond its half-resolution 15.7 Hz,
    so a quarter along each axis).

    The volumes are extruded on the GPU every frame, inside the timed ``volumes`` pass, from
    geometry uploaded in ``prepare`` (``sv_gpu``: each closed mesh's edges as degenerate quads
    with both faces' planes, McGuire et al. 2003; per-triangle volumes by a geometry shader),
    so a still scene and a moving light pay the same passes. Moving objects too: each part is
    drawn with its pose (``Frame.part_poses``) as the model transform and the light moved into
    its space, set in that pass every frame. The near-plane clip polygons are computed on the
    CPU in that pass, every frame, from the meshes moved by those poses; nearclip in the alpha
    and screen buffers
    builds all its volumes there on the CPU (``sv_cpu``), since the GPU volumes cannot put a
    volume's clip polygons between its increments and its decrements. The normalisation
    rectangles and the visibility pass shade covered pixels only.

    ``cull: cull`` and ``cull: cc`` (Lloyd, Wendt, Govindaraju, Manocha 2004, "CC shadow
    volumes") spend one more timed pass, ``receivers``, on a light-space grid of the G-buffer's
    samples (each cell's deepest receiver along the light, and its max pyramid: ``sv_cull``);
    the geometry shader then culls every per-triangle volume with no receiver beyond its
    triangle in the cells its footprint touches. ``cc`` also clamps the rest to the light
    depths from the triangle's nearest corner to that deepest receiver, per fragment (the
    rasterised volume stays: a clamped far edge rasterises otherwise and moved V at tie
    pixels), with a full mask and z-fail only. Both are conservative: V is the same as with
    ``none``, only fill and time change; the clamp lowers the fill that reaches the count, not
    the rasterised area, and costs a texel fetch a fragment (``sv_cull`` says more). They
    apply to a directional light's per-triangle volumes (open parts, or all with ``volumes:
    polygon``); silhouette volumes, and every volume of a spot or point light, are drawn as
    with ``none``.

    Volume fragments are counted untimed, with the depth test off, whenever the light, the
    camera or an object moved (once on a still scene): they are the row's
    ``frags_shadow``, so ``overdraw`` = that / scene fragments is the silhouette-map paper's O.

    ===============  =====================================================  ==========  =====
    Parameter        Meaning                                                Default     Range
    ===============  =====================================================  ==========  =====
    ``buffer``       where the count lives: ``stencil``, ``alpha``,         stencil
                     ``screen``
    ``method``       ``zpass``, ``nearclip`` (z-pass with near-plane clip   zfail
                     polygons) or ``zfail`` (capped)
    ``mask_res``     ``full``, ``half`` or ``quarter`` (bilinear            full
                     magnification)
    ``normalize``    alpha/screen: ``rectangles`` (3, section 4.3) or       rectangles
                     ``max`` (1, section 4.4)
    ``volumes``      ``auto``, ``silhouette`` (one per closed mesh, even    auto
                     non-convex) or ``polygon`` (one per triangle)
    ``cull``         ``none``; ``cull``: per-triangle volumes that reach    none
                     no visible receiver culled; ``cc``: culled, the rest
                     clamped to their receivers' light depths (Lloyd et
                     al. 2004; full mask, zfail). Directional light; not
                     with nearclip
    ``alpha``        on a scene with alpha-tested casters: ``decline``      decline
                     (skipped: a volume is extruded from whole
                     triangles) or ``ignore`` (run, cut-outs opaque)
    ===============  =====================================================  ==========  =====
    """

    name = "sv"
    colour = "#8c564b"
    summary = ("shadow volumes: stencil, alpha or screen buffer; z-pass, near-plane clipped or "
               "z-fail; half- or quarter-res mask")
    paper = ("Crow 1977, Shadow algorithms for computer graphics; Roettger, Irion, Ertl 2002, "
             "Shadow volumes revisited")
    # quality knobs: buffer and method trade cost for robustness, mask_res accuracy for time
    quality_knobs = {"buffer": ("stencil", "alpha", "screen"),
                     "method": ("zpass", "nearclip", "zfail"),
                     "mask_res": ("quarter", "half", "full")}
    # a point light's volumes are extruded from the point as a spot light's (caps included);
    # it only has no cone
    declines_lights = {}

    class Params(TechniqueParams):
        buffer: Literal["stencil", "alpha", "screen"] = "stencil"
        method: Literal["zpass", "zfail", "nearclip"] = "zfail"
        mask_res: Literal["full", "half", "quarter"] = "full"
        normalize: Literal["rectangles", "max"] = "rectangles"
        volumes: Literal["auto", "silhouette", "polygon"] = "auto"
        cull: Literal["none", "cull", "cc"] = "none"
        alpha: AlphaPolicy = "decline"

        @model_validator(mode="after")
        def _cull_needs_gpu_volumes(self):
            if self.cull != "none" and self.method == "nearclip":
                raise ValueError(f"cull: {self.cull} needs method zpass or zfail (nearclip "
                                 "draws each volume's near-plane clip polygon apart from it)")
            return self

    def prepare(self, frame: Frame) -> None:
        p = self.params
        self.front_increments = p.method != "zfail"
        self.meshes = sv_volumes.clean_parts(frame.scene.parts)
        nested = p.buffer == "stencil" or p.normalize == "max"
        self.single = [sv_volumes.one_volume(m, p.volumes, nested) for m in self.meshes]
        divisor = MASK_DIVISOR[p.mask_res]
        self.shares_scene_depth = divisor == 1
        # the clamp needs each mask pixel's receiver (the G-buffer's, at its resolution only)
        # and z-fail's closed volumes (with z-pass the camera may sit inside a volume, whose
        # fragments at a pixel then add up to one exit where its receiver lies outside it)
        clamp = p.cull == "cc" and self.shares_scene_depth and p.method == "zfail"
        self.receivers = ReceiverGrid(clamp=clamp) if p.cull != "none" else None
        self.volumes, self.near_clip = self._volume_geometry(frame)
        self.receiver_uniforms = False  # whether the volume pass culls by a grid built
        # what the diagnostics were last counted for
        self.view_proj = None  # the frame's camera, set by render
        self.counted_for = None  # the light, camera and poses the diagnostics are of
        self.mask = Framebuffer(-(-frame.width // divisor), -(-frame.height // divisor),
                                (GL.GL_RGBA8,), depth=not self.shares_scene_depth)
        if self.shares_scene_depth:
            frame.share_scene_depth(self.mask)
        self.scene_program = self.shader(__file__, "gbuffer.vert.glsl", "sv_fill.frag.glsl")
        self.fill_program = self.shader(__file__, "fullscreen.vert.glsl", "sv_fill.frag.glsl")
        self.visibility_program = mask_visibility_program(divisor)

    def _volume_geometry(self, frame: Frame):
        """The volumes and, for nearclip, the near-plane clip polygons: what the volume pass
        draws. The volumes are extruded on the GPU (``sv_gpu``), except for nearclip in the
        alpha and screen buffers, built on the CPU inside the volume pass every frame (see
        ``sv_cpu``); the clip polygons are computed on the CPU there too."""
        p = self.params
        if p.method == "nearclip" and p.buffer != "stencil":
            return sv_cpu.CpuVolumes(frame.scene.parts, self.meshes, p), None
        volumes = GpuVolumes([part.name for part in frame.scene.parts], self.meshes,
                             self.single, caps=p.method == "zfail",
                             increments_first=p.buffer != "stencil",
                             nested_counts=p.buffer == "stencil" or p.normalize == "max",
                             cull=p.cull != "none", clamp=self.receivers is not None
                             and self.receivers.clamp)
        near_clip = (sv_cpu.NearClipPolygons(self.meshes, self.single)
                     if p.method == "nearclip" else None)
        return volumes, near_clip

    def _count_diagnostics(self, frame: Frame) -> None:
        """No ``update``: all that depends on the light, the camera and the objects' poses is
        drawn in the volume pass, every frame, under either cost policy. Only diagnostics (the
        fill count, volume counts, warnings; untimed, after the timed passes) are counted
        again when any of them moved."""
        light = frame.scene.light
        light_key = tuple(b"" if v is None else v.tobytes()
                          for v in (light.direction, light.position))
        poses = frame.part_poses
        counted_for = (light_key, self.view_proj.tobytes(), poses.tobytes())
        if counted_for == self.counted_for:
            return
        self.counted_for = counted_for
        self.fill = self._count_fill(light, poses)
        counts, self.warnings = self.volumes.diagnostics(light, poses)
        redraw = self.params.buffer == "screen" and self.shares_scene_depth
        self.fill.update(counts, scene_passes=1 + (not self.shares_scene_depth) + redraw)
        self.fill.setdefault("near_clip_triangles",
                             self.near_clip.triangles if self.near_clip else 0)

    # ---- untimed fill-rate counts -------------------------------------------------------

    def _count_fill(self, light, poses: np.ndarray) -> dict:
        self.mask.bind()
        GL.glColorMask(False, False, False, False)
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glDisable(GL.GL_DEPTH_TEST)
        self._zfail_depth(True)
        volume_frags = count_fragments(lambda: self._draw_volumes(light, poses))
        self._zfail_depth(False)
        GL.glColorMask(True, True, True, True)
        return {"volume_frags": volume_frags,
                "mask_width": self.mask.width, "mask_height": self.mask.height}

    def _draw_volumes(self, light, poses: np.ndarray, **fragment_uniforms) -> None:
        if self.receiver_uniforms:  # a grid was built this frame (binds it, too)
            fragment_uniforms["receivers"] = self.receivers.uniforms()
        self.volumes.draw(light, self.view_proj, poses, front_increments=self.front_increments,
                          **fragment_uniforms)
        if self.near_clip:
            self.near_clip.draw(light, self.view_proj, poses,
                                front_increments=self.front_increments, **fragment_uniforms)

    # ---- passes ---------------------------------------------------------------------------

    def _start_value(self) -> float:
        if self.params.buffer == "stencil" or self.params.normalize == "max":
            return 1.0
        return 0.25

    def _zfail_depth(self, on: bool) -> None:
        """z-fail's depth state. Clamping: volume parts beyond the far plane count at its depth
        instead of being clipped. A polygon offset of one unit: clamped depths round other
        than the G-buffer's unclamped ones (llvmpipe: by up to 2^-23), and a near cap must
        never land in front of the surface it copies."""
        if on and self.params.method == "zfail":
            GL.glEnable(GL.GL_DEPTH_CLAMP)
            GL.glEnable(GL.GL_POLYGON_OFFSET_FILL)
            GL.glPolygonOffset(0.0, 1.0)
        else:
            GL.glDisable(GL.GL_DEPTH_CLAMP)
            GL.glDisable(GL.GL_POLYGON_OFFSET_FILL)

    def _clear_mask(self) -> None:
        """The start value in the mask, count 0 in the stencil; a shared depth stays, a mask's
        own depth is cleared too."""
        self.mask.clear((self._start_value(),) * 4)
        GL.glStencilMask(0xFF)
        GL.glClearBufferiv(GL.GL_STENCIL, 0, np.zeros(1, np.int32))

    def _depth_pass(self, frame: Frame) -> None:
        """A smaller mask's own scene pass: the scene's depth at the mask's resolution."""
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glDisable(GL.GL_CULL_FACE)
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDepthMask(True)
        GL.glColorMask(False, False, False, False)
        self.scene_program.use().set(view_proj=self.view_proj)
        frame.draw_scene()

    def _volume_pass(self, frame: Frame) -> None:
        p = self.params
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthMask(False)
        GL.glDisable(GL.GL_CULL_FACE)
        self._zfail_depth(True)
        # z-fail counts the faces behind the surface: stencil has a depth-fail operation,
        # blending only sees passing fragments, so there the test is reversed. Either way a
        # face at equal depth counts as behind (and z-fail's offset puts a near cap behind
        # its own surface).
        reversed_test = p.method == "zfail" and p.buffer != "stencil"
        GL.glDepthFunc(GL.GL_GEQUAL if reversed_test else GL.GL_LESS)
        colours = {}
        if p.buffer == "stencil":
            GL.glColorMask(False, False, False, False)
            GL.glEnable(GL.GL_STENCIL_TEST)
            GL.glStencilMask(0xFF)
            GL.glStencilFunc(GL.GL_ALWAYS, 0, 0xFF)
            keep, incr, decr = GL.GL_KEEP, GL.GL_INCR_WRAP, GL.GL_DECR_WRAP
            if p.method != "zfail":
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
            colours = dict(increment_colour=increment, decrement_colour=decrement)
        self._draw_volumes(frame.scene.light, frame.part_poses, **colours)
        self._zfail_depth(False)

    def _rectangle(self, frame: Frame, colour: float) -> None:
        """A full-window rectangle, on covered pixels only where the mask has the scene's
        depth (a smaller mask is magnified bilinearly, which reads the texels beside covered
        ones too)."""
        self.fill_program.use().set(fill_colour=(colour,) * 4)
        frame.draw_fullscreen(covered_only=self.shares_scene_depth)

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
        self.scene_program.use().set(view_proj=self.view_proj, fill_colour=(1.0,) * 4)
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
                    lit_threshold=lit_threshold)
        frame.draw_fullscreen(covered_only=True)  # V = 1 where no surface

    def render(self, frame: Frame) -> ShadowOutput:
        p = self.params
        self.view_proj = frame.camera.view_proj  # the G-buffer's: its depth is the one tested
        light = frame.scene.light
        if self.receivers and light.type == "directional":
            with frame.measure("receivers"):
                self.receivers.build(frame, light)
                self.receiver_uniforms = True
        if not self.shares_scene_depth:
            with frame.measure("depth"):
                self._clear_mask()
                self._depth_pass(frame)
        with frame.measure("volumes"):
            if self.shares_scene_depth:
                self._clear_mask()
            self._volume_pass(frame)
        with frame.measure("stencil_mask" if p.buffer == "stencil" else "normalize"):
            self._normalize_pass(frame)
        if p.buffer == "screen" and self.shares_scene_depth:
            with frame.measure("scene_redraw"):
                self._scene_redraw_pass(frame)
        with frame.measure("visibility"):
            self._visibility_pass(frame)
        self._count_diagnostics(frame)
        fill = dict(self.fill)
        return frame.output(mem_bytes=self.mask.nbytes + (self.receivers.mem_bytes
                                                          if self.receiver_uniforms else 0),
                            fetches_per_px=1 if self.shares_scene_depth else 4,
                            shadow_fragments=fill.pop("volume_frags"), extra=fill,
                            warnings=self.warnings)

    def release(self) -> None:
        if isinstance(self.volumes, GpuVolumes):  # the CPU-built volumes use no geometry shader
            # Mesa 22.3 (llvmpipe) keeps a program that draws after a geometry-shader program
            # alive past its deletion, until a geometry-shader program is bound again
            self.volumes.polygon_program.use()
        for resource in (self.volumes, self.near_clip, self.mask, self.scene_program,
                         self.fill_program, self.visibility_program, self.receivers):
            if resource:
                resource.release()
