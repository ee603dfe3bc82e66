"""Dask sweeps: the same records as a serial run, resumable when the client or a worker dies."""

import csv
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml
from helpers import rows_by_run_id

EXE = str(Path(sys.executable).with_name("shadowbench"))
SAME = ("run_id", "scene", "technique", "params", "width", "height", "mae", "rmse", "wrong_pct",
        "edge_mae", "levels", "ssim", "psnr", "nonfinite", "status", "frags_scene",
        "frags_shadow", "mem_bytes", "fetches_per_px", "array", "vertex_invocations",
        "fragment_invocations", "primitives", "covered_px", "gpu_estimate_ms")


@pytest.fixture
def sweep(tmp_path, small_scene_file):
    scene_file = small_scene_file("box_plane", "sphere_plane", "pins")
    experiment = tmp_path / "sweep.yaml"
    experiment.write_text(yaml.safe_dump({
        "scene_file": str(scene_file), "scenes": "all", "frames": 1, "warmup": 0,
        "techniques": {"sm": {"product": {"res": [256, 512]}},
                       "pcf": {"product": {"k": [1, 4, 9]}},
                       "sv": {}}}))
    return experiment


def _run(args, **kw):
    return subprocess.run([EXE, "run", *args, "--quiet"], capture_output=True, text=True,
                          timeout=600, **kw)


def test_dask_gives_the_serial_records(sweep, tmp_path, gl_context):
    from harness import cli

    serial, dask = tmp_path / "serial", tmp_path / "dask"
    assert cli.main(["run", str(sweep), "--out", str(serial), "--quiet"]) == 0  # this process
    proc = _run([str(sweep), "--out", str(dask), "--executor", "dask", "--workers", "2"])
    assert proc.returncode == 0, proc.stderr
    a, b = rows_by_run_id(serial), rows_by_run_id(dask)
    assert len(a) == 18 and a.keys() == b.keys()
    for run_id in a:
        for column in SAME:
            assert a[run_id][column] == b[run_id][column], (column, a[run_id], b[run_id])
        with np.load(serial / a[run_id]["array"]) as x, np.load(dask / b[run_id]["array"]) as y:
            assert np.array_equal(x["visibility"], y["visibility"])
    assert len({r["worker"] for r in b.values()}) == 2  # both workers rendered


def _wait_for_rows(out, count, proc, timeout=300):
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline:
        if (out / "results.csv").is_file() and len(rows_by_run_id(out)) >= count:
            return
        assert proc.poll() is None, proc.communicate()
        time.sleep(0.2)
    raise AssertionError("no rows appeared")


def test_killed_worker_the_sweep_completes(sweep, tmp_path):
    import psutil

    out = tmp_path / "dask"
    proc = subprocess.Popen([EXE, "run", str(sweep), "--out", str(out), "--executor", "dask",
                             "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True)
    _wait_for_rows(out, 1, proc)
    # LocalCluster's nannies live in the client; each worker is a spawned child process
    workers = [p for p in psutil.Process(proc.pid).children(recursive=True)
               if "spawn_main" in " ".join(p.cmdline())]
    assert workers, "no worker processes found"
    workers[0].send_signal(signal.SIGKILL)
    _, err = proc.communicate(timeout=600)
    assert proc.returncode == 0, err
    rows = rows_by_run_id(out)
    assert len(rows) == 18 and all(r["status"] == "ok" for r in rows.values())


def test_killed_client_resumes_without_loss_or_duplicates(sweep, tmp_path):
    # longer runs, so the kill lands while most of the sweep is still to do
    sweep.write_text(sweep.read_text().replace("frames: 1", "frames: 12"))
    out = tmp_path / "dask"
    proc = subprocess.Popen([EXE, "run", str(sweep), "--out", str(out), "--executor", "dask",
                             "--quiet"], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, start_new_session=True)
    _wait_for_rows(out, 2, proc)
    os.killpg(proc.pid, signal.SIGKILL)  # the client and its cluster, mid-sweep
    proc.wait()
    before = rows_by_run_id(out)
    assert 2 <= len(before) < 18
    again = _run([str(sweep), "--out", str(out), "--executor", "dask"])
    assert again.returncode == 0, again.stderr
    with (out / "results.csv").open() as f:
        ids = [r["run_id"] for r in csv.DictReader(f)]
    assert len(ids) == len(set(ids)) == 18
    after = rows_by_run_id(out)
    # finished rows untouched (later rows may add columns, empty for them)
    assert all(after[k][c] == v[c] for k, v in before.items() for c in v)


def test_threaded_external_workers_are_refused(sweep, tmp_path):
    from distributed import LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=True,
                      dashboard_address=None) as cluster:
        proc = _run([str(sweep), "--out", str(tmp_path / "x"), "--executor", "dask",
                     "--scheduler", cluster.scheduler_address])
    assert proc.returncode == 2
    assert "--nthreads 1" in proc.stderr


def test_a_task_is_a_piece_of_one_scene_and_resolution():
    """A worker can interleave only the runs one task gives it: each task holds runs of one
    scene and resolution, at most TASK_RUNS of them, in near-equal pieces; every run once.

    Catches: one task per run (nothing to interleave), or tasks mixing resolutions (a worker
    would switch frames inside its rounds)."""
    from harness.run.distributed import TASK_RUNS, tasks_of
    from harness.run import RunSpec

    specs = ([RunSpec("a", "sm", {"res": 16 * (i + 1)}, 64, 48, 15, 2, 16) for i in range(20)]
             + [RunSpec("a", "sm", {"res": 16}, 128, 96, 15, 2, 16)]
             + [RunSpec("b", "pcf", {"k": k}, 64, 48, 15, 2, 16) for k in (1, 4, 9)])
    tasks = tasks_of(specs)
    assert sorted(len(t) for t in tasks) == [1, 3, 6, 7, 7]
    assert all(len(t) <= TASK_RUNS for t in tasks)
    assert all(len({(s.scene, s.width, s.height) for s in t}) == 1 for t in tasks)
    assert sorted(s.run_id for t in tasks for s in t) == sorted(s.run_id for s in specs)
