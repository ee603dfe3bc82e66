"""Does it stay stable: scenes x techniques over every shown run, failing where a run failed,
produced NaN/Inf or a V outside [0, 1]."""

from __future__ import annotations

V_TOLERANCE = 1e-6  # V outside [0 - tol, 1 + tol] is a defect, not rounding


def stability_cells(rows) -> dict[tuple[str, str], dict]:
    """(scene, technique) -> counts of runs, failures, NaN/Inf and V outside [0, 1], the worst
    wrong_pct, and whether the cell fails (any failure, NaN/Inf or V out of range)."""
    cells = {}
    for (scene, technique), g in rows.groupby(["scene", "technique"], sort=True):
        ok = g[g["status"] == "ok"]
        errors = g[g["status"] == "error"]
        nonfinite = int((g["nonfinite"].fillna(0) > 0).sum()) if "nonfinite" in g else 0
        out_of_range = int(((g["v_min"] < -V_TOLERANCE) | (g["v_max"] > 1 + V_TOLERANCE)).sum())
        wrong = ok["wrong_pct"].dropna()
        cells[(scene, technique)] = dict(
            runs=len(g), ok=len(ok), errors=len(errors),
            skipped=int((g["status"] == "skipped").sum()), nonfinite=nonfinite,
            out_of_range=out_of_range, worst_wrong_pct=float(wrong.max()) if len(wrong) else None,
            first_error=errors["error"].iloc[0] if len(errors) else "",
            fails=bool(len(errors) or nonfinite or out_of_range))
    return cells


def stability_table(rows) -> dict:
    """The table's scenes, techniques and cells (None where a technique did not run)."""
    cells = stability_cells(rows)
    scenes = list(dict.fromkeys(rows["scene"]))
    techniques = sorted(set(rows["technique"]))
    return {"techniques": techniques,
            "rows": [(scene, [cells.get((scene, t)) for t in techniques]) for scene in scenes]}
