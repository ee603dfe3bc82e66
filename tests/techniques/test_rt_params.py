"""rt's bad input: an unknown builder or backend, a leaf size out of range, and a scene whose
BVH could exceed the memory budget are exit 2 with one line naming the file (or --set) and the
key, before anything is built or written."""

from __future__ import annotations

import pytest
import yaml

from helpers import SCENE_FILE
from harness import cli
from techniques.rt import bvh


def experiment(tmp_path, rt: dict, small_scene_file) -> tuple[str, str]:
    scenes = small_scene_file("box_plane")
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"scene_file": str(scenes), "scenes": ["box_plane"],
                                    "frames": 1, "warmup": 0, "techniques": {"rt": rt}}))
    return str(path), str(tmp_path / "out")


@pytest.mark.parametrize("rt,says", [
    ({"set": {"build": "octree"}}, "techniques.rt: rt.build: Input should be 'lbvh' or 'sah'"),
    ({"set": {"backend": "optix"}}, "rt.backend: Input should be 'gl' or 'embree'"),
    ({"set": {"leaf_size": 0}}, "rt.leaf_size: Input should be greater than or equal to 1"),
    ({"set": {"leaf_size": 17}}, "rt.leaf_size: Input should be less than or equal to 16"),
])
def test_bad_parameters_are_exit_2_naming_file_and_key(rt, says, tmp_path, small_scene_file,
                                                       capsys):
    """Catches a Params that accepts any builder or backend string (the run fails later, or
    falls back silently), and a leaf size let through to the builder."""
    path, out = experiment(tmp_path, rt, small_scene_file)
    code = cli.main(["run", path, "--out", out, "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert path in err and says in err, err


def test_a_bvh_over_the_budget_is_refused_before_it_is_built(tmp_path, small_scene_file,
                                                              capsys, monkeypatch):
    """tessellation at 10^5 triangles (99,714) could take 99,714 x (48 + 2 x 32) bytes = 10.7 MiB of
    BVH: with budget_mib 10 the plan refuses it, exit 2, one line naming the key and the
    scene, and no builder runs (none is called). Catches a budget checked only in prepare
    (a run's error row, exit 1) or not at all."""
    scene_file = tmp_path / "scenes.yaml"
    declared = yaml.safe_load(SCENE_FILE.read_text())["scenes"]["tessellation"]
    declared.update(resolution=[32, 32], family={"kind": "tessellation", "triangles": 100_000})
    scene_file.write_text(yaml.safe_dump({"scenes": {"tess": declared}}))
    path = tmp_path / "exp.yaml"
    path.write_text(yaml.safe_dump({"scene_file": str(scene_file), "scenes": ["tess"],
                                    "techniques": {"rt": {"set": {"budget_mib": 10}}}}))
    monkeypatch.setattr(bvh, "build", lambda *a, **k: pytest.fail("a BVH was built"))
    code = cli.main(["run", str(path), "--out", str(tmp_path / "out"), "--quiet"])
    err = capsys.readouterr().err.strip()
    assert code == 2 and len(err.splitlines()) == 1, err
    assert str(path) in err and "techniques.rt" in err and "rt.budget_mib" in err, err
    assert "over the budget of 10 MiB" in err and "scene tess" in err, err
    assert not (tmp_path / "out").exists()
