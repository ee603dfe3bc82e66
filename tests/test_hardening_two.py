"""Hardening, round two (issue 25): special files, run-count bombs, duplicates, --out messages,
the alias bomb's line, git's optional locks, ETA of long runs and warnings kept off the
terminal. The mesh-file rows are in test_mesh_files.py. Each test failed on the code before
issue 25 (its docstring says how)."""

from __future__ import annotations

import os
import socket
import subprocess
import sys
import time
from pathlib import Path
from unittest import mock

import numpy as np
import pytest
import yaml

from harness import config
from harness import run as runner
from harness.run import manifest
from test_config import GOOD
from test_hardening import ROOT, assert_one_line, run_cli, subprocess_env, sweep, write_scenes


def _cli_subprocess(args, timeout=60) -> tuple[int, list[str]]:
    proc = subprocess.run([sys.executable, "-m", "harness.cli", *map(str, args)],
                          capture_output=True, text=True, timeout=timeout, cwd=ROOT,
                          env=subprocess_env())
    return proc.returncode, proc.stderr.strip().splitlines()


@pytest.mark.parametrize("which", ["scene file", "experiment"])
def test_a_fifo_as_scene_file_or_experiment_is_refused_at_once(which, tmp_path):
    """Before: open() of a FIFO with no writer blocked for ever (here: the 60 s timeout)."""
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    args = (sweep(fifo, tmp_path / "out") if which == "scene file"
            else ["run", fifo, "--scene-file", write_scenes(tmp_path, {"s": GOOD}), "--out",
                  tmp_path / "out", "--quiet"])
    started = time.monotonic()
    code, err = _cli_subprocess(args)
    assert_one_line(code, err, 2, str(fifo), "not a regular file: it is a FIFO")
    assert time.monotonic() - started < 30
    assert not (tmp_path / "out").exists()


def test_a_socket_or_folder_as_scene_file_says_what_it_is(tmp_path, capsys):
    """Before: a folder said 'cannot read: Is a directory', a socket 'No such device'."""
    path = tmp_path / "sock.yaml"
    server = socket.socket(socket.AF_UNIX)
    server.bind(str(path))
    try:
        code, err = run_cli(sweep(path, tmp_path / "out"), capsys)
        assert_one_line(code, err, 2, "not a regular file: it is a socket")
    finally:
        server.close()
    code, err = run_cli(sweep(tmp_path, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "not a regular file: it is a folder")


def _curve_experiment(tmp_path, values: int, **more) -> Path:
    path = tmp_path / "e.yaml"
    path.write_text(yaml.safe_dump({"scenes": ["s"], "techniques": {
        "sm": {"curve": {"res": [64 + i for i in range(values)]}}}, **more}))
    return path


def _plan_only(args, capsys):
    planned = []
    with mock.patch.object(runner, "execute", lambda plan, *a, **k: planned.append(plan) or 0), \
            mock.patch.object(runner, "read_manifest",
                              lambda out: {"invocations": [{"runs_rendered": 0}]}):
        code, err = run_cli(args, capsys)
    return code, err, planned


def test_a_run_count_bomb_is_refused_with_the_count_and_how_to_raise_it(tmp_path, capsys):
    """Before: a curve of 10,000 res values planned 10,000 runs silently (hours of work)."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    started = time.monotonic()
    code, err, planned = _plan_only(["run", _curve_experiment(tmp_path, 10_000), "--scene-file",
                                     scene_file, "--out", tmp_path / "out"], capsys)
    assert_one_line(code, err, 2, "10,000 runs", "5,000", "max_runs:", "--max-runs")
    assert not planned and not (tmp_path / "out").exists()
    assert time.monotonic() - started < 10


def test_max_runs_in_the_experiment_and_on_the_command_line(tmp_path, capsys):
    """The limit is the experiment's max_runs, and --max-runs replaces it."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    experiment = _curve_experiment(tmp_path, 3, max_runs=2)
    code, err, _ = _plan_only(["run", experiment, "--scene-file", scene_file, "--out",
                               tmp_path / "out"], capsys)
    assert_one_line(code, err, 2, "plans 3 runs, more than the limit of 2")
    code, err, planned = _plan_only(["run", experiment, "--scene-file", scene_file, "--out",
                                     tmp_path / "out", "--max-runs", "3"], capsys)
    assert code == 0, err
    assert len(planned[0].runs) == 3


def test_a_scene_listed_twice_names_both_positions(tmp_path, capsys):
    """Before: silently deduplicated."""
    scene_file = write_scenes(tmp_path, {"s": GOOD, "t": GOOD})
    experiment = tmp_path / "e.yaml"
    experiment.write_text("scenes:\n- s\n- t\n- s\ntechniques:\n  sm:\n")
    code, err, planned = _plan_only(["run", experiment, "--scene-file", scene_file, "--out",
                                     tmp_path / "out"], capsys)
    assert_one_line(code, err, 2, f"{experiment}:4: scenes.2", "'s' is listed twice",
                    f"{experiment}:2 (scenes.0)", f"{experiment}:4 (scenes.2)")
    assert not planned


@pytest.mark.parametrize("option, value", [("--techniques", "sm,pcf,sm"),
                                           ("--scenes", "s,s")])
def test_a_name_given_twice_on_the_command_line(option, value, tmp_path, capsys):
    """Before: deduplicated silently."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, err = run_cli(["run", "--scene-file", scene_file, option, value, "--out",
                         tmp_path / "out", "--quiet"], capsys)
    assert_one_line(code, err, 2, option, "more than once")


@pytest.mark.parametrize("out", ["a file", "/proc/self/out", "/sys/out"])
def test_every_out_problem_names_out(out, tmp_path, capsys):
    """Before: '/proc/self/.lock: No such file or directory', and a file's message named only
    the path."""
    if out == "a file":
        out = tmp_path / "f"
        out.write_text("x")
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), out), capsys)
    assert_one_line(code, err, 2, f"--out {out}")


def test_the_alias_bombs_message_gives_its_line(tmp_path):
    """Before: '...: its aliases expand to more than 1,000,000 values', no line."""
    path = tmp_path / "scenes.yaml"
    path.write_text("a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n" + "".join(
        f"{x}: &{x} [{', '.join(['*' + p] * 10)}]\n" for p, x in zip("abcdefgh", "bcdefghi")))
    with pytest.raises(config.ConfigError, match=rf"^{path}:6: .*more than 1,000,000"):
        config.load_scenes(path)


def test_the_manifest_runs_git_without_optional_locks(monkeypatch):
    """Before: `git status` took .git/index.lock, colliding with the user's git commands."""
    commands = []

    def fake_run(argv, **kwargs):
        commands.append(argv)
        return subprocess.CompletedProcess(argv, 0, stdout="", stderr="")

    monkeypatch.setattr(manifest.subprocess, "run", fake_run)
    manifest._git_commit()
    manifest._git_dirty()
    git = [argv for argv in commands if argv[0] == "git"]
    assert len(git) == 2
    assert all(argv[1] == "--no-optional-locks" for argv in git), git


# --- estimates for long runs -------------------------------------------------------------------

class _FakeBar:
    def __init__(self, total: int):
        self.total, self.n, self.postfix, self.refreshed = total, 0, "", 0

    def set_postfix_str(self, text, refresh=True):
        self.postfix = text

    def refresh(self):
        self.refreshed += 1

    def update(self, n):
        self.n += n

    def set_description_str(self, text):
        pass


def test_a_moving_runs_estimate_comes_with_its_first_frame_and_follows_its_frames(monkeypatch):
    """Before: a 1000-frame run had no estimate until it ended (the ETA counted runs, and
    'about 0:10 left' stayed for 47 s)."""
    from harness.run import sweep
    from harness.run.plan import RunSpec

    now = [100.0]
    monkeypatch.setattr(sweep.time, "monotonic", lambda: now[0])
    moving = RunSpec("s", "sm", {}, 64, 64, frames=1000, warmup=0, samples=1)
    still = RunSpec("t", "sm", {}, 64, 64, frames=15, warmup=2, samples=1)
    bar = _FakeBar(total=2)
    progress = sweep._Progress(bar, [moving, still])
    now[0] += 2.0
    progress.frame_done([moving])  # 1 of 1017 frames in 2 s: 2032 s left
    assert bar.postfix == "2 to go, about 0:33:52 left"
    assert bar.refreshed == 1
    now[0] += 2.0
    progress.frame_done([moving])
    assert bar.postfix == "2 to go, about 0:33:50 left"
    progress.run_done(moving, {"status": "ok"})
    assert (bar.n, progress.left) == (1, sweep._cost(still))


def test_a_moving_scene_reports_each_frame_to_the_progress(tmp_path, gl_context, monkeypatch,
                                                          capsys):
    """The serial renderer calls the progress once per frame of a moving scene's sequence."""
    from harness.run import sweep

    frames = []
    monkeypatch.setattr(sweep._Progress, "frame_done",
                        lambda self, specs: frames.append([s.technique for s in specs]))
    scene_file = write_scenes(tmp_path, {"s": {**GOOD, "motion": {"frames": 4,
                                                                  "camera_orbit": 20}}})
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({"techniques": {"sm": None, "pcf": None},
                                          "reference": {"samples": 1}}))
    code, err = run_cli(["run", experiment, "--scene-file", scene_file, "--out",
                         tmp_path / "out", "--quiet"], capsys)
    assert code == 0, err
    assert [sorted(f) for f in frames] == [["pcf", "sm"]] * 4


# --- no stray output ---------------------------------------------------------------------------

def test_library_warnings_go_to_the_log_and_a_runs_own_into_its_row(tmp_path, gl_context,
                                                                   monkeypatch, capsys):
    """Before: any library warning (trimesh's, scikit-image's psnr) was printed among the
    progress lines."""
    import logging
    import warnings

    from harness import metrics
    from harness.run import plan as planning
    from test_hardening import _rows, _small_run

    build = planning.build_scene

    def noisy_build(*args, **kwargs):
        warnings.warn("a library's planning warning", RuntimeWarning)
        logging.getLogger("trimesh").warning("a library's log record")
        return build(*args, **kwargs)

    psnr = metrics.psnr

    def noisy_psnr(*args, **kwargs):
        warnings.warn("psnr divide by zero", RuntimeWarning)
        return psnr(*args, **kwargs)

    monkeypatch.setattr(planning, "build_scene", noisy_build)
    monkeypatch.setattr(metrics, "psnr", noisy_psnr)
    code, err = run_cli(_small_run(tmp_path), capsys)
    assert code == 0, err
    assert not any(text in line for line in err for text in ("planning warning", "log record",
                                                               "divide")), err
    log = (tmp_path / "out" / "warnings.log").read_text()
    assert "RuntimeWarning test_hardening_two.py" in log
    assert "a library's planning warning" in log
    assert "WARNING trimesh: a library's log record" in log
    (row,) = _rows(tmp_path / "out")
    assert row["warnings"] == "RuntimeWarning: psnr divide by zero"


def test_psnr_of_identical_images_is_inf_without_a_warning():
    """Before: scikit-image's 'divide by zero encountered' RuntimeWarning."""
    import warnings

    from harness import metrics

    v = np.linspace(0, 1, 64, dtype=np.float32).reshape(8, 8)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert metrics.psnr(v, v) == float("inf")
    assert metrics.psnr(v, np.clip(v + 0.1, 0, 1)) == pytest.approx(
        10 * np.log10(1 / np.mean((np.clip(v + 0.1, 0, 1) - v) ** 2)))
