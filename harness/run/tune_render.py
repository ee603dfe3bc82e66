"""Rendering for :mod:`harness.run.tune`: groups of runs on a view whose G-buffer and reference
are made once and kept while the tune needs them, each run stored as it finishes, and the runs
already stored in DIR read back instead of rendered."""

from __future__ import annotations

from pathlib import Path

from .. import results
from .measure import return_freed_memory, run_group
from .plan import RunSpec
from .score import failed_scene_row
from .store import record_run


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
            for spec in pending:
                rows[spec.run_id] = self._record(spec, {**failed_scene_row(spec, view),
                                                        **extra.get(spec.run_id, {})})
            return rows
        frame, reference = view
        # one measurement of the camera pass per group, with the group's frames
        scene_ms, frags_scene = frame.measure_scene_pass(pending[0].frames, pending[0].warmup)
        for spec, row, arrays in run_group(pending, frame, reference, scene_ms, frags_scene,
                                           self.renderer_name):
            rows[spec.run_id] = self._record(spec, {**row, **extra.get(spec.run_id, {})},
                                             arrays, reference)
        return rows

    def _record(self, spec: RunSpec, row: dict, arrays=None, reference=None) -> dict:
        record_run(self.out_dir, spec, row, arrays, reference)
        self.rendered += 1
        self.failed += row.get("status") == "error"
        if row.get("status") in ("ok", "skipped"):
            self.stored[spec.run_id] = row
        return row

    def release(self, name: str) -> None:
        view = self.views.pop(name, None)
        if isinstance(view, tuple):
            view[0].release()
            return_freed_memory()

    def release_all(self) -> None:
        for name in list(self.views):
            self.release(name)
