"""Rendering for :mod:`harness.run.tune`: groups of runs on a view whose G-buffer and reference
are made once and kept while the tune needs them, each run stored as it finishes, and the runs
already stored in DIR read back instead of rendered."""

from __future__ import annotations

import time
from pathlib import Path

from .. import results
from .measure import return_freed_memory, run_group
from .plan import RunSpec
from .score import failed_scene_row
from .store import record_runs

# the rows of a group's finished runs are stored together, at least this often: one rewrite of
# results.csv per run made the search's short runs wait on the file (O(runs^2) in all)
FLUSH_SECONDS = 5.0


class ViewRenderer:
    """Renders runs of one view (a BuiltScene) at a time; ``render`` returns every asked run's
    row by run id, the stored ones as stored (text) and the new ones as recorded."""

    def __init__(self, out_dir: Path, renderer_name: str):
        self.out_dir, self.renderer_name = Path(out_dir), renderer_name
        self.views: dict[str, tuple] = {}  # view name -> (frame, reference) or the error
        self.rendered = self.failed = 0
        self.stored = {r["run_id"]: r for r in results.read_rows(self.out_dir)
                       if r["status"] in ("ok", "skipped")}

    def _view(self, scene, spec: RunSpec):
        from ..technique import Frame
        from ..truth.reference import compute_reference

        if scene.name not in self.views:
            frame = None
            try:
                reference = compute_reference(scene.at_frame(0), samples=spec.samples,
                                              seed=spec.ref_seed)
                frame = Frame(scene)
                self.views[scene.name] = (frame, reference)
            except Exception as e:  # Mitsuba or GL cannot take this view: its runs fail
                if frame is not None:
                    frame.release()
                self.views[scene.name] = e
        return self.views[scene.name]

    def render(self, scene, specs: list[RunSpec], extra: dict | None = None) -> dict[str, dict]:
        """Rows of ``specs`` (all of ``scene``), rendering those DIR does not hold; ``extra``:
        columns by run id added to a new row before it is stored."""
        extra = extra or {}
        rows = {spec.run_id: self.stored[spec.run_id] for spec in specs
                if spec.run_id in self.stored}
        pending = list({spec.run_id: spec for spec in specs if spec.run_id not in rows}.values())
        if not pending:
            return rows
        view = self._view(scene, pending[0])
        if isinstance(view, Exception):
            failed = [(spec, {**failed_scene_row(spec, view), **extra.get(spec.run_id, {})},
                       None, None) for spec in pending]
            self._record(failed)
            rows.update({spec.run_id: row for spec, row, _, _ in failed})
            return rows
        frame, reference = view
        # one measurement of the camera pass per group, with the group's frames
        scene_ms, frags_scene = frame.measure_scene_pass(pending[0].frames, pending[0].warmup)
        finished, flushed = [], time.monotonic()
        try:
            for spec, row, arrays in run_group(pending, frame, reference, scene_ms, frags_scene,
                                               self.renderer_name):
                row = {**row, **extra.get(spec.run_id, {})}
                finished.append((spec, row, arrays, reference))
                rows[spec.run_id] = row
                if time.monotonic() - flushed >= FLUSH_SECONDS:
                    self._record(finished)
                    finished, flushed = [], time.monotonic()
        finally:  # what finished is stored, whatever stops the group
            self._record(finished)
        return rows

    def _record(self, finished: list[tuple]) -> None:
        record_runs(self.out_dir, finished)
        for spec, row, _, _ in finished:
            self.rendered += 1
            self.failed += row.get("status") == "error"
            if row.get("status") in ("ok", "skipped"):
                self.stored[spec.run_id] = row

    def release(self, name: str) -> None:
        view = self.views.pop(name, None)
        if isinstance(view, tuple):
            view[0].release()
            return_freed_memory()

    def release_all(self) -> None:
        for name in list(self.views):
            self.release(name)
