"""Planning, the first step of a run: an experiment, a scene file and the command line become
validated runs (RunSpec) and the scenes they need (Plan), before anything is rendered."""

from __future__ import annotations

import hashlib
import json
import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

import yaml
from pydantic import ValidationError

from .. import config as cfg
from ..truth import metrics
from ..technique import registry
from .scene_set import SceneSet


@dataclass(frozen=True)
class RunSpec:
    """One run. Its stable id covers the scene description and resolution, technique,
    parameters, the technique's code version, frames, warm-up, interval statistics and
    reference settings and cost policy: runs whose id is already in ``DIR/results.csv`` are
    skipped, so a killed sweep restarted with the same arguments finishes the rest without
    duplicates."""

    scene: str
    technique: str
    params: dict  # validated, every parameter present
    width: int
    height: int
    frames: int
    warmup: int
    samples: int
    ref_seed: int = 0
    scene_key: str = ""
    code_version: str = ""
    statistics: str = "order"  # how the median's interval is computed (harness.machine.timing)
    cost: str = "dynamic"  # the cost policy (harness.run.measure)
    # a run of `shadowbench tune` (harness.run.tune): its role (defaults, search, best, ...) and
    # the view its settings were tuned on; empty for any other run
    tuning: str = ""
    tuned_on: str = ""

    @property
    def params_json(self) -> str:
        return json.dumps(self.params, sort_keys=True)

    @property
    def run_id(self) -> str:
        fields = (self.scene, self.scene_key, self.width, self.height, self.technique,
                  self.params_json, self.code_version, self.frames, self.warmup, self.statistics,
                  self.samples, self.ref_seed, metrics.VERSION, self.cost)
        # a tuning role enters the id (a best setting equal to the defaults is stored as both),
        # and only then: every other run keeps the id it had before tuning existed
        if self.tuning:
            fields += (self.tuning, self.tuned_on)
        text = "|".join(map(str, fields))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass
class Plan:
    """Validated runs and the scenes they need, ready to execute."""

    runs: list[RunSpec]
    scenes: Mapping  # name -> BuiltScene: a SceneSet, built as asked for
    experiment_hash: str
    experiment_path: str = ""
    notes: list[str] = field(default_factory=list)
    cost: str = "dynamic"  # the experiment's cost policy, every run's

    def described(self) -> list[tuple[str, cfg.Scene, Path | None]]:
        """Each scene's name, description and the file its paths are relative to, without
        building a scene."""
        if isinstance(self.scenes, SceneSet):
            return self.scenes.described()
        return [(name, scene.config, scene.source) for name, scene in self.scenes.items()]


def parse_overrides(values: list[str]) -> dict[str, dict]:
    """``["pcf.k=16", ...]`` -> ``{"pcf": {"k": 16}}`` (values parsed as YAML scalars)."""
    out: dict[str, dict] = {}
    for item in values:
        key, sep, raw = item.partition("=")
        technique, dot, param = key.partition(".")
        if not sep or not dot or not technique or not param:
            raise cfg.ConfigError(f"--set {item}: expected technique.param=value, e.g. pcf.k=16")
        try:
            value = yaml.safe_load(raw)
        except yaml.YAMLError as e:
            problem = " ".join(str(getattr(e, "problem", None) or e).split())
            raise cfg.ConfigError(f"--set {item}: the value is not valid YAML: {problem}") from None
        out.setdefault(technique, {})[param] = value
    return out


def validate_params(technique: str, values: dict, where: str) -> dict:
    """Validate against the technique's Params; errors name the technique and allowed names."""
    cls = registry.get(technique)
    for name, value in values.items():  # before the ranges: .inf is not "more than 64"
        if name in cls.Params.model_fields and isinstance(value, float) and not math.isfinite(value):
            raise cfg.ConfigError(f"{where}: {technique}.{name}: must be a finite number, "
                                  f"got {value!r}")
    try:
        params = cls.Params(**values)
    except ValidationError as e:
        first = e.errors()[0]
        name = ".".join(str(p) for p in first["loc"]) or "(parameters)"
        problem = first["msg"].removeprefix("Value error, ")
        key, sep, rest = problem.partition(": ")
        if not first["loc"] and sep and key in cls.Params.model_fields:  # a check naming its key
            name, problem = key, rest
        allowed = ", ".join(cls.Params.model_fields)
        if first["type"] == "extra_forbidden":
            msg = f"{technique} has no parameter {name!r}; allowed: {allowed}"
        else:
            msg = f"{technique}.{name}: {problem}"
            if not first["loc"] and where != "--set":  # a check of a combination of values
                msg += "; leave such combinations out of a grid with exclude:"
        raise cfg.ConfigError(f"{where}: {msg}") from None
    for name, value in params.model_dump().items():  # "1e999" and .inf validate as float inf
        if isinstance(value, float) and not math.isfinite(value):
            raise cfg.ConfigError(f"{where}: {technique}.{name}: must be a finite number, "
                                  f"got {values.get(name, value)!r}")
    return params.model_dump(mode="json")


def plan_runs(*, experiment_path: str | None, scene_file: str, scenes: list[str] | None,
              techniques: list[str] | None, overrides: dict[str, dict],
              timing: dict | None = None, default_grids=None) -> Plan:
    """Everything validated up front: a bad input raises ConfigError before any output.

    ``timing``: command-line ``frames``, ``warmup``, ``statistics``, ``max_runs``, ``cost``
    replacing the experiment's (see :func:`harness.config.with_timing`). ``default_grids(cls)``:
    without an experiment, each technique's grid (default: its defaults alone)."""
    if experiment_path:
        exp, node = cfg.load_experiment(experiment_path)  # before the scene file it may name
        exp_path = Path(experiment_path)
        if exp.scene_file:
            scene_file = str(exp_path.parent / exp.scene_file)
        exp_text = exp_path.read_text()
    registered = registry.techniques()
    registry.baseline()  # two declared baselines: one line naming both, before anything else
    broken = registry.broken()
    if not experiment_path:
        if not registered:
            raise cfg.ConfigError(
                f"no technique to run: all {len(broken)} registered are broken (shadowbench list "
                f"says why); the first: {next(iter(broken.values()))}" if broken else
                "no technique is registered: install the project (make setup)")
        exp = cfg.Experiment(techniques={name: default_grids(cls) if default_grids else cfg.Grid()
                                         for name, cls in registered.items()})
        node, exp_path, exp_text = None, Path("(command line)"), ""
    exp = cfg.with_timing(exp, **(timing or {}))
    # every scene validated as written; the meshes of the chosen ones only, once chosen
    declared = cfg.load_scenes(scene_file, triangle_budget=exp.triangle_budget, only=())
    all_scenes, stands_for = sized_scenes(declared, exp, exp_path, node)

    wanted = list(declared) if exp.scenes == "all" else list(exp.scenes)
    for i, name in enumerate(wanted):
        if name not in declared:
            raise cfg.key_error(exp_path, node, ("scenes", i),
                                f"no scene {name!r} in {scene_file}; it has "
                                f"{', '.join(declared)}")
    if exp.triangles and not any(declared[name].family for name in wanted):
        raise cfg.key_error(exp_path, node, ("triangles",),
                            "sizes family scenes, but none of the experiment's scenes has a family")
    wanted_scenes = [sized for name in wanted for sized in stands_for[name]]
    if scenes:
        for name in scenes:
            if name not in all_scenes and name not in stands_for:
                raise cfg.ConfigError(f"--scenes: no scene {name!r} in {scene_file}; it has "
                                      f"{', '.join(all_scenes)}")
        scenes = [sized for name in scenes for sized in stands_for.get(name, [name])]
        outside = [s for s in scenes if s not in wanted_scenes]
        if experiment_path and outside:
            raise cfg.ConfigError(f"--scenes: {', '.join(outside)} not in {exp_path} (its scenes: "
                                  f"{', '.join(wanted_scenes)})")
        wanted_scenes = list(dict.fromkeys(scenes))
    cfg.check_scenes(scene_file, declared, [name for name, sized in stands_for.items()
                                            if set(sized) & set(wanted_scenes)],
                     exp.triangle_budget)

    grids: dict[str, list[cfg.Grid]] = {}
    chosen = ({name: cfg.Grid() for name in registered} if exp.techniques == "all"
              else {name: cfg.Grid(curve=True) for name in registered}
              if exp.techniques == "curves" else exp.techniques)
    for name, g in chosen.items():
        if name in broken:
            raise cfg.key_error(exp_path, node, ("techniques", name), f"broken: {broken[name]}")
        if name not in registered:
            raise cfg.key_error(exp_path, node, ("techniques", name),
                                f"unknown technique; registered: {', '.join(registered)}")
        grids[name] = g if isinstance(g, list) else [g]
    if techniques:
        for name in techniques:
            if name in broken:
                raise cfg.ConfigError(f"--techniques: {name} is broken: {broken[name]}")
            if name not in registered:
                raise cfg.ConfigError(f"--techniques: unknown technique {name!r}; registered: "
                                      f"{', '.join(registered)}")
        grids = {name: grids.get(name, [cfg.Grid()]) for name in techniques}
    for name in grids:
        try:
            cfg.check_name("technique", name)
        except ValueError as e:  # a plugin's entry point: its name becomes file names
            raise cfg.ConfigError(f"entry point {registry.GROUP}: {e}") from None
    for name in overrides:
        if name not in grids:
            raise cfg.ConfigError(f"--set: technique {name!r} is not in this run "
                                  f"({', '.join(grids)})")
    settings = _per_scene(exp, all_scenes, stands_for, registered, exp_path, node)

    def scene_grids(scene_name: str) -> dict[str, list[tuple[cfg.Grid, tuple]]]:
        """The scene's grids with the key path of each: the experiment's, those of the
        techniques its per_scene entry names replaced (techniques not in this run stay out)."""
        own = settings.get(scene_name)
        out = {}
        for tech, tech_grids in grids.items():
            if own is not None and tech in own[0].techniques:
                g, loc = own[0].techniques[tech], own[1] + ("techniques", tech)
            else:
                g, loc = tech_grids, ("techniques", tech)
            items = g if isinstance(g, list) else [g]
            out[tech] = [(grid, loc + ((i,) if len(items) > 1 else ()))
                         for i, grid in enumerate(items)]
        return out

    # a grid's raw count first, in constant memory (a product of long lists can stand for
    # billions), then the points themselves, validated, with duplicates merged (a curve's knobs
    # share their base)
    resolutions = len(exp.resolutions or [None])
    raw, largest, largest_loc = 0, 0, ()
    for scene_name in wanted_scenes:
        for tech, tech_grids in scene_grids(scene_name).items():
            for grid, loc in tech_grids:
                count = resolutions * (len(grid_points(registered[tech], grid, loc, exp_path, node))
                                       if grid.curve is not None else grid.count())
                raw += count
                if count > largest:
                    largest, largest_loc = count, loc
    if raw > min(max(4 * exp.max_runs, 10_000), cfg.MAX_RUNS):  # the points are made next
        line = cfg.line_of(node, largest_loc) if node is not None else None
        worst = (f"; {'.'.join(map(str, largest_loc))}{f' (line {line})' if line else ''} gives "
                 f"{'all' if largest == raw else f'{largest:,}'} of them")
        raise cfg.ConfigError(f"{exp_path}: plans {raw:,} runs before duplicate points are merged, "
                              f"far more than the limit of {exp.max_runs:,} (max_runs){worst}; "
                              f"{_raise_it(raw)}")
    points: dict[tuple, str] = {}  # each point with the key that first asks for it
    for scene_name in wanted_scenes:
        for width, height in exp.resolutions or [all_scenes[scene_name].resolution]:
            for tech, tech_grids in scene_grids(scene_name).items():
                for grid, grid_loc in tech_grids:
                    for combo, loc in grid_points(registered[tech], grid, grid_loc, exp_path,
                                                  node):
                        line = cfg.line_of(node, loc) if node is not None else None
                        where = (f"{exp_path}{f':{line}' if line else ''}: "
                                 + ".".join(map(str, loc)))
                        where = where if experiment_path else "--set"
                        params = validate_params(tech, {**combo, **overrides.get(tech, {})},
                                                 where)
                        points.setdefault((scene_name, width, height, tech,
                                           json.dumps(params, sort_keys=True)), where)
    if len(points) > exp.max_runs:
        raise cfg.ConfigError(f"{exp_path}: plans {len(points):,} runs, more than the limit of "
                              f"{exp.max_runs:,} (max_runs); {_raise_it(len(points))}")
    if exp.cost == "static":
        _check_static(wanted_scenes, all_scenes, exp_path, node,
                      from_option=bool(timing and timing.get("cost")))
    built = SceneSet({name: all_scenes[name] for name in wanted_scenes}, Path(scene_file))
    versions = {tech: registered[tech].code_version() for tech in grids}
    runs: list[RunSpec] = []
    for (scene_name, width, height, tech, params_json), where in points.items():
        own = settings.get(scene_name, (cfg.SceneSettings(), ()))[0]
        scene_at = built[scene_name].with_resolution(width, height)
        cls = registered[tech]
        try:  # a setting that cannot run on the scene at all (Technique.check_scene)
            cls.check_scene(cls.Params(**json.loads(params_json)), scene_at)
        except ValueError as e:
            raise cfg.ConfigError(f"{where}: {tech}.{e} (scene {scene_name})") from None
        # a moving scene's run measures each frame of its sequence once
        frames = (scene_at.frames if scene_at.frames > 1
                  else exp.frames if own.frames is None else own.frames)
        runs.append(RunSpec(scene_name, tech, json.loads(params_json), width, height, frames,
                            exp.warmup if own.warmup is None else own.warmup,
                            exp.reference.samples, exp.reference.seed, scene_at.key,
                            versions[tech], exp.statistics, exp.cost))
    if not runs:
        raise cfg.ConfigError(f"{exp_path}: nothing to run (no scene x technique combination)")
    exp_hash = hashlib.sha256(
        (exp_text + json.dumps(sorted(r.run_id for r in runs))).encode()).hexdigest()[:16]
    return Plan(runs, built, exp_hash, str(exp_path), cost=exp.cost,
                notes=_notes(list(grids), broken if not techniques and (
                    not experiment_path or exp.techniques in ("all", "curves")) else {}))


def _raise_it(planned: int) -> str:
    """How to plan that many runs: raise max_runs, or split what is over its hard limit."""
    if planned <= cfg.MAX_RUNS:
        return ("raise it with max_runs: in the experiment or --max-runs on the command line "
                f"(at most {cfg.MAX_RUNS:,})")
    return f"that is over the hard limit of {cfg.MAX_RUNS:,} runs: split the experiment"


def _notes(included: list[str], broken: dict[str, str]) -> list[str]:
    """What a user should know of the plan's techniques: the installed plugins it includes (a
    sweep of every technique takes in every installed one), on one line, and the broken entry
    points it leaves out, each with the reason."""
    plugins = [f"{name} ({registry.distribution_of(name)})" for name in included
               if registry.is_plugin(name)]
    notes = [f"installed plugins in this plan: {', '.join(plugins)}"] if plugins else []
    return notes + [f"left out, broken: {name}: {why}" for name, why in broken.items()]


def _check_static(names: list[str], scenes: dict, exp_path: Path, node, from_option: bool):
    """``cost: static`` declares the light and the geometry fixed: a scene whose motion turns
    the light or moves objects is a ConfigError naming the policy's key (or ``--cost``)."""
    for name in names:
        motion = scenes[name].motion
        if motion is None:
            continue
        if motion.light_orbit:
            why = (f"static declares the light fixed, and scene {name!r} turns it "
                   f"(motion.light_orbit: {motion.light_orbit:g}); use cost: dynamic")
        elif motion.objects:
            why = (f"static declares the geometry fixed, and scene {name!r} moves "
                   f"{len(motion.objects)} object(s) (motion.objects); use cost: dynamic")
        else:
            continue
        if from_option or node is None:
            raise cfg.ConfigError(f"--cost: {why}")
        raise cfg.key_error(exp_path, node, ("cost",), why)


def _per_scene(exp: cfg.Experiment, all_scenes: dict, stands_for: dict[str, list[str]],
               registered: dict, path: Path, node) -> dict[str, tuple[cfg.SceneSettings, tuple]]:
    """Each (sized) scene name with its ``per_scene`` settings and their key path: an entry for
    a declared name serves all its sizes, one for ``name@size`` that size (in place of the
    declared name's, whole: the two are not merged). An entry naming no scene of the file, or
    an unknown technique, is a ConfigError naming the key."""
    out: dict[str, tuple[cfg.SceneSettings, tuple]] = {}
    for key, own in exp.per_scene.items():
        if key not in stands_for and key not in all_scenes:
            raise cfg.key_error(path, node, ("per_scene", key),
                                f"no scene {key!r} in the scene file; it has "
                                f"{', '.join(stands_for)}")
        for tech in own.techniques:
            if tech not in registered:
                raise cfg.key_error(path, node, ("per_scene", key, "techniques", tech),
                                    f"unknown technique; registered: {', '.join(registered)}")
    for key, own in exp.per_scene.items():  # declared names first, sized ones over them
        if key in stands_for:
            out.update({name: (own, ("per_scene", key)) for name in stands_for[key]})
    for key, own in exp.per_scene.items():
        if key not in stands_for:
            out[key] = (own, ("per_scene", key))
    return out


def size_label(triangles: int) -> str:
    """1e5 for 100000, 2.5e4 for 25000: the size in a swept scene's name."""
    mantissa, exponent = f"{triangles:e}".split("e")
    return f"{float(mantissa):g}e{int(exponent)}"


def sized_scenes(declared: dict[str, cfg.Scene], exp: cfg.Experiment, path: Path,
                 node) -> tuple[dict[str, cfg.Scene], dict[str, list[str]]]:
    """The scenes an experiment's ``triangles`` sizes make: each family scene becomes one scene
    per size, ``name@size``, whose family has that size (its own key, references and run ids);
    the others stay as they are. Also, each declared name with the names it stands for."""
    scenes, stands_for = {}, {}
    for name, scene in declared.items():
        if scene.family is None or not exp.triangles:
            scenes[name], stands_for[name] = scene, [name]
            continue
        stands_for[name] = []
        for i, triangles in enumerate(exp.triangles):
            if triangles > exp.triangle_budget:
                raise cfg.key_error(path, node, ("triangles", i),
                                    f"{triangles:,} triangles, more than the budget of "
                                    f"{exp.triangle_budget:,} (what fits 4 GiB for every "
                                    "technique; raise it with triangle_budget:)")
            try:
                sized = scene.at_triangles(triangles)
            except ValueError as e:
                raise cfg.key_error(path, node, ("triangles", i), f"scene {name}: {e}") from None
            stands_for[name].append(f"{name}@{size_label(triangles)}")
            scenes[stands_for[name][-1]] = sized
    return scenes, stands_for


def grid_points(cls, grid: cfg.Grid, loc: tuple, path: Path, node) -> list[tuple[dict, tuple]]:
    """A grid's parameter combinations, each with the key path that asks for it. A curve grid
    gives the technique's quality curve from ``grid.set`` (:func:`quality_settings`), each point
    named by its knob (``techniques.pcf.curve.k``); a technique that declares no knob runs at
    ``set`` alone."""
    from ..technique import quality_settings

    if grid.curve is None:
        return [(combo, loc) for combo in grid.combinations()]
    declared = cls.quality_knobs
    knobs = declared if grid.curve is True else grid.curve
    for knob in knobs:
        if knob not in declared:
            raise cfg.key_error(path, node, loc + ("curve", knob),
                                f"{cls.name} has no quality knob {knob!r}; its knobs: "
                                f"{', '.join(declared) or 'none'}")
    if not knobs:
        return [(dict(grid.set), loc + ("curve",))]
    return [(params, loc + ("curve", knob)) for knob, params in quality_settings(knobs, grid.set)]
