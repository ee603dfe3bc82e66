"""Which technique handles cut-outs: per scene with alpha-tested casters, per technique what its
runs did with them (the ``alpha`` column: ``tested``, ``ignored``, ``declined``), with the
error and time of those that ran (an ``ignored`` run's error is what drawing them opaque
costs) and the reason of those that declined."""

from __future__ import annotations

HANDLED = ("tested", "ignored", "declined")


def cutout_table(rows) -> dict | None:
    """The view's scenes, techniques and cells ((scene, [cell or None per technique])); None
    where no shown run met a cut-out (or the folder predates the ``alpha`` column). A cell:
    ``handling`` (a technique's runs on one scene share it, one per setting of ``alpha``:
    ``ignored`` over ``declined`` where both were run), the runs that ran, their best
    ``wrong_pct`` and ``edge_ratio`` and median ``time_ms``, and a decline's reason."""
    if "alpha" not in rows or not rows["alpha"].isin(HANDLED).any():
        return None
    cut = rows[rows["alpha"].isin(HANDLED)]
    cells = {}
    for (scene, technique), g in cut.groupby(["scene", "technique"], sort=True):
        ran = g[g["status"] == "ok"]
        handling = next(h for h in HANDLED if (g["alpha"] == h).any())
        declined = g[g["alpha"] == "declined"]

        def best(column):
            values = ran[column].dropna() if column in ran else ()
            return float(values.min()) if len(values) else None

        cells[(scene, technique)] = dict(
            handling=handling, runs=len(ran), wrong_pct=best("wrong_pct"),
            edge_ratio=best("edge_ratio"),
            time_ms=float(ran["time_ms"].median()) if len(ran) else None,
            reason=str(declined["error"].iloc[0]) if len(declined) else "")
    techniques = sorted(set(cut["technique"]))
    scenes = list(dict.fromkeys(cut["scene"]))
    return {"techniques": techniques,
            "rows": [(scene, [cells.get((scene, t)) for t in techniques]) for scene in scenes]}
