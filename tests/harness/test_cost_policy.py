"""The cost policy (``cost: dynamic | static``, harness/run/measure.py): what each technique's
frames are charged under each, the setup time static reports, and the bad inputs (a policy
other than the two, static on a moving light, compare across policies) that exit 2."""

from __future__ import annotations

import numpy as np
import pytest
import yaml
from helpers import moving

from harness.technique import registry
from harness.cli import main as shadowbench

TECHNIQUES = sorted(registry.techniques())


def pass_names(row: dict) -> list[str]:
    return [p["name"] for p in row["passes"]]


@pytest.mark.parametrize("name", TECHNIQUES)
def test_dynamic_charges_a_still_scene_the_passes_of_a_moving_light(name, shipped_scenes,
                                                                     evaluate):
    """Under cost: dynamic, every technique's frame on still box_plane holds the same timed
    passes as on box_plane with its light orbiting (3 frames, 40 degrees): what a moving light
    makes an engine redo is charged when the light happens to stand still too. Catches a map
    pass, a light fit, a warp fit or a volume build moved back into work done once (an untimed
    update on a still scene, as before the policy: sm's light_fit and shadow_map missing)."""
    still = evaluate(moving(shipped_scenes, "box_plane", (64, 48)), name, frames=2)
    orbiting = evaluate(moving(shipped_scenes, "box_plane", (64, 48), frames=3,
                               light_orbit=40), name)
    if still.row["status"] == "skipped":
        assert orbiting.row["status"] == "skipped"
        return
    assert still.row["status"] == orbiting.row["status"] == "ok", (still.row.get("error"),
                                                                   orbiting.row.get("error"))
    assert still.row["cost"] == "dynamic" and still.row["setup_ms"] is None
    assert pass_names(still.row) == pass_names(orbiting.row)


class _TickingClock:
    """A stand-in for harness.gl.measure's ``time``: every read is 1 ms after the last, so
    every timed pass lasts exactly 1 ms, whatever the machine's load."""

    def __init__(self):
        self.now_ns = 0

    def perf_counter_ns(self) -> int:
        self.now_ns += 1_000_000
        return self.now_ns


def test_static_moves_the_map_into_setup_and_dynamic_pays_it_every_frame(scene_at, evaluate,
                                                                        monkeypatch):
    """sm on crowd at 128x128, 15 frames after 2. Under dynamic a frame is light fit, map and
    shading; under static the frame is the shading pass alone and setup_ms (light fit and map)
    is reported with its interval. With every pass lasting exactly 1 ms (a ticking clock in
    place of the wall clock, so no load can change the sums), time_ms(static) + setup_ms
    equals time_ms(dynamic): 1 + 2 = 3. Catches the setup missing from dynamic's frames
    (dynamic 1), the map pass left in static's frames (static 3), and a setup_ms timing
    something else (prepare, or one repeat's passes summed over the repeats)."""
    from harness.gl import measure

    scene = scene_at("crowd", 128)
    params = {"res": 2048}
    dynamic = evaluate(scene, "sm", params, frames=15, warmup=2).row
    static = evaluate(scene, "sm", params, frames=15, warmup=2, cost="static").row
    assert pass_names(dynamic) == ["light_fit", "shadow_map", "shading"]
    assert pass_names(static) == ["shading"] and static["cost"] == "static"
    assert static["setup_ms_ci_low"] <= static["setup_ms"] <= static["setup_ms_ci_high"]
    monkeypatch.setattr(measure, "time", _TickingClock())
    ticked = {cost: evaluate(scene, "sm", params, frames=15, warmup=2, cost=cost).row
              for cost in ("dynamic", "static")}
    assert ticked["dynamic"]["time_ms"] == pytest.approx(3.0)
    assert ticked["static"]["time_ms"] == pytest.approx(1.0)
    assert ticked["static"]["setup_ms"] == pytest.approx(2.0)
    assert ticked["dynamic"]["setup_ms"] is None


@pytest.mark.parametrize("name", TECHNIQUES)
def test_static_redoes_the_per_view_work_of_a_moving_camera(name, shipped_scenes, evaluate):
    """Under cost: static the light and the geometry are fixed but the camera may move: on
    box_plane with its camera orbiting and closing in (3 frames, 30 degrees, half the
    distance), every frame's V under static
    equals dynamic's (the per-frame mae series and the worst frame, bit for bit). Catches
    per-view work left in ``update``, which static runs once: csm's cascades fitted for frame
    0's camera, sv's volumes drawn with frame 0's view-projection (or none: a NaN uniform)."""
    scene = moving(shipped_scenes, "box_plane", (64, 48), frames=3, camera_orbit=30,
                   camera_dolly=0.5)
    dynamic = evaluate(scene, name)
    static = evaluate(scene, name, cost="static")
    assert static.row["status"] == dynamic.row["status"], (static.row.get("error"),
                                                           dynamic.row.get("error"))
    if dynamic.row["status"] == "skipped":
        return
    assert dynamic.row["status"] == "ok", dynamic.row.get("error")
    for key in ("series_mae", "worst_visibility"):
        np.testing.assert_array_equal(static.arrays[key], dynamic.arrays[key], err_msg=key)


def _experiment(tmp_path, **keys):
    path = tmp_path / "experiment.yaml"
    path.write_text(yaml.safe_dump({"techniques": {"sm": None}, "frames": 1, "warmup": 0,
                                    **keys}))
    return path


@pytest.mark.parametrize("keys, args, needle", [
    ({"cost": "fast"}, [], "cost"),
    ({"cost": None}, [], "cost"),
    ({}, ["--cost", "sometimes"], "--cost"),
])
def test_a_bad_cost_policy_is_exit_2_naming_file_and_key(keys, args, needle, tmp_path,
                                                         small_scene_file, capsys):
    """``cost:`` other than dynamic or static, in the experiment or as --cost: exit 2, one
    line naming the file (or the option) and the key; nothing written. Catches a policy
    validated late (after output) or not at all (an unknown word run as dynamic)."""
    path = _experiment(tmp_path, **keys)
    out = tmp_path / "out"
    code = shadowbench(["run", str(path), "--scene-file", str(small_scene_file()), "--out",
                        str(out), "--quiet", *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1 and needle in err, err
    if not args:
        assert str(path) in err
    assert not out.exists()


@pytest.mark.parametrize("motion, needle", [
    ({"frames": 3, "light_orbit": 20}, "light_orbit"),
    ({"frames": 3, "objects": [{"object": 1, "spin": 30}]}, "motion.objects"),
])
def test_static_on_a_moving_light_or_objects_is_exit_2(motion, needle, tmp_path,
                                                       shipped_scenes, capsys):
    """cost: static declares the light and the geometry fixed: a scene whose motion turns the
    light or moves an object is bad input, one line naming the experiment and its cost key.
    Catches static run on a moving light or caster, whose frames would be shaded from a map
    made once for frame 0."""
    scene = shipped_scenes["box_plane"].model_dump(mode="json")
    scene.update(resolution=[32, 32], motion=motion)
    scenes = tmp_path / "scenes.yaml"
    scenes.write_text(yaml.safe_dump({"scenes": {"orbiting": scene}}))
    path = _experiment(tmp_path, cost="static")
    out = tmp_path / "out"
    code = shadowbench(["run", str(path), "--scene-file", str(scenes), "--out", str(out),
                        "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(path) in err and "cost" in err and "orbiting" in err and needle in err
    assert not out.exists()


def test_compare_refuses_folders_of_different_policies(tmp_path, make_results, capsys):
    """Two folders of the same runs, one measured under dynamic and one under static: their
    times hold different work, so compare exits 2 with one line naming both folders and their
    policies; folders of one policy compare as usual. Catches a comparison that reads static's
    smaller frame times as a speed-up."""
    runs = [{"params": {"res": 512}, "time_ms": 2.0}]
    dynamic = make_results(tmp_path / "dynamic", [{**r, "cost": "dynamic"} for r in runs])
    static = make_results(tmp_path / "static", [{**r, "cost": "static", "time_ms": 0.5,
                                                 "setup_ms": 1.5} for r in runs])
    assert shadowbench(["compare", str(dynamic), str(static)]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1, err
    assert all(s in err for s in (str(dynamic), str(static), "dynamic", "static")), err
    assert shadowbench(["compare", str(static), str(static)]) == 0


def test_the_dashboard_names_the_policy_on_every_cost_axis(tmp_path, make_results):
    """A static folder's page titles its cost axes and run-table cost headings with the policy
    (time_ms (static), setup_ms (static)) and none with another. Catches a page that shows
    static frame times as if they held the whole frame's work."""
    from harness.report import build_report

    folder = make_results(tmp_path / "static", [
        {"params": {"res": 512}, "time_ms": 0.5, "setup_ms": 1.5, "cost": "static"},
        {"params": {"res": 1024}, "time_ms": 0.6, "setup_ms": 3.0, "cost": "static"}])
    page = build_report(folder).read_text()
    assert "time_ms (static): time per frame" in page
    assert "setup_ms (static): setup time" in page
    assert "time ms (static)" in page and "setup ms (static)" in page
    assert "(dynamic)" not in page


class _SecondsClock:
    """A stand-in for harness.run.measure's ``time``: every read of ``perf_counter`` is one
    second after the last."""

    def __init__(self):
        self.now = 0.0

    def perf_counter(self) -> float:
        self.now += 1.0
        return self.now


@pytest.mark.parametrize("cost", ["dynamic", "static"])
def test_prepare_is_reported_once_and_charged_in_no_frame(cost, scene_at, evaluate,
                                                          monkeypatch):
    """prepare_ms is the wall time of the technique's prepare alone, once per run, under either
    policy, and no frame holds it: with run.measure's clock ticking one second per read and
    every pass one millisecond (harness.gl.measure's ticking clock), sm's prepare_ms is exactly
    1000 and its frame 3 passes (dynamic) or 1 (static) of 1 ms. Catches prepare_ms missing
    (run against a _start that drops it: None), and a prepare_ms measured over more than the
    one call wherever that reads the run's clock (each read adds a second)."""
    from harness.gl import measure as pass_measure
    from harness.run import measure

    monkeypatch.setattr(measure, "time", _SecondsClock())
    monkeypatch.setattr(pass_measure, "time", _TickingClock())
    row = evaluate(scene_at("box_plane", 32), "sm", frames=3, warmup=2, cost=cost).row
    assert row["status"] == "ok", row.get("error")
    assert row["prepare_ms"] == 1000.0
    assert row["time_ms"] == pytest.approx(3.0 if cost == "dynamic" else 1.0)
