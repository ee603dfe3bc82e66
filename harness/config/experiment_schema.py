"""Top of the config package, above scene_schema: the experiment file (which scenes, which
techniques over which parameter grids, the timing and reference settings) and its loading."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Literal, Union

from pydantic import ConfigDict, Field, ValidationError, field_validator, model_validator

from ..machine.timing import STATISTICS
from .limits import DEFAULT_MAX_RUNS, DEFAULT_TRIANGLE_BUDGET, MAX_RUNS
from .field_types import SquareInt, Strict
from .scene_schema import TriangleCount
from .yaml_source import ConfigError, line_of, key_error, read_yaml, validation_error

Scalar = Union[bool, int, float, str]


class Grid(Strict):
    """One parameter grid: every combination of ``product`` times each row of ``zip``,
    with ``set`` fixed, less those ``exclude`` matches (each entry a partial combination,
    ``{cull: cull, method: nearclip}``: every combination with all of its values is left out);
    or, with ``curve``, the technique's quality curve from ``set`` (true: every declared knob
    and value; a mapping: those knobs, with these values), expanded by the planner, which
    knows the techniques' declarations."""

    # a non-finite value is the technique's error (run.plan.validate_params), named there
    model_config = ConfigDict(extra="forbid", frozen=True, allow_inf_nan=True)

    product: dict[str, list[Scalar]] = {}
    zip: dict[str, list[Scalar]] = {}
    set: dict[str, Scalar] = {}
    curve: Union[Literal[True], dict[str, list[Scalar]], None] = None
    exclude: list[dict[str, Scalar]] = []

    @model_validator(mode="after")
    def _nonempty(self):
        if self.curve is not None and (self.product or self.zip or self.exclude):
            raise ValueError("curve: goes with set only, not with product, zip or exclude (a "
                             "curve walks one knob at a time)")
        if isinstance(self.curve, dict):
            if not self.curve:
                raise ValueError("curve: is empty; name a quality knob with its values, or "
                                 "write true for every declared one")
            for key, values in self.curve.items():
                if not values:
                    raise ValueError(f"curve.{key} is an empty list")
        kinds = {"product": self.product, "zip": self.zip, "set": self.set}
        for name in set().union(*kinds.values()):
            where = [k for k, values in kinds.items() if name in values]
            if len(where) > 1:
                raise ValueError(f"parameter {name!r} is in both {' and '.join(where)}; "
                                 "give each parameter in one of product, zip, set")
        for kind in ("product", "zip"):
            for key, values in getattr(self, kind).items():
                if not values:
                    raise ValueError(f"{kind}.{key} is an empty list")
        lengths = {len(v) for v in self.zip.values()}
        if len(lengths) > 1:
            raise ValueError(f"zip lists must have equal lengths, got {sorted(lengths)}")
        self._check_exclude()
        return self

    def _check_exclude(self) -> None:
        """Each exclusion names parameters of product or zip, with values they list: a typo
        (``nearclp``) would otherwise exclude nothing, silently."""
        given = {**{k: [v] for k, v in self.set.items()}, **self.product, **self.zip}
        for i, entry in enumerate(self.exclude):
            if not entry:
                raise ValueError(f"exclude.{i}: is empty; give the parameter values whose "
                                 "combinations to leave out, e.g. {cull: cull, method: nearclip}")
            for key, value in entry.items():
                if key not in self.product and key not in self.zip:
                    where = "is in set, so every combination has it" if key in self.set else \
                        "is not a parameter of this grid's product or zip"
                    raise ValueError(f"exclude.{i}.{key}: {where}; exclude leaves out "
                                     "combinations of product and zip values")
                if not any(_same(value, v) for v in given[key]):
                    raise ValueError(f"exclude.{i}.{key}: {value!r} is not among its values "
                                     f"({', '.join(map(repr, given[key]))})")

    def count(self) -> int:
        """How many combinations :meth:`combinations` gives before exclusions, at most, without
        making them (a product of long lists can stand for billions)."""
        rows = len(next(iter(self.zip.values()))) if self.zip else 1
        return math.prod(len(values) for values in self.product.values()) * rows

    def combinations(self) -> list[dict]:
        import itertools

        names = list(self.product)
        prods = [dict(zip(names, values))
                 for values in itertools.product(*(self.product[n] for n in names))]
        rows = ([dict(zip(self.zip, values)) for values in zip(*self.zip.values())]
                if self.zip else [{}])
        combos = [{**self.set, **p, **z} for p in prods for z in rows]
        return [c for c in combos if not any(
            all(k in c and _same(c[k], v) for k, v in entry.items()) for entry in self.exclude)]


def _same(a, b) -> bool:
    """Equal as YAML values: 4 and 4.0 alike, true and 1 not."""
    return a == b and isinstance(a, bool) == isinstance(b, bool)


class ReferenceSettings(Strict):
    samples: SquareInt = Field(16, le=1024)
    seed: int = Field(0, ge=0)


class SceneSettings(Strict):
    """What one scene runs differently from the rest of its experiment (``per_scene:``): its
    measured frames and warm-up, and grids that replace the experiment's for the techniques it
    names (the others keep theirs). For scenes whose frames cost seconds, such as the 10^5
    triangle families in ``make bench``: fewer frames, or a shorter curve, rather than no scene."""

    frames: int | None = Field(None, ge=1, le=1000)
    warmup: int | None = Field(None, ge=0, le=1000)
    techniques: dict[str, Union[Grid, list[Grid]]] = {}

    @field_validator("techniques")
    @classmethod
    def _grids(cls, v):
        for name, grids in v.items():
            if isinstance(grids, list) and not grids:
                raise ValueError(f"{name}: empty list of grids")
        return v


class Experiment(Strict):
    scene_file: str | None = None  # relative to the experiment file; default: --scene-file
    scenes: Union[Literal["all"], list[str]] = "all"
    # technique name -> grid(s); or "all": every registered technique at its defaults; or
    # "curves": every registered technique along its declared quality curve
    techniques: Union[Literal["all", "curves"], dict[str, Union[Grid, list[Grid]]]]
    resolutions: list[tuple[int, int]] | None = None  # default: each scene's own
    triangle_budget: int = Field(DEFAULT_TRIANGLE_BUDGET, ge=1, le=100_000_000)
    # sizes of the family scenes: each becomes the scenes name@size (e.g. architecture@1e5)
    triangles: list[TriangleCount] | None = None
    frames: int = Field(15, ge=1, le=1000)  # measured frames per run, after the warm-up
    warmup: int = Field(2, ge=0, le=1000)
    # the 95% interval of each median time: order statistics or bootstrap (harness.machine.timing)
    statistics: Literal[STATISTICS] = "order"
    # what a frame's time holds (harness.run.measure): dynamic, everything that depends on the
    # light and the geometry, every frame; static, that done once and timed as setup_ms
    cost: Literal["dynamic", "static"] = "dynamic"
    reference: ReferenceSettings = ReferenceSettings()
    # a typo in a grid (10,000 values for 10) is refused before hours of work, not run
    max_runs: int = Field(DEFAULT_MAX_RUNS, ge=1)
    # scene name (a declared name: every size of a family; or name@size) -> its own settings
    per_scene: dict[str, SceneSettings] = {}

    @field_validator("scenes")
    @classmethod
    def _some_scenes(cls, v):
        if not v:
            raise ValueError("must name at least one scene, or be 'all'")
        return v

    @field_validator("techniques")
    @classmethod
    def _some(cls, v):
        if v in ("all", "curves"):
            return v
        if not v:
            raise ValueError("must name at least one technique")
        for name, grids in v.items():
            if isinstance(grids, list) and not grids:
                raise ValueError(f"{name}: empty list of grids")
        return v

    @field_validator("max_runs")
    @classmethod
    def _hard_limit(cls, v):
        if v > MAX_RUNS:
            raise ValueError(f"must be at most {MAX_RUNS:,}, the hard limit (harness/config/"
                             f"limits.py); split the experiment instead, got {v:,}")
        return v

    @field_validator("triangles")
    @classmethod
    def _some_sizes(cls, v):
        if v is not None and not v:
            raise ValueError("must list at least one size, e.g. [1e3, 1e4]")
        return v

    @field_validator("resolutions")
    @classmethod
    def _res(cls, v):
        if v is not None and (not v or not all(16 <= x <= 8192 for r in v for x in r)):
            raise ValueError("must be a non-empty list of [width, height] in [16, 8192]")
        return v


def with_timing(exp: Experiment, **options) -> Experiment:
    """The experiment with command-line timing options (``frames``, ``warmup``,
    ``statistics``, ``cost``; None keeps the experiment's) validated as if the file had them; a bad
    value is a ConfigError naming the option, e.g. ``--frames: must be >= 1, got 0``."""
    given = {k: v for k, v in options.items() if v is not None}
    if not given:
        return exp
    data = {**exp.model_dump(), **given}
    # the command line's frames and warm-up are every scene's, per_scene ones included
    data["per_scene"] = {name: {k: v for k, v in settings.items() if k not in given}
                         for name, settings in data["per_scene"].items()}
    try:
        return Experiment.model_validate(data)
    except ValidationError as e:
        first = e.errors()[0]
        option = str(first["loc"][0])
        msg = first["msg"].removeprefix("Value error, ")
        got = "" if ", got " in msg else f", got {given.get(option)!r}"  # said once
        raise ConfigError(f"--{option.replace('_', '-')}: {msg}{got}") from None


def load_experiment(path: str | Path) -> tuple[Experiment, object]:
    """Validate an experiment file; returns the model and the YAML root node (for lines).

    A technique's grid may be empty or null (its defaults), one grid (or curve), or a list of
    them."""
    path = Path(path)
    data, node = read_yaml(path)
    if not isinstance(data, dict):
        raise ConfigError(f"{path}: an experiment is a mapping with at least a 'techniques' key "
                          f"(see experiments/default.yaml), got {type(data).__name__}")
    techniques = data.get("techniques")
    if isinstance(techniques, dict):
        # each grid on its own, so an error names techniques.<name>... rather than the union
        data = {**data, "techniques": {name: _grids(path, node, name, grids)
                                       for name, grids in techniques.items()}}
    per_scene = data.get("per_scene")
    if isinstance(per_scene, dict):
        data = {**data, "per_scene": {
            scene: ({**settings, "techniques": {
                name: _grids(path, node, name, grids, ("per_scene", scene))
                for name, grids in settings["techniques"].items()}}
                if isinstance(settings, dict) and isinstance(settings.get("techniques"), dict)
                else settings)
            for scene, settings in per_scene.items()}}
    try:
        experiment = Experiment.model_validate(data)
    except ValidationError as e:
        raise validation_error(path, e, node, model=Experiment) from None
    if isinstance(experiment.scenes, list):
        _no_repeats(path, node, experiment.scenes)
    return experiment, node


def _no_repeats(path: Path, node, scenes: list[str]) -> None:
    """A scene listed twice is a mistake (a name meant and another typed), not a request to
    run it twice: both positions are named."""
    first: dict[str, int] = {}
    for i, name in enumerate(scenes):
        if name in first:
            where = [f"{path}:{line_of(node, ('scenes', j))} (scenes.{j})"
                     for j in (first[name], i)]
            raise key_error(path, node, ("scenes", i),
                            f"scene {name!r} is listed twice, at {' and '.join(where)}")
        first[name] = i


def _grids(path: Path, node, name: str, grids, under: tuple = ()) -> Grid | list[Grid]:
    if grids is None:
        return Grid()
    items = grids if isinstance(grids, list) else [grids]
    checked = []
    for i, item in enumerate(items):
        prefix = under + ("techniques", name) + ((i,) if isinstance(grids, list) else ())
        try:
            checked.append(Grid.model_validate(item))
        except ValidationError as e:
            raise validation_error(path, e, node, prefix, model=Grid) from None
    return checked if isinstance(grids, list) else checked[0]
