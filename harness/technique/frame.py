"""The frame a technique works in, owned by the harness: the scene at one frame of its
sequence, the camera, the G-buffer pass and its arrays, the visibility target, the pass meter;
and what a technique's ``render`` returns (:class:`ShadowOutput`)."""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from OpenGL import GL

from ..truth import metrics
from ..gl.gbuffer import GBuffer
from ..gl.framebuffer import Framebuffer
from ..gl.alpha import AlphaTextures
from ..gl.geometry import FullscreenTriangle, SceneMesh
from ..gl import measure as pass_measure
from ..gl.measure import PassMeter, default_timer
from ..gl.objects import live_objects, names_now
from ..gl.shaders import Program
from ..scene import BuiltScene
from ..scene.transforms import camera_matrices


@dataclass
class ShadowOutput:
    visibility: np.ndarray  # float32 (H, W) in [0, 1], 1 = lit
    mem_bytes: int
    fetches_per_px: float
    nonfinite: int = 0  # NaN/Inf seen in the technique's matrices
    # fragments of the shadow geometry when the technique counts them itself (e.g. shadow
    # volumes drawn with the depth test off: the silhouette-map paper's overdraw O, the
    # `overdraw` column of docs/results.md); else the harness sums the fragments of the
    # measured passes
    shadow_fragments: int | None = None
    extra: dict[str, Any] = field(default_factory=dict)  # additional result columns
    # per-pixel diagnostic maps (float (H, W)), stored with the run and shown by the report
    maps: dict[str, np.ndarray] = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)



class Frame:
    """Everything a technique may use for one scene at one resolution, owned by the harness.

    For a moving scene ``scene`` is the frame of its sequence the frame is at (a still scene:
    that frame's camera, light and objects), starting at frame 0; :meth:`move_to` moves it."""

    def __init__(self, scene: BuiltScene):
        self.sequence = scene  # the scene as given, moving or still
        self.index = 0  # where in the sequence the frame is
        self.scene = scene.at_frame(0)
        self.width, self.height = scene.width, scene.height
        self.camera = camera_matrices(self.scene.config.camera, self.width, self.height)
        self.timer = default_timer(GL.glGetString(GL.GL_RENDERER).decode())
        # why the driver cannot count pipeline statistics ('' where it can)
        self.counters_missing = pass_measure.pipeline_statistics_missing()
        self._make_gl_objects()
        self.arrays = self._camera_pass()

    def _make_gl_objects(self) -> None:
        """The frame's own GL objects, the names they took noted (:meth:`renew_context`)."""
        first = names_now()
        self.geometry = self._scene_mesh()
        # the cut-outs' textures for alpha_test.glsl (bind_alpha), where the scene has any
        self.alpha = AlphaTextures(self.scene.alpha_masks) if self.scene.has_alpha else None
        self.gbuffer = GBuffer(self.width, self.height, self.alpha)
        self.fullscreen_triangle = FullscreenTriangle()
        self.visibility_target = Framebuffer(self.width, self.height, (GL.GL_R32F,), depth=False)
        self.share_scene_depth(self.visibility_target)  # for draw_fullscreen(covered_only=True)
        self.meter = self.new_meter()
        self._names = (first, names_now())

    def renew_context(self, context) -> bool:
        """Make the GL context anew (``GLContext.renew``: what llvmpipe kept of the draws so far
        goes with the old one) and this frame's objects in it again, the G-buffer drawn again
        (the same pixels: :attr:`arrays` stay), the state as ``reset_gl_state`` leaves it; only
        when no other GL object lives (a run's, a caller's). Whether it did."""
        first, made = self._names
        if live_objects() != live_objects(first) or live_objects(made):
            return False
        self.release()
        context.renew()
        self._make_gl_objects()
        self.gbuffer.render(self.geometry, self.camera.view_proj)
        reset_gl_state()
        return True

    def _scene_mesh(self) -> SceneMesh:
        s = self.scene
        cutouts = (s.face_mask, s.face_texcoords) if s.has_alpha else None
        return SceneMesh(*s.indexed, s.face_normals, s.face_albedo, cutouts)

    def _camera_pass(self):
        self.gbuffer.render(self.geometry, self.camera.view_proj)
        return self.gbuffer.read()

    @property
    def frames(self) -> int:
        """Frames of the scene's sequence (1 for a still scene)."""
        return self.sequence.frames

    @property
    def part_poses(self) -> np.ndarray:
        """Each part's rigid transform (P, 4, 4) float64 from where it was at frame 0, the
        geometry ``prepare`` saw: how far moving objects have gone (identities when none
        moved, and always on a still scene, even one that is a moved frame of another)."""
        poses = self.scene.poses if self.sequence.config.motion else None
        return np.tile(np.eye(4), (len(self.scene.parts), 1, 1)) if poses is None else poses

    def move_to(self, index: int) -> None:
        """Put the frame at frame ``index`` of its moving scene: that camera, light and
        geometry (the scene's vertex buffer uploaded again where objects moved, as an
        animation system does before the frame's passes), the G-buffer rendered and read
        again; the targets and timers stay."""
        if index == self.index:
            return
        previous, self.scene = self.scene, self.sequence.at_frame(index)
        self.index = index
        if self.scene.parts is not previous.parts:
            self.geometry.release()
            self.geometry = self._scene_mesh()
        self.camera = camera_matrices(self.scene.config.camera, self.width, self.height)
        self.arrays = self._camera_pass()

    def new_meter(self) -> PassMeter:
        """A fresh pass record (one per run; its owner releases it)."""
        return PassMeter(self.timer, counters=not self.counters_missing)

    @contextmanager
    def metered(self, meter: PassMeter):
        """Send :meth:`measure` to ``meter`` within the block: runs measured in interleaved
        rounds each keep their own record."""
        previous, self.meter = self.meter, meter
        try:
            yield meter
        finally:
            self.meter = previous

    def measure(self, name: str):
        """Context manager around one pass: times it and counts its fragments."""
        return self.meter.measure(name)

    def compared_pixels(self, reference_covered: np.ndarray) -> np.ndarray:
        """The pixels metrics compare: covered in both views and reached by the light (see
        :func:`harness.truth.metrics.receives_light`)."""
        a = self.arrays
        return reference_covered & a.covered & metrics.receives_light(
            a.normal, a.position, self.scene.light, self.camera.position)

    def draw_scene(self) -> None:
        self.geometry.draw()

    def draw_fullscreen(self, covered_only: bool = False) -> None:
        """The full-screen triangle. ``covered_only``, into the visibility target: only where
        the G-buffer holds a surface. The triangle is tested at the far plane against the
        scene's depth, so the renderer skips shading the other pixels (llvmpipe skips a 4x4
        block no pixel of which passes), which keep V's clear value, lit. A shader drawn so
        must give them V = 1 anyway: this saves time and never changes V."""
        if not covered_only:
            self.fullscreen_triangle.draw()
            return
        GL.glEnable(GL.GL_DEPTH_TEST)
        GL.glDepthFunc(GL.GL_GREATER)  # depth 1 is the clear value: no surface there
        GL.glDepthMask(GL.GL_FALSE)
        GL.glDepthRange(1.0, 1.0)
        self.fullscreen_triangle.draw()
        GL.glDepthRange(0.0, 1.0)
        GL.glDepthMask(GL.GL_TRUE)
        GL.glDepthFunc(GL.GL_LESS)
        GL.glDisable(GL.GL_DEPTH_TEST)

    def bind_gbuffer(self, program: Program, first_unit: int = 0) -> int:
        """Bind the G-buffer textures for ``gbuffer_read.glsl``; returns the next free unit."""
        program.set(gbuffer_position=self.gbuffer.position_texture.bind(first_unit),
                    gbuffer_normal=self.gbuffer.normal_texture.bind(first_unit + 1))
        return first_unit + 2

    def bind_alpha(self, program: Program, first_unit: int) -> int:
        """Bind the cut-outs' textures for ``alpha_test.glsl`` to ``program`` (in use), from
        texture unit ``first_unit``; returns the next free unit (``first_unit`` on a scene
        without cut-outs)."""
        return first_unit if self.alpha is None else self.alpha.bind(program, first_unit)

    def share_scene_depth(self, target: Framebuffer) -> None:
        """Attach the G-buffer's depth-stencil to ``target`` (a framebuffer of the frame's size
        made with ``depth=False``), so a technique depth-tests against the camera pass, the
        scene pass every technique gets, instead of drawing the scene again. That depth was
        written with ``camera.view_proj`` by ``gbuffer.vert.glsl``; a technique may use the
        stencil bits but must not write depth. ``target.release()`` leaves it alone."""
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, target.id)
        GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT,
                                  GL.GL_TEXTURE_2D, self.gbuffer.depth_texture.id, 0)
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            raise RuntimeError(f"framebuffer with the scene's depth incomplete: 0x{status:x}")

    def begin_visibility(self) -> None:
        """Bind the visibility target (cleared to lit) for a full-screen pass writing V."""
        self.visibility_target.clear((1, 1, 1, 1))
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_STENCIL_TEST)
        GL.glDisable(GL.GL_BLEND)
        GL.glDisable(GL.GL_CULL_FACE)

    def output(self, *, mem_bytes: int, fetches_per_px: float, **kwargs) -> ShadowOutput:
        return ShadowOutput(self.visibility_target.read(), mem_bytes, fetches_per_px, **kwargs)

    def measure_scene_pass(self, frames: int, warmup: int):
        """Time the G-buffer pass alone: the no-shadow cost. Returns (median ms, fragments)."""
        meter = PassMeter(self.timer)
        for i in range(warmup + frames):
            meter.new_frame(i >= warmup)
            with meter.measure("scene"):
                self.gbuffer.render(self.geometry, self.camera.view_proj)
        stats = meter.passes()[0]
        meter.release()
        return stats.ms, stats.fragments

    def release(self) -> None:
        for r in (self.geometry, self.gbuffer, self.fullscreen_triangle, self.visibility_target,
                  self.meter, self.alpha):
            if r is not None:
                r.release()


def reset_gl_state() -> None:
    """Put the GL state a technique may have changed back to the defaults the harness assumes."""
    GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
    GL.glUseProgram(0)
    GL.glBindVertexArray(0)
    for cap in (GL.GL_BLEND, GL.GL_STENCIL_TEST, GL.GL_CULL_FACE, GL.GL_POLYGON_OFFSET_FILL,
                GL.GL_DEPTH_CLAMP):
        GL.glDisable(cap)
    GL.glEnable(GL.GL_DEPTH_TEST)
    GL.glDepthFunc(GL.GL_LESS)
    GL.glDepthMask(GL.GL_TRUE)
    GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
    GL.glStencilMask(0xFF)
    while GL.glGetError() != GL.GL_NO_ERROR:
        pass
