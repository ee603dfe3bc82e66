"""shadowbench tune (issue 46): the search finds a bias known from an independent sweep, under
its constraints; bad input; what it stores (tuned.yaml usable as an experiment, held-out error,
the rows' parts); the bias window; the verdict on tuned runs in the analysis and the report."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml
from helpers import GOOD, result_rows, run_cli, write_scenes

from harness import config
from harness.analysis import tuning
from harness.scene import build_scene

# A floor under a light at 45 degrees, a thin wall standing on it (a contact shadow, so bias
# beyond what acne needs lifts the shadow off the wall: peter-panning, edge error and then
# leaks grow with it) and, beyond the floor, a ramp the light grazes at 80 degrees (its acne
# needs about five times the floor's bias; it casts its shadow out of view, so its acne lies
# outside every edge band). Without the acne limit the least edge error is at the floor's
# bias (acne left on the ramp); with it, at the smallest bias that clears the ramp too.
KNOWN = {
    "resolution": [160, 120],
    "camera": {"position": [1, -8, 6], "target": [1.5, 0, 0.5], "up": [0, 0, 1], "yfov": 50,
               "near": 0.1, "far": 100},
    "light": {"type": "directional", "direction": [-1, 0, -1]},
    "effects": ["shadow"],
    "objects": [
        {"shape": "plane", "size": [8, 8]},
        {"shape": "plane", "size": [1.5, 3], "rotate": [0, 90, 0], "translate": [0, 0, 0.75]},
        {"shape": "plane", "size": [2, 3], "rotate": [0, -35, 0], "translate": [5.5, 0, 1]},
    ]}
MAP = 64
SAMPLES = 4
BUDGET = 30
# the independent sweep: the constant bias alone, a quarter decade apart
SWEEP_STEP = 0.25
SWEEP = 10.0 ** np.arange(-2.0, 0.51, SWEEP_STEP)


def _experiment(tmp_path, techniques: dict, frames: int = 1) -> str:
    path = tmp_path / "tune.yaml"
    path.write_text(yaml.safe_dump({"techniques": techniques, "frames": frames, "warmup": 0,
                                    "reference": {"samples": SAMPLES}}))
    return str(path)


@pytest.fixture(scope="module")
def known(tmp_path_factory, gl_context):
    """The known scene tuned once: sm at map 64 with its constant bias alone searched (slope
    and normal offset fixed at 0, the bias mode at slope, by --set), BUDGET settings."""
    folder = tmp_path_factory.mktemp("tune")
    scene_file = write_scenes(folder, {"known": KNOWN})
    experiment = _experiment(folder, {"sm": {"set": {"res": MAP}}})
    out = folder / "out"
    args = ["tune", experiment, "--scene-file", scene_file, "--budget", BUDGET,
            "--set", "sm.slope_bias=0", "--set", "sm.normal_offset=0", "--set", "sm.bias_mode=slope",
            "--out", out, "--quiet"]
    from harness.cli import main

    code = main([str(a) for a in args])
    return {"out": out, "code": code, "scene_file": scene_file, "args": args}


def _rows(out, tuning_part: str):
    return [r for r in result_rows(out) if r["tuning"] == tuning_part]


def test_the_search_finds_the_bias_an_independent_sweep_finds(known, evaluate):
    """The best setting's bias is within one sweep step of the sweep's best: the lowest
    edge_mae among biases with acne <= 0.1 % and leak <= sm's at defaults + 0.1. (Tried once
    with the constraint ignored in tune_search.Search: its best was 0.079, where the floor is
    clear and the ramp is not, 3.4 steps below the sweep's 0.56, and this failed.)"""
    assert known["code"] == 0
    scene = build_scene("known", config.Scene(**KNOWN))
    defaults = evaluate(scene, "sm", {"res": MAP}, samples=SAMPLES).row
    limit = defaults["leak_pct"] + tuning.LEAK_MARGIN
    sweep = []
    for bias in SWEEP:
        row = evaluate(scene, "sm", {"res": MAP, "bias": float(bias), "slope_bias": 0.0,
                                     "normal_offset": 0.0}, samples=SAMPLES).row
        if row["acne_pct"] <= tuning.ACNE_LIMIT and row["leak_pct"] <= limit:
            sweep.append((row["edge_mae"], float(bias)))
    assert sweep, "the scene must have a window of qualifying biases"
    # and without the limits, the least edge error lies elsewhere (the test would be blind)
    unconstrained = min((evaluate(scene, "sm", {"res": MAP, "bias": float(b), "slope_bias": 0.0,
                                                "normal_offset": 0.0}, samples=SAMPLES)
                         .row["edge_mae"], float(b)) for b in SWEEP)
    known_best = min(sweep)[1]
    assert abs(math.log10(unconstrained[1]) - math.log10(known_best)) > SWEEP_STEP
    (best,) = _rows(known["out"], "best")
    tuned_bias = json.loads(best["params"])["bias"]
    assert abs(math.log10(tuned_bias) - math.log10(known_best)) <= SWEEP_STEP, (tuned_bias,
                                                                                 known_best)
    assert best["tuning_met"] == "1"


def test_every_run_is_a_row_with_its_part_and_view(known):
    rows = result_rows(known["out"])
    parts = {r["tuning"] for r in rows}
    assert parts == {"baseline", "search", "held_out", "window", "defaults", "best"}
    assert len(_rows(known["out"], "search")) <= BUDGET
    assert {r["tuned_on"] for r in rows} == {"known"}
    (best,) = _rows(known["out"], "best")
    assert best["scene"] == "known" and best["tune_point"] == f"res={MAP}"
    assert int(best["tuning_trials"]) == len(_rows(known["out"], "search"))
    # a still scene: the best setting also scored on the orbited view
    assert math.isfinite(float(best["held_out_edge_mae"]))
    (held,) = [r for r in _rows(known["out"], "held_out") if r["params"] == best["params"]]
    assert held["scene"] == "known.orbit10"
    assert float(held["edge_mae"]) == float(best["held_out_edge_mae"])
    assert float(best["bias_window"]) >= 0


def test_a_rerun_renders_nothing_and_chooses_the_same(known, capsys):
    from harness.run import read_manifest

    before = {r["run_id"]: r["params"] for r in _rows(known["out"], "best")}
    code, _ = run_cli(known["args"], capsys)
    assert code == 0
    assert read_manifest(known["out"])["invocations"][-1]["runs_rendered"] == 0
    assert {r["run_id"]: r["params"] for r in _rows(known["out"], "best")} == before


def test_tuned_yaml_runs_the_settings_chosen(known):
    """DIR/tuned.yaml is an experiment: planned, it runs exactly the best settings."""
    from harness.run import plan_runs

    path = known["out"] / "tuned.yaml"
    plan = plan_runs(experiment_path=str(path), scene_file="unused.yaml", scenes=None,
                     techniques=None, overrides={})
    best = {json.dumps(json.loads(r["params"]), sort_keys=True)
            for r in _rows(known["out"], "best")}
    assert {spec.params_json for spec in plan.runs} == best
    assert {spec.scene for spec in plan.runs} == {"known"}
    # a grid's set: is usable on its own in another experiment
    grid = yaml.safe_load(path.read_text())["per_scene"]["known"]["techniques"]["sm"][0]
    config.Grid.model_validate(grid)


def test_the_verdict_and_the_report_use_the_tuned_runs(known):
    from harness import analysis, results
    from harness.report import build_report

    current = analysis.current(results.load(known["out"]))
    verdict = tuning.verdict_rows(current)
    assert set(verdict["tuning"]) == {"best"}
    gain = tuning.tuning_gain(current)
    assert list(gain["technique"]) == ["sm"] and gain["tuning_gain"].iloc[0] > 0
    (curve,) = tuning.window_curves(current)
    assert len(curve["scale"]) >= 2
    page = build_report(known["out"]).read_text()
    assert 'id="tuning"' in page and "bias-window-plot" in page and "At their defaults" in page


def _tiny(tmp_path, **changes):
    scene = json.loads(json.dumps(GOOD))
    scene.update(changes)
    return write_scenes(tmp_path, {"s": scene})


@pytest.mark.parametrize("budget", ["0", "1001", "-3"])
def test_a_budget_out_of_range_is_one_line_and_nothing_written(tmp_path, capsys, budget):
    out = tmp_path / "out"
    code, err = run_cli(["tune", "--scene-file", _tiny(tmp_path), "--budget", budget, "--out",
                         out], capsys)
    assert code == 2 and len(err) == 1 and "--budget" in err[0], err
    assert not out.exists()


def test_a_technique_with_nothing_tunable_is_named_and_skipped(tmp_path, capsys, gl_context):
    experiment = _experiment(tmp_path, {"sv": {}, "sm": {}})
    out = tmp_path / "out"
    code, err = run_cli(["tune", experiment, "--scene-file", _tiny(tmp_path), "--budget", "2",
                         "--out", out, "--quiet"], capsys)
    assert code == 0, err
    assert [line for line in err if line.startswith("sv")] == [
        "sv: nothing tunable (its class declares no tunable settings); skipped"]
    rows = result_rows(out)
    assert {r["technique"] for r in rows} == {"sm"}
    assert {r["tuning"] for r in rows if r["tuning"] == "best"} == {"best"}


def test_only_untunable_techniques_tune_nothing(tmp_path, capsys):
    out = tmp_path / "out"
    code, err = run_cli(["tune", "--scene-file", _tiny(tmp_path), "--techniques", "sv",
                         "--out", out], capsys)
    assert code == 0 and err[-1] == "nothing to tune", err
    assert not (out / "results.csv").exists()


def test_an_unreachable_limit_is_said_per_technique_and_the_closest_kept(
        tmp_path, capsys, gl_context, monkeypatch):
    """A leak limit below zero (no setting can meet it): one line per point, exit 0, the
    closest setting stored as best with tuning_met 0 and written to tuned.yaml."""
    from harness.run import tune

    monkeypatch.setattr(tune, "LEAK_MARGIN", -1.0)
    experiment = _experiment(tmp_path, {"sm": {}, "silhouette": {}})
    out = tmp_path / "out"
    code, err = run_cli(["tune", experiment, "--scene-file", _tiny(tmp_path), "--budget", "2",
                         "--out", out, "--quiet"], capsys)
    assert code == 0, err
    unmet = [line for line in err if "no setting meets acne <= 0.1 %" in line]
    assert len(unmet) == 2 and any(" sm " in line for line in unmet), err
    best = _rows(out, "best")
    assert {r["technique"] for r in best} == {"sm", "silhouette"}
    assert {r["tuning_met"] for r in best} == {"0"}
    assert (out / "tuned.yaml").is_file()


def test_a_moving_scene_is_tuned_on_its_first_frame_and_scored_on_every_frame(
        tmp_path, capsys, gl_context):
    experiment = _experiment(tmp_path, {"sm": {"set": {"res": 64}}})
    out = tmp_path / "out"
    scene_file = _tiny(tmp_path, motion={"frames": 3, "camera_orbit": 20})
    code, err = run_cli(["tune", experiment, "--scene-file", scene_file, "--budget", "2",
                         "--out", out, "--quiet"], capsys)
    assert code == 0, err
    search = _rows(out, "search")
    assert {r["scene"] for r in search} == {"s.frame0"} and {r["frames"] for r in search} == {"1"}
    (best,) = _rows(out, "best")
    assert best["scene"] == "s" and best["tuned_on"] == "s.frame0" and best["frames"] == "3"
    assert best["held_out_edge_mae"] == ""  # a moving scene has its frames, not a second view
    assert not _rows(out, "held_out")


# --- the bias window, a pure function ------------------------------------------------------

def test_bias_window_on_a_hand_built_table():
    """Nine scales half a decade apart, 10^-2 .. 10^2: acne below 10^-0.5, leaks over the
    limit above 10^1. Each qualifying scale stands for half a decade, so the four of them make
    a window of 2 decades. (Tried once counting the span between the first and last qualifying
    scales instead: 1.5, and this failed.)"""
    scale = 10.0 ** (np.arange(-4, 5) / 2)
    acne = np.array([5, 2, 0.5, 0.05, 0, 0, 0, 0, 0])
    leak = np.array([0, 0, 0, 0, 0, 0.1, 0.15, 0.3, 2.0])
    assert tuning.bias_window(scale, acne, leak, leak_limit=0.15) == pytest.approx(2.0)
    assert tuning.bias_window(scale, acne, leak, leak_limit=0.2, acne_limit=1.0) == \
        pytest.approx(2.5)
    # the order of the rows does not matter; a gap splits the window, the widest counts
    shuffled = np.random.default_rng(0).permutation(9)
    assert tuning.bias_window(scale[shuffled], acne[shuffled], leak[shuffled],
                              leak_limit=0.15) == pytest.approx(2.0)
    gap = acne.copy()
    gap[5] = 1.0
    assert tuning.bias_window(scale, gap, leak, leak_limit=0.15) == pytest.approx(1.0)
    assert tuning.bias_window(scale, acne + 1, leak, leak_limit=0.15) == 0.0
    assert tuning.bias_window(scale[:1], acne[:1] * 0, leak[:1], leak_limit=1) == 0.0
    with_nan = acne.astype(float)
    with_nan[4] = np.nan
    assert tuning.bias_window(scale, with_nan, leak, leak_limit=0.15) == pytest.approx(1.0)


@pytest.mark.parametrize("scale, acne, leak, message", [
    ([1, 2], [0], [0, 0], "1-D arrays of one length"),
    ([[1, 2]], [[0, 0]], [[0, 0]], "1-D arrays"),
    ([1, 0], [0, 0], [0, 0], "> 0"),
    ([1, 1], [0, 0], [0, 0], "more than once"),
])
def test_bias_window_checks_its_arrays(scale, acne, leak, message):
    with pytest.raises(ValueError, match=message):
        tuning.bias_window(scale, acne, leak, leak_limit=0.1)


# --- what a technique declares -------------------------------------------------------------

@pytest.mark.parametrize("tunable, bias_terms, message", [
    ({"nope": ("log", 1e-3, 1.0)}, (), "nope: not a parameter"),
    ({"res": ("choice", (256, 512))}, (), "res: is a quality knob"),
    ({"bias": ("log", 0.0, 1.0)}, (), "log range needs low > 0"),
    ({"bias": ("log", 0.1, 1.0)}, (), "the default 0.02 is outside"),
    ({"bias": ("float", 1.0, 0.5)}, (), "low < high"),
    ({"bias": ("gauss", 0.0, 1.0)}, (), "kind one of"),
    ({"slope_bias": ("float", 0.0, 100.0)}, (), "100.0 is not valid"),
    ({"bias": ("choice", (0.02,))}, (), "two values or more"),
    ({"bias": ("choice", (0.02, 0.1))}, ("bias",), "is not a tunable range"),
    ({"bias": ("log", 1e-3, 1.0)}, ("slope_bias",), "is not a tunable range"),
])
def test_bad_tunable_declarations_are_refused_naming_the_parameter(tunable, bias_terms,
                                                                   message):
    from harness.technique.tunable import check_tunable
    from techniques.sm.sm import ShadowMap

    declared = type("Declared", (ShadowMap,), {"tunable": tunable, "bias_terms": bias_terms})
    with pytest.raises(ValueError, match=message):
        check_tunable(declared)


def test_every_map_technique_declares_its_tunable_settings():
    from harness.technique import registry

    declared = {name for name, cls in registry.techniques().items() if cls.tunable}
    assert {"sm", "pcf", "mdsm", "csm", "silhouette", "psm", "lispsm", "gmnpr"} <= declared
    assert registry.broken() == {}
