"""``shadowbench plan`` (issue 35): the runs a ``run`` would make, after duplicate points are
merged, grouped by scene and technique, with a time estimate from stored runs; rendering
nothing."""

import csv
import json
import re
from datetime import datetime

import pytest

from harness.cli import main
from helpers import ROOT

SCENES = str(ROOT / "scenes.yaml")

# sm's res curve (3 points) and pcf's two curves from res 256: res 256, 1024, 4096 at k 16 and
# k 1, 4, 16, 36 at res 256, where (res 256, k 16) comes twice: 3 + 7 - 1 = 9 runs
EXPERIMENT = """\
scenes: [box_plane]
techniques:
  sm: {curve: true}
  pcf: {curve: true, set: {res: 256}}
resolutions: [[32, 32]]
frames: 1
warmup: 0
reference: {samples: 1}
"""


def shadowbench(capsys, *args) -> tuple[int, str, str]:
    code = main([str(a) for a in args])
    captured = capsys.readouterr()
    return code, captured.out, captured.err


@pytest.fixture(scope="module")
def small_run(tmp_path_factory):
    """The experiment run for real: (experiment path, results folder)."""
    work = tmp_path_factory.mktemp("plan")
    experiment = work / "small.yaml"
    experiment.write_text(EXPERIMENT)
    assert main(["run", str(experiment), "--scene-file", SCENES, "--out", str(work / "out"),
                 "--quiet"]) == 0
    return experiment, work / "out"


def test_plan_counts_the_rows_a_run_writes(small_run, capsys):
    """plan says 9 runs (box_plane: sm 3, pcf 6) and the run wrote 9 rows; with --out the 9 are
    there already. Catches a plan that does not merge duplicate points (10 runs, sm 3, pcf 7).
    """
    experiment, out = small_run
    with (out / "results.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 9
    code, text, _ = shadowbench(capsys, "plan", experiment, "--scene-file", SCENES)
    assert code == 0
    assert text.splitlines()[:2] == [
        "9 runs (duplicate points merged) in 1 scenes, cost policy dynamic:",
        "  box_plane 32x32: 9 runs: sm 3, pcf 6"]
    code, text, _ = shadowbench(capsys, "plan", experiment, "--scene-file", SCENES, "--out", out)
    assert "9 of them in" in text.splitlines()[0] and f"every run is in {out} already" in text


def test_the_limit_counts_runs_after_duplicates_merge(small_run, capsys, tmp_path):
    """--max-runs 8 refuses the plan as 9 runs, the count a run makes. Catches the old count
    before merging ("plans 10 runs")."""
    experiment, _ = small_run
    code, _, err = shadowbench(capsys, "run", experiment, "--scene-file", SCENES, "--max-runs",
                               "8", "--out", tmp_path / "out")
    assert code == 2 and "plans 9 runs, more than the limit of 8" in err, err


def test_the_estimate_from_a_folder_of_the_same_runs_is_its_wall_time(small_run, capsys):
    """Every planned run is like one stored, at the same frames: their shares of the folder's
    wall time (its manifest's invocations) add up to all of it. Catches shares not normalised
    to the wall time, or runs not matched (the median for each)."""
    experiment, out = small_run
    manifest = json.loads((out / "manifest.json").read_text())
    wall = sum((datetime.fromisoformat(i["finished"]) - datetime.fromisoformat(i["started"]))
               .total_seconds() for i in manifest["invocations"])
    code, text, _ = shadowbench(capsys, "plan", experiment, "--scene-file", SCENES, "--from", out)
    assert code == 0
    line = text.splitlines()[-1]
    found = re.fullmatch(r"time: about (?:(\d+) min )?(\d+) s for the 9 runs to render, at the "
                         r"pace of the runs stored in .* \(9 as stored there, 0 priced by .*", line)
    assert found, line
    assert int(found[1] or 0) * 60 + int(found[2]) == round(wall)


def test_default_experiment_plans_563_runs(capsys):
    """experiments/default.yaml (make bench) plans 563 runs, and experiments/curves.yaml (every
    technique's curve on every scene, make bench's experiment until it outgrew its 8 minutes)
    711 (450 before the real corpus's 36, 486 before rt's 40, 526 before ptsv's 25, 551
    before ptsv's full mask on architecture, foliage and crowd, 554 before vsm's 52 and izb's
    40, 646 before the five alpha-tested scenes' 65, every technique at its defaults), as
    README and the experiments say, with the built-ins alone installed. Catches a plan that
    does not merge duplicate points (508 before the corpus)."""
    code, text, _ = shadowbench(capsys, "plan", ROOT / "experiments" / "curves.yaml")
    assert code == 0
    assert text.splitlines()[0].startswith("711 runs (duplicate points merged) in 21 scenes")
    code, text, _ = shadowbench(capsys, "plan", ROOT / "experiments" / "default.yaml")
    assert code == 0
    print(text.splitlines()[0])
    assert text.splitlines()[0].startswith("563 runs (duplicate points merged) in 21 scenes")
