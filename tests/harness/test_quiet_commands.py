"""No Python warning reaches the terminal (issue 47, friction 3): every command on a real small
folder, and ``results.load`` as the README's one-liner calls it, each in a process of its own
with Python's warnings shown (``-W default``, ``PYTHONWARNINGS=default``: pytest's own filters
would hide them), write nothing on stderr that a warning would."""

import re
import subprocess
import sys
import warnings

import pytest
import yaml
from helpers import ROOT, subprocess_env

# a shown warning: "file.py:53: PerformanceWarning: ..." or logging's "WARNING name: ..."
WARNING = re.compile(r"\b[A-Z]\w*Warning: |^WARNING ", re.M)


def shadowbench(*args, cwd=ROOT) -> subprocess.CompletedProcess:
    return subprocess.run([sys.executable, "-W", "default", "-m", "harness.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=300, cwd=cwd,
                          env=subprocess_env(PYTHONWARNINGS="default"))


@pytest.fixture(scope="module")
def folder(tmp_path_factory, shipped_scenes):
    """Every registered technique at its defaults on two shipped scenes at 64x64, one frame:
    its results have 120-odd columns, as make bench's have, which a frame typed column by
    column turns into one block each (pandas warns past 100)."""
    work = tmp_path_factory.mktemp("quiet")
    scenes = {}
    for name in ("box_plane", "sphere_plane"):
        scenes[name] = shipped_scenes[name].model_dump(mode="json") | {"resolution": [64, 64]}
    (work / "scenes.yaml").write_text(yaml.safe_dump({"scenes": scenes}))
    (work / "e.yaml").write_text(yaml.safe_dump({"techniques": "all", "frames": 1,
                                                 "warmup": 0, "reference": {"samples": 1}}))
    run = shadowbench("run", work / "e.yaml", "--scene-file", work / "scenes.yaml",
                      "--out", work / "out", "--quiet")
    assert run.returncode == 0, run.stderr
    return work, run


def assert_quiet(proc: subprocess.CompletedProcess, *, stderr_empty=True):
    assert proc.returncode in (0, 1), proc.stderr
    assert not WARNING.search(proc.stderr), proc.stderr
    if stderr_empty:
        assert proc.stderr == "", proc.stderr


def test_run_prints_no_warning(folder):
    """run's summary is on stdout; its stderr holds at most the noisy runs' warning line, no
    Python warning."""
    _, run = folder
    assert_quiet(run, stderr_empty=False)
    assert "runs in" in run.stdout


@pytest.mark.parametrize("command", ["list", "plan", "reference", "report", "compare"])
def test_a_command_prints_no_warning(folder, command):
    """Catches the report's worker processes printing pandas' PerformanceWarning (a frame
    fragmented by results.load) once per scene: the command's catching of warnings covered its
    own process only."""
    work, _ = folder
    out, scene_file = work / "out", work / "scenes.yaml"
    args = {"list": ["list", "--scene-file", scene_file],
            "plan": ["plan", work / "e.yaml", "--scene-file", scene_file, "--from", out],
            "reference": ["reference", "--scene", "box_plane", "--scene-file", scene_file,
                          "--out", out, "--samples", "1"],
            "report": ["report", out],
            "compare": ["compare", out, out]}[command]
    proc = shadowbench(*args)
    # reference and report show their progress on stderr
    assert_quiet(proc, stderr_empty=command not in ("reference", "report"))
    assert proc.stdout


def test_results_load_prints_no_warning(folder):
    """The README's one-liner. Catches results.load's own PerformanceWarning (its stale column
    added to a frame of one block per column)."""
    work, _ = folder
    proc = subprocess.run(
        [sys.executable, "-W", "default", "-c",
         "from harness import results; df = results.load('out'); df['x'] = 1; "
         "print(df[['technique', 'time_ms', 'edge_mae', 'wrong_pct']])"],
        capture_output=True, text=True, timeout=120, cwd=work,
        env=subprocess_env(PYTHONWARNINGS="default"))
    assert proc.returncode == 0, proc.stderr
    assert proc.stderr == "", proc.stderr
    assert "edge_mae" in proc.stdout


def test_a_worker_process_warning_comes_back_as_lines(monkeypatch):
    """What a report worker warns comes back as lines (for DIR/warnings.log), not printed:
    catches a worker that leaves Python's default (stderr) in place."""
    from harness import report

    def noisy(*args):
        warnings.warn("a library's warning in a worker", UserWarning)
        return {"scene": args}, ["a note"]

    monkeypatch.setattr(report, "scene_part", noisy)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # one that escaped the worker's catching raises here
        section, notes, lines = report.scene_part_quietly("x")
    assert section == {"scene": ("x",)} and notes == ["a note"]
    assert len(lines) == 1 and "UserWarning" in lines[0] and "in a worker" in lines[0]


def test_a_dask_worker_warning_comes_back_as_lines(monkeypatch):
    """What a Dask worker warns while it renders a task comes back with the task's rows (the
    client appends it to DIR/warnings.log), not printed on the worker's stderr, which is the
    terminal: catches run_on_worker without its catching."""
    from harness.run import distributed

    def noisy(specs, scene, platform):
        warnings.warn("a library's warning in a Dask worker", UserWarning)
        return ["rows"], "reference"

    monkeypatch.setattr(distributed, "_runs_on_worker", noisy)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        finished, reference, lines = distributed.run_on_worker([], None, None)
    assert (finished, reference) == (["rows"], "reference")
    assert len(lines) == 1 and "UserWarning" in lines[0] and "Dask worker" in lines[0]


def test_caught_lines_keep_warnings_and_log_records():
    import logging

    from harness.machine import warnings_log

    with warnings_log.Caught() as caught:
        warnings.warn("first", RuntimeWarning)
        logging.getLogger("trimesh").warning("a record")
    assert caught.lines[0].startswith("RuntimeWarning test_quiet_commands.py:")
    assert caught.lines[1] == "WARNING trimesh: a record"
