"""harness.analysis on small hand-built result tables whose answers are worked out by hand in
each test (a front you can see, a cheapest setting you can name, a ratio you can compute)."""

from __future__ import annotations

import math

import pandas as pd
import pytest

from harness import analysis
from harness.technique import registry


def run(technique: str, time_ms: float, edge_mae: float = math.nan, *, scene: str = "a",
        size: tuple[int, int] = (512, 512), params: dict | None = None, **columns) -> dict:
    return {"scene": scene, "width": size[0], "height": size[1], "technique": technique,
            "params": params or {}, "time_ms": time_ms, "edge_mae": edge_mae, "status": "ok",
            "run_id": f"{technique}-{scene}-{time_ms}-{sorted((params or {}).items())}",
            **columns}


def table(*rows: dict, index=None) -> pd.DataFrame:
    return pd.DataFrame(list(rows), index=index)


def test_pareto_front_per_scene_and_size():
    """By eye: in scene a, A (1, .5), B (2, .3) and the twin runs E, F (4, .1) are on the front;
    C (3, .3) is beaten by B at equal error, D (2, .4) by B at equal cost; G has no time. Scene
    b's only run is on its own front though A beats it. Catches: dominance that needs both
    strictly lower (C and D on the front), a front across scenes (b's run off it), twins
    dropping each other (F off it), a result aligned by position on a non-default index."""
    df = table(run("t1", 1, .5), run("t2", 2, .3), run("t3", 3, .3), run("t4", 2, .4),
               run("t5", 4, .1), run("t6", 4, .1), run("t7", math.nan, .01),
               run("t8", 10, .9, scene="b"), index=[17, 3, 9, 4, 11, 5, 30, 2])
    front = analysis.pareto_front(df)
    assert front.index.equals(df.index)
    assert dict(zip(df["technique"], front)) == {
        "t1": True, "t2": True, "t3": False, "t4": False, "t5": True, "t6": True, "t7": False,
        "t8": True}
    # another cost column; one the results lack gives an all-False answer, not an error
    other = analysis.pareto_front(df.assign(gpu_ms=[5, 1, 1, 1, 1, 1, 1, 1]), cost="gpu_ms")
    assert dict(zip(df["technique"], other))["t1"] is False
    assert not analysis.pareto_front(df, cost="gpu_estimate_ms").any()


def test_curves_join_points_in_knob_order_with_readable_settings():
    """pcf ran res 256, 1024, 2048 at k=16 (listed out of order) and k=4 at res 1024: a res curve
    256 -> 1024 -> 2048 (base k=16) and a k curve 4 -> 16 (base res=1024), the defaults a point
    of both. sv's buffer values are not numbers: joined by time, alpha (1 ms), screen (2),
    stencil (3). mdsm's extra exists only at n=2 and must not split its n curve. sm ran once: a
    point of its own. Catches: points in row order, a categorical knob sorted by name, a
    parameter some runs lack taken as a knob, the shared point left out of one curve."""
    pcf = {"res": 1024, "k": 16, "sampling": "grid"}
    mdsm = {"res": 1024, "k": 9}
    df = table(
        run("pcf", 30, .05, params={**pcf, "res": 2048}), run("pcf", 10, .2, params={**pcf, "res": 256}),
        run("pcf", 18, .1, params=pcf), run("pcf", 12, .15, params={**pcf, "k": 4}),
        run("sv", 2, .04, params={"buffer": "stencil"}), run("sv", 1, .04, params={"buffer": "alpha"}),
        run("sv", 3, .04, params={"buffer": "screen"}),
        run("mdsm", 5, .2, params={**mdsm, "n": 1}),
        run("mdsm", 7, .1, params={**mdsm, "n": 2, "extra": "max"}),
        run("mdsm", 9, .09, params={**mdsm, "n": 3}),
        run("sm", 4, .08, params={"res": 1024}),
        run("sm", math.nan, .08, params={"res": 2048}))  # no time: no point
    c = analysis.curves(df)
    lines = {(t, k, b): list(g.sort_values("order")["setting"])
             for (t, k, b), g in c.groupby(["technique", "knob", "base"])}
    assert lines == {
        ("pcf", "res", "k=16"): ["res=256", "res=1024", "res=2048"],
        ("pcf", "k", "res=1024"): ["k=4", "k=16"],
        ("sv", "buffer", ""): ["buffer=alpha", "buffer=stencil", "buffer=screen"],
        ("mdsm", "n", ""): ["n=1", "n=2", "n=3"],
        ("sm", "", ""): [""],
    }
    res_curve = c[(c["technique"] == "pcf") & (c["knob"] == "res")].sort_values("order")
    assert list(res_curve["time_ms"]) == [10, 18, 30] and list(res_curve["value"]) == [256, 1024, 2048]
    assert {"on_front", "run_id", "params", "edge_mae"} <= set(c.columns)
    # results without the cost column: an empty answer with the same columns
    empty = analysis.curves(df, cost="gpu_estimate_ms")
    assert empty.empty and set(analysis.CURVE_COLUMNS) <= set(empty.columns)


def floor_table() -> pd.DataFrame:
    """Scene a, edge_floor 1/16: sm res 256 / 1024 / 4096 cost 1 / 2 / 8 with edge_mae 0.15,
    0.078125 (1.25 x floor), 0.06640625 (1.0625 x); pcf res 256 / 1024 cost 1.5 / 3 with
    0.09375 (1.5 x) and 0.0703125 (1.125 x). wrong_pct: sm 2, 0.8, 0.3; pcf 0.9, 0.4. Scene b,
    edge_floor 1/32: one sm run at 0.0625 (2 x its floor, 1 x scene a's)."""
    a = dict(edge_floor=0.0625, scene_ms=1.0)
    return table(
        run("sm", 1, .15, params={"res": 256}, wrong_pct=2.0, **a),
        run("sm", 2, .078125, params={"res": 1024}, wrong_pct=0.8, **a),
        run("sm", 8, .06640625, params={"res": 4096}, wrong_pct=0.3, **{**a, "scene_ms": 1.2}),
        run("pcf", 1.5, .09375, params={"res": 256}, wrong_pct=0.9, **a),
        run("pcf", 3, .0703125, params={"res": 1024}, wrong_pct=0.4, **{**a, "scene_ms": 0.7}),
        run("sm", 1, .0625, scene="b", params={"res": 256}, wrong_pct=5.0, edge_floor=0.03125,
            scene_ms=1.0))


def test_cheapest_at_error_uses_multiples_of_each_rows_floor():
    """Worked by hand (table in floor_table): at 1.1 x floor (0.06875) only sm res=4096 (8 ms)
    qualifies, pcf none; at 1.25 x (0.078125, met with equality) sm res=1024 (2 ms) beats pcf
    res=1024 (3 ms); at 1.5 x pcf res=256 (1.5 ms) beats sm res=1024; at 3 x sm res=256 (1 ms).
    wrong_pct <= 0.5: pcf res=1024 (3 ms) beats sm res=4096; <= 1: pcf res=256. Scene b (floor
    1/32) meets 3 x but not 1.5 x. Catches: a strict < (1.25 x unmet for sm), the most accurate
    run instead of the cheapest, one floor for every scene (b meeting 2 x), the wrong technique
    marked cheapest."""
    got = analysis.cheapest_at_error(floor_table(), multiples=(1.1, 1.25, 1.5, 3),
                                     wrong_pct=(0.5, 1))
    a = got[got["scene"] == "a"]

    def pick(metric, level, technique):
        r = a[(a["metric"] == metric) & (a["level"] == level) & (a["technique"] == technique)]
        assert len(r) == 1
        r = r.iloc[0]
        return (r["setting"], r["time_ms"]) if r["met"] else None

    assert pick("edge_mae", 1.1, "sm") == ("res=4096", 8) and pick("edge_mae", 1.1, "pcf") is None
    assert pick("edge_mae", 1.25, "sm") == ("res=1024", 2)
    assert pick("edge_mae", 1.25, "pcf") == ("res=1024", 3)
    assert pick("edge_mae", 1.5, "pcf") == ("res=256", 1.5)
    assert pick("edge_mae", 3, "sm") == ("res=256", 1)
    assert pick("wrong_pct", 0.5, "pcf") == ("res=1024", 3)
    assert pick("wrong_pct", 0.5, "sm") == ("res=4096", 8)
    assert pick("wrong_pct", 1, "pcf") == ("res=256", 1.5)
    cheapest = {(r.metric, r.level): r.technique for r in a[a["cheapest"]].itertuples()}
    assert cheapest == {("edge_mae", 1.1): "sm", ("edge_mae", 1.25): "sm", ("edge_mae", 1.5): "pcf",
                        ("edge_mae", 3): "sm", ("wrong_pct", 0.5): "pcf", ("wrong_pct", 1): "pcf"}
    assert a.loc[a["metric"] == "edge_mae", "threshold"].round(9).tolist()[:2] == [0.06875, 0.06875]
    b = got[(got["scene"] == "b") & (got["metric"] == "edge_mae")]
    assert dict(zip(b["level"], b["met"])) == {1.1: False, 1.25: False, 1.5: False, 3: True}


def test_cheapest_at_error_degrades_without_the_columns():
    """Results from before edge_floor existed give the wrong_pct rows only; without wrong_pct
    too, an empty table with the same columns. Catches: a KeyError on older results."""
    df = floor_table()
    no_floor = analysis.cheapest_at_error(df.drop(columns="edge_floor"), wrong_pct=(0.5,))
    assert set(no_floor["metric"]) == {"wrong_pct"} and len(no_floor) == 3
    nothing = analysis.cheapest_at_error(df.drop(columns=["edge_floor", "wrong_pct"]))
    assert nothing.empty and set(analysis.CHEAPEST_COLUMNS) <= set(nothing.columns)


def test_best_within_budget_uses_the_scenes_median_g_buffer_time():
    """Scene a's G-buffer time is the median of its runs' scene_ms (1.0, 1.0, 1.2, 1.0, 0.7) =
    1.0 ms. Budget 1x: sm res=256 (0.15), pcf nothing; 2x: sm res=1024 (0.078) beats pcf res=256
    (0.094); 4x: pcf res=1024 (3 ms, 0.0703) beats sm res=1024; 8x: sm res=4096 (0.0664).
    Catches: each row's own scene_ms (pcf res=1024 at 0.7 ms would miss 4x), the cheapest run
    instead of the most accurate, a strict < (8 ms in 8x missed)."""
    got = analysis.best_within_budget(floor_table())
    a = got[got["scene"] == "a"]
    assert set(a["budget_ms"]) == {1.0, 2.0, 4.0, 8.0}
    chosen = {(r.budget, r.technique): r.setting if r.met else None for r in a.itertuples()}
    assert chosen == {(1, "sm"): "res=256", (1, "pcf"): None, (2, "sm"): "res=1024",
                      (2, "pcf"): "res=256", (4, "sm"): "res=1024", (4, "pcf"): "res=1024",
                      (8, "sm"): "res=4096", (8, "pcf"): "res=1024"}
    best = {r.budget: r.technique for r in a[a["most_accurate"]].itertuples()}
    assert best == {1: "sm", 2: "sm", 4: "pcf", 8: "sm"}
    for lacking in ("scene_ms", "time_ms", "edge_mae"):  # e.g. flicker on still scenes only
        assert analysis.best_within_budget(floor_table().drop(columns=lacking)).empty


def test_summary_front_share_and_cost_ratio_at_equal_error():
    """Scene a: sm (1, .4) (2, .2) (4, .1); pcf (1.5, .3) (3, .1) (6, .05). At sm's errors:
    L=.4: pcf's cheapest within it 1.5 / sm's 1 = 1.5; L=.2: 3 / 2 = 1.5; L=.1: 3 / 4 = 0.75.
    Scene b: sm (1, .3) (2, .1), pcf (5, .2), sv (0.5, .5): L=.3: pcf 5 / 1 = 5; L=.1: pcf
    unreached; sv reaches neither. pcf: median of [1.5, 1.5, .75, 5] = 1.5, worst 5 at b, .3.
    Fronts: a has sm and pcf on it, b sm and sv (pcf's (5, .2) is beaten by sm's (2, .1)), so
    pcf 1 of 2, sm 2 of 2, sv 1 of 1. Catches: a ratio of runs at the same setting rather than
    at equal error, a level the technique misses counted as a ratio, a front share over every
    scene rather than those it ran on, a mean instead of the median (2.19)."""
    df = table(run("sm", 1, .4), run("sm", 2, .2), run("sm", 4, .1),
               run("pcf", 1.5, .3), run("pcf", 3, .1), run("pcf", 6, .05),
               run("sm", 1, .3, scene="b"), run("sm", 2, .1, scene="b"),
               run("pcf", 5, .2, scene="b"), run("sv", .5, .5, scene="b"))
    s = analysis.summary(df).set_index("technique")
    pcf = s.loc["pcf"]
    assert (pcf["groups"], pcf["front_groups"], pcf["front_share"]) == (2, 1, 0.5)
    assert pcf["ratio_median"] == pytest.approx(1.5)
    assert (pcf["ratio_count"], pcf["unreached"]) == (4, 1)
    assert (pcf["worst_ratio"], pcf["worst_scene"], pcf["worst_size"], pcf["worst_error"]) == (
        pytest.approx(5), "b", "512x512", .3)
    sm = s.loc["sm"]
    assert (sm["front_share"], sm["ratio_median"], sm["ratio_count"]) == (1.0, 1.0, 5)
    sv = s.loc["sv"]
    assert sv["front_share"] == 1.0 and math.isnan(sv["ratio_median"]) and sv["unreached"] == 2
    # no reference runs: the ratio columns are empty, the fronts still counted
    without = analysis.summary(df[df["technique"] != "sm"]).set_index("technique")
    assert without["ratio_median"].isna().all() and without.loc["pcf", "front_share"] == 1.0


def test_current_keeps_ok_rows_of_the_installed_code_the_last_of_each_setting():
    """Rows: an ok sm run of the installed code (kept), the same setting rerun later (kept
    instead of the first), one of an older sm code version, a failed run and a technique not
    installed here (all left out). Catches: rows of older code counted, the first of two
    reruns kept, failed or skipped rows counted."""
    version = registry.get("sm").code_version()
    df = table(run("sm", 2, .1, params={"res": 256}, code_version=version, frames=5),
               run("sm", 3, .1, params={"res": 512}, code_version="0" * 12),
               {**run("sm", 4, .1, params={"res": 1024}, code_version=version), "status": "error"},
               run("gone", 1, .1, code_version=version),
               run("sm", 2.5, .1, params={"res": 256}, code_version=version, frames=15))
    got = analysis.current(df)
    assert list(got["time_ms"]) == [2.5] and list(got["frames"]) == [15]
