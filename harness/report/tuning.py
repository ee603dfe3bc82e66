"""The Tuning view of a folder ``shadowbench tune`` wrote: per scene and technique what the
tuned settings bought (:func:`harness.analysis.tuning.tuning_gain`), and the bias window's
acne-against-leak curve, from the stored window runs (:func:`harness.analysis.tuning.
window_curves`). Read from stored results only, like every part of the page."""

from __future__ import annotations

from ..analysis import tuning
from . import plots


def tuning_view(current, colours: dict[str, str]) -> dict | None:
    """What tuning.html.j2 shows; None when the rows hold no tuned runs."""
    if not tuning.has_tuning(current):
        return None
    gain = []
    for r in tuning.tuning_gain(current).to_dict("records"):
        gain.append({**r, "size": plots.size_label(r["width"], r["height"]),
                     "colour": colours.get(r["technique"], "#888")})
    return {"gain": gain, "window": _window_chart(tuning.window_curves(current), colours),
            "search_runs": int((current["tuning"] == "search").sum()),
            "acne_limit": tuning.ACNE_LIMIT, "leak_margin": tuning.LEAK_MARGIN}


def _window_chart(curves: list[dict], colours: dict[str, str]) -> dict | None:
    """acne_pct against leak_pct per technique, one facet per scene and size."""
    if not curves:
        return None
    facets: dict[str, list] = {}
    for c in curves:
        title = f"{c['scene']} {plots.size_label(c['width'], c['height'])}"
        name = f"{c['technique']}: window {c['bias_window']:.2g} decades"
        points = [{"x": leak, "y": acne,
                   "tip": f"{c['technique']} × {scale:.3g} bias\nacne {acne:.3g} %\nleak "
                          f"{leak:.3g} % (limit {c['leak_limit']:.3g})"}
                  for scale, acne, leak in zip(c["scale"], c["acne"], c["leak"])
                  if plots.number(acne) is not None and plots.number(leak) is not None]
        facets.setdefault(title, []).append({
            "name": name, "group": c["technique"], "colour": colours.get(c["technique"], "#888"),
            "points": points, "markers": True})
    techniques = sorted({c["technique"] for c in curves})
    return {"facets": [{"title": t, "series": s} for t, s in facets.items()],
            "legend": [{"name": t, "colour": colours.get(t, "#888")} for t in techniques],
            "x": {"title": "leak_pct: % of fully shadowed pixels lit (too much bias)",
                  "log": False},
            "y": {"title": "acne_pct: % of fully lit pixels shadowed (too little bias)",
                  "shared": True, "log": False}}
