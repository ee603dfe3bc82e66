"""The Scale view, shown when the results hold family scenes (the scale experiment's, each size a
scene of its own): per family, each technique's cost at equal error and at its defaults against
triangles (log-log), the exponents of its cost (:func:`harness.analysis.scaling.scaling`), the
cost-accuracy fronts per size, and the crossover table (:func:`harness.analysis.scaling.crossover`): each
technique against the baseline and against the rivals its class names. A family run at one size
gets no exponent: the view says that a fit needs two sizes or more."""

from __future__ import annotations

import json

from .. import analysis
from ..technique import registry
from ..analysis import scaling
from . import plots

LEVEL = 1.5  # equal error: edge_mae within 1.5 x edge_floor, the level of the scenes' picks
EXPONENT_METRICS = {"time_ms": "time", "frags_shadow": "shadow fragments",
                    "vertex_invocations": "vertex invocations"}


def scale_view(current, colours: dict[str, str], baseline: str | None,
               rivals: dict[str, tuple[str, ...]] | None = None) -> dict | None:
    """Everything the Scale view shows, or None when no current run is of a family scene.
    ``rivals``: per technique, the others its crossovers weigh it against besides the
    baseline (:attr:`harness.technique.Technique.rivals`)."""
    rows = scaling.family_rows(current)
    if rows.empty:
        return None
    groups = [(key, g) for key, g in rows.groupby(["family", "width", "height"], sort=True)]
    one_size = len({(w, h) for (_, w, h), _ in groups}) == 1
    titled = [(family if one_size else f"{family} {plots.size_label(w, h)}", g)
              for (family, w, h), g in groups]
    return {"level": LEVEL, "cost_charts": cost_charts(titled, colours),
            "exponents": exponent_rows(rows, colours),
            "fronts": [{"title": title, "id": f"scale-front-{i}", "chart": front_chart(g, colours)}
                       for i, (title, g) in enumerate(titled)],
            "crossovers": crossover_rows(titled, baseline, rivals or {}), "baseline": baseline,
            "metrics": list(EXPONENT_METRICS.values()), "one_size": one_size_families(rows)}


def one_size_families(rows) -> list[dict]:
    """The families whose runs hold one triangle count (no exponent can be fitted), with it."""
    counts = rows.groupby("family", sort=True)["triangles"]
    return [{"family": family, "triangles": triangles_label(t.iloc[0])}
            for family, t in counts if t.nunique() < 2]


def triangles_label(triangles: float) -> str:
    return f"{triangles:,.0f}"


def cost_charts(titled, colours: dict[str, str]) -> list[dict]:
    """Time against triangles, a panel per family and a line per technique: at equal error (its
    cheapest run within LEVEL x edge_floor at each size) and at its default parameters."""
    return [
        {"id": "scale-cost", "title": "Time at equal error against triangles",
         "chart": _against_triangles(titled, colours, _cheapest_within_level,
                                     "time per frame (ms) of the cheapest run with edge_mae ≤ "
                                     f"{LEVEL:g} × edge_floor"),
         "explain": "A technique missing at a size reaches the level with none of its runs "
                    "there."},
        {"id": "scale-defaults", "title": "Time at the default parameters against triangles",
         "chart": _against_triangles(titled, colours, _at_defaults,
                                     "time per frame (ms) at the technique's defaults"),
         "explain": "Each technique as it comes, whatever its error."}]


def _against_triangles(titled, colours: dict[str, str], pick, y_title: str) -> dict:
    """A chart of the runs ``pick(rows)`` chooses (scene, technique, time_ms, setting) in each
    family, a line per technique against the scene's triangles."""
    facets = []
    for title, g in titled:
        triangles = g.groupby("scene")["triangles"].median()
        chosen = pick(g)
        series = []
        for technique, t in chosen.groupby("technique", sort=True):
            t = t.assign(triangles=t["scene"].map(triangles)).sort_values("triangles")
            series.append({"name": technique, "group": technique, "colour": colours[technique],
                           "points": [{"x": float(n), "y": float(ms),
                                       "tip": f"{technique} {setting}\n{title}, "
                                              f"{triangles_label(n)} triangles\n{ms:.4g} ms"}
                                      for n, ms, setting in zip(t["triangles"], t["time_ms"],
                                                                t["setting"])]})
        facets.append({"title": title, "series": series})
    techniques = sorted({s["group"] for f in facets for s in f["series"]})
    return {"facets": facets, "legend": [{"name": t, "colour": colours[t]} for t in techniques],
            "x": {"title": "triangles", "log": True}, "y": {"title": y_title, "log": True}}


def _cheapest_within_level(g):
    cheapest = analysis.cheapest_at_error(g, multiples=(LEVEL,), wrong_pct=())
    met = cheapest[cheapest["met"].astype(bool)]
    return met.assign(setting=met["setting"].fillna(""))


def _at_defaults(g):
    defaults = {t: json.dumps(registry.get(t).Params().model_dump(mode="json"), sort_keys=True)
                for t in set(g["technique"])}
    keep = [json.dumps(p, sort_keys=True) == defaults[t]
            for t, p in zip(g["technique"], g["params"])]
    return g[keep].assign(setting="at its defaults")


def exponent_rows(rows, colours: dict[str, str]) -> list[dict]:
    """Per family, image size, technique and setting: the whole frame's exponents and, under
    ``passes``, each pass's."""
    fits = scaling.scaling(rows)
    out = []
    for (family, w, h, technique, setting), g in fits.groupby(
            ["family", "width", "height", "technique", "setting"], sort=True):
        by_pass = []
        for name, p in g.groupby("pass_name", sort=True):
            cells = {r["metric"]: r for r in p.to_dict("records")}
            by_pass.append({"name": name or "whole frame",
                            "cells": [cells.get(m) for m in EXPONENT_METRICS]})
        frame = next((p for p in by_pass if p["name"] == "whole frame"), None)
        out.append({"family": family, "size": plots.size_label(w, h), "technique": technique,
                    "colour": colours[technique], "setting": setting,
                    "frame": frame["cells"] if frame else [None] * len(EXPONENT_METRICS),
                    "passes": [p for p in by_pass if p is not frame]})
    return out


def front_chart(g, colours: dict[str, str]) -> dict:
    """One family's cost-accuracy plot: a panel per size (time against edge_mae, log-log),
    each technique's runs joined in knob order, and the Pareto front."""
    points = analysis.curves(g)
    triangles = g.groupby("scene")["triangles"].median().sort_values()
    facets = []
    for scene, n in triangles.items():
        here = points[points["scene"] == scene]
        series = []
        for (technique, knob, base), line in here.groupby(["technique", "knob", "base"],
                                                          sort=True):
            line = line.sort_values("order")
            name = f"{technique} {base}".strip() + (f" ({knob})" if knob else "")
            series.append({"name": name, "group": technique, "colour": colours[technique],
                           "points": [{"x": float(c), "y": float(e), "label": s if knob else "",
                                       "tip": f"{name} {s}\n{c:.4g} ms, edge_mae {e:.4g}"}
                                      for c, e, s in zip(line["time_ms"], line["edge_mae"],
                                                         line["setting"])]})
        front = here[here["on_front"].astype(bool)]
        facets.append({"title": f"{triangles_label(n)} triangles", "series": series,
                       "front": [{"x": float(c), "y": float(e)}
                                 for c, e in zip(front["time_ms"], front["edge_mae"])]})
    techniques = sorted({s["group"] for f in facets for s in f["series"]})
    return {"facets": facets, "legend": [{"name": t, "colour": colours[t]} for t in techniques],
            "x": {"title": plots.COSTS["time_ms"], "log": True},
            "y": {"title": plots.ERRORS["edge_mae"], "log": True}}


def compared_pairs(present: set[str], baseline: str | None,
                   rivals: dict[str, tuple[str, ...]]) -> list[tuple[str, str]]:
    """The (a, b) pairs of the crossover table among the techniques ``present``: each against
    the baseline, then against each of its rivals, each unordered pair once."""
    pairs, seen = [], set()
    for a in sorted(present):
        for b in ((baseline,) if baseline else ()) + tuple(rivals.get(a, ())):
            if b in present and b != a and frozenset((a, b)) not in seen:
                seen.add(frozenset((a, b)))
                pairs.append((a, b))
    return pairs


def crossover_rows(titled, baseline: str | None,
                   rivals: dict[str, tuple[str, ...]]) -> list[dict]:
    """Per family and pair (a, b) of :func:`compared_pairs`: where a starts to cost more than b
    at equal error, or why there is no such size, with a / b at each size both reach the
    level."""
    out = []
    for title, g in titled:
        for a, b in compared_pairs(set(g["technique"]), baseline, rivals):
            costs = scaling.equal_error_costs(g, a, b, level=LEVEL)
            crossing = scaling.crossover(g, a, b, level=LEVEL)
            out.append({"family": title, "a": a, "b": b,
                        "crossing": None if crossing is None else {
                            "triangles": triangles_label(crossing.triangles),
                            "below": _bracket(crossing.below), "above": _bracket(crossing.above)},
                        "why": None if crossing else _no_crossing(costs, a, b),
                        "ratios": [{"triangles": triangles_label(r["triangles"]),
                                    "ratio": r["ratio"]} for r in costs.to_dict("records")]})
    return out


def _bracket(point: dict) -> dict:
    return {"triangles": triangles_label(point["triangles"]), "ratio": point["ratio"],
            "cost_a": point["cost_a"], "cost_b": point["cost_b"]}


def _no_crossing(costs, a: str, b: str) -> str:
    ratios = costs["ratio"].dropna()
    if len(ratios) < 2:
        return f"fewer than two sizes where both {a} and {b} reach the level"
    if (ratios > 1).all():
        return f"{a} costs more at every size"
    if (ratios <= 1).all():
        return f"{a} costs at most {b}'s at every size"
    return f"{a} costs at most {b}'s at the largest size"
