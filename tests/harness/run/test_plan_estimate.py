"""plan's time estimate (issue 47, friction 8): a run not stored is priced by its scene's
triangles and pixels at its technique's stored cost per triangle and per pixel, not at the
median stored run; long times are written in hours."""

from __future__ import annotations

import json
import re
from datetime import datetime, timedelta, timezone
from types import SimpleNamespace

import pytest

from harness import results
from harness.cli import main
from harness.cli.listing import plan_lines
from harness.run import Plan, RunSpec
from harness.run import estimate as est
from harness.run.plan import size_label
from helpers import ROOT

PIXELS = 256 * 256
# per frame, exactly: sv 0.01 ms a triangle and 1e-5 ms a pixel; sm 2 ms whatever the scene
COST = {"sv": (0.01, 1e-5), "sm": (0.0, 2 / PIXELS)}
FRAMES = 5


def frame_ms(technique: str, triangles: int, pixels: int = PIXELS) -> float:
    b, c = COST[technique]
    return b * triangles + c * pixels


def stored_folder(folder, sizes=(1000, 10000), techniques=("sm", "sv")):
    """Runs of ``techniques`` on a family scene at each triangle count of ``sizes`` (one batch
    each), 256x256, FRAMES frames, their times exactly COST's; the manifest's invocation and
    the rows' finish times make each batch's wall time its frame work (no overhead)."""
    folder.mkdir(parents=True, exist_ok=True)
    start = datetime(2026, 1, 1, tzinfo=timezone.utc)
    now, rows = start, []
    for triangles in sizes:
        name = f"architecture@{size_label(triangles)}"
        for technique in techniques:
            ms = frame_ms(technique, triangles)
            now += timedelta(milliseconds=FRAMES * ms)
            rows.append({"run_id": f"{len(rows):016d}", "schema": results.SCHEMA_VERSION,
                         "scene": name, "technique": technique, "params": "{}", "width": 256,
                         "height": 256, "triangles": triangles, "frames": FRAMES, "time_ms": ms,
                         "status": "ok", "finished_at": now.isoformat(timespec="milliseconds")})
    results.write_rows(folder, rows)
    (folder / "manifest.json").write_text(json.dumps({"invocations": [
        {"started": start.isoformat(), "finished": now.isoformat()}]}))
    return folder


def spec(scene: str, technique: str, *, frames=FRAMES, warmup=0, size=256) -> RunSpec:
    return RunSpec(scene, technique, {}, size, size, frames, warmup, 1)


def test_a_larger_scene_is_priced_by_its_triangles(tmp_path, capsys):
    """Stored: sm and sv on architecture at 10^3 and 10^4 triangles (sv 10.7 and 100.7 ms a
    frame). Planned: the same at 10^5: sv 1000.7 ms a frame, 5 frames, so about 5 s in all.
    Catches the estimate that priced each unseen run at the median stored run's share (tried:
    "about 0 s")."""
    stored = stored_folder(tmp_path / "stored")
    experiment = tmp_path / "big.yaml"
    experiment.write_text(f"scenes: [architecture]\ntriangles: [1e5]\nresolutions: [[256, 256]]\n"
                          f"frames: {FRAMES}\nwarmup: 0\ntechniques: {{sm: {{}}, sv: {{}}}}\n")
    assert main(["plan", str(experiment), "--scene-file", str(ROOT / "scenes.yaml"),
                 "--from", str(stored)]) == 0
    line = capsys.readouterr().out.splitlines()[-1]
    found = re.match(r"time: about (\d+) s for the 2 runs to render", line)
    assert found, line
    expected = FRAMES * (frame_ms("sv", 100_000) + frame_ms("sm", 100_000)) / 1e3
    assert abs(int(found[1]) - expected) <= 1, (line, expected)
    assert "0 as stored there, 2 priced by their scene's triangles and pixels" in line


def test_the_fit_finds_each_techniques_cost_per_triangle_and_per_pixel(tmp_path):
    """Three sizes and two image sizes: the fitted costs are COST's."""
    folder = stored_folder(tmp_path / "a", sizes=(1000, 4000, 20000))
    rows = results.read_rows(folder)
    rows += [{**r, "run_id": r["run_id"] + "b", "width": "128", "height": "128",
              "time_ms": str(COST[r["technique"]][0] * float(r["triangles"])
                             + COST[r["technique"]][1] * 128 * 128)} for r in rows]
    costs = est.frame_costs(rows)
    for technique, unit in COST.items():
        assert costs.per_unit[technique] == pytest.approx(unit, rel=1e-6, abs=1e-12)
        assert costs.how[technique] == "own"


def test_long_times_are_written_in_hours(tmp_path):
    """sv at 7.5 x 10^9 triangles: 75,000 s a frame, 5 frames: about 104 h 10 min, as hours
    and minutes. Catches the median-run estimate (tried: "about 0 s") and minutes past the
    hour (the old format would have said "6250 min 3 s")."""
    stored = stored_folder(tmp_path / "stored")
    plan = Plan([spec("huge", "sv")], {"huge": SimpleNamespace(triangles=range(7_500_000_000))},
                "x")
    line = plan_lines(plan, None, stored)[-1]
    assert line.startswith("time: about 104 h 10 min for the 1 runs"), line
    assert est.duration(59) == "59 s" and est.duration(61) == "1 min 1 s"
    assert est.duration(3600 * 104 + 12 * 60 + 20) == "104 h 12 min"


def test_one_scene_at_one_size_grows_half_by_triangles_half_by_pixels(tmp_path):
    """Stored: one scene at one size (its triangles and pixels cannot be told apart). A scene
    of 10x the triangles at the same size: half the time per triangle, half per pixel: 5.5x.
    A technique never stored is priced at the median stored technique's level."""
    stored = stored_folder(tmp_path / "stored", sizes=(1000,))
    rows, manifest = results.read_rows(stored), json.loads((stored / "manifest.json").read_text())
    one = est.estimate([spec("s", "sv")], {"s": 1000}, rows, manifest)
    ten = est.estimate([spec("s", "sv")], {"s": 10_000}, rows, manifest)
    assert ten.seconds == pytest.approx(5.5 * one.seconds, rel=1e-6)
    assert "half and half" in ten.how
    other = est.estimate([spec("s", "pcf")], {"s": 1000}, rows, manifest)
    level = (frame_ms("sm", 1000) + frame_ms("sv", 1000)) / 2  # the median of two
    assert other.seconds == pytest.approx(FRAMES * level / 1e3, rel=1e-4)
    assert "pcf not stored" in other.how


def test_a_stored_run_takes_its_own_time_and_the_pace_its_folders(tmp_path):
    """A planned run that is stored takes its own frame time; the folder's batches give the
    pace: here each batch took twice its frame work, so the estimate is twice the work."""
    folder = stored_folder(tmp_path / "stored")
    manifest = json.loads((folder / "manifest.json").read_text())
    rows = results.read_rows(folder)
    start = datetime.fromisoformat(manifest["invocations"][0]["started"])
    for row in rows:  # every finish twice as far from the start
        at = datetime.fromisoformat(row["finished_at"])
        row["finished_at"] = (start + 2 * (at - start)).isoformat(timespec="milliseconds")
    end = datetime.fromisoformat(manifest["invocations"][0]["finished"])
    manifest["invocations"][0]["finished"] = (start + 2 * (end - start)).isoformat()
    assert est.pace(rows, manifest) == pytest.approx((2.0, 0.0), abs=1e-2)  # ms stamps
    found = est.estimate([spec("architecture@1e4", "sv")], {}, rows, manifest)
    assert found.stored == 1 and found.modelled == 0
    assert found.seconds == pytest.approx(2 * FRAMES * frame_ms("sv", 10_000) / 1e3, rel=1e-2)
