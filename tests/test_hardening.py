"""Hostile input and a hostile machine (issue 16): every bad input is exit 2 with one line and
nothing written, every path stays inside --out, every expected failure is one line, folders
heal after kills, and Ctrl-C stops the command.

Each test names, in its docstring, the broken code it catches. The fixture
``hostile_results`` (a results folder whose rows carry hostile scene and technique names, with
their arrays inside the folder) is there for report tests: see the two at the end.
"""

from __future__ import annotations

import copy
import csv
import json
import os
import signal
import socket
import stat
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
import yaml

from harness import cli, config, interrupt, registry, results
from harness import run as runner
from test_config import GOOD  # a valid 32x32 scene: a plane and a box, directional light

ROOT = Path(__file__).resolve().parent.parent
PY = sys.executable
HOSTILE_SCENE = "x\" onerror=\"document.title='PWNED'\""
HOSTILE_TECHNIQUE = "<img src=x onerror=alert(1)>"


def scene_with(**changes) -> dict:
    """GOOD with ``a__b__0=value`` changes (keys joined by double underscores)."""
    scene = copy.deepcopy(GOOD)
    for path, value in changes.items():
        *parents, last = [int(k) if k.isdigit() else k for k in path.split("__")]
        node = scene
        for key in parents:
            node = node[key]
        node[last] = value
    return scene


def write_scenes(folder: Path, scenes: dict) -> Path:
    path = folder / "scenes.yaml"
    path.write_text(yaml.safe_dump({"scenes": scenes}, sort_keys=False))
    return path


def files_under(folder: Path) -> set[Path]:
    return {p for p in folder.rglob("*") if p.is_file()}


def run_cli(args, capsys) -> tuple[int, list[str]]:
    code = cli.main([str(a) for a in args])
    return code, capsys.readouterr().err.strip().splitlines()


def sweep(scene_file, out, *more):
    return ["run", "--scene-file", scene_file, "--techniques", "sm", "--out", out, "--quiet",
            *more]


def assert_one_line(code, err, expected_code, *needles):
    assert code == expected_code, err
    assert len(err) == 1, err
    assert "Traceback" not in err[0]
    for needle in needles:
        assert needle in err[0], err


def subprocess_env(**extra) -> dict:
    return {**os.environ, "PYTHONPATH": str(ROOT), **extra}


def can_mount_tmpfs() -> bool:
    try:
        return subprocess.run(["unshare", "-rm", "sh", "-c", "mount -t tmpfs none /mnt"],
                              capture_output=True, timeout=30).returncode == 0
    except (OSError, subprocess.SubprocessError):
        return False


needs_tmpfs = pytest.mark.skipif(not can_mount_tmpfs(), reason="no mount namespace here "
                                 "(unshare -rm) for a small or read-only file system")


# --- numbers -----------------------------------------------------------------------------------

NAN, INF = float("nan"), float("inf")
BAD_NUMBERS = {
    "NaN camera position": ({"camera__position": [0, NAN, 4]}, "camera.position.1"),
    "Inf light direction": ({"light__direction": [-0.3, INF, -1]}, "light.direction.1"),
    "NaN plane size": ({"objects__0__size": [10, NAN]}, "objects.0.size.1"),
    "Inf scale": ({"objects__1__scale": INF}, "objects.1.scale"),
    "zero scale": ({"objects__1__scale": 0}, "objects.1.scale"),
    "a zero scale axis": ({"objects__1__scale": [1, 0, 1]}, "objects.1.scale"),
    "NaN rotate": ({"objects__1__rotate": [0, NAN, 0]}, "objects.1.rotate.1"),
    "Inf near": ({"camera__near": INF}, "camera.near"),
    "NaN far": ({"camera__far": NAN}, "camera.far"),
    "NaN radius": ({"objects__1": {"shape": "sphere", "radius": NAN}}, "objects.1.radius"),
    "NaN lathe profile": ({"objects__1": {"shape": "lathe", "profile": [[0, 0], [0.5, NAN],
                                                                       [0, 1]]}},
                          "objects.1.profile.1.1"),
    "Inf array step": ({"objects__1__array": {"count": [2, 1, 1], "step": [INF, 0, 0]}},
                       "objects.1.array.step.0"),
    "NaN albedo": ({"objects__1__albedo": NAN}, "objects.1.albedo"),
    "NaN ambient": ({"ambient": NAN}, "ambient"),
    "NaN spot fov": ({"light": {"type": "spot", "position": [3, -2, 6], "target": [0, 0, 0],
                                "fov": NAN}}, "light.fov"),
    "far/near 1e12 (issue: near 1e-7)": ({"camera__near": 1e-7, "camera__far": 1e5},
                                         "camera.far"),
    "near 1e-7, far 1e9": ({"camera__near": 1e-7, "camera__far": 1e9}, "camera.far"),
    "coordinate 1e30": ({"camera__position": [0, -6, 1e30]}, "camera.position.2"),
    "yfov 1e-30": ({"camera__yfov": 1e-30}, "camera.yfov"),
    "a lathe with every radius 0 (found by the fuzz test)": (
        {"objects": [{"shape": "lathe", "profile": [[0, 0], [0, 1]]}]}, "objects.0.profile"),
}


@pytest.mark.parametrize("case", list(BAD_NUMBERS))
def test_non_finite_or_unrepresentable_numbers_are_bad_input(case, tmp_path, capsys):
    """Catches: the config models accepting NaN/Inf (pydantic's default), a zero scale, a
    depth range the 24-bit depth buffer cannot resolve, or coordinates float32 cannot hold.
    Before: each ran, exit 0 with 'ok' rows and empty metrics."""
    changes, keypath = BAD_NUMBERS[case]
    scene_file = write_scenes(tmp_path, {"s": scene_with(**changes)})
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, str(scene_file), f"scenes.s.{keypath}")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("value", [".inf", "-.inf", ".nan", "1e999"])
def test_set_rejects_non_finite_values(value, tmp_path, capsys):
    """Catches: --set passing YAML's .inf/.nan (or an overflowing 1e999) to a technique.
    Before: `--set sm.bias=.inf` ran, exit 0."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, err = run_cli(sweep(scene_file, tmp_path / "out", "--set", f"sm.bias={value}"), capsys)
    assert_one_line(code, err, 2, "--set", "sm.bias")  # bias >= 0 says so first for -inf, nan
    assert not (tmp_path / "out").exists()


def test_experiment_grid_rejects_non_finite_values(tmp_path, capsys):
    """Catches: a parameter grid passing .inf to a technique. Before: it ran, exit 0."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    experiment = tmp_path / "e.yaml"
    experiment.write_text("techniques:\n  sm:\n    product: {bias: [0.01, .inf]}\n")
    code, err = run_cli(["run", experiment, "--scene-file", scene_file, "--out",
                         tmp_path / "out"], capsys)
    assert_one_line(code, err, 2, f"{experiment}:3: techniques.sm", "sm.bias", "finite")


def test_the_depth_ratio_limit_keeps_every_pixel_the_reference_covers(gl_context):
    """The limit is right: with far/near at MAX_DEPTH_RATIO and the farthest visible point at
    far/2 (the worst case the limit's rule covers), GL's 24-bit depth covers exactly what
    Mitsuba's rays hit. Catches: MAX_DEPTH_RATIO raised to 2^25 (GL then loses pixels: at
    far/2 a point is only half a depth step in front of the cleared depth)."""
    from harness.reference import compute_reference
    from harness.scene import build_scene
    from harness.technique import Frame

    # the plane's far corners are 12.7 from the camera: far/2 = 13
    camera = {**GOOD["camera"], "far": 26.0, "near": 26.0 / config.MAX_DEPTH_RATIO}
    scene = build_scene("depth", config.Scene.model_validate({**GOOD, "camera": camera,
                                                              "resolution": [96, 72]}))
    frame = Frame(scene)
    try:
        gl_covered = frame.arrays.covered
    finally:
        frame.release()
    reference = compute_reference(scene, samples=1)
    assert reference.covered.mean() > 0.5
    assert (gl_covered == reference.covered).mean() >= 0.999


# --- limits --------------------------------------------------------------------------------------

@pytest.mark.parametrize("args, needle", [
    (["--resolution", "0", "0"], "--resolution"),
    (["--resolution", "100000", "100000"], "--resolution"),
    (["--resolution", "16", "8193"], "--resolution"),
    (["--samples", "1000000"], "--samples"),
    (["--samples", "0"], "--samples"),
    (["--samples", "5"], "--samples"),
])
def test_reference_command_bounds_resolution_and_samples(args, needle, tmp_path, capsys):
    """Catches: `reference` skipping the 16..8192 and 1..1024 checks of run. Before: `0 0`
    divided by zero (traceback), 100000^2 reached 11 GB, 1e6 samples ran for ever."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, err = run_cli(["reference", "--scene", "s", "--scene-file", scene_file, "--out",
                         tmp_path / "out", *args], capsys)
    assert_one_line(code, err, 2, needle)
    assert not (tmp_path / "out").exists()


def test_workers_are_bounded(tmp_path, capsys):
    """Catches: --workers 0 reaching LocalCluster (which then waits for ever)."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, err = run_cli(sweep(scene_file, tmp_path / "out", "--executor", "dask",
                              "--workers", "0"), capsys)
    assert_one_line(code, err, 2, "--workers")


MANY_SPHERES = {"shape": "sphere", "radius": 0.1, "subdivisions": 5,
                "array": {"count": [100, 100, 1], "step": [0.2, 0.2, 0]}}


def test_a_scene_over_the_triangle_budget_is_bad_input(tmp_path, capsys):
    """Catches: no triangle budget. Before: 10,000 spheres of 20,480 triangles each were
    built (minutes, gigabytes) before anything failed."""
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1=MANY_SPHERES)})
    started = time.monotonic()
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects", "204,800,002 triangles", "1,000,000")
    assert time.monotonic() - started < 30  # counted, not built


def test_an_experiment_may_raise_the_triangle_budget(tmp_path):
    """Catches: triangle_budget in the experiment being ignored (or unknown)."""
    scene = scene_with(objects__1={**MANY_SPHERES, "array": {"count": [60, 1, 1],
                                                             "step": [0.2, 0, 0]}})
    scene_file = write_scenes(tmp_path, {"s": scene})  # 1,228,802 triangles
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({"scene_file": str(scene_file),
                                          "techniques": {"sm": None}}))
    with pytest.raises(config.ConfigError, match="1,228,802 triangles"):
        runner.plan_runs(experiment_path=str(experiment), scene_file="", scenes=None,
                         techniques=None, overrides={})
    experiment.write_text(yaml.safe_dump({"scene_file": str(scene_file), "techniques":
                                          {"sm": None}, "triangle_budget": 1_300_000}))
    plan = runner.plan_runs(experiment_path=str(experiment), scene_file="", scenes=None,
                            techniques=None, overrides={})
    assert len(plan.scenes["s"].triangles) == 1_228_802


@pytest.mark.parametrize("obj", [
    {"shape": "plane"}, {"shape": "box"},
    *({"shape": "sphere", "subdivisions": s} for s in (1, 3, 5)),
    *({"shape": "cylinder", "sections": n} for n in (3, 32, 256)),
    *({"shape": "capsule", "sections": n} for n in (3, 16, 128)),
    {"shape": "lathe", "profile": [[0.5, 0], [1, 0.5], [0.5, 1]], "sections": 7},
    {"shape": "lathe", "profile": [[0, 0], [1, 0], [0, 1]], "sections": 24},
])
def test_triangle_counts_are_trimeshs(obj):
    """The budget counts without building: each shape's formula against the mesh trimesh
    builds (an independent count); a lathe's is an upper bound, exact without a radius 0
    (trimesh drops the degenerate triangles there). Catches: a wrong formula (e.g. a capsule
    counted as 2n triangles, not 2n^2)."""
    from harness.scene import build_parts

    scene = config.Scene.model_validate({**GOOD, "objects": [obj]})
    built = sum(len(p.faces) for p in build_parts(scene))
    if any(r == 0 for r, _ in obj.get("profile", [(1, 0)])):
        assert built < scene.objects[0].triangles()
    else:
        assert scene.objects[0].triangles() == built


# --- names and paths -------------------------------------------------------------------------------

BAD_NAMES = ["../../../../elsewhere", "/tmp/shadowbench-absolute", HOSTILE_SCENE, ".hidden",
             "a/b", "two words", "line\nbreak", "tab\there", "ünïcode", "x" * 65, ""]


@pytest.mark.parametrize("name", BAD_NAMES)
def test_scene_names_are_names(name, tmp_path, capsys):
    """Catches: scene names used as folder names unchecked. Before: '../../../../elsewhere'
    wrote its arrays four levels above --out; an absolute name was a ValueError traceback."""
    deep = tmp_path / "a" / "b" / "c" / "d"
    deep.mkdir(parents=True)
    scene_file = write_scenes(tmp_path, {name: GOOD})
    before = files_under(tmp_path)
    code, err = run_cli(sweep(scene_file, deep / "out"), capsys)
    assert_one_line(code, err, 2, "scene name")
    assert files_under(tmp_path) == before
    assert not Path("/tmp/shadowbench-absolute").exists()


def test_names_of_letters_digits_dots_dashes_and_underscores_are_fine(tmp_path):
    scenes = config.load_scenes(write_scenes(tmp_path, {n: GOOD for n in ("a.b-c_1", "7", "x-")}))
    assert set(scenes) == {"a.b-c_1", "7", "x-"}


def test_technique_names_are_names(tmp_path, monkeypatch, capsys):
    """Catches: a plugin's technique name becoming file names unchecked."""
    sm = registry.get("sm")
    hostile = type("Hostile", (sm,), {"name": "../escape"})
    monkeypatch.setattr(registry, "techniques", lambda: {"../escape": hostile, "sm": sm})
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, err = run_cli(["run", "--scene-file", scene_file, "--out", tmp_path / "out",
                         "--quiet"], capsys)
    assert_one_line(code, err, 2, "technique name '../escape'")


def test_inside_resolves_and_refuses_paths_out_of_the_folder(tmp_path):
    """Catches: a containment check on the unresolved path (`..` or a link out passes)."""
    out = tmp_path / "out"
    (out / "arrays").mkdir(parents=True)
    (out / "link").symlink_to(tmp_path)
    assert results.inside(out, "arrays/a.npz") == (out / "arrays/a.npz").resolve()
    for escape in ("../x.npz", "arrays/../../x.npz", "/etc/passwd", "link/x.npz"):
        with pytest.raises(config.ConfigError, match="outside"):
            results.inside(out, escape)


def _small_run(tmp_path, *techniques, frames=1):
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({
        "techniques": {t: None for t in techniques or ("sm",)}, "frames": frames, "warmup": 0,
        "reference": {"samples": 1}}))
    args = ["run", str(experiment), "--scene-file", str(scene_file), "--out",
            str(tmp_path / "out"), "--quiet"]
    return args


def _rows(out):
    with (out / "results.csv").open() as f:
        return list(csv.DictReader(f))


def test_a_rerun_never_reads_arrays_outside_the_folder(tmp_path, gl_context):
    """Catches: a results.csv whose `array` points out of the folder being trusted. Before:
    the run counted as done and the row kept '../outside.npz'."""
    args = _small_run(tmp_path)
    assert cli.main(args) == 0
    out = tmp_path / "out"
    rows = _rows(out)
    outside = tmp_path / "outside.npz"
    (out / rows[0]["array"]).rename(outside)
    rows[0]["array"] = "../outside.npz"
    results.write_rows(out, rows)
    assert cli.main(args) == 0
    again = _rows(out)
    assert again[0]["status"] == "ok"
    assert results.inside(out, again[0]["array"]).is_file()


# --- one line for every failure ----------------------------------------------------------------------

def test_binary_scene_file(tmp_path, capsys):
    """Catches: read_text's UnicodeDecodeError escaping. Before: a traceback."""
    scene_file = tmp_path / "scenes.yaml"
    scene_file.write_bytes(bytes(range(256)) * 4)
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, str(scene_file), "not a text file")


def test_binary_experiment(tmp_path, capsys):
    """Before: a UnicodeDecodeError traceback."""
    experiment = tmp_path / "e.yaml"
    experiment.write_bytes(b"\xff\xfe\x00garbage\x80")
    code, err = run_cli(["run", experiment, "--scene-file", write_scenes(tmp_path, {"s": GOOD}),
                         "--out", tmp_path / "out"], capsys)
    assert_one_line(code, err, 2, str(experiment), "not a text file")


@pytest.mark.parametrize("text", ["scenes: {s: [", "\x00\x01\x02", "scenes:\n\t- x"])
def test_yaml_errors_are_one_line(text, tmp_path, capsys):
    """Catches: a YAML error whose message spans lines (the reader's, for control
    characters) printed as is."""
    scene_file = tmp_path / "scenes.yaml"
    scene_file.write_text(text)
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, str(scene_file), "not valid YAML")


def test_set_value_that_is_not_yaml(tmp_path, capsys):
    """Before: `--set sm.bias=[` was a ScannerError traceback."""
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), tmp_path / "out", "--set",
                              "sm.bias=["), capsys)
    assert_one_line(code, err, 2, "--set sm.bias=[", "not valid YAML")


@pytest.mark.parametrize("where", ["a file", "under a file"])
def test_out_that_cannot_be_a_folder(where, tmp_path, capsys):
    """Before: FileExistsError / NotADirectoryError tracebacks."""
    (tmp_path / "f").write_text("x")
    out = tmp_path / "f" if where == "a file" else tmp_path / "f" / "out"
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), out), capsys)
    assert_one_line(code, err, 2, str(out))


@needs_tmpfs
def test_out_on_a_read_only_file_system(tmp_path):
    """Before: an OSError (EROFS) traceback."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    (tmp_path / "ro").mkdir()
    script = (f"mount -t tmpfs -o ro,size=1m none {tmp_path}/ro && exec {PY} -m harness.cli run "
              f"--scene-file {scene_file} --techniques sm --out {tmp_path}/ro/out --quiet")
    proc = subprocess.run(["unshare", "-rm", "sh", "-c", script], capture_output=True,
                          text=True, timeout=300, env=subprocess_env())
    err = proc.stderr.strip().splitlines()
    assert_one_line(proc.returncode, err, 2, f"{tmp_path}/ro/out", "Read-only file system")


FOREIGN = {
    "results.csv": ["name,value\nfoo,1\n", bytes(range(256))],
    "manifest.json": ["[1, 2, 3]", "{not json", b"\xff\xfe", '{"invocations": 3}'],
}


@pytest.mark.parametrize("name, content", [(n, c) for n, cs in FOREIGN.items() for c in cs])
def test_foreign_files_in_out_are_refused(name, content, tmp_path, capsys):
    """Catches: a results.csv or manifest.json of someone else in --out. Before: KeyError
    ('status') and AttributeError ('list' object has no attribute 'get') tracebacks; a broken
    manifest was silently replaced."""
    out = tmp_path / "out"
    out.mkdir()
    file = out / name
    file.write_bytes(content if isinstance(content, bytes) else content.encode())
    code, err = run_cli(sweep(write_scenes(tmp_path, {"s": GOOD}), out), capsys)
    assert_one_line(code, err, 2, str(file), "not a shadowbench")
    assert file.read_bytes() == (content if isinstance(content, bytes) else content.encode())
    assert {p.name for p in out.iterdir()} <= {name, ".lock"}


@pytest.mark.parametrize("content, needle", [
    ("", "no results"), ("run_id,scene,technique,params,status\n", "no results"),
    (bytes(range(256)), "not a shadowbench results file"),
    ("name,value\nfoo,1\n", "not a shadowbench results file"),
])
def test_report_on_a_csv_that_is_not_results(content, needle, tmp_path, capsys):
    """Before: EmptyDataError, ParserError and KeyError ('params') tracebacks."""
    out = tmp_path / "out"
    out.mkdir()
    (out / "results.csv").write_bytes(content if isinstance(content, bytes) else content.encode())
    code, err = run_cli(["report", out], capsys)
    assert_one_line(code, err, 2, str(out / "results.csv"), needle)


def test_nan_lathe_profile_in_reference_command(tmp_path, capsys):
    """Before: a Mitsuba RuntimeError traceback (jit_var_gather on an empty array)."""
    lathe = {"shape": "lathe", "profile": [[0, 0], [0.5, NAN], [0, 1]]}
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1=lathe)})
    code, err = run_cli(["reference", "--scene", "s", "--scene-file", scene_file, "--out",
                         tmp_path / "out", "--samples", "1"], capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.profile.1.1", "finite")


def test_a_scene_that_fails_mid_sweep_gives_error_rows_and_the_sweep_goes_on(
        tmp_path, monkeypatch, capsys, gl_context):
    """Catches: render_serial letting a scene's reference failure end the sweep. Before: the
    RuntimeError ended everything (no rows for the other scene; a traceback)."""
    from harness import reference

    traced = reference.compute_reference

    def compute_reference(scene, **kw):
        if scene.name == "bad":
            raise RuntimeError("[Mesh] Mitsuba cannot trace this scene")
        return traced(scene, **kw)

    monkeypatch.setattr(reference, "compute_reference", compute_reference)
    scene_file = write_scenes(tmp_path, {"bad": GOOD, "good": GOOD})
    out = tmp_path / "out"
    code, err = run_cli(["run", "--scene-file", scene_file, "--techniques", "sm,pcf", "--out",
                         out, "--quiet"], capsys)
    assert code == 1
    status = {(r["scene"], r["technique"]): (r["status"], r["error"]) for r in _rows(out)}
    assert status[("good", "sm")] == ("ok", "") and status[("good", "pcf")] == ("ok", "")
    for technique in ("sm", "pcf"):
        state, error = status[("bad", technique)]
        assert state == "error" and "Mitsuba cannot trace this scene" in error
    assert json.loads((out / "manifest.json").read_text())["status"] == "complete"
    assert any("failed: bad sm" in line for line in err)
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
    from harness.distributed import SCHEDULER_TIMEOUT_S

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
    script = (f"mount -t tmpfs -o size=600k none {tmp_path}/small && {PY} -m harness.cli run "
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


# --- odd ------------------------------------------------------------------------------------------

def test_a_duplicate_key_names_both_lines(tmp_path, capsys):
    """Catches: YAML keeping the last of two equal keys. Before: the second scene 's' silently
    replaced the first, exit 0."""
    scene_file = tmp_path / "scenes.yaml"
    one = yaml.safe_dump({"s": GOOD}, sort_keys=False)
    scene_file.write_text("scenes:\n" + "".join("  " + line + "\n"
                                                for line in (one + one).splitlines()))
    second = 2 + len(one.splitlines())
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, f"{scene_file}:{second}:", "'s'", f"lines 2 and {second}")


def test_a_duplicate_key_on_one_line_and_merge_keys(tmp_path):
    """A flow mapping repeating a key is caught; a merge key (`<<: *base`) overridden by an
    explicit key is not a duplicate."""
    path = tmp_path / "scenes.yaml"
    path.write_text("scenes:\n  s: {resolution: [32, 32], resolution: [64, 64]}\n")
    with pytest.raises(config.ConfigError, match=r":2: key 'resolution' is given twice"):
        config.read_yaml(path)
    path.write_text("base: &b {a: 1, b: 2}\nuse: {<<: *b, a: 3}\n")
    assert config.read_yaml(path)[0]["use"] == {"a": 3, "b": 2}


@pytest.mark.parametrize("text, needle", [
    ("a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n" + "".join(
        f"{x}: &{x} [{', '.join(['*' + p] * 10)}]\n" for p, x in zip("abcdefgh", "bcdefghi")),
     "expand to more than"),
    ("a: &a [*a]\n", "refers to the node"),
    ("[" * 5000 + "]" * 5000, "not valid YAML"),
])
def test_alias_bombs_recursion_and_deep_nesting(text, needle, tmp_path):
    """Catches: a YAML 'billion laughs' (10^9 values from 9 alias levels) validated for ever,
    a self-containing alias, or a nesting overflowing Python's stack."""
    path = tmp_path / "scenes.yaml"
    path.write_text(text)
    started = time.monotonic()
    with pytest.raises(config.ConfigError, match=needle):
        config.load_scenes(path)
    assert time.monotonic() - started < 10


@pytest.mark.parametrize("option", ["--techniques", "--scenes"])
@pytest.mark.parametrize("value", [",", "", " , "])
def test_a_list_option_naming_nothing_is_an_error(option, value, tmp_path, capsys):
    """Catches: an empty list read as 'not given'. Before: `--techniques ,` ran all eight."""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    code, err = run_cli(["run", "--scene-file", scene_file, option, value, "--out",
                         tmp_path / "out", "--quiet"], capsys)
    assert_one_line(code, err, 2, option, "names nothing")
    assert not (tmp_path / "out").exists()


@pytest.mark.parametrize("make, needle", [
    (lambda p: p.mkdir(), "not a regular file: it is a folder"),
    (lambda p: p.write_bytes(bytes(range(256)) * 8), "not a mesh file"),
    (lambda p: p.write_text("v 1e39 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"), "beyond +-1e+07"),
    (lambda p: p.write_text("v 0 0 0\nf 1 2 9\n"), "cannot load mesh"),
])
def test_mesh_files_that_are_not_meshes(make, needle, tmp_path, capsys):
    """Before: a folder said 'no such file'; random bytes said "No module named
    'charset_normalizer'"; a vertex at 1e39 (inf in float32) was accepted."""
    make(tmp_path / "m.obj")
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1={"shape": "mesh",
                                                                      "path": "m.obj"})})
    code, err = run_cli(sweep(scene_file, tmp_path / "out"), capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.path", needle)
    assert "charset_normalizer" not in err[0]


def test_arrays_and_results_get_the_umasks_mode(tmp_path, gl_context):
    """Catches: mkstemp's 0600 on stored arrays. Before: every .npz was 0600."""
    args = _small_run(tmp_path)
    previous = os.umask(0o027)
    try:
        assert cli.main(args) == 0
    finally:
        os.umask(previous)
    out = tmp_path / "out"
    stored = [*out.rglob("*.npz"), out / "results.csv", out / "manifest.json"]
    assert len(stored) == 4
    assert {stat.S_IMODE(p.stat().st_mode) for p in stored} == {0o640}


def test_the_next_run_heals_what_a_kill_left(tmp_path, gl_context):
    """What a SIGKILL leaves, rebuilt by hand: an invocation still 'running', temporary files
    (this version's and older ones' names), a truncated array and a missing one. The next run
    marks the invocation interrupted, removes the temporaries, and renders again the runs
    whose arrays are damaged. Catches: each of these left as it was. Before: 'running' stayed,
    *.tmp.npz stayed, and the damaged runs counted as done (the report then failed on them)."""
    args = _small_run(tmp_path, "sm", "pcf", "silhouette")
    assert cli.main(args) == 0
    out = tmp_path / "out"
    manifest = json.loads((out / "manifest.json").read_text())
    killed = {**manifest["invocations"][0], "id": "0badf00d", "status": "running",
              "started": "2000-01-01T00:00:00+00:00", "finished": None}
    manifest["invocations"].insert(0, killed)
    (out / "manifest.json").write_text(json.dumps(manifest))
    rows = {r["technique"]: r for r in _rows(out)}
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
    again = {r["technique"]: r for r in _rows(out)}
    assert {r["status"] for r in again.values()} == {"ok"}
    for technique in ("sm", "pcf"):
        assert results.readable_npz(out / again[technique]["array"])
    assert again["silhouette"]["finished_at"] == rows["silhouette"]["finished_at"]  # not redone


def test_damaged_arrays_of_runs_not_in_this_plan_become_error_rows(tmp_path, gl_context):
    """Another experiment's run into the same folder marks a damaged run failed (rather than
    leaving an 'ok' row whose array the report cannot read)."""
    args = _small_run(tmp_path, "sm", "pcf")
    assert cli.main(args) == 0
    out = tmp_path / "out"
    rows = {r["technique"]: r for r in _rows(out)}
    (out / rows["pcf"]["array"]).unlink()
    assert cli.main(_small_run(tmp_path, "sm")) == 0
    pcf = {r["technique"]: r for r in _rows(out)}["pcf"]
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
    patch = ("import harness.reference as r\n"
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


# --- the report (its code is another change's: these say what it must do) ---------------------

@pytest.fixture(scope="module")
def hostile_results(tmp_path_factory, gl_context):
    """A results folder whose rows name a hostile scene and technique (as results copied from
    elsewhere or edited by hand would), with their arrays inside the folder. Returns the
    folder; its rows' names are HOSTILE_SCENE and HOSTILE_TECHNIQUE."""
    root = tmp_path_factory.mktemp("hostile")
    assert cli.main(_small_run(root)) == 0
    out = root / "out"
    rows = _rows(out)
    for row in rows:
        row.update(scene=HOSTILE_SCENE, technique=HOSTILE_TECHNIQUE)
    results.write_rows(out, rows)
    return out


def _files_outside(out: Path, before: set[Path]) -> set[Path]:
    return {p for p in files_under(out.parent) - before if out not in p.parents}


def test_a_report_of_hostile_names_runs_no_script_and_writes_only_in_the_folder(
        hostile_results):
    from harness import report

    before = files_under(hostile_results.parent)
    try:
        page = report.build_report(hostile_results).read_text()
    except config.ConfigError:
        page = ""  # refusing the rows is fine too
    assert not _files_outside(hostile_results, before)
    assert "onerror=\"document.title='PWNED'\"" not in page
    assert "<img src=x onerror=alert(1)>" not in page


def test_report_reads_arrays_only_from_inside_the_folder(tmp_path, monkeypatch, gl_context):
    from harness import report

    assert cli.main(_small_run(tmp_path)) == 0
    out = tmp_path / "out"
    rows = _rows(out)
    for row in rows:
        for column in ("array", "reference_array"):
            outside = tmp_path / f"outside-{column}.npz"
            outside.write_bytes((out / row[column]).read_bytes())
            row[column] = f"../{outside.name}"
    results.write_rows(out, rows)
    opened = []
    load = np.load
    monkeypatch.setattr(np, "load", lambda file, *a, **k: opened.append(Path(file)) or
                        load(file, *a, **k))
    try:
        report.build_report(out)
    except config.ConfigError:
        pass  # refusing the rows is fine too
    assert all(out.resolve() in p.resolve().parents for p in opened)
