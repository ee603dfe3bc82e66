"""The technique contract (the frame a technique renders into: :mod:`.frame`).

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

from pathlib import Path
from typing import ClassVar, Literal

from pydantic import ConfigDict

from .code_version import code_hash
from ..config import LIGHT_TYPES, TypesAsWritten
from ..gl.shaders import HARNESS_GLSL, Program
from ..scene import BuiltScene
from .frame import Frame, ShadowOutput, reset_gl_state

__all__ = ["Frame", "NotApplicable", "ShadowOutput", "Technique", "TechniqueParams",
           "reset_gl_state"]


class NotApplicable(Exception):
    """Raised by ``prepare`` when the technique does not apply to a scene (status=skipped)."""


# What a technique that does not treat alpha-tested casters does on a scene with them, as its
# ``alpha`` parameter: ``decline`` (skipped, the reason in ``error``) or ``ignore`` (it runs with
# every cut-out drawn opaque, the row's ``alpha`` column ``ignored``, so its error shows).
AlphaPolicy = Literal["decline", "ignore"]


class TechniqueParams(TypesAsWritten):
    """Base of every ``Params`` model: unknown names are errors, values are validated."""

    model_config = ConfigDict(extra="forbid", frozen=True)


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
