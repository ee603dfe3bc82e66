"""Executing a plan, the loop around the steps: pending runs go to a renderer (serial here, or
harness.run.distributed's on Dask) that measures, scores and stores them; progress and manifest."""

from __future__ import annotations

import os
import sys
import time
from pathlib import Path

from .. import results
from ..config.cache_entry import take_rebuilt_notes
from .manifest import MANIFEST_FILE, SPACE_RESERVE, SPACE_RESERVE_BYTES, read_manifest, write_manifest
from .measure import return_freed_memory, run_group
from .plan import Plan, RunSpec
from .score import failed_scene_row
from .store import exclusive, record_run, utc_now

PROGRESS_FORMAT = "{desc} | {n_fmt}/{total_fmt} runs done{postfix} | {elapsed} elapsed"


def _frame_cost(spec: RunSpec) -> float:
    """Relative time of one frame of a run, for the estimate of the time left: frames at
    1024x1024 take many times those at 256x256, so a plain rate misjudges a multi-resolution
    sweep. The constant is the per-frame overhead, about that of a 256x256 frame."""
    return spec.width * spec.height + 256 * 256


def _cost(spec: RunSpec) -> float:
    """A run's frames, warm-up included: a moving scene's run renders (and traces the
    reference of) every frame of its sequence."""
    return _frame_cost(spec) * (spec.frames + spec.warmup)


class _Progress:
    """The progress bar and its estimate of the time left, from the cost done so far: runs
    finished and, on moving scenes, each frame as its round ends (a 1000-frame run has an
    estimate after its first frame, not only when it ends). Renderers get it as their bar."""

    REFRESH_S = 1.0  # per-frame updates redraw the bar at most this often

    def __init__(self, bar, pending: list[RunSpec]):
        self.bar, self.failed = bar, 0
        self.left, self.done = float(sum(map(_cost, pending))), 0.0
        self.counted: dict[str, float] = {}  # frames of unfinished runs already counted
        self.clock = self.drawn = time.monotonic()

    def set_description_str(self, text: str) -> None:
        self.bar.set_description_str(text)

    def frame_done(self, specs: list[RunSpec]) -> None:
        for spec in specs:
            self._advance(_frame_cost(spec))
            self.counted[spec.run_id] = self.counted.get(spec.run_id, 0.0) + _frame_cost(spec)
        self._show(runs_left=self.bar.total - self.bar.n)
        if time.monotonic() - self.drawn >= self.REFRESH_S:
            self.bar.refresh()
            self.drawn = time.monotonic()

    def run_done(self, spec: RunSpec, row: dict) -> None:
        self.failed += row["status"] == "error"
        self._advance(_cost(spec) - self.counted.pop(spec.run_id, 0.0))
        self._show(runs_left=self.bar.total - self.bar.n - 1)
        self.bar.update(1)

    def _advance(self, cost: float) -> None:
        self.done += cost
        self.left -= cost

    def _show(self, runs_left: int) -> None:
        self.bar.set_postfix_str(
            f"{runs_left} to go" + (f", {self.failed} failed" if self.failed else "")
            + (f", {_time_left(time.monotonic() - self.clock, self.done, self.left)}"
               if runs_left and self.done else ""), refresh=False)


def _time_left(elapsed_s: float, done: float, left: float) -> str:
    seconds = round(elapsed_s / done * max(left, 0.0))
    return f"about {seconds // 3600}:{seconds // 60 % 60:02d}:{seconds % 60:02d} left"


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
    process, or ``harness.run.distributed.dask_renderer(...)`` on a Dask cluster.

    Each finished run's row is appended by replacing results.csv whole, so SIGKILL or Ctrl-C
    at any moment leaves every finished run recorded once and no partial row; the next call
    with the same plan skips them. Arrays are written before their row: a kill between the two
    leaves an unreferenced array that the rerun overwrites. The next call also heals what a
    kill leaves: it removes temporary files, marks the killed invocation ``interrupted``, and
    renders again the runs whose stored arrays are missing or damaged."""
    from tqdm import tqdm

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
                   "status": "running", "runs_pending": len(pending), "runs_rendered": 0,
                   # one line per damaged cache entry built again, planning's included
                   "notes": take_rebuilt_notes()}
        results.replace_atomically(out_dir / SPACE_RESERVE,
                                   lambda f: f.write(bytes(SPACE_RESERVE_BYTES)))
        write_manifest(out_dir, plan, context, session)
        bar = tqdm(total=len(plan.runs), initial=len(plan.runs) - len(pending), unit="run",
                   disable=not progress, file=sys.stderr, dynamic_ncols=True,
                   bar_format=PROGRESS_FORMAT, postfix=f"{len(pending)} to go",
                   desc="" if pending else "nothing to render")
        progress = _Progress(bar, pending)
        try:
            for spec, row in renderer(plan, pending, out_dir, context, progress):
                raise_if_interrupted()
                session["notes"] += take_rebuilt_notes()
                session["runs_rendered"] += 1
                failed += row["status"] == "error"
                progress.run_done(spec, row)
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
            session["notes"] += take_rebuilt_notes()
            session["finished"] = utc_now()
            write_manifest(out_dir, plan, context, session)
            (out_dir / SPACE_RESERVE).unlink(missing_ok=True)
    return 1 if failed else 0


def render_serial(plan: Plan, pending: list[RunSpec], out_dir: Path, context, bar):
    """Render the pending runs, one scene and resolution at a time (its reference and G-buffer
    shared, its runs measured in interleaved rounds: :func:`run_group`), appending each row
    as it finishes; yields (spec, row) for each. A scene whose reference or frame fails gives
    its runs error rows, and the sweep goes on."""
    from ..truth.reference import compute_reference
    from ..technique import Frame

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
                                               context.renderer,
                                               on_frame=getattr(bar, "frame_done", None)):
                bar.set_description_str(f"{scene_name} {width}x{height}: {spec.technique}")
                record_run(out_dir, spec, row, arrays, reference)
                yield spec, row
        finally:
            frame.release()
            del frame, reference
            return_freed_memory()  # what the group left behind, before the next scene
