"""Faults and interrupts: a scene failing mid-sweep, unexpected exceptions, an unreachable
scheduler, a full disk, kills and Ctrl-C, damaged arrays, progress of long runs and warnings
kept off the terminal. Each test names the broken code it catches."""

from __future__ import annotations

import json
import signal
import socket
import subprocess
import time
from pathlib import Path

import yaml
from helpers import (
    GOOD,
    PY,
    assert_one_line,
    needs_tmpfs,
    result_rows,
    run_cli,
    scene_with,
    small_run,
    subprocess_env,
    sweep,
    write_scenes,
)

from harness import cli, results
from harness.machine import interrupt
from harness import run as runner


def test_a_scene_that_fails_mid_sweep_gives_error_rows_and_the_sweep_goes_on(
        tmp_path, monkeypatch, capsys, gl_context):
    """Catches: render_serial letting a scene's reference failure end the sweep. Before: the
    RuntimeError ended everything (no rows for the other scene; a traceback)."""
    from harness.truth import reference

    traced = reference.compute_reference

    def compute_reference(scene, **kw):
        if scene.name == "bad":
            raise RuntimeError("[Mesh] Mitsuba cannot trace this scene")
        return traced(scene, **kw)

    monkeypatch.setattr(reference, "compute_reference", compute_reference)
    scene_file = write_scenes(tmp_path, {"bad": GOOD, "good": GOOD})
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(scene_file), "--techniques", "sm,pcf", "--out",
                     str(out), "--quiet"])
    summary = capsys.readouterr().out.splitlines()
    assert code == 1
    status = {(r["scene"], r["technique"]): (r["status"], r["error"]) for r in result_rows(out)}
    assert status[("good", "sm")] == ("ok", "") and status[("good", "pcf")] == ("ok", "")
    for technique in ("sm", "pcf"):
        state, error = status[("bad", technique)]
        assert state == "error" and "Mitsuba cannot trace this scene" in error
    assert json.loads((out / "manifest.json").read_text())["status"] == "complete"
    assert any("failed: bad sm" in line for line in summary)
    # a rerun retries the failed scene: it traces now
    monkeypatch.setattr(reference, "compute_reference", traced)
    assert cli.main(["run", "--scene-file", str(scene_file), "--techniques", "sm,pcf",
                     "--out", str(out), "--quiet"]) == 0


def test_an_unexpected_exception_prints_its_traceback_under_a_line_asking_to_report(
        tmp_path, monkeypatch, capsys):
    """Catches: a handler that swallows bugs into one line (or lets them out bare)."""
    def plan_runs(**kw):
        return 1 / 0

    monkeypatch.setattr(runner, "plan_runs", plan_runs)
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), tmp_path / "out"), capsys)
    assert code == 1
    assert "internal error" in err[0] and "report" in err[0]
    assert err[1].startswith("Traceback") and err[-1] == "ZeroDivisionError: division by zero"


def test_an_unreachable_scheduler_fails_within_seconds(tmp_path, capsys):
    """Catches: Dask's default 30 s connect timeout and its OSError traceback."""
    with socket.socket() as s:  # a port nothing listens on
        s.bind(("127.0.0.1", 0))
        address = f"tcp://127.0.0.1:{s.getsockname()[1]}"
    started = time.monotonic()
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), tmp_path / "out",
                              "--executor", "dask", "--scheduler", address), capsys)
    from harness.run.distributed import SCHEDULER_TIMEOUT_S

    assert time.monotonic() - started < SCHEDULER_TIMEOUT_S + 10
    assert_one_line(code, err, 2, f"--scheduler {address}")
    assert not (tmp_path / "out").exists()


@needs_tmpfs
def test_a_full_disk_is_one_line_and_the_manifest_says_failed(tmp_path):
    """Catches: raw ENOSPC with no file named, and the manifest left 'running' (its final
    write needs space too: the space reserve gives it). Before: an OSError traceback."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "techniques": {"sm": {"product": {"res": list(range(64, 4096, 16))}}},
        "resolutions": [[256, 256]], "frames": 1, "warmup": 0, "reference": {"samples": 1}}))
    (tmp_path / "small").mkdir()
    out = tmp_path / "small" / "out"
    script = (f"mount -t tmpfs -o size=150k none {tmp_path}/small && {PY} -m harness.cli run "
              f"{experiment} --scene-file {scene_file} --out {out} --quiet; echo EXIT=$?; "
              f"cat {out}/manifest.json")
    proc = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True,
                          text=True, timeout=600, env=subprocess_env())
    exit_line, _, manifest = proc.stdout.partition("\n")
    err = proc.stderr.strip().splitlines()
    assert_one_line(int(exit_line.removeprefix("EXIT=")), err, 1, str(out),
                    "No space left on device")
    assert json.loads(manifest)["status"] == "failed"


def test_a_kill_while_a_dask_cluster_starts_writes_nothing(tmp_path):
    """Catches: the sweep writing its manifest before the cluster is up, and an interrupted
    cluster start failing in Dask's exit handler. Before: SIGTERM left the manifest
    'running' (and took 6 s)."""
    import psutil

    out = tmp_path / "out"
    proc = subprocess.Popen([PY, "-m", "harness.cli", *sweep(write_scenes(tmp_path, {"s": GOOD}),
                                                             out, "--executor", "dask")],
                            stderr=subprocess.PIPE, text=True, env=subprocess_env(),
                            start_new_session=True)
    parent = psutil.Process(proc.pid)
    deadline = time.monotonic() + 120
    workers = []
    while not workers and time.monotonic() < deadline and proc.poll() is None:
        try:
            workers = [p for p in parent.children(recursive=True)
                       if "spawn_main" in " ".join(p.cmdline())]
        except psutil.Error:
            pass
        time.sleep(0.02)
    assert workers, "no worker process started"
    children = parent.children(recursive=True)
    signalled = time.monotonic()
    proc.send_signal(signal.SIGTERM)
    while proc.poll() is None and time.monotonic() - signalled < 30:
        time.sleep(0.02)
    stopped = time.monotonic() - signalled
    err = proc.communicate(timeout=60)[1]
    assert proc.returncode == interrupt.EXIT_CODE, err
    assert stopped < interrupt.GRACE_S + 1.5
    assert "Traceback" not in err and interrupt.MESSAGE in err
    assert not out.exists()
    time.sleep(1)
    assert not [c for c in children if c.is_running() and c.status() != psutil.STATUS_ZOMBIE]


def test_the_next_run_heals_what_a_kill_left(tmp_path, gl_context):
    """What a SIGKILL leaves, rebuilt by hand: an invocation still 'running', temporary files
    (this version's and older ones' names), a truncated array and a missing one. The next run
    marks the invocation interrupted, removes the temporaries, and renders again the runs
    whose arrays are damaged. Catches: each of these left as it was. Before: 'running' stayed,
    *.tmp.npz stayed, and the damaged runs counted as done (the report then failed on them)."""
    args = small_run(tmp_path, "sm", "pcf", "silhouette")
    assert cli.main(args) == 0
    out = tmp_path / "out"
    manifest = json.loads((out / "manifest.json").read_text())
    killed = {**manifest["invocations"][0], "id": "0badf00d", "status": "running",
              "started": "2000-01-01T00:00:00+00:00", "finished": None}
    manifest["invocations"].insert(0, killed)
    (out / "manifest.json").write_text(json.dumps(manifest))
    rows = {r["technique"]: r for r in result_rows(out)}
    truncated, missing = out / rows["sm"]["array"], out / rows["pcf"]["array"]
    truncated.write_bytes(truncated.read_bytes()[:100])
    missing.unlink()
    folder = truncated.parent
    stale = [folder / "tmpab12cd.tmp.npz", folder / f".{truncated.name}.0a1b2c3d.tmp",
             out / ".results.csv.tmp", out / ".manifest.json.tmp",
             out / ".results.csv.0a1b2c3d.tmp"]
    for path in stale:
        path.write_bytes(b"PK\x03\x04partial")
    assert cli.main(args) == 0
    statuses = [i["status"] for i in json.loads((out / "manifest.json").read_text())
                ["invocations"]]
    assert statuses == ["interrupted", "complete", "complete"]
    assert not [p for p in stale if p.exists()]
    assert not (out / runner.SPACE_RESERVE).exists()
    again = {r["technique"]: r for r in result_rows(out)}
    assert {r["status"] for r in again.values()} == {"ok"}
    for technique in ("sm", "pcf"):
        assert results.readable_npz(out / again[technique]["array"])
    assert again["silhouette"]["finished_at"] == rows["silhouette"]["finished_at"]  # not redone


def test_damaged_arrays_of_runs_not_in_this_plan_become_error_rows(tmp_path, gl_context):
    """Another experiment's run into the same folder marks a damaged run failed (rather than
    leaving an 'ok' row whose array the report cannot read)."""
    args = small_run(tmp_path, "sm", "pcf")
    assert cli.main(args) == 0
    out = tmp_path / "out"
    rows = {r["technique"]: r for r in result_rows(out)}
    (out / rows["pcf"]["array"]).unlink()
    assert cli.main(small_run(tmp_path, "sm")) == 0
    pcf = {r["technique"]: r for r in result_rows(out)}["pcf"]
    assert pcf["status"] == "error" and rows["pcf"]["array"] in pcf["error"]


CTRL_C = """
import os, signal, sys, threading, time
from harness import cli
from harness import run as runner
start = threading.Event()
def interrupt():
    start.wait()
    time.sleep({delay})
    print("SIGINT", time.monotonic(), file=sys.stderr, flush=True)
    os.kill(os.getpid(), signal.SIGINT)
threading.Thread(target=interrupt, daemon=True).start()
{patch}
sys.argv[1:] = {args!r}
sys.exit(cli.main())
"""


def _interrupted(args, delay, patch="start.set()"):
    """Run the CLI in a child that sends itself SIGINT ``delay`` s after ``patch`` sets
    ``start``; its return code, the seconds from the signal to its exit, its stderr lines."""
    script = CTRL_C.format(delay=delay, args=[str(a) for a in args], patch=patch)
    proc = subprocess.Popen([PY, "-c", script], stderr=subprocess.PIPE, text=True,
                            env=subprocess_env())
    try:
        _, err = proc.communicate(timeout=300)
    finally:
        proc.kill()
    ended = time.monotonic()
    lines = err.strip().splitlines()
    signalled = next(float(line.split()[1]) for line in lines if line.startswith("SIGINT"))
    return proc.returncode, ended - signalled, lines


def test_ctrl_c_stops_when_a_library_swallows_it(tmp_path):
    """While the scene's spheres are built, the fifth icosphere gets Ctrl-C inside an
    ``except BaseException: pass``, as in trimesh's 144 such places (some in its icosphere and
    optional imports); each later sphere takes 50 ms. Catches: a stop that relies on the
    KeyboardInterrupt (the sweep ran on to its end) and one that waits for the watcher (no
    re-raise after the library call, in scene.build_parts)."""
    spheres = [{"shape": "sphere", "radius": 0.05, "subdivisions": 4,
                "translate": [0.12 * (i % 20) - 1.2, 0.12 * (i // 20) - 0.6, 1]}
               for i in range(40)]
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects=GOOD["objects"] + spheres)})
    patch = ("import trimesh\n"
             "icosphere, calls = trimesh.creation.icosphere, []\n"
             "def swallowing(*a, **k):\n"
             "    calls.append(1)\n"
             "    try:\n"
             "        if len(calls) == 5:\n"
             "            print('SIGINT', time.monotonic(), file=sys.stderr, flush=True)\n"
             "            os.kill(os.getpid(), signal.SIGINT)\n"
             "        time.sleep(0.05)\n"
             "    except BaseException:\n"
             "        pass\n"
             "    return icosphere(*a, **k)\n"
             "trimesh.creation.icosphere = swallowing\n")
    code, seconds, err = _interrupted(sweep(scene_file, tmp_path / "out"), delay=0,
                                      patch=patch)
    assert code == interrupt.EXIT_CODE, err
    assert seconds < interrupt.GRACE_S, err  # stopped at a safe point, not by the watcher
    assert err[-1] == interrupt.MESSAGE


def test_ctrl_c_stops_a_library_that_never_lets_go(tmp_path):
    """A 'library' that catches BaseException for ever (in the reference's place): the
    watcher ends the process GRACE_S after the signal. Catches: a stop that relies on the
    main thread reaching a safe point."""
    patch = ("import harness.truth.reference as r\n"
             "def stubborn(*a, **k):\n"
             "    start.set()\n"
             "    while True:\n"
             "        try:\n"
             "            time.sleep(0.01)\n"
             "        except BaseException:\n"
             "            pass\n"
             "r.compute_reference = stubborn\n")
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, seconds, err = _interrupted(sweep(scene_file, tmp_path / "out"), delay=0.1,
                                      patch=patch)
    assert code == interrupt.EXIT_CODE, err
    assert interrupt.GRACE_S <= seconds < interrupt.GRACE_S + 1.0, err
    assert err[-1] == interrupt.MESSAGE


def test_ctrl_c_keeps_every_run_whose_frames_are_done_and_a_rerun_does_the_rest(tmp_path):
    """Issue 47, friction 5: a real run of two scenes of six runs, SIGINT as soon as the first
    row is stored. The six runs of the first scene are interleaved in one batch and finish
    their frames in the same round: all six are stored, whole, and the manifest counts them;
    a rerun renders the second scene's six and leaves the first six as they were. Catches a
    sweep that lets Ctrl-C land between the stores of runs already done (before: 1 or 2 of
    the 6 stored, the other runs' frames thrown away)."""
    scene_file = write_scenes(tmp_path, {"a": scene_with(resolution=[64, 64]),
                                         "b": scene_with(resolution=[64, 64])})
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "techniques": {"sm": {"product": {"res": [64, 128, 256]}},
                       "pcf": {"product": {"k": [1, 4, 9]}}},
        "frames": 2, "warmup": 0, "reference": {"samples": 1}}))
    out = tmp_path / "out"
    args = ["-m", "harness.cli", "run", str(experiment), "--scene-file", str(scene_file),
            "--out", str(out)]
    proc = subprocess.Popen([PY, *args], stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                            text=True, env=subprocess_env())
    deadline = time.monotonic() + 120
    while proc.poll() is None and not (out / "results.csv").exists() and time.monotonic() < deadline:
        time.sleep(0.002)
    proc.send_signal(signal.SIGINT)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode == interrupt.EXIT_CODE, err
    assert err.splitlines()[-1] == interrupt.MESSAGE
    stored = result_rows(out)
    assert sorted(r["scene"] for r in stored) == ["a"] * 6, [r["technique"] for r in stored]
    for row in stored:
        assert row["status"] == "ok" and row["time_ms"] and row["finished_at"]
        assert results.readable_npz(out / row["array"])
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "interrupted"
    assert manifest["invocations"][-1]["runs_rendered"] == 6

    rerun = subprocess.run([PY, *args, "--quiet"], capture_output=True, text=True, timeout=300,
                           env=subprocess_env())
    assert rerun.returncode == 0, rerun.stderr
    assert "12 runs in" in rerun.stdout and "6 rendered now, 6 already done" in rerun.stdout
    after = {r["run_id"]: r for r in result_rows(out)}
    assert len(after) == 12
    assert all(after[r["run_id"]] == r for r in stored)  # not redone


def test_a_moving_runs_estimate_comes_with_its_first_frame_and_follows_its_frames(monkeypatch):
    """Before: a 1000-frame run had no estimate until it ended (the ETA counted runs, and
    'about 0:10 left' stayed for 47 s)."""
    import io

    from harness.run import progress as shown
    from harness.run import sweep
    from harness.run.plan import RunSpec

    now = [100.0]
    monkeypatch.setattr(shown.time, "monotonic", lambda: now[0])
    moving = RunSpec("s", "sm", {}, 64, 64, frames=1000, warmup=0, samples=1)
    still = RunSpec("t", "sm", {}, 64, 64, frames=15, warmup=2, samples=1)
    progress = sweep.RunProgress(2, [moving, still], stream=io.StringIO(), terminal=False)
    now[0] += 2.0
    progress.frame_done([moving])  # 1 of 1017 frames in 2 s: 2032 s left
    assert progress.postfix() == "2 to go, about 0:33:52 left"
    now[0] += 2.0
    progress.frame_done([moving])
    assert progress.postfix() == "2 to go, about 0:33:50 left"
    progress.run_done(moving, {"status": "ok"})
    assert (progress.n, progress.left) == (1, sweep._cost(still))


def test_a_moving_scene_reports_each_frame_to_the_progress(tmp_path, gl_context, monkeypatch,
                                                          capsys):
    """The serial renderer calls the progress once per frame of a moving scene's sequence."""
    from harness.run import sweep

    frames = []
    monkeypatch.setattr(sweep.RunProgress, "frame_done",
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


def test_library_warnings_go_to_the_log_and_a_runs_own_into_its_row(tmp_path, gl_context,
                                                                   monkeypatch, capsys):
    """Before: any library warning (trimesh's, scikit-image's psnr) was printed among the
    progress lines."""
    import logging
    import warnings

    from helpers import result_rows, small_run

    from harness.truth import metrics
    from harness.run import scene_set as planning

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
    code, err = run_cli(small_run(tmp_path), capsys)
    assert code == 0, err
    assert not any(text in line for line in err for text in ("planning warning", "log record",
                                                               "divide")), err
    log = (tmp_path / "out" / "warnings.log").read_text()
    assert f"RuntimeWarning {Path(__file__).name}" in log
    assert "a library's planning warning" in log
    assert "WARNING trimesh: a library's log record" in log
    (row,) = result_rows(tmp_path / "out")
    assert row["warnings"] == "RuntimeWarning: psnr divide by zero"
