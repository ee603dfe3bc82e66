"""Bad values in scene files, experiments and options: non-finite numbers, names that are
not names, budgets, duplicate keys, YAML bombs, special files and run-count bombs. Each is
exit 2 with one line and nothing written; each test names the broken code it catches."""

from __future__ import annotations

import os
import socket
import time
from pathlib import Path
from unittest import mock

import pytest
import yaml
from helpers import (
    GOOD,
    HOSTILE_SCENE,
    assert_one_line,
    cli_subprocess,
    files_under,
    run_cli,
    scene_with,
    sweep,
    write_scenes,
)

from harness import config
from harness.technique import registry
from harness import run as runner

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
    from harness.truth.reference import compute_reference
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


def test_nan_lathe_profile_in_reference_command(tmp_path, capsys):
    """Before: a Mitsuba RuntimeError traceback (jit_var_gather on an empty array)."""
    lathe = {"shape": "lathe", "profile": [[0, 0], [0.5, NAN], [0, 1]]}
    scene_file = write_scenes(tmp_path, {"s": scene_with(objects__1=lathe)})
    code, err = run_cli(["reference", "--scene", "s", "--scene-file", scene_file, "--out",
                         tmp_path / "out", "--samples", "1"], capsys)
    assert_one_line(code, err, 2, "scenes.s.objects.1.profile.1.1", "finite")


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


@pytest.mark.parametrize("which", ["scene file", "experiment"])
def test_a_fifo_as_scene_file_or_experiment_is_refused_at_once(which, tmp_path):
    """Before: open() of a FIFO with no writer blocked for ever (here: the 60 s timeout)."""
    fifo = tmp_path / "fifo.yaml"
    os.mkfifo(fifo)
    args = (sweep(fifo, tmp_path / "out") if which == "scene file"
            else ["run", fifo, "--scene-file", write_scenes(tmp_path, {"s": GOOD}), "--out",
                  tmp_path / "out", "--quiet"])
    started = time.monotonic()
    code, err = cli_subprocess(args)
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
    """Before: a curve of 8,000 res values planned 8,000 runs silently (hours of work). (Every
    value is a valid map size: the planner validates each point before it merges duplicates.)"""
    scene_file = write_scenes(tmp_path, {"s": GOOD})
    started = time.monotonic()
    code, err, planned = _plan_only(["run", _curve_experiment(tmp_path, 8_000), "--scene-file",
                                     scene_file, "--out", tmp_path / "out"], capsys)
    assert_one_line(code, err, 2, "8,000 runs", "5,000", "max_runs:", "--max-runs")
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


def test_the_alias_bombs_message_gives_its_line(tmp_path):
    """Before: '...: its aliases expand to more than 1,000,000 values', no line."""
    path = tmp_path / "scenes.yaml"
    path.write_text("a: &a [1, 2, 3, 4, 5, 6, 7, 8, 9, 10]\n" + "".join(
        f"{x}: &{x} [{', '.join(['*' + p] * 10)}]\n" for p, x in zip("abcdefgh", "bcdefghi")))
    with pytest.raises(config.ConfigError, match=rf"^{path}:6: .*more than 1,000,000"):
        config.load_scenes(path)
