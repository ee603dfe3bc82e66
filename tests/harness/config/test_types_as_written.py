"""Types as written: YAML's true or false where a number, an index or a name is expected is bad
input (exit 2, one line naming the key), not 1 or 0. Catches the lax models (pydantic reads
true as 1: ``object: true`` moved object 1 and the scene ran), the check removed from
harness.config.TypesAsWritten (seen failing: every case below but the last exits 0)."""

from __future__ import annotations

import copy

import pytest
import yaml

from harness import cli, run

SCENE = {"resolution": [32, 32],
         "camera": {"position": [0, -6, 4], "target": [0, 0, 0]},
         "light": {"type": "directional", "direction": [-0.3, 0.2, -1]},
         "objects": [{"shape": "plane", "size": [10, 10]},
                     {"shape": "box", "size": [1, 1, 1], "translate": [0, 0, 1.5]}]}


def _scene_file(tmp_path, **changes):
    scene = copy.deepcopy(SCENE)
    scene.update(changes)
    path = tmp_path / "scenes.yaml"
    path.write_text(yaml.safe_dump({"scenes": {"s": scene}}))
    return path


@pytest.fixture
def planned(monkeypatch):
    """Plans that pass are recorded, not rendered."""
    plans = []
    monkeypatch.setattr(run, "execute", lambda plan, *a, **k: plans.append(plan) or 0)
    monkeypatch.setattr(run, "read_manifest", lambda out: {"invocations": [{"runs_rendered": 0}]})
    return plans


@pytest.mark.parametrize("changes, key", [
    ({"motion": {"frames": 3, "objects": [{"object": True, "spin": 90}]}},
     "scenes.s.motion.objects.0.object: true is a boolean"),
    ({"camera": {"position": [0, True, 4], "target": [0, 0, 0]}},
     "scenes.s.camera.position: true is a boolean"),
    ({"resolution": [32, False]}, "scenes.s.resolution: false is a boolean"),
    ({"motion": {"frames": True}}, "scenes.s.motion.frames: true is a boolean"),
])
def test_a_boolean_in_a_scene_is_refused(changes, key, tmp_path, capsys):
    code = cli.main(["list", "--scene-file", str(_scene_file(tmp_path, **changes))])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and key in err[0], err


@pytest.mark.parametrize("experiment, more, key", [
    ({"techniques": {"sm": None}, "frames": True}, [], "frames: true is a boolean"),
    ({"techniques": {"sm": {"product": {"res": [256, True]}}}}, [],
     "sm.res: true is a boolean"),
    ({"techniques": {"pcf": None}}, ["--set", "pcf.k=true"], "pcf.k: true is a boolean"),
])
def test_a_boolean_in_an_experiment_is_refused(experiment, more, key, tmp_path, capsys,
                                               planned):
    path = tmp_path / "experiment.yaml"
    path.write_text(yaml.safe_dump({"scene_file": str(_scene_file(tmp_path)), **experiment}))
    code = cli.main(["run", str(path), "--out", str(tmp_path / "out"), *more])
    err = capsys.readouterr().err.strip().splitlines()
    assert code == 2 and len(err) == 1 and key in err[0], err
    assert not planned


def test_booleans_where_booleans_are_expected_still_pass(tmp_path, capsys, planned):
    """csm's stabilize and a grid's ``set`` (any scalar) keep taking true."""
    path = tmp_path / "experiment.yaml"
    path.write_text(yaml.safe_dump({"scene_file": str(_scene_file(tmp_path)), "techniques": {
        "csm": {"set": {"stabilize": True}}, "silhouette": {"curve": True}}}))
    assert cli.main(["run", str(path), "--out", str(tmp_path / "out")]) == 0, capsys.readouterr()
    stabilize = {spec.params.get("stabilize") for spec in planned[0].runs}
    assert stabilize == {True, None}
