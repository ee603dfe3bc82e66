"""The technique contract and the frame a technique renders into.

A technique subclasses :class:`Technique`, defines ``name``, ``summary``, ``paper`` and a pydantic
``Params`` model, and implements ``prepare``, ``render`` and ``release`` (and ``update`` when
something depends on the light and the geometry). It computes per-pixel light visibility V for
the G-buffer pixels: its last pass draws V into the frame's visibility target
(``frame.begin_visibility()``), and ``render`` returns ``frame.output(...)``.

The work is split by what it depends on. ``update(frame)`` holds the work that depends on the
light and the geometry only (maps, light fits, silhouette edges, shadow-volume geometry);
``render(frame)`` the per-view work (what depends on the camera: the warps' fit, the shading
passes). Every piece of either goes inside a timed pass (``frame.measure(name)``); only
diagnostics a renderer would not compute (aliasing maps, fill counts) stay outside.

The harness calls ``prepare(frame)`` once per run, then frames as the run's cost policy says
(``cost:`` in the experiment, :mod:`harness.run.measure`): under ``dynamic`` (the default) each
frame, warm-up and measured, calls ``update`` then ``render``, and its time holds both; under
``static`` ``update`` is the run's setup, timed apart as ``setup_ms``, and each frame calls
``render`` alone. On a moving scene (``motion`` in the scene file) the frame moves to each
sequence frame's camera, light and objects between frames (:meth:`Frame.move_to`: the scene's
vertex buffer holds the moved triangles, the G-buffer is rendered again), so the technique
keeps its GL resources across the sequence. Geometry a technique builds once in ``prepare``
from ``frame.scene.parts`` follows moving objects through :attr:`Frame.part_poses` (each
part's rigid transform from those parts).
"""

from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, ClassVar, Literal

import numpy as np
from OpenGL import GL
from pydantic import ConfigDict

from ..truth import metrics
from .code_version import code_hash
from ..config import LIGHT_TYPES, TypesAsWritten
from ..gl.gbuffer import GBuffer
from ..gl.framebuffer import Framebuffer
from ..gl.alpha import AlphaTextures
from ..gl.geometry import FullscreenTriangle, SceneMesh
from ..gl import measure as pass_measure
from ..gl.measure import PassMeter, default_timer
from ..gl.objects import live_objects, names_now
from ..gl.shaders import HARNESS_GLSL, Program
from ..scene import BuiltScene
from ..scene.transforms import camera_matrices


class NotApplicable(Exception):
    """Raised by ``prepare`` when the technique does not apply to a scene (status=skipped)."""


# What a technique that does not treat alpha-tested casters does on a scene with them, as its
# ``alpha`` parameter: ``decline`` (skipped, the reason in ``error``) or ``ignore`` (it runs with
# every cut-out drawn opaque, the row's ``alpha`` column ``ignored``, so its error shows).
AlphaPolicy = Literal["decline", "ignore"]


class TechniqueParams(TypesAsWritten):
    """Base of every ``Params`` model: unknown names are errors, values are validated."""

    model_config = ConfigDict(extra="forbid", frozen=True)


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


class Technique:
    name: ClassVar[str]
    summary: ClassVar[str]
    paper: ClassVar[str]
    Params: ClassVar[type[TechniqueParams]]
    # The quality knob(s) and the values worth trying, ``{parameter: (value, ...)}``: what
    # ``techniques: curves`` runs, one knob at a time from the defaults (see
    # :func:`quality_settings`); checked by :func:`check_quality_knobs` when registered.
    quality_knobs: ClassVar[dict[str, tuple]] = {}
    # The settings a user would adjust per scene, and the ranges ``shadowbench tune`` searches:
    # ``{parameter: ("log" | "float" | "int", low, high) or ("choice", (value, ...))}``, each
    # holding the default; ``bias_terms``: those of them one scale multiplies together for the
    # bias window. Checked by :func:`harness.technique.tunable.check_tunable` when registered.
    tunable: ClassVar[dict[str, tuple]] = {}
    bias_terms: ClassVar[tuple[str, ...]] = ()
    # The technique whose cost the others' is divided by at equal error (analysis.summary, the
    # dashboard's overview): one registered technique says so in its own class body, the harness
    # names none. A subclass does not inherit it (:func:`declares_baseline`).
    baseline: ClassVar[bool] = False
    # The techniques this one is weighed against in the Scale view's crossover table, besides
    # the baseline: those its paper or its issue asks to be compared with (rays against
    # volumes, say). Names not in a results folder are left out there.
    rivals: ClassVar[tuple[str, ...]] = ()
    # The technique's colour in every dashboard, "#rrggbb", declared in its own class body (not
    # inherited); without one, its name's colour (:mod:`harness.technique.colour`).
    colour: ClassVar[str | None] = None
    # Light types (harness.scene.Light.type) the technique does not render, each with the
    # reason, which a run on a scene so lit reports as skipped (:meth:`check_light`, before
    # ``prepare``). A point light shines every way, so a technique built on one light frustum
    # declines it unless it says otherwise (``declines_lights = {}``).
    declines_lights: ClassVar[dict[str, str]] = {
        "point": "it declares no point-light path (a point light shines every way, past any "
                 "one light frustum)"}

    # Whether the technique treats alpha-tested casters (``BuiltScene.has_alpha``: a texture's
    # alpha cuts the surface out, by the rule of harness.scene.alpha) in its own passes. One
    # that does not declines a scene with them unless its ``alpha`` parameter (AlphaPolicy)
    # says ``ignore`` (:meth:`alpha_handling`).
    alpha_casters: ClassVar[bool] = False

    def __init__(self, params: TechniqueParams):
        self.params = params

    @classmethod
    def alpha_handling(cls, params: TechniqueParams, scene: BuiltScene) -> str:
        """What the run does with the scene's cut-outs, the row's ``alpha`` column: ``none``
        (the scene has none), ``tested`` (the technique treats them), ``ignored`` (drawn
        opaque, as its ``alpha: ignore`` asks) or ``declined`` (see :meth:`check_alpha`)."""
        if not scene.has_alpha:
            return "none"
        if cls.alpha_casters:
            return "tested"
        return "ignored" if getattr(params, "alpha", "decline") == "ignore" else "declined"

    @classmethod
    def check_alpha(cls, params: TechniqueParams, scene: BuiltScene) -> None:
        """Raise :class:`NotApplicable` naming the reason where the technique declines the
        scene's alpha-tested casters."""
        if cls.alpha_handling(params, scene) == "declined":
            how = (" (alpha: ignore runs it with them drawn opaque)"
                   if "alpha" in cls.Params.model_fields else "")
            raise NotApplicable(f"{cls.name} does not treat alpha-tested casters: it draws "
                                f"every triangle whole, cut-outs included{how}")

    @classmethod
    def check_light(cls, light) -> None:
        """Raise :class:`NotApplicable` naming the reason when the technique declines the
        type of ``light`` (a :class:`harness.scene.Light`)."""
        reason = cls.declines_lights.get(light.type)
        if reason:
            raise NotApplicable(f"{cls.name} does not treat a {light.type} light: {reason}")

    @classmethod
    def check_scene(cls, params: TechniqueParams, scene: BuiltScene) -> None:
        """Raise ValueError ``"<parameter>: <why>"`` where ``params`` cannot run on ``scene``
        at all (memory it would take over a budget parameter): the plan refuses that as bad
        input, naming the experiment's key, before anything is built or run."""

    def prepare(self, frame: "Frame") -> None:
        """Allocate GL resources and upload what depends on geometry (where objects move,
        as at frame 0, then moved by :attr:`Frame.part_poses`)."""

    def update(self, frame: "Frame") -> None:
        """Recompute what depends on the frame's light and geometry (a light frustum's fit, a
        map pass, silhouette edges, shadow volumes, where moving objects are now), each step
        inside ``frame.measure(name)``. Under ``cost: dynamic`` it runs before every
        ``render``, in the frame's time; under ``static`` it is the setup, repeated to time it
        (``setup_ms``). Each call redoes the work, as an engine does when the light or the
        geometry moves, and leaves the same state when nothing moved. What depends on the
        camera belongs in ``render``."""

    def render(self, frame: "Frame") -> ShadowOutput:
        raise NotImplementedError

    def release(self) -> None:
        """Free GL resources."""

    @classmethod
    def code_version(cls) -> str:
        """Hash of the technique's code: its module, the modules of technique packages it
        imports, and the .glsl files any of them names, following ``#include``
        (:mod:`harness.technique.code_version`): a changed shared helper or shader changes the version,
        so stored results are not reused."""
        return code_hash(cls.__module__)

    @staticmethod
    def shader(module_file: str, vertex: str, fragment: str, **defines) -> Program:
        """Compile a program from .glsl files beside ``module_file`` (or the harness's own)."""
        here = Path(module_file).parent

        def find(name):
            return here / name if (here / name).is_file() else HARNESS_GLSL / name

        return Program(find(vertex), find(fragment), defines or None)


def declares_baseline(cls: type[Technique]) -> bool:
    """Whether ``baseline = True`` is in the class's own body: a plugin subclassing the
    baseline's class (to change a bias, say) is not a second baseline."""
    return cls.__dict__.get("baseline") is True


def check_quality_knobs(cls: type[Technique]) -> None:
    """Check a technique's ``quality_knobs`` like its Params: each knob a parameter, a non-empty
    list of distinct values, each value valid with every other parameter at its default (that
    is the setting that runs). Raises ValueError ``"<knob>: <what is wrong>"``."""
    from pydantic import ValidationError

    if not isinstance(cls.quality_knobs, dict):
        raise ValueError(f"must be a mapping {{parameter: (value, ...)}}, got "
                         f"{type(cls.quality_knobs).__name__}")
    parameters = list(cls.Params.model_fields)
    for knob, values in cls.quality_knobs.items():
        if knob not in parameters:
            raise ValueError(f"{knob}: not a parameter of {cls.__name__}.Params; parameters: "
                             f"{', '.join(parameters)}")
        if not isinstance(values, (list, tuple)) or not values:
            raise ValueError(f"{knob}: needs a non-empty list of values, got {values!r}")
        for value in values:
            try:
                cls.Params(**{knob: value})
            except ValidationError as e:
                reason = e.errors()[0]["msg"].removeprefix("Value error, ")
                raise ValueError(f"{knob}: value {value!r} is not valid: {reason}") from None
        repeated = sorted({repr(v) for v in values if values.count(v) > 1})
        if repeated:
            raise ValueError(f"{knob}: {', '.join(repeated)} listed more than once")


def check_declined_lights(cls: type[Technique]) -> None:
    """Check ``declines_lights``: light types of the scene format, each with a reason. Raises
    ValueError ``"<type>: <what is wrong>"``."""
    if not isinstance(cls.declines_lights, dict):
        raise ValueError(f"must be a mapping {{light type: reason}}, got "
                         f"{type(cls.declines_lights).__name__}")
    for kind, reason in cls.declines_lights.items():
        if kind not in LIGHT_TYPES:
            raise ValueError(f"{kind}: not a light type; light types: {', '.join(LIGHT_TYPES)}")
        if not isinstance(reason, str) or not reason.strip():
            raise ValueError(f"{kind}: needs the reason, got {reason!r}")


def quality_settings(knobs: dict[str, list], base: dict | None = None) -> list[tuple[str, dict]]:
    """The settings of a curve, one knob at a time: ``(knob, {**base, knob: value})`` for each
    knob and value in order. Walking one knob from a shared base (the defaults unless ``base``
    says otherwise) keeps every point one readable change from it, so each curve has one order
    (its knob's), and costs the sum of the value lists' lengths in runs, not their product."""
    return [(knob, {**(base or {}), knob: value})
            for knob, values in knobs.items() for value in values]


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
