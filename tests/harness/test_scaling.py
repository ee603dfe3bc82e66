"""harness.analysis.scaling on synthetic tables: a known power law to recover, a crossing worked out by
hand, size bands at their edges."""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd
import pytest

from harness.analysis import scaling


def family_run(technique: str, triangles: float, time_ms: float, edge_mae: float = 0.1, *,
               family: str = "arch", params: dict | None = None, **columns) -> dict:
    return {"scene": f"{family}@{triangles:g}", "family": family, "triangles": triangles,
            "width": 256, "height": 256, "technique": technique, "params": params or {},
            "time_ms": time_ms, "edge_mae": edge_mae, "edge_floor": 0.1, "status": "ok",
            "run_id": f"{technique}-{family}-{triangles}-{sorted((params or {}).items())}",
            **columns}


def power_law(n: int, seed: int = 0) -> pd.DataFrame:
    """sm at n sizes from 10^3 to 10^6: time = 3 T^0.7 and its map pass's fragments = 0.5 T^1.2,
    each times lognormal noise (sigma 0.05); a second setting at twice the time."""
    rng = np.random.default_rng(seed)
    rows = []
    for t in np.logspace(3, 6, n):
        for res, factor in ((1024, 1), (2048, 2)):
            noise = np.exp(rng.normal(0, 0.05, size=2))
            passes = [{"name": "shadow_map", "ms": 1.0, "fragments": 0.5 * t ** 1.2 * noise[1]},
                      {"name": "shading", "ms": 2.0, "fragments": 100.0}]
            rows.append(family_run("sm", t, factor * 3 * t ** 0.7 * noise[0],
                                   params={"res": res}, passes=json.dumps(passes)))
    return pd.DataFrame(rows)


def test_scaling_recovers_a_known_exponent_within_its_interval():
    """time = 3 T^0.7 with 5 % noise at 6 sizes: exponent 0.7 inside the 95 % interval, the
    prefactor near 3 (6 for res=2048, the same exponent), the map pass's fragments at 1.2; with
    24 sizes the interval is narrower. Catches: a fit in linear space, an interval from the
    standard error alone (no t quantile: too narrow at 6 points), settings pooled into one fit,
    pass counts mixed into the frame's."""
    few = scaling.scaling(power_law(6))
    frame = few[(few["pass_name"] == scaling.FRAME) & (few["metric"] == "time_ms")]
    assert sorted(frame["setting"]) == ["res=1024", "res=2048"]
    fit = frame.set_index("setting").loc["res=1024"]
    assert fit["ci_low"] < 0.7 < fit["ci_high"] and fit["exponent"] == pytest.approx(0.7, abs=0.05)
    assert fit["prefactor"] == pytest.approx(3, rel=0.25) and fit["points"] == 6
    t_quantile = (fit["ci_high"] - fit["exponent"]) / fit["stderr"]
    assert t_quantile == pytest.approx(2.776, abs=1e-3)  # Student's t, 4 degrees of freedom
    assert frame.set_index("setting").loc["res=2048", "prefactor"] == pytest.approx(6, rel=0.25)
    shadow_map = few[(few["pass_name"] == "shadow_map") & (few["metric"] == "frags_shadow")
                     & (few["setting"] == "res=1024")].iloc[0]
    assert shadow_map["ci_low"] < 1.2 < shadow_map["ci_high"]
    shading = few[(few["pass_name"] == "shading") & (few["metric"] == "frags_shadow")].iloc[0]
    assert shading["exponent"] == pytest.approx(0, abs=1e-9)
    assert not ((few["pass_name"] == "shading") & (few["metric"] == "vertex_invocations")).any()
    many = scaling.scaling(power_law(24, seed=1))
    wide = fit["ci_high"] - fit["ci_low"]
    narrow = many[(many["pass_name"] == scaling.FRAME) & (many["metric"] == "time_ms")
                  & (many["setting"] == "res=1024")].iloc[0]
    assert narrow["ci_low"] < 0.7 < narrow["ci_high"]
    assert narrow["ci_high"] - narrow["ci_low"] < wide / 2


def test_scaling_keeps_families_apart_and_skips_what_cannot_be_fitted():
    """Two families with exponents 1 and 2 (exact) give 1 and 2, not a pooled slope; two sizes
    give the exponent with no interval; one size and ordinary scenes give no fit. Catches:
    fits across families, a zero-width interval at two points, a crash on one size."""
    rows = [family_run("sv", t, t / 100) for t in (1e3, 1e4, 1e5)]
    rows += [family_run("sv", t, (t / 1e3) ** 2, family="foliage") for t in (1e3, 1e4)]
    rows += [family_run("sm", 1e3, 1.0), {**family_run("sm", 2e3, 2.0), "family": ""}]
    got = scaling.scaling(pd.DataFrame(rows), metrics=("time_ms",))
    exponents = dict(zip(zip(got["family"], got["technique"]), got["exponent"]))
    assert exponents == {("arch", "sv"): pytest.approx(1), ("foliage", "sv"): pytest.approx(2)}
    assert math.isnan(got.set_index("family").loc["foliage", "ci_low"])
    with pytest.raises(ValueError, match="overdraw"):
        scaling.scaling(pd.DataFrame(rows), metrics=("overdraw",))
    no_family = pd.DataFrame(rows).drop(columns="family")
    assert scaling.scaling(no_family).empty


def crossing_table() -> pd.DataFrame:
    """Family arch, edge_floor 0.1 (level 1.5: edge_mae <= 0.15). sm costs 1, 2, 4, 8 ms at
    10^3..10^6; sv costs 0.25, 1, 8, 32: ratios 0.25, 0.5, 2, 4. sv's cheaper setting (0.1 ms
    at every size) misses the level (edge_mae 0.3), and at 10^6 a cheap sm run misses it too."""
    rows = []
    for t, sm_ms, sv_ms in ((1e3, 1, 0.25), (1e4, 2, 1), (1e5, 4, 8), (1e6, 8, 32)):
        rows.append(family_run("sm", t, sm_ms, 0.12, params={"res": 2048}))
        rows.append(family_run("sv", t, sv_ms, 0.1, params={"buffer": "stencil"}))
        rows.append(family_run("sv", t, 0.1, 0.3, params={"buffer": "alpha"}))
    rows.append(family_run("sm", 1e6, 0.5, 0.3, params={"res": 256}))
    return pd.DataFrame(rows)


def test_crossover_interpolates_in_log_log_between_the_bracketing_sizes():
    """By hand: sv/sm is 0.5 at 10^4 and 2 at 10^5; log10 ratio -0.301 -> +0.301 crosses 0
    half way, at 10^4.5 = 31,623 triangles. The reversed pair never starts to cost more
    (sm is dearer, then cheaper): None. Catches: the cheap settings that miss the level taken
    (sv would be cheaper at every size: no crossing), linear rather than log interpolation
    (55,000), the first size where a costs more (10^5) reported as the crossing."""
    df = crossing_table()
    crossing = scaling.crossover(df, "sv", "sm")
    assert crossing.triangles == pytest.approx(10 ** 4.5)
    assert (crossing.below["triangles"], crossing.below["ratio"]) == (1e4, 0.5)
    assert (crossing.above["triangles"], crossing.above["ratio"]) == (1e5, 2)
    assert crossing.above["setting_a"] == "buffer=stencil"
    assert scaling.crossover(df, "sm", "sv") is None
    costs = scaling.equal_error_costs(df, "sv", "sm")
    assert list(costs["ratio"]) == [0.25, 0.5, 2, 4] and list(costs["cost_b"]) == [1, 2, 4, 8]


def test_crossover_is_none_without_a_lasting_crossing_and_refuses_mixed_families():
    """sv dearer again after a dip (ratios 2, 0.5, 2, 0.5 ... ends cheaper): None; a ratio of
    exactly 1 at 10^4 then 2: the crossing is 10^4. Results without a family column: None.
    Rows of two families: ValueError naming them. Catches: a crossing reported while a is
    cheaper at the largest size, an off-by-one at equality, a KeyError on ordinary results,
    sizes of different families interpolated together."""
    def pair(ratios):
        return pd.DataFrame([r for t, q in zip((1e3, 1e4, 1e5, 1e6), ratios) for r in (
            family_run("sm", t, 1.0), family_run("sv", t, q))])

    assert scaling.crossover(pair([2, 0.5, 2, 0.5]), "sv", "sm") is None
    assert scaling.crossover(pair([0.5, 1, 2, 3]), "sv", "sm").triangles == pytest.approx(1e4)
    assert scaling.crossover(pair([0.5, 2, 3, 4]).drop(columns="family"), "sv", "sm") is None
    mixed = pd.concat([pair([1, 2, 3, 4]), pair([1, 2, 3, 4]).assign(family="foliage")])
    with pytest.raises(ValueError, match="arch 256x256, foliage 256x256"):
        scaling.crossover(mixed, "sv", "sm")


def test_size_bands_keep_a_family_size_in_its_band():
    """9,600 and 104,000 triangles (a 10^4 and a 10^5 family scene, within their 5 %) are both
    in the middle band; 2,500 below, 900,000 above; a row without triangles in the unknown
    band. Catches: the bare edges (9,600 below 10^4, 104,000 above 10^5), a missing count
    read as 0 (the lowest band)."""
    df = pd.DataFrame({"triangles": [2500, 9600, 104000, 9e5, math.nan, 0]})
    assert list(scaling.size_band(df)) == [
        "below 10⁴ triangles", "10⁴ to 10⁵ triangles", "10⁴ to 10⁵ triangles",
        "above 10⁵ triangles", scaling.UNKNOWN_SIZE, scaling.UNKNOWN_SIZE]
    assert set(scaling.size_band(df.drop(columns="triangles"))) == {scaling.UNKNOWN_SIZE}
