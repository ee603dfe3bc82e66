"""Expand sweeps into runs, run them, append one record per run. Resumable.

Each run has a stable id (scene description and resolution, technique, parameters, the
technique's code version, frames, warm-up, interval statistics and reference settings). Runs
whose id is already in ``DIR/results.csv`` are skipped, so a killed sweep restarted with the
same arguments finishes the rest without duplicates.
"""

from __future__ import annotations

import datetime as dt
import errno
import hashlib
import json
import math
import os
import platform
import subprocess
import sys
import time
import traceback
import warnings
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from pydantic import ValidationError

from . import config as cfg
from . import cost_model, metrics, registry, results
from .gl import measure as pass_measure
from .gl.measure import COUNTERS, default_timer
from .scene import BuiltScene, build_scene, load_scene
from .timing import CONFIDENCE, NOISY_CONTENTION, cpu_sample, median_interval, others_time


@dataclass(frozen=True)
class RunSpec:
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
    statistics: str = "order"  # how the median's interval is computed (harness.timing)

    @property
    def params_json(self) -> str:
        return json.dumps(self.params, sort_keys=True)

    @property
    def run_id(self) -> str:
        text = "|".join(map(str, (self.scene, self.scene_key, self.width, self.height,
                                  self.technique, self.params_json, self.code_version,
                                  self.frames, self.warmup, self.statistics, self.samples,
                                  self.ref_seed, metrics.VERSION)))
        return hashlib.sha256(text.encode()).hexdigest()[:16]


@dataclass
class Plan:
    """Validated runs and the scenes they need, ready to execute."""

    runs: list[RunSpec]
    scenes: dict[str, BuiltScene]
    experiment_hash: str
    experiment_path: str = ""
    notes: list[str] = field(default_factory=list)


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
    try:
        params = cls.Params(**values)
    except ValidationError as e:
        first = e.errors()[0]
        name = ".".join(str(p) for p in first["loc"]) or "(parameters)"
        allowed = ", ".join(cls.Params.model_fields)
        if first["type"] == "extra_forbidden":
            msg = f"{technique} has no parameter {name!r}; allowed: {allowed}"
        else:
            msg = f"{technique}.{name}: {first['msg'].removeprefix('Value error, ')}"
        raise cfg.ConfigError(f"{where}: {msg}") from None
    for name, value in params.model_dump().items():  # "1e999" and .inf validate as float inf
        if isinstance(value, float) and not math.isfinite(value):
            raise cfg.ConfigError(f"{where}: {technique}.{name}: must be a finite number, "
                                  f"got {values.get(name, value)!r}")
    return params.model_dump(mode="json")


def plan_runs(*, experiment_path: str | None, scene_file: str, scenes: list[str] | None,
              techniques: list[str] | None, overrides: dict[str, dict],
              timing: dict | None = None) -> Plan:
    """Everything validated up front: a bad input raises ConfigError before any output.

    ``timing``: command-line ``frames``, ``warmup``, ``statistics`` replacing the
    experiment's (see :func:`harness.config.with_timing`)."""
    if experiment_path:
        exp, node = cfg.load_experiment(experiment_path)  # before the scene file it may name
        exp_path = Path(experiment_path)
        if exp.scene_file:
            scene_file = str(exp_path.parent / exp.scene_file)
        exp_text = exp_path.read_text()
    registered = registry.techniques()
    if not experiment_path:
        exp = cfg.Experiment(techniques={name: cfg.Grid() for name in registered})
        node, exp_path, exp_text = None, Path("(command line)"), ""
    exp = cfg.with_timing(exp, **(timing or {}))
    all_scenes = cfg.load_scenes(scene_file, triangle_budget=exp.triangle_budget)

    wanted_scenes = list(all_scenes) if exp.scenes == "all" else list(exp.scenes)
    for i, name in enumerate(wanted_scenes):
        if name not in all_scenes:
            raise cfg.key_error(exp_path, node, ("scenes", i),
                                f"no scene {name!r} in {scene_file}; it has "
                                f"{', '.join(all_scenes)}")
    if scenes:
        for name in scenes:
            if name not in all_scenes:
                raise cfg.ConfigError(f"--scenes: no scene {name!r} in {scene_file}; it has "
                                      f"{', '.join(all_scenes)}")
        outside = [s for s in scenes if s not in wanted_scenes]
        if experiment_path and outside:
            raise cfg.ConfigError(f"--scenes: {', '.join(outside)} not in {exp_path} (its scenes: "
                                  f"{', '.join(wanted_scenes)})")
        wanted_scenes = list(dict.fromkeys(scenes))

    grids: dict[str, list[cfg.Grid]] = {}
    chosen = ({name: cfg.Grid() for name in registered} if exp.techniques == "all"
              else {name: cfg.Grid(curve=True) for name in registered}
              if exp.techniques == "curves" else exp.techniques)
    for name, g in chosen.items():
        if name not in registered:
            raise cfg.key_error(exp_path, node, ("techniques", name),
                                f"unknown technique; registered: {', '.join(registered)}")
        grids[name] = g if isinstance(g, list) else [g]
    if techniques:
        for name in techniques:
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

    built = {name: build_scene(name, all_scenes[name], Path(scene_file))
             for name in wanted_scenes}
    runs: list[RunSpec] = []
    seen: set[str] = set()
    for scene_name in wanted_scenes:
        base = built[scene_name]
        for width, height in exp.resolutions or [base.config.resolution]:
            scene_at = base.with_resolution(width, height)
            for tech, tech_grids in grids.items():
                version = registered[tech].code_version()
                for gi, grid in enumerate(tech_grids):
                    grid_loc = ("techniques", tech) + ((gi,) if len(tech_grids) > 1 else ())
                    for combo, loc in grid_points(registered[tech], grid, grid_loc, exp_path,
                                                  node):
                        line = cfg._line_of(node, loc) if node is not None else None
                        where = (f"{exp_path}{f':{line}' if line else ''}: "
                                 + ".".join(map(str, loc)))
                        params = validate_params(tech, {**combo, **overrides.get(tech, {})},
                                                 where if experiment_path else "--set")
                        # a moving scene's run measures each frame of its sequence once
                        frames = scene_at.frames if scene_at.frames > 1 else exp.frames
                        spec = RunSpec(scene_name, tech, params, width, height, frames,
                                       exp.warmup, exp.reference.samples, exp.reference.seed,
                                       scene_at.key, version, exp.statistics)
                        if spec.run_id not in seen:
                            seen.add(spec.run_id)
                            runs.append(spec)
    if not runs:
        raise cfg.ConfigError(f"{exp_path}: nothing to run (no scene x technique combination)")
    exp_hash = hashlib.sha256(
        (exp_text + json.dumps(sorted(r.run_id for r in runs))).encode()).hexdigest()[:16]
    return Plan(runs, built, exp_hash, str(exp_path))


def grid_points(cls, grid: cfg.Grid, loc: tuple, path: Path, node) -> list[tuple[dict, tuple]]:
    """A grid's parameter combinations, each with the key path that asks for it. A curve grid
    gives the technique's quality curve from ``grid.set`` (:func:`quality_settings`), each point
    named by its knob (``techniques.pcf.curve.k``); a technique that declares no knob runs at
    ``set`` alone."""
    from .technique import quality_settings

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


def _git_commit() -> str:
    try:
        here = Path(__file__).resolve().parent
        return subprocess.run(["git", "-C", str(here), "rev-parse", "HEAD"], capture_output=True,
                              text=True, timeout=10).stdout.strip()
    except (OSError, subprocess.SubprocessError):
        return ""


def _cpu() -> str:
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip() + f" ({os.cpu_count()} logical)"
    except OSError:
        pass
    return platform.processor() or platform.machine()


def _nvidia_gpus() -> list[dict]:
    """Name and driver of each NVIDIA GPU (empty without nvidia-smi)."""
    try:
        out = subprocess.run(["nvidia-smi", "--query-gpu=name,driver_version,memory.total",
                              "--format=csv,noheader"], capture_output=True, text=True,
                             timeout=20).stdout
    except (OSError, subprocess.SubprocessError):
        return []
    keys = ("name", "driver", "memory")
    return [dict(zip(keys, (f.strip() for f in line.split(",")))) for line in out.splitlines()
            if line.strip()]


def _version(module: str) -> str:
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version(module)
    except PackageNotFoundError:
        return ""


def _git_dirty() -> bool | None:
    try:
        here = Path(__file__).resolve().parent
        out = subprocess.run(["git", "-C", str(here), "status", "--porcelain",
                              "--untracked-files=no"], check=False, capture_output=True,
                             text=True, timeout=10)
        return bool(out.stdout.strip()) if out.returncode == 0 else None
    except (OSError, subprocess.SubprocessError):
        return None


MANIFEST_FILE = "manifest.json"


def read_manifest(out_dir: Path) -> dict:
    """DIR/manifest.json ({} when missing or empty); a ConfigError when it is not ours."""
    path = Path(out_dir) / MANIFEST_FILE
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        return {}
    except UnicodeDecodeError:
        raise _not_a_manifest(path) from None
    if not text.strip():
        return {}  # written, then lost in a crash before it reached the disk: rewritten now
    try:
        manifest = json.loads(text)
    except ValueError:
        raise _not_a_manifest(path) from None
    invocations = manifest.get("invocations", []) if isinstance(manifest, dict) else None
    if not isinstance(invocations, list) or not all(isinstance(i, dict) for i in invocations):
        raise _not_a_manifest(path)
    return manifest


def _not_a_manifest(path: Path) -> cfg.ConfigError:
    return cfg.ConfigError(f"{path}: not a shadowbench manifest; use another folder or move the "
                           "file away")


# Kept free while a sweep runs, so that its manifest can still say how it ended on a full disk.
SPACE_RESERVE = ".space-reserve"
SPACE_RESERVE_BYTES = 1 << 16


def write_manifest(out_dir: Path, plan: Plan, context, session: dict) -> None:
    """Record what produced DIR. ``started`` is the first invocation of this experiment into
    DIR, ``finished`` the end of the invocation that completed it (None until one does);
    ``invocations`` lists every start with how many runs it rendered and how it ended (one
    still ``running`` in the manifest when another starts was killed: ``interrupted``).
    When the disk is full, the space reserve is given up to write it."""
    previous = read_manifest(out_dir)
    same = previous.get("experiment_hash") == plan.experiment_hash
    earlier = [dict(i, status="interrupted") if i.get("status") == "running" else i
               for i in (previous.get("invocations", []) if same else [])
               if i.get("id") != session["id"]]
    invocations = earlier + [session]
    complete = session["status"] == "complete"
    counters_missing = pass_measure.pipeline_statistics_missing()
    manifest = {
        "shadowbench": _version("shadowbench"),
        "versions": {name: _version(dist) for name, dist in (
            ("pyrender", "scikit-robot-pyrender"), ("PyOpenGL", "PyOpenGL"),
            ("mitsuba", "mitsuba"), ("drjit", "drjit"), ("numpy", "numpy"),
            ("trimesh", "trimesh"))},
        "python": sys.version.split()[0],
        "gl": {"platform": context.platform, "vendor": context.vendor,
               "renderer": context.renderer, "version": context.version,
               "timer": default_timer(context.renderer),
               # the work counters (vertex_invocations, ...): empty columns where unavailable
               "pipeline_statistics": ({"available": False, "why": counters_missing}
                                       if counters_missing else {"available": True})},
        "timing": {"interval": f"{CONFIDENCE:.0%} interval of the median",
                   "noisy_contention": NOISY_CONTENTION, "batch_bytes": BATCH_BYTES,
                   "batch_runs": BATCH_RUNS},
        "gpu": _nvidia_gpus(),
        "cpu": _cpu(),
        "git_commit": _git_commit(),
        "git_dirty": _git_dirty(),
        "experiment": plan.experiment_path,
        "experiment_hash": plan.experiment_hash,
        "runs_planned": len(plan.runs),
        "scenes": {name: {"description": scene.config.description,
                          "effects": list(scene.config.effects)}
                   for name, scene in plan.scenes.items()},
        "started": invocations[0]["started"],
        "finished": (previous.get("finished") if same and previous.get("finished")
                     else session["finished"] if complete else None),
        "status": session["status"],
        "invocations": invocations,
    }
    text = json.dumps(manifest, indent=2).encode()
    try:
        results.replace_atomically(out_dir / MANIFEST_FILE, lambda f: f.write(text))
    except OSError as e:
        reserve = out_dir / SPACE_RESERVE
        if e.errno != errno.ENOSPC or not reserve.is_file():
            raise
        reserve.unlink()
        results.replace_atomically(out_dir / MANIFEST_FILE, lambda f: f.write(text))


def _now() -> str:
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")


def _one_line(e: BaseException) -> str:
    return f"{type(e).__name__}: {' '.join(str(e).split())}"[:500]


def _run_columns(spec: RunSpec) -> dict:
    return {"run_id": spec.run_id, "schema": results.SCHEMA_VERSION, "scene": spec.scene,
            "technique": spec.technique, "params": spec.params_json, "width": spec.width,
            "height": spec.height, "res": spec.params.get("res"), "frames": spec.frames,
            "code_version": spec.code_version, "ref_samples": spec.samples}


def failed_scene_row(spec: RunSpec, error: Exception) -> dict:
    """The row of a run whose scene could not be prepared (its reference or its frame failed):
    the scene's failure is its runs' error rows, not the end of the sweep."""
    return {**_run_columns(spec), "status": "error",
            "error": f"scene {spec.scene} {spec.width}x{spec.height}: {_one_line(error)}"}


# Runs of one scene and resolution are measured in interleaved rounds (each round renders one
# measured frame of every run of a batch), so a burst of load from other processes spreads
# over all of them instead of landing on one. A batch keeps its runs prepared at once, so it
# closes when its runs' maps (their mem_bytes, known after the first frame) reach
# BATCH_BYTES or it holds BATCH_RUNS runs: memory stays within about one batch (a 4096^2
# float map is 64 MiB) whatever the sweep.
BATCH_BYTES = 256 * 2**20
BATCH_RUNS = 16


@dataclass
class _Timed:
    """A run between prepare and release: its row so far, technique, pass record and the
    output of its last frame."""

    spec: RunSpec
    row: dict
    meter: object  # harness.gl.measure.PassMeter, the run's own
    technique: object = None
    output: object = None  # harness.technique.ShadowOutput
    measured: int = 0  # measured frames rendered so far
    sequence: "_Sequence | None" = None  # a moving scene's run: what it keeps across frames

    @property
    def alive(self) -> bool:
        return "status" not in self.row


def _render(timed: _Timed, frame, measuring: bool, update: bool = False) -> None:
    """One frame of the run; ``update``: the technique's update first, in the same frame (a
    moving scene's frame: its timed part counts in the frame's time)."""
    from .technique import reset_gl_state

    try:
        with frame.metered(timed.meter):
            timed.meter.new_frame(measuring)
            if update:
                timed.technique.update(frame)
            timed.output = timed.technique.render(frame)
        timed.measured += measuring
    finally:
        reset_gl_state()  # each run's frame starts from the state the harness assumes


def _release(timed: _Timed) -> None:
    from .technique import reset_gl_state

    if timed.technique is not None:
        try:
            timed.technique.release()
        except Exception as e:  # the run's result stands; a failed release only leaks
            timed.row["warnings"] = f"release failed: {_one_line(e)}"
        timed.technique = None
    timed.meter.release()
    reset_gl_state()


def _attempt(timed: _Timed, step, *args) -> bool:
    """``step(*args)``; a technique's failure ends its run (status and error in its row,
    resources released), never the sweep."""
    from .technique import NotApplicable

    try:
        step(*args)
        return True
    except NotApplicable as e:
        timed.row.update(status="skipped", error=str(e))
    except Exception as e:  # a technique's failure is its row's, not the sweep's
        timed.row.update(status="error", error=_one_line(e))
        if os.environ.get("SHADOWBENCH_DEBUG"):
            traceback.print_exc()
    _release(timed)
    return False


def _start(spec: RunSpec, frame, row: dict) -> _Timed:
    """Prepare the run, update it to the frame and render its warm-up frames (with no
    warm-up, its first measured frame; on a moving scene, one unmeasured frame): its map
    bytes are then known."""
    cls = registry.get(spec.technique)
    timed = _Timed(spec, row, frame.new_meter())
    moving = frame.frames > 1
    warmup = max(spec.warmup, 1) if moving else spec.warmup

    def prepare():
        cls.check_light(frame.scene.light)
        timed.technique = cls(cls.Params(**spec.params))
        timed.technique.prepare(frame)
        with frame.metered(timed.meter):  # not a measured frame: untimed
            timed.technique.update(frame)
        for _ in range(warmup):
            _render(timed, frame, measuring=False)

    if _attempt(timed, prepare) and warmup == 0:
        _measure_round([timed], frame, 0)
    return timed


def _measure_round(batch: list[_Timed], frame, turn: int, update: bool = False) -> None:
    """One measured frame of each run (``update``: each technique's update first), starting
    at a position that turns each round (no run always follows the same one). The CPU time
    other processes used during the round is attributed to each run in proportion to its
    share of the round's wall time."""
    order = batch[turn % len(batch):] + batch[:turn % len(batch)]
    walls = []
    before, began = cpu_sample(), time.perf_counter()
    for timed in order:
        start = time.perf_counter()
        if _attempt(timed, _render, timed, frame, True, update):
            walls.append((timed, time.perf_counter() - start))
    round_s, after = time.perf_counter() - began, cpu_sample()
    if before is None or after is None or round_s <= 0:
        return
    others_s, capacity_s = others_time(before, after)
    for timed, wall in walls:
        timed.meter.add_load(others_s * wall / round_s, capacity_s * wall / round_s)


def _batches(specs: list[RunSpec], start):
    """The runs started (``start(spec)``: prepared and warmed up) in batches that close at
    BATCH_RUNS runs or BATCH_BYTES of maps; yields (the runs that could not start, the
    batch)."""
    queue = list(specs)
    while queue:
        failed, batch, batch_bytes = [], [], 0
        while queue and len(batch) < BATCH_RUNS and batch_bytes < BATCH_BYTES:
            timed = start(queue.pop(0))
            if not timed.alive:
                failed.append(timed)
                continue
            batch.append(timed)
            batch_bytes += timed.output.mem_bytes
        yield failed, batch


def run_group(specs: list[RunSpec], frame, reference, scene_ms: float, frags_scene: int,
              renderer: str):
    """Run ``specs`` (one scene and resolution, ``frame`` prepared for it) in batches of
    interleaved rounds; yields ``(spec, row, arrays)`` as each run finishes (arrays None
    unless it ran). Never raises for a technique's failure: that is the row's status.

    On a moving scene (``frame.frames`` > 1, ``reference`` its frame 0's) each round is a
    frame of the sequence: :func:`_run_sequence`."""
    def start(spec):
        return _start(spec, frame, _first_columns(spec, reference, scene_ms, frags_scene,
                                                  renderer))

    if frame.frames > 1:
        yield from _run_sequence(_batches(specs, start), frame)
        return
    for failed, batch in _batches(specs, start):
        for timed in failed:
            yield timed.spec, timed.row, None
        turn = 0
        while live := [t for t in batch if t.alive and t.measured < t.spec.frames]:
            _measure_round(live, frame, turn)
            turn += 1
        for timed in batch:
            if not timed.alive:
                yield timed.spec, timed.row, None
                continue
            _release(timed)
            yield (timed.spec, *_score(timed, frame, reference))


def run_one(spec: RunSpec, frame, reference, scene_ms: float, frags_scene: int,
            renderer: str) -> tuple[dict, dict[str, np.ndarray] | None]:
    """Run one technique alone on a prepared frame: its row and the arrays to store with it
    (V, coverage and the technique's diagnostic maps as ``map_<name>``; None unless it ran).

    Never raises for a technique's failure: that is the row's status and error."""
    ((_, row, arrays),) = run_group([spec], frame, reference, scene_ms, frags_scene, renderer)
    return row, arrays


def _first_columns(spec: RunSpec, reference, scene_ms: float, frags_scene: int,
                   renderer: str) -> dict:
    return {**_run_columns(spec), "scene_ms": scene_ms, "frags_scene": frags_scene,
            "renderer": renderer, "ref_seconds": reference.seconds}


def _timing_columns(timed: _Timed) -> dict:
    """Median frame time with its interval, per-pass times and work counters, machine load."""
    meter, method = timed.meter, timed.spec.statistics
    totals = meter.frame_totals_ms
    time_ms, low, high = median_interval(totals, method=method)
    passes = meter.passes(method)
    load = meter.cpu_contention
    return dict(
        time_ms=time_ms, time_ms_ci_low=low, time_ms_ci_high=high, time_ms_min=min(totals),
        time_ms_max=max(totals), frame_ms=[round(t, 4) for t in totals],
        cpu_contention=None if load is None else round(load, 4),
        noisy=None if load is None else int(load > NOISY_CONTENTION),
        **{c: sum(getattr(p, c) for p in passes) if meter.counts else None for c in COUNTERS},
        passes=[{"name": p.name, "ms": round(p.ms, 4), "ms_ci_low": round(p.ms_ci_low, 4),
                 "ms_ci_high": round(p.ms_ci_high, 4), "fragments": p.fragments,
                 **({c: getattr(p, c) for c in COUNTERS} if meter.counts else {})}
                for p in passes])


def _cost_columns(timed: _Timed, frame) -> dict:
    """Timing, counters, fill, memory and the range of V, from the run's last frame."""
    row, output = timed.row, timed.output
    v = output.visibility
    columns = _timing_columns(timed)
    frags_shadow = (output.shadow_fragments if output.shadow_fragments is not None
                    else sum(p["fragments"] for p in columns["passes"]))
    columns.update(
        frags_shadow=frags_shadow, overdraw=frags_shadow / max(row["frags_scene"], 1),
        mem_bytes=output.mem_bytes, fetches_per_px=output.fetches_per_px,
        covered_px=int(frame.arrays.covered.sum()),
        nonfinite=output.nonfinite + metrics.nonfinite(v),
        v_min=float(np.nanmin(v)) if v.size else None,
        v_max=float(np.nanmax(v)) if v.size else None,
        warnings="; ".join(output.warnings + ([row["warnings"]] if "warnings" in row else [])),
    )
    columns["gpu_estimate_ms"] = cost_model.estimate_ms({**row, **columns})
    return columns


def _clean(v: np.ndarray) -> np.ndarray:
    """V as the metrics see it: NaN half lit, infinities clipped."""
    return np.nan_to_num(v, nan=0.5, posinf=1.0, neginf=0.0)


@dataclass
class _Truth:
    """A frame's reference as the metrics see it, shared by the runs scored against it: the
    compared pixels, V_ref in float64 and its edge band."""

    index: int  # the frame of the sequence (0 for a still scene)
    reference: object  # harness.reference.Reference
    mask: np.ndarray  # Frame.compared_pixels

    def __post_init__(self):
        self.visibility = self.reference.visibility.astype(np.float64)
        self.band = metrics.edge_band(self.visibility, mask=self.mask)
        self.edge_floor = metrics.edge_floor(self.visibility, mask=self.mask, band=self.band)


def _metric_columns(v_clean: np.ndarray, frame, truth: _Truth) -> tuple[dict, dict]:
    """The error metrics of one frame's V against its reference on the compared pixels, and
    the shaded images where the scene asks for shading."""
    v, ref_v, mask, band = v_clean.astype(np.float64), truth.visibility, truth.mask, truth.band
    columns = dict(
        mae=metrics.mae(v, ref_v, mask=mask),
        rmse=metrics.rmse(v, ref_v, mask=mask),
        wrong_pct=metrics.wrong_pct(v, ref_v, mask=mask),
        edge_mae=metrics.edge_mae(v, ref_v, mask=mask, band=band),
        levels=metrics.levels(v, ref_v, mask=mask, band=band),
        ssim=metrics.ssim(v, ref_v, mask=mask),
        psnr=metrics.psnr(v, ref_v, mask=mask),
        acne_pct=metrics.acne_pct(v, ref_v, mask=mask, band=band),
        leak_pct=metrics.leak_pct(v, ref_v, mask=mask, band=band),
        edge_floor=truth.edge_floor,
    )
    # edge_mae as a multiple of the best a 0/1 answer can do; empty where that best is 0
    floor = truth.edge_floor
    columns["edge_ratio"] = columns["edge_mae"] / floor if floor > 0 else None
    reference, images = truth.reference, {}
    if reference.direct is not None:
        a = frame.arrays
        ambient = frame.scene.config.ambient
        shaded = metrics.shade(v_clean, a.normal, a.position, a.albedo, frame.scene.light,
                               ambient=ambient)
        shaded_ref = reference.direct + (ambient * a.albedo)[..., None]
        columns["flip"] = metrics.flip(shaded, shaded_ref)
        # grey images (one channel) for the report's viewer; float16 is plenty to look at
        images["shaded"] = shaded[..., 0].astype(np.float16)
        images["shaded_reference"] = shaded_ref.mean(-1).astype(np.float16)
    return columns, images


def _frame_arrays(output, frame, truth: _Truth, images: dict) -> dict[str, np.ndarray]:
    """V, coverage, the compared pixels, the shaded images and the technique's diagnostic maps
    of one frame, as a run stores them."""
    return {"visibility": output.visibility.astype(np.float32), "covered": frame.arrays.covered,
            "compared": truth.mask, **images,
            **{f"map_{name}": np.asarray(m, np.float32) for name, m in output.maps.items()}}


def _score(timed: _Timed, frame, reference) -> tuple[dict, dict[str, np.ndarray]]:
    """The finished run's row (timing, counters, metrics) and arrays, from its last frame."""
    row, output = timed.row, timed.output
    row.update(_cost_columns(timed, frame))
    truth = _Truth(0, reference, frame.compared_pixels(reference.covered))
    columns, images = _metric_columns(_clean(output.visibility), frame, truth)
    row.update(columns)
    row.update(output.extra)
    row["status"] = "ok"
    return row, _frame_arrays(output, frame, truth, images)


# --- moving scenes ----------------------------------------------------------------------------

# A moving run stores, besides frame 0's arrays and its per-frame series, its worst frame's
# V, reference and error and a strip of STRIP_RADIUS frames either side of it.
STRIP_RADIUS = 2
# The worst frame of a sequence's metrics: the largest of each; of ssim and psnr the smallest;
# none of levels (not an error) and edge_floor (the reference's, not the technique's).
WORST_IS_LOWEST = ("ssim", "psnr")
NO_WORST = ("levels", "edge_floor")


@dataclass
class _Sequence:
    """What a run on a moving scene keeps across frames: per-frame values, its previous V
    (for flicker), frame 0's arrays, the worst frame so far and the strip around it. Memory
    stays a few images per run however long the sequence."""

    series: dict[str, list] = field(default_factory=dict)
    extras: dict[str, list] = field(default_factory=dict)  # the technique's columns per frame
    previous: np.ndarray | None = None
    first: dict | None = None  # frame 0's arrays
    # (t, V, V_ref, coverage) of the last STRIP_RADIUS frames
    recent: list = field(default_factory=list)
    worst_key: tuple = (-math.inf, -math.inf)
    worst: dict | None = None
    strip: list = field(default_factory=list)  # (t, V, V_ref, coverage) around the worst frame
    strip_wanted: int = 0  # frames after the worst still to join the strip
    nonfinite: int = 0
    v_range: tuple = (math.inf, -math.inf)

    def add(self, name: str, value) -> None:
        self.series.setdefault(name, []).append(value)


def _observe(timed: _Timed, frame, truth: _Truth, previous: _Truth | None) -> None:
    """Score frame ``truth.index`` of a run on a moving scene into its :class:`_Sequence`."""
    sequence = timed.sequence = timed.sequence or _Sequence()
    output, t, covered = timed.output, truth.index, frame.arrays.covered
    v = _clean(output.visibility)
    ref_v = truth.reference.visibility
    columns, images = _metric_columns(v, frame, truth)
    for name, value in columns.items():
        sequence.add(name, value)
    flicker = (math.nan if previous is None else
               metrics.flicker(v, sequence.previous, ref_v, previous.reference.visibility,
                               mask=truth.mask, mask_previous=previous.mask))
    sequence.add("flicker", flicker)
    for name, value in output.extra.items():
        sequence.extras.setdefault(name, []).append(value)
    sequence.nonfinite += output.nonfinite + metrics.nonfinite(output.visibility)
    if output.visibility.size:
        low, high = sequence.v_range
        sequence.v_range = (min(low, float(np.nanmin(output.visibility))),
                            max(high, float(np.nanmax(output.visibility))))
    if t == 0:
        sequence.first = _frame_arrays(output, frame, truth, images)
    # the worst frame: the largest flicker (a pop), the largest mae among equals
    key = (0.0 if math.isnan(flicker) else flicker,
           -math.inf if math.isnan(columns["mae"]) else columns["mae"])
    if key > sequence.worst_key:
        sequence.worst_key = key
        error = np.where(truth.mask, np.abs(v - ref_v), np.nan).astype(np.float32)
        sequence.worst = dict(worst_frame=np.int64(t), worst_visibility=v.astype(np.float32),
                              worst_reference=ref_v, worst_error=error, worst_covered=covered)
        sequence.strip = sequence.recent + [(t, v, ref_v, covered)]
        sequence.strip_wanted = STRIP_RADIUS
    elif sequence.strip_wanted:
        sequence.strip.append((t, v, ref_v, covered))
        sequence.strip_wanted -= 1
    sequence.recent = (sequence.recent + [(t, v, ref_v, covered)])[-STRIP_RADIUS:]
    sequence.previous = v


def _sequence_score(timed: _Timed, frame) -> tuple[dict, dict[str, np.ndarray]]:
    """A moving run's row and arrays: metrics as the mean over frames and their worst frame,
    flicker, pop frames; costs from the last frame, timing over the sequence's frames."""
    row, sequence = timed.row, timed.sequence
    row.update(_cost_columns(timed, frame))
    series = {name: np.asarray(values, np.float64) for name, values in sequence.series.items()}
    flicker = series.pop("flicker")
    with warnings.catch_warnings():  # a metric NaN in every frame stays NaN
        warnings.simplefilter("ignore", RuntimeWarning)
        for name, values in series.items():
            row[name] = float(np.nanmean(values))
            if name in WORST_IS_LOWEST:
                row[f"{name}_min"] = float(np.nanmin(values))
            elif name not in NO_WORST:
                row[f"{name}_max"] = float(np.nanmax(values))
        row.update(flicker=float(np.nanmean(flicker[1:])),
                   flicker_max=float(np.nanmax(flicker[1:])))
    row.update(pop_frames=metrics.pop_frames(flicker[1:]),
               worst_frame=int(sequence.worst["worst_frame"]), nonfinite=sequence.nonfinite,
               v_min=sequence.v_range[0], v_max=sequence.v_range[1])
    for name, values in sequence.extras.items():  # the technique's columns
        if all(isinstance(x, (int, float, np.number)) for x in values):  # bools count too
            series[f"extra_{name}"] = np.asarray(values, np.float64)
            row[name] = float(np.mean(series[f"extra_{name}"]))
        else:
            row[name] = values[-1]
    row["status"] = "ok"
    strip_frames, strip_v, strip_ref, strip_covered = zip(*sequence.strip)
    arrays = {**sequence.first, **sequence.worst,
              **{f"series_{name}": values for name, values in series.items()},
              "series_flicker": flicker,
              "series_frame_ms": np.asarray(timed.meter.frame_totals_ms, np.float64),
              "strip_frames": np.asarray(strip_frames, np.int64),
              "strip_visibility": np.stack(strip_v).astype(np.float32),
              "strip_reference": np.stack(strip_ref).astype(np.float32),
              "strip_covered": np.stack(strip_covered)}
    return row, arrays


def _run_sequence(batches, frame):
    """Runs on a moving scene (``frame`` at its frame 0), batch by batch: each batch goes
    through the sequence, one interleaved round per frame (each technique's update, then its
    render, measured), and each run's frame is scored as it is rendered against that frame's
    reference (from the cache, or traced); yields ``(spec, row, arrays)`` per run."""
    from .reference import compute_reference

    for failed, batch in batches:
        for timed in failed:
            yield timed.spec, timed.row, None
        previous, traced_s = None, 0.0
        for t in range(frame.frames):
            if not any(timed.alive for timed in batch):
                break
            spec = batch[0].spec
            try:
                frame.move_to(t)
                reference = compute_reference(frame.scene, samples=spec.samples,
                                              seed=spec.ref_seed)
            except Exception as e:  # Mitsuba or GL cannot take this frame: the runs fail
                for timed in batch:
                    if timed.alive:
                        timed.row.update(status="error", error=f"scene {spec.scene} frame {t}: "
                                                               f"{_one_line(e)}")
                        _release(timed)
                break
            traced_s += reference.seconds
            truth = _Truth(t, reference, frame.compared_pixels(reference.covered))
            live = [timed for timed in batch if timed.alive]
            _measure_round(live, frame, t, update=True)
            for timed in live:
                if timed.alive:
                    _attempt(timed, _observe, timed, frame, truth, previous)
            previous = truth
        for timed in batch:
            if not timed.alive:
                yield timed.spec, timed.row, None
                continue
            _release(timed)
            timed.row["ref_seconds"] = traced_s
            yield (timed.spec, *_sequence_score(timed, frame))
        frame.move_to(0)  # the next batch warms up at frame 0


def reference_array_path(scene: str, width: int, height: int, samples: int, seed: int) -> Path:
    """Where a run directory keeps a scene's reference: one file per sampling, so a rerun with
    other reference settings never scores against, or shows, a stale one."""
    return Path("arrays") / scene / f"{width}x{height}" / f"reference-{samples}spp-seed{seed}.npz"


@contextmanager
def _exclusive(out_dir: Path):
    """Hold DIR's lock: two sweeps appending to one results.csv would lose each other's rows.
    The kernel drops the lock when the holder dies, so a killed run never leaves DIR locked."""
    import fcntl

    with (out_dir / ".lock").open("a+") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise cfg.ConfigError(f"{out_dir}: another shadowbench run is writing here; wait "
                                  "for it or choose another --out") from None
        yield


PROGRESS_FORMAT = "{desc} | {n_fmt}/{total_fmt} runs done{postfix} | {elapsed} elapsed"


def _cost(spec: RunSpec) -> float:
    """Relative time of a run for the estimate of the time left: runs at 1024x1024 take many
    times those at 256x256, so a plain runs-per-second rate misjudges a multi-resolution sweep.
    The constant is the per-run overhead, about that of a 256x256 run."""
    return spec.width * spec.height + 256 * 256


def _time_left(elapsed_s: float, done: float, left: float) -> str:
    seconds = round(elapsed_s / done * left)
    return f"about {seconds // 60}:{seconds % 60:02d} left"


def noisy_runs(plan: Plan, out_dir: str | Path) -> list[RunSpec]:
    """The plan's runs recorded ok in DIR but timed while the machine was busy (``noisy``)."""
    noisy = {r["run_id"] for r in results.read_rows(out_dir)
             if r["status"] == "ok" and r.get("noisy") == "1"}
    return [spec for spec in plan.runs if spec.run_id in noisy]


def execute(plan: Plan, out_dir: str | Path, *, platform_name: str | None = None,
            progress: bool = True, renderer=None, retime_noisy: bool = False) -> int:
    """Run every pending run of the plan; returns the exit code (0 ok, 1 some failed).

    ``retime_noisy``: then measure again the runs whose row says ``noisy`` (rendered anew, in
    interleaved rounds among themselves; their rows are replaced: the technique's output is
    deterministic, so only the timing and load columns change).

    ``renderer(plan, pending, out_dir, context, bar)`` renders and records the pending runs,
    yielding ``(spec, row)`` as each is recorded: :func:`render_serial` (the default) in this
    process, or ``harness.distributed.dask_renderer(...)`` on a Dask cluster.

    Each finished run's row is appended by replacing results.csv whole, so SIGKILL or Ctrl-C
    at any moment leaves every finished run recorded once and no partial row; the next call
    with the same plan skips them. Arrays are written before their row: a kill between the two
    leaves an unreferenced array that the rerun overwrites. The next call also heals what a
    kill leaves: it removes temporary files, marks the killed invocation ``interrupted``, and
    renders again the runs whose stored arrays are missing or damaged."""
    from tqdm import tqdm

    from .interrupt import raise_if_interrupted

    renderer = renderer or render_serial
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with _exclusive(out_dir):
        read_manifest(out_dir)  # foreign files stop the run before anything changes
        results.read_rows(out_dir)
        results.remove_temporaries(out_dir, (results.RESULTS_FILE, MANIFEST_FILE, SPACE_RESERVE))
        results.mark_damaged_runs(out_dir)
        done = results.done_ids(out_dir)
        pending = [r for r in plan.runs if r.run_id not in done]  # failed ones are retried
        failed = 0
        from .gl.context import get_context

        context = get_context(platform_name)
        # the id tells this invocation's entry from others started in the same second
        session = {"id": os.urandom(4).hex(), "started": _now(), "finished": None,
                   "status": "running", "runs_pending": len(pending), "runs_rendered": 0}
        results.replace_atomically(out_dir / SPACE_RESERVE,
                                   lambda f: f.write(bytes(SPACE_RESERVE_BYTES)))
        write_manifest(out_dir, plan, context, session)
        bar = tqdm(total=len(plan.runs), initial=len(plan.runs) - len(pending), unit="run",
                   disable=not progress, file=sys.stderr, dynamic_ncols=True,
                   bar_format=PROGRESS_FORMAT, postfix=f"{len(pending)} to go",
                   desc="" if pending else "nothing to render")
        cost_left, cost_done, clock = sum(map(_cost, pending)), 0.0, time.monotonic()
        try:
            for spec, row in renderer(plan, pending, out_dir, context, bar):
                raise_if_interrupted()
                session["runs_rendered"] += 1
                failed += row["status"] == "error"
                cost_done += _cost(spec)
                cost_left -= _cost(spec)
                left = bar.total - bar.n - 1
                bar.set_postfix_str(
                    f"{left} to go" + (f", {failed} failed" if failed else "")
                    + (f", {_time_left(time.monotonic() - clock, cost_done, cost_left)}"
                       if left else ""), refresh=False)
                bar.update(1)
            if retime_noisy:
                again = noisy_runs(plan, out_dir)
                session["runs_retimed"] = len(again)
                bar.reset(total=len(again))
                bar.set_postfix_str("retiming the noisy runs", refresh=False)
                for _, row in renderer(plan, again, out_dir, context, bar):
                    failed += row["status"] == "error"
                    bar.update(1)
            session["status"] = "complete"
        except KeyboardInterrupt:
            session["status"] = "interrupted"
            raise
        except BaseException:
            session["status"] = "failed"
            raise
        finally:
            bar.close()
            session["finished"] = _now()
            write_manifest(out_dir, plan, context, session)
            (out_dir / SPACE_RESERVE).unlink(missing_ok=True)
    return 1 if failed else 0


def record_run(out_dir: Path, spec: RunSpec, row: dict, arrays: dict[str, np.ndarray] | None,
               reference) -> None:
    """Store one finished run: the scene's reference arrays (once), its arrays, then the row.

    Arrays are written before their row: a kill between the two leaves an unreferenced array
    that the rerun overwrites. Every executor records through here, the client alone. A run
    whose scene failed has no reference (None) and no arrays."""
    if reference is not None:
        ref_name = reference_array_path(spec.scene, spec.width, spec.height, spec.samples,
                                        spec.ref_seed)
        ref_path = results.inside(out_dir, ref_name)
        row["reference_array"] = str(ref_name)
        if not results.readable_npz(ref_path):
            results.save_arrays(ref_path, visibility=reference.visibility,
                                covered=reference.covered,
                                **({"direct": reference.direct} if reference.direct is not None
                                   else {}))
    if arrays is not None:
        array = ref_name.with_name(f"{spec.technique}-{spec.run_id}.npz")
        results.save_arrays(results.inside(out_dir, array), **arrays)
        row["array"] = str(array)
    row["finished_at"] = _now()
    results.record_row(out_dir, row)


def render_serial(plan: Plan, pending: list[RunSpec], out_dir: Path, context, bar):
    """Render the pending runs, one scene and resolution at a time (its reference and G-buffer
    shared, its runs measured in interleaved rounds: :func:`run_group`), appending each row
    as it finishes; yields (spec, row) for each. A scene whose reference or frame fails gives
    its runs error rows, and the sweep goes on."""
    from .reference import compute_reference
    from .technique import Frame

    groups: dict[tuple, list[RunSpec]] = {}
    for spec in pending:
        groups.setdefault((spec.scene, spec.width, spec.height, spec.samples, spec.ref_seed),
                          []).append(spec)
    for (scene_name, width, height, samples, ref_seed), specs in groups.items():
        scene = plan.scenes[scene_name].with_resolution(width, height)
        bar.set_description_str(f"{scene_name} {width}x{height}: reference")
        frame = None
        try:
            reference = compute_reference(scene.at_frame(0), samples=samples, seed=ref_seed)
            frame = Frame(scene)
            frames, warmup = specs[0].frames, specs[0].warmup
            scene_ms, frags_scene = frame.measure_scene_pass(frames, warmup)
        except Exception as e:  # Mitsuba or GL cannot take this scene: its runs fail
            if frame is not None:
                frame.release()
            for spec in specs:
                row = failed_scene_row(spec, e)
                record_run(out_dir, spec, row, None, None)
                yield spec, row
            continue
        try:
            bar.set_description_str(f"{scene_name} {width}x{height}: {len(specs)} runs in rounds")
            for spec, row, arrays in run_group(specs, frame, reference, scene_ms, frags_scene,
                                               context.renderer):
                bar.set_description_str(f"{scene_name} {width}x{height}: {spec.technique}")
                record_run(out_dir, spec, row, arrays, reference)
                yield spec, row
        finally:
            frame.release()


@dataclass
class Evaluation:
    row: dict
    visibility: np.ndarray | None
    reference: object  # harness.reference.Reference
    frame_arrays: object  # harness.gbuffer.GBufferArrays
    mask: np.ndarray  # the pixels every metric compares (Frame.compared_pixels)
    arrays: dict | None = None  # what the run stores (a moving scene's series among them)


def evaluate(scene: BuiltScene | str, technique: str, params: dict | None = None, *,
             scene_file: str | Path = "scenes.yaml", resolution: tuple[int, int] | None = None,
             frames: int = 1, warmup: int = 0, samples: int = 16) -> Evaluation:
    """Run one technique on one scene in this process and score it (for tests, notebooks).

    ``scene`` is a built scene or the name of one in ``scene_file``; ``resolution`` (width,
    height) replaces the scene's own. The reference comes from the on-disk cache when present.
    A moving scene runs its whole sequence (``frames`` is then its length); ``visibility``,
    ``reference``, ``frame_arrays`` and ``mask`` are frame 0's.
    """
    from .gl.context import get_context
    from .reference import compute_reference
    from .technique import Frame

    if isinstance(scene, str):
        scene = load_scene(scene, scene_file)
    if resolution is not None:
        scene = scene.with_resolution(*resolution)
    context = get_context()
    cls = registry.get(technique)
    checked = validate_params(technique, params or {}, "evaluate()")
    spec = RunSpec(scene.name, technique, checked, scene.width, scene.height,
                   scene.frames if scene.frames > 1 else frames, warmup, samples, 0, scene.key,
                   cls.code_version())
    reference = compute_reference(scene.at_frame(0), samples=samples)
    frame = Frame(scene)
    try:
        scene_ms, frags_scene = frame.measure_scene_pass(frames, warmup)
        row, arrays = run_one(spec, frame, reference, scene_ms, frags_scene, context.renderer)
        return Evaluation(row, arrays["visibility"] if arrays else None, reference, frame.arrays,
                          frame.compared_pixels(reference.covered), arrays)
    finally:
        frame.release()
