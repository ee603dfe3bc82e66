"""Executing a plan, the loop around the steps: pending runs go to a renderer (serial here, or
harness.run.distributed's on Dask) that measures, scores and stores them; progress and manifest."""

from __future__ import annotations

import os
import warnings
from pathlib import Path

from .. import results
from ..config.cache_entry import take_rebuilt_notes
from .manifest import MANIFEST_FILE, SPACE_RESERVE, SPACE_RESERVE_BYTES, read_manifest, write_manifest
from .measure import return_freed_memory, run_group
from .plan import Plan, RunSpec
from .progress import NORMAL, QUIET, Progress
from .score import failed_scene_row
from .store import exclusive, record_run, utc_now


def _frame_cost(spec: RunSpec) -> float:
    """Relative time of one frame of a run, for the estimate of the time left: frames at
    1024x1024 take many times those at 256x256, so a plain rate misjudges a multi-resolution
    sweep. The constant is the per-frame overhead, about that of a 256x256 frame."""
    return spec.width * spec.height + 256 * 256


def _cost(spec: RunSpec) -> float:
    """A run's frames, warm-up included: a moving scene's run renders (and traces the
    reference of) every frame of its sequence."""
    return _frame_cost(spec) * (spec.frames + spec.warmup)


def _changed_params(spec: RunSpec) -> str:
    """``res=512 k=4``: the run's parameters that differ from its technique's defaults."""
    from ..technique import registry

    try:
        defaults = registry.get(spec.technique).Params().model_dump(mode="json")
    except Exception:  # a technique that cannot say its defaults: every parameter
        defaults = {}
    return " ".join(f"{k}={v}" for k, v in spec.params.items() if defaults.get(k, ...) != v)


def _run_line(spec: RunSpec, row: dict) -> str:
    """A stored run as ``--verbose`` shows it: scene, size, technique, its changed parameters,
    then its median time, or its status and error."""
    status = row["status"]
    how = (f"{row['time_ms']:.4g} ms" if status == "ok" and row.get("time_ms") is not None
           else f"{status}: {row.get('error', '')}" if status != "ok" else status)
    where = f" ({row['worker']})" if row.get("worker") else ""  # a Dask worker's run
    label = " ".join(filter(None, (spec.technique, _changed_params(spec))))
    return f"{spec.scene} {spec.width}x{spec.height} {label}: {how}{where}"


class RunProgress(Progress):
    """The sweep's progress: its steps the runs, its work their frames (``_cost``), counted as
    each round ends (a 1000-frame run has an estimate after its first frame, not only when it
    ends) and as each run is stored. Renderers get it as their ``bar``: ``stage`` as a scene's
    group begins, ``status`` for what the group does, ``frame_done`` after each round."""

    def __init__(self, total: int, pending: list[RunSpec], **options):
        super().__init__(total, done=total - len(pending), work=sum(map(_cost, pending)),
                         **options)
        self.counted: dict[str, float] = {}  # frames of unfinished runs already counted

    def frame_done(self, specs: list[RunSpec]) -> None:
        for spec in specs:
            self.counted[spec.run_id] = self.counted.get(spec.run_id, 0.0) + _frame_cost(spec)
        self.advance(sum(map(_frame_cost, specs)))

    def run_done(self, spec: RunSpec, row: dict) -> None:
        self.step(_run_line(spec, row), work=_cost(spec) - self.counted.pop(spec.run_id, 0.0),
                  failed=row["status"] == "error")


def noisy_runs(plan: Plan, out_dir: str | Path) -> list[RunSpec]:
    """The plan's runs recorded ok in DIR but timed while the machine was busy (``noisy``)."""
    noisy = {r["run_id"] for r in results.read_rows(out_dir)
             if r["status"] == "ok" and r.get("noisy") == "1"}
    return [spec for spec in plan.runs if spec.run_id in noisy]


def execute(plan: Plan, out_dir: str | Path, *, platform_name: str | None = None,
            progress: bool | str = True, renderer=None, retime_noisy: bool = False) -> int:
    """Run every pending run of the plan; returns the exit code (0 ok, 1 some failed).
    ``progress``: a mode of :mod:`harness.run.progress` (quiet, normal, verbose), or a bool
    (normal or quiet).

    ``retime_noisy``: then measure again the runs whose row says ``noisy`` (rendered anew, in
    interleaved rounds among themselves; their rows are replaced: the technique's output is
    deterministic, so only the timing and load columns change).

    ``renderer(plan, pending, out_dir, context, bar)`` renders and records the pending runs,
    yielding ``(spec, row)`` as each is recorded: :func:`render_serial` (the default) in this
    process, or ``harness.run.distributed.dask_renderer(...)`` on a Dask cluster. ``bar`` is
    the :class:`RunProgress`.

    Each run is stored as soon as its frames are done (with the others of its round: runs
    interleaved in one batch finish together), its row appended by replacing results.csv
    whole, so SIGKILL at any moment leaves every stored run recorded once and no partial row,
    and Ctrl-C waits until the runs whose frames are done are stored
    (``interrupt.finishing``); the next call with the same plan skips them. Arrays are
    written before their row: a kill between the two leaves an unreferenced array that the
    rerun overwrites. The next call also heals what a kill leaves: it removes temporary
    files, marks the killed invocation ``interrupted``, and renders again the runs whose
    stored arrays are missing or damaged."""
    from ..machine.interrupt import raise_if_interrupted

    renderer = renderer or render_serial
    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    with exclusive(out_dir):
        read_manifest(out_dir)  # foreign files stop the run before anything changes
        results.read_rows(out_dir)
        results.remove_temporaries(out_dir, (results.RESULTS_FILE, MANIFEST_FILE, SPACE_RESERVE))
        results.mark_damaged_runs(out_dir)
        done = results.done_ids(out_dir)
        pending = [r for r in plan.runs if r.run_id not in done]  # failed ones are retried
        failed = 0
        from ..gl.context import get_context

        context = get_context(platform_name)
        # the id tells this invocation's entry from others started in the same second
        session = {"id": os.urandom(4).hex(), "started": utc_now(), "finished": None,
                   "status": "running", "experiment": plan.experiment_path,
                   "experiment_hash": plan.experiment_hash, "scenes": list(plan.scenes),
                   "runs_planned": len(plan.runs), "runs_pending": len(pending),
                   "runs_rendered": 0,
                   # one line per damaged cache entry built again, planning's included
                   "notes": take_rebuilt_notes()}
        results.replace_atomically(out_dir / SPACE_RESERVE,
                                   lambda f: f.write(bytes(SPACE_RESERVE_BYTES)))
        write_manifest(out_dir, plan, context, session)
        mode = progress if isinstance(progress, str) else NORMAL if progress else QUIET
        bar = RunProgress(len(plan.runs), pending, mode=mode)
        if not pending:
            bar.stage("nothing to render")
        runs = None
        try:
            runs = renderer(plan, pending, out_dir, context, bar)
            for spec, row in runs:
                session["notes"] += take_rebuilt_notes()
                session["runs_rendered"] += 1
                failed += row["status"] == "error"
                bar.run_done(spec, row)
                raise_if_interrupted()  # a library may have swallowed Ctrl-C: stop here
            if retime_noisy:
                again = noisy_runs(plan, out_dir)
                session["runs_retimed"] = len(again)
                bar.reset(len(again), sum(map(_cost, again)), stage="retiming the noisy runs")
                runs = renderer(plan, again, out_dir, context, bar)
                for spec, row in runs:
                    failed += row["status"] == "error"
                    bar.run_done(spec, row)
                    raise_if_interrupted()
            session["status"] = "complete"
        except KeyboardInterrupt:
            session["status"] = "interrupted"
            raise
        except BaseException:
            session["status"] = "failed"
            raise
        finally:
            if hasattr(runs, "close"):
                runs.close()  # the renderer's own clean-up (its frame released) comes first
            bar.close()
            session["notes"] += take_rebuilt_notes()
            session["finished"] = utc_now()
            write_manifest(out_dir, plan, context, session)
            (out_dir / SPACE_RESERVE).unlink(missing_ok=True)
    return 1 if failed else 0


def render_serial(plan: Plan, pending: list[RunSpec], out_dir: Path, context, bar):
    """Render the pending runs, one scene and resolution at a time (its reference and G-buffer
    shared, its runs measured in interleaved rounds: :func:`run_group`), storing each run as
    its frames are done; yields (spec, row) for each. A scene whose reference or frame fails
    gives its runs error rows, and the sweep goes on.

    Between groups nothing of the last one stays: its scene (built again by the plan when
    another group asks for it), G-buffer, reference and runs are dropped, what they freed
    goes back to the system (``return_freed_memory``) and the GL objects made during the
    group are counted: any left alive (a technique's release that misses some) is a warning,
    in DIR/warnings.log where the command keeps them; with no object alive in it at all (a
    caller may hold its own), the GL context is made anew (``GLContext.renew``: what llvmpipe
    kept of the group's draws goes with the old one). Every group starts on a context as the
    first does: the state a technique assumes is set by the harness (``reset_gl_state``) and
    by each pass, not left by an earlier group."""
    from ..gl.objects import live_objects, names_now

    groups: dict[tuple, list[RunSpec]] = {}
    for spec in pending:
        groups.setdefault((spec.scene, spec.width, spec.height, spec.samples, spec.ref_seed),
                          []).append(spec)
    for (scene_name, width, height, samples, ref_seed), specs in groups.items():
        bar.stage(f"{scene_name} {width}x{height}: {len(specs)} run{'s' * (len(specs) > 1)}")
        names = names_now()
        try:
            yield from _render_group(plan, specs, out_dir, context, bar)
        finally:
            if release := getattr(plan.scenes, "release", None):
                release()  # the plan's own copy of a large scene
        # not after Ctrl-C: the process ends within interrupt.GRACE_S, manifest written first
        if left := live_objects(names):
            warnings.warn(f"{scene_name} {width}x{height}: GL objects left alive after its "
                          f"group: {', '.join(f'{n} {kind}' for kind, n in left.items())} "
                          "(a technique's release misses them)", RuntimeWarning, stacklevel=2)
        elif not live_objects():  # no object of anyone else's either (a caller's own)
            context.renew()  # what llvmpipe kept of the group's draws goes with the context
        return_freed_memory()  # what the group left behind, before the next scene


def _render_group(plan: Plan, specs: list[RunSpec], out_dir: Path, context, bar):
    """One scene and resolution of :func:`render_serial`: what it builds lives in this
    generator's frame, gone when it returns."""
    from ..truth.reference import compute_reference
    from ..technique import Frame

    first = specs[0]
    scene = plan.scenes[first.scene].with_resolution(first.width, first.height)
    bar.status("reference")
    frame = None
    try:
        reference = compute_reference(scene.at_frame(0), samples=first.samples,
                                      seed=first.ref_seed)
        frame = Frame(scene)
        scene_ms, frags_scene = frame.measure_scene_pass(first.frames, first.warmup)
    except Exception as e:  # Mitsuba or GL cannot take this scene: its runs fail
        if frame is not None:
            frame.release()
        for spec in specs:
            row = failed_scene_row(spec, e)
            record_run(out_dir, spec, row, None, None)
            yield spec, row
        return
    del scene  # the frame holds it
    bar.status("interleaved rounds")
    rounds = run_group(specs, frame, reference, scene_ms, frags_scene, context.renderer,
                       on_frame=getattr(bar, "frame_done", None))
    try:
        for spec, row, arrays in rounds:  # within interrupt.finishing: stored at once
            record_run(out_dir, spec, row, arrays, reference)
            del arrays  # written: not kept while the next run is scored
            yield spec, row
    finally:
        rounds.close()  # leaves interrupt.finishing if a consumer stopped inside it
        frame.release()
