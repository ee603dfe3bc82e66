"""A scene's group leaves nothing behind for the next one (issue 53): its scene's arrays, its
Frame, its techniques, its GL objects (counted before the sweep renews the GL context, and
after) and the Mitsuba scenes of its reference and of rt's ``backend: embree`` are gone once
``render_serial`` has moved on. Two small scenes stand for
the 10^6-triangle ones (``LARGE_SCENE`` at 0: every scene is kept only while its group
runs), their references traced (an empty cache: Mitsuba builds each scene).

Seen failing against the sweep before issue 53, whose plan held every scene it built for the
whole run (the first scene's vertex arrays alive when the second group began), and against a
SceneSet that kept the last large scene after its group (release() doing nothing)."""

from __future__ import annotations

import gc
import weakref

import pytest
import yaml
from helpers import SCENE_FILE

TECHNIQUES = {"sm": None, "silhouette": None, "sv": None, "ptsv": None,
              "rt": [{}, {"set": {"backend": "embree"}}]}


def _mitsuba_scenes() -> int:
    """Mitsuba scenes any Python object (a generator's suspended frame included) holds."""
    found = set()
    for holder in gc.get_objects():
        for o in gc.get_referents(holder):
            kind = type(o)
            if kind.__name__ == "Scene" and kind.__module__.startswith("mitsuba"):
                found.add(id(o))
    return len(found)


def test_nothing_of_a_group_is_alive_when_the_next_begins(tmp_path, monkeypatch, gl_context):
    from harness import run
    from harness.gl.objects import live_objects, names_now
    from harness.run import scene_set
    from harness.technique import Frame, Technique

    monkeypatch.setenv("SHADOWBENCH_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(scene_set, "LARGE_SCENE", 0)
    monkeypatch.setattr(run.measure, "FOOTPRINTS", run.measure.Footprints())  # no other test's
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "scenes": ["box_plane", "sphere_plane"], "resolutions": [[48, 48]], "frames": 1,
        "warmup": 0, "reference": {"samples": 1}, "techniques": TECHNIQUES}))
    plan = run.plan_runs(experiment_path=str(experiment), scene_file=str(SCENE_FILE),
                         scenes=None, techniques=None, overrides={})
    tracked: list[tuple[str, weakref.ref]] = []

    frame_init = Frame.__init__

    def tracking_frame(self, scene):
        frame_init(self, scene)
        tracked.extend([("frame", weakref.ref(self)), ("scene", weakref.ref(scene)),
                        # the arrays the plan's own copy of the scene shares with it
                        ("scene vertices", weakref.ref(scene.parts[0].vertices))])

    technique_init = Technique.__init__

    def tracking_technique(self, params):
        technique_init(self, params)
        tracked.append((type(self).name, weakref.ref(self)))

    monkeypatch.setattr(Frame, "__init__", tracking_frame)
    monkeypatch.setattr(Technique, "__init__", tracking_technique)
    gc.collect()
    mitsuba_before = _mitsuba_scenes()
    names = [names_now()]  # the objects made since are the sweep's, in the context of now
    renewed = []
    renew = type(gl_context).renew

    def counting_renew(context):
        renewed.append(live_objects(names[-1]))  # what the old context still held of ours
        renew(context)
        names.append(names_now())

    monkeypatch.setattr(type(gl_context), "renew", counting_renew)
    left_behind = []

    def check(when: str):
        gc.collect()
        alive = [what for what, ref in tracked if ref() is not None]
        left_behind.append((when, alive, live_objects(names[-1]),
                            _mitsuba_scenes() - mitsuba_before))

    class Bar:
        groups = 0

        def stage(self, text):
            if Bar.groups:
                check(f"as {text} began")
            Bar.groups += 1

        def status(self, text):
            pass

        def frame_done(self, specs):
            pass

    rows = [row for _, row in run.render_serial(plan, plan.runs, tmp_path / "out", gl_context,
                                                 Bar())]
    check("after the sweep")
    assert Bar.groups == 2 and len(rows) == 2 * 6
    assert all(row["status"] == "ok" for row in rows), [row.get("error") for row in rows]
    assert {"frame", "scene", "sv", "rt"} <= {what for what, _ in tracked}
    # after each group (unless objects of other tests were alive), and before each batch its
    # runs' measured start is expected to need it for (FOOTPRINTS: what this machine measured):
    # however many, each found nothing of the sweep's alive in the context it replaced
    assert all(held == {} for held in renewed), renewed
    for when, alive, gl_objects, mitsuba_scenes in left_behind:
        assert alive == [], f"{when}: {alive} still alive"
        assert gl_objects == {}, f"{when}: GL objects alive: {gl_objects}"
        assert mitsuba_scenes == 0, f"{when}: {mitsuba_scenes} Mitsuba scenes alive"


@pytest.fixture(autouse=True)
def _no_warnings_of_leaks(recwarn):
    """render_serial's own check agrees: no GL object left after either group."""
    yield
    leaks = [str(w.message) for w in recwarn if "GL objects left alive" in str(w.message)]
    assert leaks == []


def test_a_context_made_anew_between_batches_changes_no_result(tmp_path, monkeypatch, gl_context):
    """Every batch of one run on a GL context made anew (``RENEW_BYTES`` 0, ``BATCH_RUNS`` 1:
    the frame's objects made again, its G-buffer drawn again) against the same runs in one
    batch on one context: every row's numbers but the times and the V of every run equal.
    Catches a renewal that loses state the runs rely on (a G-buffer not drawn again: V all
    lit)."""
    import numpy as np

    from harness import results, run
    from harness.run import measure

    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "scenes": ["box_plane"], "resolutions": [[48, 48]], "frames": 1, "warmup": 1,
        "reference": {"samples": 1}, "techniques": TECHNIQUES}))
    renewals = []
    frame_renew = measure._renew_context

    def counting(frame):
        renewals.append(frame_renew(frame))
        return renewals[-1]

    outputs = {}
    for name, renew_bytes, batch_runs in (("one", 2**62, 16), ("renewed", 0, 1)):
        monkeypatch.setattr(measure, "RENEW_BYTES", renew_bytes)
        monkeypatch.setattr(measure, "BATCH_RUNS", batch_runs)
        monkeypatch.setattr(measure, "_renew_context", counting)
        plan = run.plan_runs(experiment_path=str(experiment), scene_file=str(SCENE_FILE),
                             scenes=None, techniques=None, overrides={})
        out = tmp_path / name
        list(run.render_serial(plan, plan.runs, out, gl_context, _Quiet()))
        outputs[name] = out
    assert renewals == [True] * 6  # one a batch, in the second sweep only
    timing = {"time_ms", "time_ms_min", "time_ms_max", "time_ms_ci_low", "time_ms_ci_high",
              "frame_ms", "prepare_ms", "setup_ms", "setup_ms_ci_low", "setup_ms_ci_high",
              "cpu_contention", "noisy", "scene_ms", "ref_seconds", "ref_build_seconds",
              "finished_at", "passes", "gpu_estimate_ms"}
    one, renewed = (sorted(results.read_rows(outputs[n]), key=lambda r: r["run_id"])
                    for n in ("one", "renewed"))
    assert [r["run_id"] for r in one] == [r["run_id"] for r in renewed]
    for a, b in zip(one, renewed):
        assert {k: v for k, v in a.items() if k not in timing} == \
            {k: v for k, v in b.items() if k not in timing}, a["technique"]
        v_a = np.load(outputs["one"] / a["array"])["visibility"]
        v_b = np.load(outputs["renewed"] / b["array"])["visibility"]
        assert np.array_equal(v_a, v_b), a["technique"]
        assert v_a.min() < 1  # shadows drawn: the G-buffer was there


class _Quiet:
    def stage(self, text):
        pass

    def status(self, text):
        pass

    def frame_done(self, specs):
        pass
