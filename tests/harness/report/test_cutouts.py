"""The dashboard's Cut-outs view (harness/report/cutouts.py): per scene with alpha-tested
casters, which technique cut them out, which ignored them (and its error), which declined."""

from __future__ import annotations

import numpy as np
import pandas as pd

from harness.report import build_report, cutouts


def test_cells_say_how_each_technique_met_the_cut_outs():
    """tested and ignored cells carry their best error and median time, a declined cell its
    reason, a technique run both ways is `ignored` (it ran), a scene without cut-outs is not in
    the view, and a folder with none has no view. Catches a cell taking the worst run's error
    (3.0 and 0.4, not 1.0 and 0.2), `declined` winning over a run that ran, the opaque scene
    listed, or the view shown with nothing to show."""
    rows = pd.DataFrame({
        "scene": ["cards"] * 6 + ["plain"],
        "technique": ["sm", "sm", "sv", "sv", "ptsv", "rt", "sm"],
        "alpha": ["tested", "tested", "declined", "ignored", "declined", "tested", "none"],
        "status": ["ok", "ok", "skipped", "ok", "skipped", "ok", "ok"],
        "error": ["", "", "sv does not treat alpha-tested casters", "",
                  "ptsv does not treat alpha-tested casters", "", ""],
        "wrong_pct": [3.0, 1.0, np.nan, 12.0, np.nan, 0.0, 0.5],
        "edge_ratio": [0.4, 0.2, np.nan, 5.0, np.nan, 1.0, 1.0],
        "time_ms": [2.0, 4.0, np.nan, 7.0, np.nan, 9.0, 1.0]})
    table = cutouts.cutout_table(rows)
    assert table["techniques"] == ["ptsv", "rt", "sm", "sv"]
    assert [scene for scene, _ in table["rows"]] == ["cards"]
    ptsv, rt, sm, sv = table["rows"][0][1]
    assert (sm["handling"], sm["wrong_pct"], sm["edge_ratio"], sm["time_ms"]) == \
        ("tested", 1.0, 0.2, 3.0)
    assert (sv["handling"], sv["wrong_pct"], sv["runs"]) == ("ignored", 12.0, 1)
    assert sv["reason"].startswith("sv does not treat")
    assert ptsv["handling"] == "declined" and ptsv["wrong_pct"] is None and ptsv["reason"]
    assert rt["handling"] == "tested"
    assert cutouts.cutout_table(rows[rows["scene"] == "plain"]) is None
    assert cutouts.cutout_table(rows.drop(columns="alpha")) is None


def test_the_page_shows_the_view_only_where_cut_outs_were_met(tmp_path, make_results):
    """A folder whose runs met cut-outs gets the Cut-outs section and its link; one without
    does not. Catches the template's section or link missing, or shown on every page."""
    met = build_report(make_results(tmp_path / "met", [{"alpha": "tested"}])).read_text()
    assert 'id="cutouts"' in met and 'href="#cutouts"' in met and ">tested" in met
    plain = build_report(make_results(tmp_path / "plain", [{"alpha": "none"}])).read_text()
    assert 'id="cutouts"' not in plain and 'href="#cutouts"' not in plain
