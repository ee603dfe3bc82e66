"""What the plots show, as JSON for ``static/charts.js`` (one small SVG plotter, no library).

A scene's cost-accuracy plot holds every run once (``runs``) and, per choice of cost and error
axis, the curves of :func:`harness.analysis.curves` (each technique's runs joined in knob order,
labelled with their setting) and the Pareto front; the page switches between them. Image sizes
are facets. The theta plot (alias and edge error against the angle between view and light)
appears when the results span at least three angles; it joins points only across scenes that
differ in their light alone.
"""

from __future__ import annotations

import math

import numpy as np

from .. import analysis
from ..technique import registry

# column -> axis title (with its unit); offered where the results have finite values. A cost
# axis is shown with the results' cost policy (:func:`cost_axes`): what a frame's time holds.
COSTS = {
    "time_ms": "time per frame (ms, median)",
    "gpu_estimate_ms": "estimated GPU time per frame (ms, an estimate from counted work)",
    "setup_ms": "setup time, once per run (ms, median)",
}
ERRORS = {
    "edge_mae": "edge_mae: mean |V − V_ref| within 2 px of a shadow edge",
    "edge_ratio": "edge_mae ÷ edge_floor (1 = the best a 0/1 technique can score)",
    "wrong_pct": "wrong_pct: % of compared pixels more than 0.5 off",
    "mae": "mae: mean |V − V_ref| over the compared pixels",
    "flip": "FLIP of the shaded image against the reference (0 to 1)",
    "flicker": "flicker: mean |ΔV − ΔV_ref| between frames (moving scenes)",
}
# values shown in a point's hover besides the axes
HOVER = ["time_ms", "gpu_estimate_ms", "edge_mae", "edge_ratio", "wrong_pct", "mae", "flip",
         "acne_pct", "leak_pct", "flicker", "pop_frames"]
# the Papers page's series (claims' curves, not techniques), in their order
PALETTE = ["#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2",
           "#7f7f7f", "#bcbd22", "#17becf"]
THETA_PLOT_MIN_ANGLES = 3


def colours(techniques) -> dict[str, str]:
    """One colour per technique, the same on every plot and table of the page and in every
    dashboard: the technique's own (:func:`harness.technique.registry.colour`), whatever else
    ran."""
    return {t: registry.colour(t) for t in sorted(set(techniques))}


def number(value) -> float | None:
    """A finite float for JSON, else None."""
    try:
        x = float(value)
    except (TypeError, ValueError):
        return None
    return x if math.isfinite(x) else None


def has_number(rows, column: str) -> np.ndarray:
    """Per row, whether ``column`` holds a finite number (all False without the column)."""
    if column not in rows:
        return np.zeros(len(rows), bool)
    return np.array([number(v) is not None for v in rows[column]], bool)


def axes(rows, names: dict[str, str]) -> dict[str, str]:
    """The axis choices the rows have finite values for, in ``names``' order."""
    return {c: t for c, t in names.items() if has_number(rows, c).any()}


def cost_policy(rows) -> str:
    """The cost policy of the rows (their ``cost`` column), several joined by '+'."""
    policies = sorted({str(p) for p in rows["cost"].dropna()}) if "cost" in rows else []
    return "+".join(policies) or "unknown"


def cost_axes(rows) -> dict[str, str]:
    """The cost axes the rows have values for, each titled with its column and the rows' cost
    policy, e.g. ``time_ms (dynamic): time per frame (ms, median)``."""
    policy = cost_policy(rows)
    return {c: f"{c} ({policy}): {t}" for c, t in axes(rows, COSTS).items()}


def size_label(width, height) -> str:
    return f"{int(width)}x{int(height)}"


def cost_accuracy(current, run_index: dict[str, int]) -> dict:
    """Curves and fronts of one scene's current runs for every (cost, error) choice;
    ``run_index`` maps a run_id to its place in the scene's run list."""
    costs, errors = cost_axes(current), axes(current, ERRORS)
    sizes = sorted({(int(w), int(h)) for w, h in zip(current["width"], current["height"])},
                   key=lambda s: s[0] * s[1])
    views = {}
    for cost in costs:
        for error in errors:
            points = analysis.curves(current, cost=cost, error=error)
            lines = []
            for (w, h, technique, knob, base), g in points.groupby(
                    ["width", "height", "technique", "knob", "base"], sort=True):
                g = g.sort_values("order")
                lines.append({"size": size_label(w, h), "technique": technique,
                              "name": f"{technique} {base}".strip() + (f" ({knob})" if knob else ""),
                              "runs": [run_index[r] for r in g["run_id"]],
                              "labels": list(g["setting"]) if knob else [""] * len(g)})
            front = sorted(run_index[r] for r in points.loc[points["on_front"].astype(bool),
                                                            "run_id"].unique())
            views[f"{cost}|{error}"] = {"lines": lines, "front": front}
    return {"costs": costs, "errors": errors, "sizes": [size_label(*s) for s in sizes],
            "views": views}


def run_values(row) -> dict:
    """A run's numbers for hovers and tables; None where absent."""
    values = {c: number(row.get(c)) for c in HOVER}
    low, high = number(row.get("time_ms_ci_low")), number(row.get("time_ms_ci_high"))
    return {"values": values, "ci": [low, high] if low is not None and high is not None else None,
            "noisy": bool(number(row.get("noisy")))}


# what the stored rows say of a scene's geometry and camera: scenes equal in all of these
# differ in their light alone (a light sweep, experiments/theta_sweep.yaml)
SAME_VIEW = ("width", "height", "triangles", "parts", "covered_px")


def same_view(rows) -> list[str]:
    """Per row, a key equal for rows of scenes that differ in their light alone: the
    SAME_VIEW columns; the scene's own name where one of them is missing."""
    def key(row) -> str:
        values = [number(row.get(c)) for c in SAME_VIEW]
        return "|".join(map(str, values)) if None not in values else f"scene {row['scene']}"
    return [key(row) for row in rows.to_dict("records")]


def theta(current, technique_colours: dict[str, str]) -> dict | None:
    """Alias and edge error against theta_deg per technique (and setting), one facet per metric,
    when the current runs span at least THETA_PLOT_MIN_ANGLES angles; else None. A line joins
    a technique's points in angle order only across scenes that differ in their light alone
    (:func:`same_view`); the points of unrelated scenes stand alone."""
    rows = current[has_number(current, "theta_deg")]
    if rows.empty or rows["theta_deg"].round(6).nunique() < THETA_PLOT_MIN_ANGLES:
        return None
    rows = rows.assign(_setting=analysis.setting_labels(rows), _view=same_view(rows))
    facets = []
    for metric in [m for m in ("alias_mean", "alias_near", "edge_mae") if m in rows]:
        series = []
        have = rows[has_number(rows, metric)]
        for (technique, w, h, setting, _), g in have.groupby(
                ["technique", "width", "height", "_setting", "_view"], sort=True):
            g = g.sort_values("theta_deg")
            scenes = g["scene"].unique()
            where = scenes[0] if len(scenes) == 1 else f"{len(scenes)} lights"
            name = " ".join(filter(None, [technique, size_label(w, h), setting, where]))
            series.append({"name": name, "group": technique, "colour": technique_colours[technique],
                           "points": [{"x": float(t), "y": float(v),
                                       "tip": f"{name}\nscene {s}\ntheta {t:.3g}°\n{metric} {v:.4g}"}
                                      for t, v, s in zip(g["theta_deg"], g[metric], g["scene"])]})
        if series:
            facets.append({"title": metric, "series": series})
    if not facets:
        return None
    techniques = sorted({s["group"] for f in facets for s in f["series"]})
    return {"facets": facets, "legend": [{"name": t, "colour": technique_colours[t]}
                                         for t in techniques],
            "x": {"title": "theta: angle between view and light (degrees)", "log": False},
            "y": {"title": "alias (pixels per texel), edge_mae", "shared": False, "log": bool(
                  all(p["y"] > 0 for f in facets for s in f["series"] for p in s["points"]))}}


def series_chart(plot: dict) -> dict:
    """A Papers-page plot ({x_title, y_title, log_x, log_y, series: [{name, x, y, dash}]}) in
    the chart script's form."""
    series = []
    for i, s in enumerate(plot["series"]):
        points = [{"x": float(x), "y": float(y), "tip": f"{s['name']}\n{x:.4g}, {y:.4g}"}
                  for x, y in zip(s["x"], s["y"]) if number(x) is not None and number(y) is not None]
        series.append({"name": s["name"], "colour": PALETTE[i % len(PALETTE)],
                       "dash": s.get("dash", "solid") != "solid", "points": points,
                       "markers": len(points) <= 12})
    return {"facets": [{"title": "", "series": series}],
            "x": {"title": plot["x_title"], "log": bool(plot.get("log_x"))},
            "y": {"title": plot["y_title"], "log": bool(plot.get("log_y"))}}
