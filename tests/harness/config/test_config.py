"""Bad input is exit code 2 with one line naming file, scene and key path; nothing written."""

import subprocess
import sys
from pathlib import Path

import pytest
import yaml

from harness import cli, config
from helpers import GOOD


def _with(path, value):
    scene = yaml.safe_load(yaml.safe_dump(GOOD))
    *parents, last = path
    node = scene
    for key in parents:
        node = node[key]
    if value is DELETE:
        del node[last]
    else:
        node[last] = value
    return scene


DELETE = object()

BAD = {
    "resolution too small": (("resolution",), [8, 32], "resolution"),
    "resolution too large": (("resolution",), [9000, 32], "resolution"),
    "yfov zero": (("camera", "yfov"), 0, "camera.yfov"),
    "yfov 180": (("camera", "yfov"), 180, "camera.yfov"),
    "zero up": (("camera", "up"), [0, 0, 0], "camera.up"),
    "up parallel to view": (("camera", "up"), [0, 6, -4], "camera.up"),
    "target equals position": (("camera", "target"), [0, -6, 4], "camera.target"),
    "near zero": (("camera", "near"), 0, "camera.near"),
    "far below near": (("camera", "far"), 0.05, "camera.far"),
    "zero light direction": (("light", "direction"), [0, 0, 0], "light.direction"),
    "spot fov": (("light",), {"type": "spot", "position": [3, -2, 6], "target": [0, 0, 0],
                              "fov": 190}, "light.fov"),
    "unknown light type": (("light", "type"), "area", "light"),
    "empty objects": (("objects",), [], "objects"),
    "missing camera": (("camera",), DELETE, "camera"),
    "unknown key": (("camera", "fovy"), 60, "camera.fovy"),
    "misspelled object key": (("objects", 1, "translte"), [0, 0, 1], "objects.1.translte"),
    "wrong type": (("camera", "near"), "close", "camera.near"),
    "unknown shape": (("objects", 0, "shape"), "torus", "objects.0"),
    "missing mesh file": (("objects", 0), {"shape": "mesh", "path": "nope.obj"},
                          "objects.0.path"),
    "mesh that does not load": (("objects", 0), {"shape": "mesh", "path": "broken.obj"},
                                "objects.0.path"),
}


def _write(tmp_path, scene):
    (tmp_path / "broken.obj").write_text("this is not a mesh\n")
    path = tmp_path / "scenes.yaml"
    path.write_text(yaml.safe_dump({"scenes": {"bad_scene": scene}}, sort_keys=False))
    return path


@pytest.mark.parametrize("case", list(BAD))
def test_bad_scene_is_exit_2_one_line_naming_key(case, tmp_path, capsys):
    path, value, keypath = BAD[case]
    scene_file = _write(tmp_path, _with(path, value))
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(scene_file), "--out", str(out), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2
    assert len(err.splitlines()) == 1, err
    assert str(scene_file) in err and f"scenes.bad_scene.{keypath}" in err, err
    assert "Traceback" not in err
    assert not out.exists()


def test_error_names_the_line(tmp_path):
    scene_file = _write(tmp_path, _with(("camera", "yfov"), 200))
    with pytest.raises(config.ConfigError) as e:
        config.load_scenes(scene_file)
    line = next(i for i, text in enumerate(scene_file.read_text().splitlines(), 1)
                if "yfov" in text)
    assert f"{scene_file}:{line}:" in str(e.value)


def test_good_scene_loads_with_defaults(tmp_path):
    scenes = config.load_scenes(_write(tmp_path, GOOD))
    assert scenes["bad_scene"].camera.yfov == 60
    assert scenes["bad_scene"].objects[1].albedo == 0.8


@pytest.mark.parametrize("args, needle", [
    (["--set", "pcf.kk=4"], "pcf has no parameter 'kk'; allowed: res, k"),
    (["--set", "pcf.k=5"], "pcf.k: must be a square number"),
    (["--set", "sm.res=8"], "sm.res"),
    (["--set", "pcf.k"], "expected technique.param=value"),
    (["--techniques", "nope"], "unknown technique 'nope'"),
    (["--scenes", "nowhere"], "no scene 'nowhere'"),
])
def test_bad_command_line_is_exit_2(args, needle, tmp_path, capsys):
    scene_file = _write(tmp_path, GOOD)
    out = tmp_path / "out"
    code = cli.main(["run", "--scene-file", str(scene_file), "--out", str(out), "--quiet",
                     *args])
    err = capsys.readouterr().err.strip()
    assert code == 2 and needle in err and len(err.splitlines()) == 1, err
    assert not out.exists()


def test_console_script_reports_bad_input_without_traceback(tmp_path):
    scene_file = _write(tmp_path, _with(("camera", "yfov"), 0))
    exe = Path(sys.executable).with_name("shadowbench")
    proc = subprocess.run([str(exe), "run", "--scene-file", str(scene_file), "--out",
                           str(tmp_path / "out")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert proc.stderr.count("\n") == 1 and "camera.yfov" in proc.stderr
    assert not (tmp_path / "out").exists()


def test_shipped_scenes_validate():
    from helpers import SCENE_FILE

    scenes = config.load_scenes(SCENE_FILE)
    assert {"sphere_plane", "box_plane", "pins", "castle", "crowd", "terrain_long"} <= set(scenes)


def test_scene_named_like_a_shape_keeps_its_name_in_the_key_path(tmp_path):
    path = tmp_path / "scenes.yaml"
    scene = _with(("camera", "yfov"), 190)
    path.write_text(yaml.safe_dump({"scenes": {"sphere": scene}}, sort_keys=False))
    with pytest.raises(config.ConfigError, match=r"scenes\.sphere\.camera\.yfov: must be in"):
        config.load_scenes(path)
