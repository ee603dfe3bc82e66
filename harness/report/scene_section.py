"""One scene's section: its description, the cost-accuracy plot, which technique to pick at
each error threshold and time budget, the image viewer and every run in a table (a row opens
its images)."""

from __future__ import annotations

import json

import pandas as pd

from .. import analysis
from . import plots
from .motion import motion_part
from .viewer import SceneImages

# the run table's columns where the results have them: column -> (heading, digits)
RUN_COLUMNS = {
    "time_ms": ("time ms", 3), "setup_ms": ("setup ms", 3), "gpu_estimate_ms": ("GPU est. ms", 3),
    "edge_mae": ("edge_mae", 3), "edge_floor": ("edge_floor", 3),
    "edge_ratio": ("× floor", 3), "acne_pct": ("acne %", 3), "leak_pct": ("leak %", 3),
    "wrong_pct": ("wrong %", 3), "mae": ("mae", 3), "flip": ("flip", 3), "levels": ("levels", 3),
    "mem_bytes": ("memory B", 3), "fetches_per_px": ("fetches/px", 3),
    "overdraw": ("overdraw", 3), "frags_shadow": ("shadow frags", 3),
    "flicker": ("flicker", 3), "flicker_max": ("flicker max", 3), "pop_frames": ("pops", 3),
    "world_flicker": ("world flicker", 3), "world_changed_pct": ("world changed %", 3),
    "mae_max": ("mae worst frame", 3),
    "vertex_invocations": ("vertex inv.", 3), "fragment_invocations": ("fragment inv.", 3),
    "primitives": ("primitives", 3),
}


def run_key(rows):
    """Scene, size, technique and parameters: what makes two rows the same run."""
    return list(zip(rows["scene"], rows["width"], rows["height"], rows["technique"],
                    rows["params"].map(lambda p: json.dumps(p, sort_keys=True))))


def shown_rows(everything, current):
    """The current runs and the latest failed or skipped row of each run no current run
    replaces (same scene, size, technique and parameters)."""
    done = set(run_key(current))
    others = everything[everything["status"] != "ok"]
    others = others.assign(_key=run_key(others))
    others = (others[~others["_key"].isin(done)].drop_duplicates("_key", keep="last")
              .drop(columns="_key"))
    return pd.concat([current, others], ignore_index=True)


def scene_section(images: SceneImages, shown, current, cheapest, budgets,
                  colours: dict[str, str], description: str | None) -> dict:
    """Everything the template needs for one scene (``shown``, ``current``, ``cheapest`` and
    ``budgets`` already cut to it)."""
    shown = shown.assign(_pixels=shown["width"] * shown["height"]).sort_values(
        ["_pixels", "technique"], kind="stable").reset_index(drop=True)
    settings = analysis.setting_labels(shown)
    runs = []
    for i, row in shown.iterrows():
        pictures, why = images.run(row)
        runs.append({"i": i, "technique": row["technique"],
                     "size": plots.size_label(row["width"], row["height"]),
                     "setting": settings[i], "status": row["status"],
                     "error": row.get("error") or "",
                     "params": ", ".join(f"{k}={v}" for k, v in row["params"].items()),
                     **plots.run_values(row), "table": [plots.number(row.get(c))
                                                        for c in RUN_COLUMNS if c in shown],
                     "images": pictures, "unavailable": why})
    run_index = {rid: i for i, rid in enumerate(shown["run_id"])}
    policy = plots.cost_policy(shown)
    sizes = sorted({(int(w), int(h)) for w, h in zip(shown["width"], shown["height"])},
                   key=lambda s: s[0] * s[1])
    references = {plots.size_label(*s): images.references.get(plots.size_label(*s))
                  for s in sizes}
    return {
        "name": images.scene, "description": description,
        "sizes": [plots.size_label(*s) for s in sizes],
        # a cost column's heading names the cost policy its times were measured under
        "columns": [(c, f"{RUN_COLUMNS[c][0]} ({policy})" if c in plots.COSTS
                     else RUN_COLUMNS[c][0]) for c in RUN_COLUMNS if c in shown],
        "runs": runs, "colours": colours,
        "plot": plots.cost_accuracy(current, run_index) if len(current) else None,
        "cheapest": threshold_table(cheapest, sizes),
        "budgets": budget_table(budgets, sizes),
        "references": references,
        "thumbnail": images.thumbnail(),
        "motion": motion_part(images.folder, shown, colours),
    }


def threshold_table(cheapest, sizes) -> list[dict]:
    """Rows of thresholds (edge_mae within m x edge_floor, wrong_pct within t %), a cell per
    size: the cheapest technique and setting, and which other techniques meet it."""
    out = []
    for (metric, level), g in cheapest.groupby(["metric", "level"], sort=False):
        label = (f"edge_mae ≤ {level:g} × edge_floor" if metric != "wrong_pct"
                 else f"wrong_pct ≤ {level:g} %")
        cells = []
        for w, h in sizes:
            here = g[(g["width"] == w) & (g["height"] == h)]
            best = here[here["cheapest"].astype(bool)]
            met = sorted(here.loc[here["met"].astype(bool), "technique"])
            cells.append(None if best.empty else {
                "technique": best.iloc[0]["technique"], "setting": best.iloc[0]["setting"] or "",
                "cost": best.iloc[0].get("time_ms"), "value": best.iloc[0]["value"],
                "also": [t for t in met if t != best.iloc[0]["technique"]]})
        out.append({"label": label, "cells": cells})
    return out


def budget_table(budgets, sizes) -> list[dict]:
    """Rows of time budgets (multiples of the G-buffer pass's time), a cell per size: the most
    accurate technique within it."""
    out = []
    for budget, g in budgets.groupby("budget", sort=True):
        cells = []
        for w, h in sizes:
            here = g[(g["width"] == w) & (g["height"] == h)]
            best = here[here["most_accurate"].astype(bool)]
            cells.append(None if best.empty else {
                "technique": best.iloc[0]["technique"], "setting": best.iloc[0]["setting"] or "",
                "cost": best.iloc[0].get("time_ms"), "error": best.iloc[0].get("edge_mae"),
                "budget_ms": best.iloc[0]["budget_ms"]})
        out.append({"label": f"≤ {budget:g} × the G-buffer pass", "cells": cells})
    return out
