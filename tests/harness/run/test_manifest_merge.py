"""Runs added to an existing results folder merge into its manifest (issue 47, friction 4):
scenes, experiments, invocations and their notes are kept, never replaced."""

from __future__ import annotations

import json

import yaml
from helpers import GOOD, write_scenes

from harness import cli

DESCRIBED = {name: {**GOOD, "description": f"the {name} scene, as described"}
             for name in ("first", "second", "third")}


def test_a_second_invocation_with_other_scenes_keeps_the_first_ones(tmp_path, gl_context):
    """Two invocations into one folder, scenes first and second, then third: the manifest
    keeps all three scenes, both invocations and the first's start, and the dashboard
    describes every scene. Catches the manifest replaced by the latest invocation's (before:
    the scenes of the last only, one invocation, the dashboard without the first two scenes'
    descriptions and with the second invocation's start)."""
    scene_file = write_scenes(tmp_path, DESCRIBED)
    experiment = tmp_path / "e.yaml"
    experiment.write_text(yaml.safe_dump({"techniques": {"sm": None}, "frames": 1, "warmup": 0,
                                          "reference": {"samples": 1}}))
    out = tmp_path / "out"

    def run(scenes):
        assert cli.main(["run", str(experiment), "--scene-file", str(scene_file), "--scenes",
                         scenes, "--out", str(out), "--quiet"]) == 0
        return json.loads((out / "manifest.json").read_text())

    first = run("first,second")
    merged = run("third")
    assert set(merged["scenes"]) == set(DESCRIBED)
    assert merged["scenes"]["first"]["description"] == "the first scene, as described"
    invocations = merged["invocations"]
    assert [i["scenes"] for i in invocations] == [["first", "second"], ["third"]]
    assert invocations[0] == first["invocations"][0]  # kept as it was, its notes included
    assert [i["runs_rendered"] for i in invocations] == [2, 1]
    assert merged["started"] == first["started"]
    assert merged["finished"] == invocations[-1]["finished"]
    assert len(merged["experiments"]) == 2  # two plans of one file: two hashes
    assert merged["experiment_hash"] == invocations[-1]["experiment_hash"]

    assert cli.main(["report", str(out)]) == 0
    page = (out / "index.html").read_text()
    for name in DESCRIBED:
        assert f"the {name} scene, as described" in page, name
    assert f"started {first['started']}" in page
