"""What the command line prints about the installation and the input before anything is rendered:
``list`` (techniques with their parameters, broken entry points, stale editable installs; the
scenes and the file they came from), ``inspect`` (a scene's objects as placed: bounds, up axis,
triangles, parts) and ``plan`` (the runs a ``run`` would make, grouped, with a time estimate).
Each function returns the lines; the command prints them."""

from __future__ import annotations

from collections import Counter
from pathlib import Path

from .. import config
from ..technique import registry


def _show(value) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _allowed(annotation) -> str:
    """``grid | jitter`` for a Literal, the type's name otherwise (unions joined)."""
    import types
    import typing

    origin = typing.get_origin(annotation)
    if origin is typing.Literal:
        return " | ".join(_show(v) for v in typing.get_args(annotation))
    if origin in (typing.Union, types.UnionType):
        return " | ".join(_allowed(a) for a in typing.get_args(annotation))
    if annotation is bool:
        return "true | false"
    if annotation is type(None):
        return "none"
    return getattr(annotation, "__name__", str(annotation))


def _limit(meta) -> str | None:
    import annotated_types as at
    from pydantic import AfterValidator

    for kind, op in ((at.Ge, ">="), (at.Gt, ">"), (at.Le, "<="), (at.Lt, "<")):
        if isinstance(meta, kind):
            return f"{op} {_show(getattr(meta, kind.__name__.lower()))}"
    if isinstance(meta, at.MultipleOf):
        return f"multiple of {_show(meta.multiple_of)}"
    if isinstance(meta, AfterValidator):
        if meta.func is config.square_number:
            return "square number"
        return getattr(meta.func, "__name__", None)
    return None  # other metadata (strictness, ...) says nothing about the range


PROBED = 10_000  # the widest range of an int field whose values a validator is asked about
SHOWN = 16  # the most accepted values listed one by one


def _bounds(field) -> tuple[int | None, int | None]:
    """An int field's inclusive bounds from its Field(ge=, gt=, le=, lt=)."""
    import annotated_types as at

    low = high = None
    for meta in field.metadata:
        if isinstance(meta, at.Ge):
            low = meta.ge
        elif isinstance(meta, at.Gt):
            low = meta.gt + 1
        elif isinstance(meta, at.Le):
            high = meta.le
        elif isinstance(meta, at.Lt):
            high = meta.lt - 1
    return low, high


def _validated(cls, pname: str, field) -> str | None:
    """What a field validator of ``Params`` (``@field_validator``, invisible in the type and
    its bounds) leaves of an int field's range: each value in the bounds asked of Params with
    the other parameters at their defaults; ``one of 2, 4``, or how many pass when more than
    :data:`SHOWN` do; None when there is no such validator or it refuses none."""
    from pydantic import ValidationError

    validators = cls.Params.__pydantic_decorators__.field_validators.values()
    if field.annotation is not int or not any(
            pname in v.info.fields or "*" in v.info.fields for v in validators):
        return None
    low, high = _bounds(field)
    if low is None or high is None or not 0 <= high - low <= PROBED:
        return None
    accepted = []
    for value in range(low, high + 1):
        try:
            cls.Params(**{pname: value})
        except ValidationError:
            continue
        accepted.append(value)
    if len(accepted) == high - low + 1:
        return None
    if len(accepted) <= SHOWN:
        return "one of " + ", ".join(map(str, accepted)) if accepted else "no value"
    return f"{len(accepted)} values in {low} .. {high} (a validator refuses the others)"


def parameter_rows(cls) -> list[tuple[str, str, str]]:
    """(name, default, allowed values) of each parameter of a technique's Params: the type,
    then its bounds, or what a field validator leaves of them (:func:`_validated`)."""
    from pydantic_core import PydanticUndefined

    rows = []
    for pname, field in cls.Params.model_fields.items():
        default = (field.default_factory() if field.default_factory is not None
                   else "(required)" if field.default is PydanticUndefined else field.default)
        limits = [text for text in map(_limit, field.metadata) if text]
        validated = _validated(cls, pname, field)
        rows.append((pname, _show(default), ", ".join(
            [_allowed(field.annotation)] + ([validated] if validated else limits))))
    return rows


def techniques_lines() -> list[str]:
    """Every technique with each parameter's default and allowed values and its quality knobs
    (the values its curve walks); the plugins' distributions; broken entry points."""
    lines = ["techniques:"]
    for name, cls in registry.techniques().items():
        dist = registry.distribution_of(name)
        plugin = f" (plugin: {dist})" if registry.is_plugin(name) else ""
        lines.append(f"  {name:10s} {cls.summary}  [{cls.paper}]{plugin}")
        for pname, default, range_text in parameter_rows(cls):
            lines.append(f"      {pname:14s} default {default:11s} {range_text}")
        for knob, values in cls.quality_knobs.items():
            lines.append(f"      quality knob {knob}: {', '.join(map(_show, values))}")
    for name, why in registry.broken().items():
        lines.append(f"  {name:10s} BROKEN, left out of every run: {why}")
    return lines


def scenes_lines(path: Path | None) -> list[str]:
    """The scenes of ``path`` (None: there is none), naming the file."""
    if path is None:
        return ["scenes: no scene file (no ./scenes.yaml, and none shipped with the package); "
                "give one with --scene-file"]
    lines = [f"scenes (from {path}):"]
    scenes = config.load_scenes(path, triangle_budget=None, only=())
    node = config.read_yaml(path)[1]
    for name, scene in scenes.items():
        geometry = (f"{scene.family.kind} family, {scene.family.triangles:,} triangles"
                    if scene.family else f"{len(scene.objects)} objects")
        if scene.family and scene.objects:
            geometry += f" and {len(scene.objects)} objects"
        lines.append(f"  {name:16s} {scene.resolution[0]}x{scene.resolution[1]}  "
                     f"{scene.light.type} light, {geometry}, effects {'+'.join(scene.effects)}")
        if scene.description:
            lines.append(f"      {scene.description}")
        try:  # one scene's unusable mesh file is its own line, not the end of the list
            config.check_scenes(path, scenes, [name], None, node)
        except config.ConfigError as e:
            lines.append(f"      CANNOT LOAD (a command naming it exits 2): {e}")
            continue
        for obj in scene.objects:
            if isinstance(obj, config.MeshFile):
                parts = config.mesh_parts(config.resolve_mesh_path(path, obj), obj.up)
                lines.append(f"      mesh {obj.label}: {parts.summary()}")
    return lines


def experiments_lines() -> list[str]:
    """The shipped experiments, by the name ``run`` and ``plan`` take from any folder."""
    names = config.shipped.experiments()
    if not names:
        return ["experiments: none shipped with this installation"]
    return [f"experiments (shipped in {config.shipped.root() / 'experiments'}; "
            "`shadowbench run NAME --out DIR` from any folder):", f"  {', '.join(names)}"]


def inspect_lines(path: Path, name: str) -> list[str]:
    """Each object of scene ``name`` as the scene places it (``scale``, then ``rotate`` about x,
    y, z, then ``translate``; never recentred; a mesh file turned to z up first): its world
    bounds, up axis, triangles and parts; then the scene's bounds."""
    import numpy as np

    from ..scene import build_parts

    scenes = config.load_scenes(path, triangle_budget=None)
    if name not in scenes:
        raise config.ConfigError(f"--scene {name}: no such scene in {path}; it has "
                                 f"{', '.join(scenes)}")
    scene = scenes[name]
    parts = build_parts(scene, Path(path))
    lines = [f"scene {name} (from {path}): z is up; object = translate(rotate_z(rotate_y("
             "rotate_x(scale(vertices))))), in the file's own origin (never recentred)"]

    def bounds(vertices) -> str:
        low, high = vertices.min(axis=0), vertices.max(axis=0)
        return (f"[{', '.join(f'{v:.4g}' for v in low)}] .. "
                f"[{', '.join(f'{v:.4g}' for v in high)}]")

    for index, obj in enumerate(scene.objects):
        own = [p for p in parts if p.object_index == index]
        vertices = np.concatenate([p.vertices for p in own])
        triangles = sum(len(p.faces) for p in own)
        label = obj.label if isinstance(obj, config.MeshFile) else obj.shape
        up = f"file up {obj.up}" if isinstance(obj, config.MeshFile) else "z up"
        copies = f", {int(np.prod(obj.array.count))} copies" if obj.array else ""
        lines.append(f"  {index}: {label}{f' ({obj.name})' if obj.name else ''}: bounds "
                     f"{bounds(vertices)}, {up}, {triangles:,} triangles, {len(own)} parts"
                     f"{copies}")
    family = [p for p in parts if p.object_index == -1]
    if family:
        vertices = np.concatenate([p.vertices for p in family])
        lines.append(f"  family {scene.family.kind}: bounds {bounds(vertices)}, "
                     f"{sum(len(p.faces) for p in family):,} triangles, {len(family)} parts")
    if parts:
        lines.append(f"  scene bounds {bounds(np.concatenate([p.vertices for p in parts]))}")
    return lines


def plan_lines(plan, out: Path | None, stored: Path | None) -> list[str]:
    """The runs of ``plan`` grouped by scene (runs of each technique), the plan's notes, and the
    time the runs not yet in ``out`` would take, from the runs stored in ``stored``
    (:mod:`harness.run.estimate`)."""
    from ..results import read_rows

    done = {r["run_id"] for r in (read_rows(out) if out is not None else [])
            if r["status"] in ("ok", "skipped")}
    todo = [spec for spec in plan.runs if spec.run_id not in done]
    lines = [f"{len(plan.runs)} runs (duplicate points merged) in {len(plan.scenes)} scenes, "
             f"cost policy {plan.cost}" + (f"; {len(plan.runs) - len(todo)} of them in {out} "
                                           "already" if out is not None else "") + ":"]
    by_scene: dict[tuple, Counter] = {}
    for spec in plan.runs:
        by_scene.setdefault((spec.scene, spec.width, spec.height), Counter())[spec.technique] += 1
    for (scene, width, height), counts in by_scene.items():
        lines.append(f"  {scene} {width}x{height}: {sum(counts.values())} runs: "
                     + ", ".join(f"{t} {n}" for t, n in counts.items()))
    lines += plan.notes
    if not todo:
        lines.append(f"time: none; every run is in {out} already")
        return lines
    from ..run import read_manifest
    from ..run.estimate import duration, estimate

    rows = read_rows(stored) if stored is not None else []
    found = estimate(todo, {name: len(scene.triangles) for name, scene in plan.scenes.items()},
                     rows, read_manifest(stored)) if rows else None
    if found is None or not found.seconds:
        lines.append("time: no estimate (no stored run with a time and a triangle count to price "
                     "them from; give --from DIR, a folder an earlier run of this experiment "
                     "wrote)")
        return lines
    lines.append(f"time: about {duration(found.seconds)} for the {len(todo)} runs to render, at "
                 f"the pace of the runs stored in {stored} on the machine that ran them "
                 f"({found.stored} as stored there, {found.modelled} priced by their scene's "
                 f"triangles and pixels" + (f": {found.how})" if found.modelled else ")"))
    return lines


