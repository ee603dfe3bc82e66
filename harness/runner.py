"""Expand sweeps into runs, run them, append one record per run. Resumable.

Each run has a stable id (scene description and resolution, technique, parameters, the
technique's code version, frames, warm-up and reference settings). Runs whose id is already
in ``DIR/results.csv`` are skipped, so a killed sweep restarted with the same arguments
finishes the rest without duplicates.
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
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import yaml
from pydantic import ValidationError

from . import config as cfg
from . import metrics, registry, results
from .gl.measure import default_timer
from .scene import BuiltScene, build_scene


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

    @property
    def params_json(self) -> str:
        return json.dumps(self.params, sort_keys=True)

    @property
    def run_id(self) -> str:
        text = "|".join(map(str, (self.scene, self.scene_key, self.width, self.height,
                                  self.technique, self.params_json, self.code_version,
                                  self.frames, self.warmup, self.samples, self.ref_seed,
                                  metrics.VERSION)))
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
              techniques: list[str] | None, overrides: dict[str, dict]) -> Plan:
    """Everything validated up front: a bad input raises ConfigError before any output."""
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
              else exp.techniques)
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
                    for combo in grid.combinations():
                        loc = ("techniques", tech) + ((gi,) if len(tech_grids) > 1 else ())
                        line = cfg._line_of(node, loc) if node is not None else None
                        where = (f"{exp_path}{f':{line}' if line else ''}: "
                                 + ".".join(map(str, loc)))
                        params = validate_params(tech, {**combo, **overrides.get(tech, {})},
                                                 where if experiment_path else "--set")
                        spec = RunSpec(scene_name, tech, params, width, height, exp.frames,
                                       exp.warmup, exp.reference.samples, exp.reference.seed,
                                       scene_at.key, version)
                        if spec.run_id not in seen:
                            seen.add(spec.run_id)
                            runs.append(spec)
    if not runs:
        raise cfg.ConfigError(f"{exp_path}: nothing to run (no scene x technique combination)")
    exp_hash = hashlib.sha256(
        (exp_text + json.dumps(sorted(r.run_id for r in runs))).encode()).hexdigest()[:16]
    return Plan(runs, built, exp_hash, str(exp_path))


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
    manifest = {
        "shadowbench": _version("shadowbench"),
        "versions": {name: _version(dist) for name, dist in (
            ("pyrender", "scikit-robot-pyrender"), ("PyOpenGL", "PyOpenGL"),
            ("mitsuba", "mitsuba"), ("drjit", "drjit"), ("numpy", "numpy"),
            ("trimesh", "trimesh"))},
        "python": sys.version.split()[0],
        "gl": {"platform": context.platform, "vendor": context.vendor,
               "renderer": context.renderer, "version": context.version,
               "timer": default_timer(context.renderer)},
        "gpu": _nvidia_gpus(),
        "cpu": _cpu(),
        "git_commit": _git_commit(),
        "git_dirty": _git_dirty(),
        "experiment": plan.experiment_path,
        "experiment_hash": plan.experiment_hash,
        "runs_planned": len(plan.runs),
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


def run_one(spec: RunSpec, frame, reference, scene_ms: float, frags_scene: int,
            renderer: str) -> tuple[dict, dict[str, np.ndarray] | None]:
    """Run one technique on a prepared frame: its row and the arrays to store with it (V,
    coverage and the technique's diagnostic maps as ``map_<name>``; None unless it ran).

    Never raises for a technique's failure: that is the row's status and error."""
    from .technique import NotApplicable, reset_gl_state

    row = {**_run_columns(spec), "scene_ms": scene_ms, "frags_scene": frags_scene,
           "renderer": renderer, "ref_seconds": reference.seconds}
    cls = registry.get(spec.technique)
    technique = None
    frame.new_meter()
    try:
        technique = cls(cls.Params(**spec.params))
        technique.prepare(frame)
        for i in range(spec.warmup + spec.frames):
            frame.meter.new_frame(measuring=i >= spec.warmup)
            output = technique.render(frame)
    except NotApplicable as e:
        row.update(status="skipped", error=str(e))
        return row, None
    except Exception as e:  # a technique's failure is its row's, not the sweep's
        row.update(status="error", error=_one_line(e))
        if os.environ.get("SHADOWBENCH_DEBUG"):
            traceback.print_exc()
        return row, None
    finally:
        if technique is not None:
            try:
                technique.release()
            except Exception as e:  # the run's result stands; a failed release only leaks
                row["warnings"] = f"release failed: {_one_line(e)}"
        reset_gl_state()

    v = output.visibility
    mask = frame.compared_pixels(reference.covered)
    totals = frame.meter.frame_totals_ms
    passes = frame.meter.passes()
    frags_shadow = (output.shadow_fragments if output.shadow_fragments is not None
                    else sum(p.fragments for p in passes))
    row.update(
        time_ms=float(np.median(totals)), time_ms_min=min(totals), time_ms_max=max(totals),
        frags_shadow=frags_shadow, overdraw=frags_shadow / max(frags_scene, 1),
        mem_bytes=output.mem_bytes, fetches_per_px=output.fetches_per_px,
        passes=[{"name": p.name, "ms": round(p.ms, 4), "fragments": p.fragments}
                for p in passes],
        nonfinite=output.nonfinite + metrics.nonfinite(v),
        v_min=float(np.nanmin(v)) if v.size else None,
        v_max=float(np.nanmax(v)) if v.size else None,
        warnings="; ".join(output.warnings + ([row["warnings"]] if "warnings" in row else [])),
    )
    v_clean = np.nan_to_num(v, nan=0.5, posinf=1.0, neginf=0.0)
    ref_v = reference.visibility
    row.update(
        mae=metrics.mae(v_clean, ref_v, mask=mask),
        rmse=metrics.rmse(v_clean, ref_v, mask=mask),
        wrong_pct=metrics.wrong_pct(v_clean, ref_v, mask=mask),
        edge_mae=metrics.edge_mae(v_clean, ref_v, mask=mask),
        levels=metrics.levels(v_clean, ref_v, mask=mask),
        ssim=metrics.ssim(v_clean, ref_v, mask=mask),
        psnr=metrics.psnr(v_clean, ref_v, mask=mask),
    )
    if reference.direct is not None:
        a = frame.arrays
        ambient = frame.scene.config.ambient
        shaded = metrics.shade(v_clean, a.normal, a.position, a.albedo, frame.scene.light,
                               ambient=ambient)
        shaded_ref = reference.direct + (ambient * a.albedo)[..., None]
        row["flip"] = metrics.flip(shaded, shaded_ref)
    row.update(output.extra)
    row["status"] = "ok"
    arrays = {"visibility": v.astype(np.float32), "covered": frame.arrays.covered,
              **{f"map_{name}": np.asarray(m, np.float32) for name, m in output.maps.items()}}
    return row, arrays


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


def execute(plan: Plan, out_dir: str | Path, *, platform_name: str | None = None,
            progress: bool = True, renderer=None) -> int:
    """Run every pending run of the plan; returns the exit code (0 ok, 1 some failed).

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
    shared), appending each row as it finishes; yields (spec, row) for each. A scene whose
    reference or frame fails gives its runs error rows, and the sweep goes on."""
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
            reference = compute_reference(scene, samples=samples, seed=ref_seed)
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
            for spec in specs:
                bar.set_description_str(f"{scene_name} {width}x{height}: {spec.technique}")
                row, arrays = run_one(spec, frame, reference, scene_ms, frags_scene,
                                 context.renderer)
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


def evaluate(scene: BuiltScene, technique: str, params: dict | None = None, *,
             frames: int = 1, warmup: int = 0, samples: int = 16) -> Evaluation:
    """Run one technique on one scene in this process and score it (for tests, notebooks).

    ``scene`` carries its resolution (``BuiltScene.with_resolution``); the reference comes from
    the on-disk cache when present.
    """
    from .gl.context import get_context
    from .reference import compute_reference
    from .technique import Frame

    context = get_context()
    cls = registry.get(technique)
    checked = validate_params(technique, params or {}, "evaluate()")
    spec = RunSpec(scene.name, technique, checked, scene.width, scene.height, frames, warmup,
                   samples, 0, scene.key, cls.code_version())
    reference = compute_reference(scene, samples=samples)
    frame = Frame(scene)
    try:
        scene_ms, frags_scene = frame.measure_scene_pass(frames, warmup)
        row, arrays = run_one(spec, frame, reference, scene_ms, frags_scene, context.renderer)
        return Evaluation(row, arrays["visibility"] if arrays else None, reference, frame.arrays,
                          frame.compared_pixels(reference.covered))
    finally:
        frame.release()
