"""Experiments: validation (exit code 2, one line naming file and key, nothing written), grid
expansion, and resumable runs that survive SIGKILL and Ctrl-C without duplicate or lost rows."""

from __future__ import annotations

import fcntl
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from harness import config, results
from harness import run as runner
from harness.cli import main as shadowbench
from helpers import ROOT, run_cli

SCENE_FILE = ROOT / "scenes.yaml"
CLI = [sys.executable, "-m", "harness.cli"]


def _write(tmp_path: Path, text: str) -> Path:
    path = tmp_path / "exp.yaml"
    path.write_text(text)
    return path


# --- validation ---------------------------------------------------------------------------------

BAD = [
    ("techniques: all\nbogus: 1\n", "exp.yaml:2: bogus: unknown key"),
    ("techniques: {sm: {product: {res: []}}}\n", "techniques.sm: product.res is an empty list"),
    ("techniques:\n  sm: {prodcut: {res: [512]}}\n", "exp.yaml:2: techniques.sm.prodcut: unknown key"),
    ("techniques: {nosuch: {}}\n", "techniques.nosuch: unknown technique; registered:"),
    ("techniques:\n  sm: {product: {nosuch: [1]}}\n",
     "exp.yaml:2: techniques.sm: sm has no parameter 'nosuch'; allowed:"),
    ("techniques: {sm: {product: {res: [256, x]}}}\n", "techniques.sm: sm.res:"),
    ("techniques: {sm: {zip: {res: [256, 512], bias: [0.1]}}}\n",
     "techniques.sm: zip lists must have equal lengths, got [1, 2]"),
    ("techniques: {sm: {product: {res: [256]}, zip: {res: [512]}}}\n",
     "techniques.sm: parameter 'res' is in both product and zip"),
    ("techniques: {sm: []}\n", "techniques.sm: empty list of grids"),
    ("techniques: {}\n", "techniques: must name at least one technique"),
    ("scenes: []\ntechniques: all\n", "scenes: must name at least one scene"),
    ("scenes: [box_plane, nowhere]\ntechniques: all\n", "exp.yaml:1: scenes.1: no scene 'nowhere'"),
    ("techniques: all\nresolutions: []\n", "resolutions: must be a non-empty list"),
    ("techniques: all\nreference: {samples: 5}\n", "reference.samples: must be a square number"),
    ("techniques: all\nframes: 0\n", "frames: Input should be greater than or equal to 1"),
    ("", "exp.yaml: an experiment is a mapping with at least a 'techniques' key"),
    ("techniques: [sm\n", "exp.yaml:2: not valid YAML"),
    # quality curves: an empty curve, a knob the technique does not declare, a bad value
    ("techniques: {sm: {curve: {res: []}}}\n", "techniques.sm: curve.res is an empty list"),
    ("techniques: {sm: {curve: {}}}\n", "techniques.sm.curve: is empty; name a quality knob"),
    ("techniques:\n  sm: {curve: {bias: [0.1]}}\n",
     "exp.yaml:2: techniques.sm.curve.bias: sm has no quality knob 'bias'; its knobs: res"),
    ("techniques:\n  sm: {curve: {res: [256, 100000]}}\n",
     "exp.yaml:2: techniques.sm.curve.res: sm.res: Input should be less than or equal to 8192"),
    ("techniques: {sv: {curve: {method: [zpass, nearly]}}}\n",
     "techniques.sv.curve.method: sv.method: Input should be 'zpass', 'zfail' or 'nearclip'"),
    ("techniques: {mdsm: {curve: {n: [1, 4]}}}\n",
     "techniques.mdsm.curve.n: mdsm.(parameters): select=minmax allows n in [1, 2, 3]"),
    ("techniques: {sm: {curve: true, product: {res: [256]}}}\n",
     "techniques.sm.curve: goes with set only, not with product, zip or exclude"),
    # exclude: combinations that do not go together, left out; a bad exclusion is named
    ("techniques: {sv: {product: {cull: [none, cull], method: [zfail, nearclip]}}}\n",
     "techniques.sv: sv.cull: cull needs method zpass or zfail (nearclip draws each volume's "
     "near-plane clip polygon apart from it); leave such combinations out of a grid with "
     "exclude:"),
    ("techniques:\n  sv:\n    product: {cull: [none, cull], method: [zfail, nearclip]}\n"
     "    exclude: [{cull: cull, method: nearclp}]\n",
     "exp.yaml:4: techniques.sv.exclude.0.method: 'nearclp' is not among its values ('zfail', "
     "'nearclip')"),
    ("techniques:\n  sv:\n    product: {cull: [none, cull], method: [zfail, nearclip]}\n"
     "    exclude: [{cul: cull}]\n",
     "techniques.sv.exclude.0.cul: is not a parameter of this grid's product or zip"),
    ("techniques:\n  sv:\n    product: {cull: [none, cull]}\n    set: {method: zfail}\n"
     "    exclude: [{method: zfail}]\n",
     "techniques.sv.exclude.0.method: is in set, so every combination has it"),
    ("techniques: {sv: {product: {cull: [none, cull]}, exclude: [{}]}}\n",
     "techniques.sv.exclude.0: is empty; give the parameter values"),
    ("techniques: {sv: {product: {cull: [none, cull]}, exclude: {cull: cull}}}\n",
     "techniques.sv.exclude: Input should be a valid list"),
    ("techniques: {sv: {curve: true, exclude: [{method: zpass}]}}\n",
     "techniques.sv.curve: goes with set only, not with product, zip or exclude"),
    # per-scene settings: the scene, the technique and the grid are checked like the rest
    ("techniques: curves\nper_scene:\n  nowhere: {frames: 3}\n",
     "exp.yaml:3: per_scene.nowhere: no scene 'nowhere' in the scene file"),
    ("techniques: curves\nper_scene:\n  castle: {frames: 0}\n",
     "per_scene.castle.frames: Input should be greater than or equal to 1"),
    ("techniques: curves\nper_scene:\n  castle: {rounds: 3}\n",
     "per_scene.castle.rounds: unknown key"),
    ("techniques: curves\nper_scene:\n  castle:\n    techniques: {nosuch: {}}\n",
     "exp.yaml:4: per_scene.castle.techniques.nosuch: unknown technique"),
    ("techniques: curves\nper_scene:\n  castle:\n    techniques: {sm: {curve: {bias: [1]}}}\n",
     "exp.yaml:4: per_scene.castle.techniques.sm.curve.bias: sm has no quality knob 'bias'"),
    ("techniques: curves\nper_scene:\n  castle:\n    techniques: {sm: {prodcut: {}}}\n",
     "exp.yaml:4: per_scene.castle.techniques.sm.prodcut: unknown key"),
]


@pytest.mark.parametrize(("text", "message"), BAD, ids=[m.split(":")[-1][:30] for _, m in BAD])
def test_bad_experiment_exits_2_with_one_line_and_writes_nothing(tmp_path, capsys, text, message):
    path = _write(tmp_path, text)
    out = tmp_path / "out"
    code = shadowbench(["run", str(path), "--scene-file", str(SCENE_FILE), "--out", str(out)])
    err = capsys.readouterr().err
    assert code == 2
    assert err.count("\n") == 1 and err.startswith(f"shadowbench: {path}"), err
    assert message in err, err
    assert not out.exists()


def test_exclude_leaves_out_the_combinations_that_do_not_go_together(tmp_path):
    """sv's ``cull: cull`` and ``cc`` need zpass or zfail: a product of cull and method with
    the nearclip pairs excluded plans the other 7 of its 9 combinations (a zip row goes too
    when it matches). Broken version caught (the old behaviour): no way to leave them out, so
    the whole file was refused (``cull: cull needs method zpass or zfail``)."""
    path = _write(tmp_path, """\
scenes: [box_plane]
resolutions: [[64, 64]]
techniques:
  sv:
    product: {cull: [none, cull, cc], method: [zpass, zfail, nearclip]}
    exclude: [{cull: cull, method: nearclip}, {cull: cc, method: nearclip}]
  pcf:
    zip: {k: [4, 9, 16], res: [256, 512, 1024]}
    exclude: [{k: 9}]
""")
    plan = runner.plan_runs(experiment_path=str(path), scene_file=str(SCENE_FILE), scenes=None,
                            techniques=None, overrides={})
    sv = sorted((r.params["cull"], r.params["method"]) for r in plan.runs if r.technique == "sv")
    assert sv == sorted([("none", "zpass"), ("none", "zfail"), ("none", "nearclip"),
                         ("cull", "zpass"), ("cull", "zfail"), ("cc", "zpass"), ("cc", "zfail")])
    pcf = sorted((r.params["k"], r.params["res"]) for r in plan.runs if r.technique == "pcf")
    assert pcf == [(4, 256), (16, 1024)]
    grid = config.Grid(product={"res": [512, 512.0]}, exclude=[{"res": 512}])
    assert grid.combinations() == [] and grid.count() == 2  # count: before exclusions


def test_scenes_outside_the_experiment_are_an_error(tmp_path, capsys):
    path = _write(tmp_path, "scenes: [box_plane]\ntechniques: {sm: }\n")
    out = tmp_path / "out"
    code = shadowbench(["run", str(path), "--scene-file", str(SCENE_FILE), "--scenes", "castle",
                        "--out", str(out)])
    assert code == 2 and "--scenes: castle not in" in capsys.readouterr().err
    assert not out.exists()


@pytest.mark.parametrize(("technique", "knobs", "message"), [
    ("sm", {"nosuch": (1,)}, "quality_knobs.nosuch: not a parameter of ShadowMap.Params"),
    ("sm", {"res": ()}, "quality_knobs.res: needs a non-empty list of values"),
    ("sm", {"res": (256, 8)}, "quality_knobs.res: value 8 is not valid: Input should be greater"),
    ("sm", {"res": (256, 256)}, "quality_knobs.res: 256 listed more than once"),
    ("mdsm", {"n": (1, 4)}, "quality_knobs.n: value 4 is not valid: select=minmax allows n in"),
], ids=["not a parameter", "empty", "invalid value", "repeated", "invalid at the defaults"])
def test_bad_quality_knob_declaration_exits_2_naming_technique_and_key(
        tmp_path, capsys, monkeypatch, technique, knobs, message):
    """A technique declaring a knob that is not a parameter, an empty curve or a value its
    Params refuse (with the other parameters at their defaults, as the curve runs it) makes the
    technique broken when the registry loads it: bad input where a run names it (the others
    still run: tests/harness/test_plugin_safety.py). Catches: a declaration checked only when a
    curve runs (this run asks for no curve), a knob checked against nothing, a traceback
    instead of exit 2."""
    from harness.technique import registry

    cls = registry.get(technique)
    monkeypatch.setattr(cls, "quality_knobs", knobs)
    registry.techniques.cache_clear()
    out = tmp_path / "out"
    try:
        code = shadowbench(["run", "--scene-file", str(SCENE_FILE), "--scenes", "box_plane",
                            "--techniques", technique, "--out", str(out)])
    finally:
        monkeypatch.undo()
        registry.techniques.cache_clear()
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1, err
    assert err.startswith(f"shadowbench: --techniques: {technique} is broken: technique "
                          f"{technique!r} (techniques.{technique}:"), err
    assert message in err, err
    assert not out.exists()


def test_curves_walk_one_knob_at_a_time_from_the_defaults(tmp_path):
    """``techniques: curves`` runs every registered technique at each declared value of each
    knob with every other parameter at its default (the defaults once, however many curves
    cross there); ``curve: {knob: [...]}`` picks knobs and values, ``set`` moves the base.
    Catches: a product of the knobs (pcf would run 25 settings), a knob left out, the base
    ignored, the shared point run twice."""
    from harness.technique import registry

    def plan(text):
        return runner.plan_runs(experiment_path=str(_write(tmp_path, text)),
                                scene_file=str(SCENE_FILE), scenes=None, techniques=None,
                                overrides={})

    runs = plan("scenes: [box_plane]\ntechniques: curves\n").runs
    assert {r.technique for r in runs} == set(registry.techniques())
    assert len({r.run_id for r in runs}) == len(runs)
    for name, cls in registry.techniques().items():
        defaults = cls.Params().model_dump(mode="json")
        settings = [r.params for r in runs if r.technique == name]
        # mdsm leaves ``extra`` out where it does not apply: compare the names both have
        changed = [{k for k in defaults if k in p and p[k] != defaults[k]} for p in settings]
        assert all(len(c) <= 1 and c <= set(cls.quality_knobs) for c in changed), (name, changed)
        for knob, values in cls.quality_knobs.items():
            assert {p[knob] for p in settings} == set(values), (name, knob)
    pcf = registry.get("pcf").quality_knobs
    assert len([r for r in runs if r.technique == "pcf"]) == len(pcf["res"]) + len(pcf["k"]) - 1

    chosen = plan("scenes: [box_plane]\ntechniques:\n"
                  "  mdsm: {curve: {k: [1, 4], n: [1]}, set: {res: 512}}\n"
                  "  sm: [{curve: {res: [256]}}, {}]\n").runs
    assert sorted((r.params["res"], r.params["n"], r.params["k"]) for r in chosen
                  if r.technique == "mdsm") == [(512, 1, 4), (512, 2, 1), (512, 2, 4)]
    assert sorted(r.params["res"] for r in chosen if r.technique == "sm") == [256, 1024]


def test_per_scene_settings_replace_frames_warmup_and_named_techniques_grids(tmp_path):
    """``per_scene:`` gives a scene (every size of a family, or one name@size) its own frames,
    warm-up and grids for the techniques it names; other scenes and techniques keep the
    experiment's, and the command line's --frames is every scene's. Catches: the settings
    leaking into other scenes, a named technique's grid added to the experiment's instead of
    replacing it, a sized entry losing to its family's, --frames ignored for the scene."""
    text = ("scenes: [castle, architecture]\ntriangles: [1e3, 1e4]\nframes: 9\nwarmup: 2\n"
            "techniques: {sm: {curve: {res: [256, 512]}}, sv: {}}\nper_scene:\n"
            "  architecture: {frames: 3, warmup: 1, techniques: {sm: {set: {res: 1024}}}}\n"
            "  architecture@1e4: {frames: 4}\n")

    def plan(**timing):
        return runner.plan_runs(experiment_path=str(_write(tmp_path, text)),
                                scene_file=str(SCENE_FILE), scenes=None, techniques=None,
                                overrides={}, timing=timing).runs

    runs = {(r.scene, r.technique, r.params.get("res"), r.frames, r.warmup) for r in plan()}
    assert runs == {("castle", "sm", 256, 9, 2), ("castle", "sm", 512, 9, 2),
                    ("castle", "sv", None, 9, 2),
                    ("architecture@1e3", "sm", 1024, 3, 1), ("architecture@1e3", "sv", None, 3, 1),
                    ("architecture@1e4", "sv", None, 4, 2)} | {
                       ("architecture@1e4", "sm", res, 4, 2) for res in (256, 512)}
    assert {(r.scene, r.frames) for r in plan(frames=2)} == {
        ("castle", 2), ("architecture@1e3", 2), ("architecture@1e4", 2)}


def test_grid_expands_product_times_zip_with_set_fixed():
    grid = config.Grid(product={"res": [256, 512], "k": [4, 9]},
                       zip={"bias_min": [0.01, 0.02, 0.03], "bias_max": [0.1, 0.2, 0.3]},
                       set={"sampling": "jitter"})
    combos = grid.combinations()
    assert len(combos) == 2 * 2 * 3
    assert all(c["sampling"] == "jitter" for c in combos)
    assert {(c["bias_min"], c["bias_max"]) for c in combos} == {(0.01, 0.1), (0.02, 0.2),
                                                                (0.03, 0.3)}
    assert len({json.dumps(c, sort_keys=True) for c in combos}) == len(combos)
    assert config.Grid().combinations() == [{}]


def test_run_ids_are_stable_and_change_with_what_defines_a_run(tmp_path):
    text = ("scenes: [box_plane]\nresolutions: [[64, 64]]\nframes: 1\nwarmup: 0\n"
            "techniques: {sm: {product: {res: [256, 512]}}, pcf: }\n")
    path = _write(tmp_path, text)

    def plan(**kw):
        return runner.plan_runs(experiment_path=str(path), scene_file=str(SCENE_FILE),
                                scenes=None, techniques=None, overrides=kw.get("set", {}))

    first, again = plan(), plan()
    assert [r.run_id for r in first.runs] == [r.run_id for r in again.runs]
    assert len({r.run_id for r in first.runs}) == 3
    assert first.experiment_hash == again.experiment_hash
    changed = plan(set={"sm": {"bias": 0.05}})
    assert {r.run_id for r in changed.runs if r.technique == "sm"}.isdisjoint(
        {r.run_id for r in first.runs if r.technique == "sm"})
    assert ({r.run_id for r in changed.runs if r.technique == "pcf"}
            == {r.run_id for r in first.runs if r.technique == "pcf"})
    # a run id covers the technique's code version too
    spec = first.runs[0]
    edited = runner.RunSpec(**{**spec.__dict__, "code_version": "0" * 12})
    assert edited.run_id != spec.run_id


# --- resumable runs -----------------------------------------------------------------------------

SWEEP = """
scenes: [box_plane, sphere_plane]
resolutions: [[64, 64]]
frames: 1
warmup: 0
reference: {samples: 4}
techniques:
  sm: {product: {res: [256, 512, 1024, 2048], bias: [0.01, 0.02, 0.05]}}
  pcf: {product: {k: [1, 4, 9, 16], res: [512, 1024]}}
"""
SWEEP_RUNS = 2 * (12 + 8)


def _start(experiment: Path, out: Path) -> subprocess.Popen:
    return subprocess.Popen(CLI + ["run", str(experiment), "--scene-file", str(SCENE_FILE),
                                   "--out", str(out)], cwd=ROOT, stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)


def _stop_after_first_row(proc: subprocess.Popen, out: Path, sig: int) -> int:
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if len(results.read_rows(out)) >= 1:
            proc.send_signal(sig)
            break
        time.sleep(0.01)
    proc.communicate(timeout=120)
    return proc.returncode


def _digest(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def _check_complete(out: Path, before: list[dict]):
    rows = results.read_rows(out)
    ids = [r["run_id"] for r in rows]
    assert len(ids) == len(set(ids)) == SWEEP_RUNS  # nothing lost, nothing twice
    assert all(r["status"] == "ok" for r in rows)
    assert all((out / r["array"]).is_file() for r in rows)
    by_id = {r["run_id"]: r for r in rows}
    assert all(by_id[r["run_id"]] == r for r in before)  # rows from before the kill unchanged


@pytest.mark.parametrize("sig", [signal.SIGKILL, signal.SIGINT], ids=["SIGKILL", "Ctrl-C"])
def test_a_killed_sweep_finishes_on_rerun_without_duplicates(tmp_path, sig, gl_context, capsys):
    experiment = _write(tmp_path, SWEEP)
    out = tmp_path / "out"
    code = _stop_after_first_row(_start(experiment, out), out, sig)
    before = results.read_rows(out)
    assert 1 <= len(before) < SWEEP_RUNS, "the sweep finished before it could be stopped"
    if sig == signal.SIGKILL:
        assert code == -signal.SIGKILL
    else:
        assert code == 130
        manifest = json.loads((out / "manifest.json").read_text())
        assert manifest["status"] == "interrupted" and manifest["finished"] is None

    # the reruns in this process: what the kill left is on disk, the killed process gone
    code, err = run_cli(["run", experiment, "--scene-file", SCENE_FILE, "--out", out, "--quiet"],
                        capsys)
    assert code == 0, err
    _check_complete(out, before)
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["status"] == "complete" and manifest["finished"]
    last = manifest["invocations"][-1]
    assert last["runs_rendered"] == last["runs_pending"] == SWEEP_RUNS - len(before)

    # a completed experiment run again renders nothing and leaves results.csv as it was
    digest = _digest(out / "results.csv")
    code, err = run_cli(["run", experiment, "--scene-file", SCENE_FILE, "--out", out], capsys)
    assert code == 0, err
    assert any("nothing to render" in line for line in err)
    assert _digest(out / "results.csv") == digest
    manifest = json.loads((out / "manifest.json").read_text())
    assert manifest["invocations"][-1]["runs_rendered"] == 0
    assert manifest["finished"] == last["finished"]  # when the experiment completed


def test_a_second_run_into_a_busy_directory_is_refused(tmp_path, capsys):
    experiment = _write(tmp_path, "scenes: [box_plane]\nresolutions: [[32, 32]]\n"
                                  "techniques: {sm: }\n")
    out = tmp_path / "out"
    out.mkdir()
    with (out / ".lock").open("a+") as held:
        fcntl.flock(held, fcntl.LOCK_EX)
        code = shadowbench(["run", str(experiment), "--scene-file", str(SCENE_FILE),
                            "--out", str(out), "--quiet"])
    assert code == 2 and "another shadowbench run is writing here" in capsys.readouterr().err
    assert not (out / "results.csv").exists()


def test_manifest_and_typed_results(tmp_path, gl_context):
    experiment = _write(tmp_path, "scenes: [box_plane]\nresolutions: [[48, 40]]\nframes: 1\n"
                                  "warmup: 0\nreference: {samples: 4}\ntechniques: {sm: , pcf: }\n")
    out = tmp_path / "out"
    assert shadowbench(["run", str(experiment), "--scene-file", str(SCENE_FILE),
                        "--out", str(out), "--quiet"]) == 0
    manifest = json.loads((out / "manifest.json").read_text())
    for key in ("pyrender", "PyOpenGL", "mitsuba", "drjit", "numpy"):
        assert manifest["versions"][key], key
    assert manifest["shadowbench"] and manifest["cpu"] and manifest["experiment_hash"]
    assert all(manifest["gl"][k] for k in ("vendor", "renderer", "version"))
    assert len(manifest["git_commit"]) in (40, 0)  # empty outside a git checkout
    assert manifest["started"] <= manifest["finished"]
    assert manifest["experiment_hash"] == runner.plan_runs(
        experiment_path=str(experiment), scene_file=str(SCENE_FILE), scenes=None,
        techniques=None, overrides={}).experiment_hash

    df = results.load(out)
    assert len(df) == 2 and set(df["technique"]) == {"sm", "pcf"}
    assert str(df["width"].dtype) == "int64" and list(df["width"]) == [48, 48]
    assert list(df["height"]) == [40, 40]
    for column in ("time_ms", "mae", "edge_mae", "wrong_pct", "mem_bytes", "frags_shadow"):
        assert df[column].dtype.kind == "f", column
    assert (df["mem_bytes"] > 0).all()
    assert all(isinstance(p, dict) and "res" in p for p in df["params"])
    assert os.path.isabs(str(out)) and not (out / ".results.csv.tmp").exists()
