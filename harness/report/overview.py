"""The overview: the answer across all scenes in one screen. Per band of scene size (toy scenes
are not pooled with production-sized ones) and technique, how often it is on a scene's
cost-accuracy front, its median cost ratio to the baseline technique at equal error and its worst
case (:func:`harness.analysis.summary`, for every cost and error axis the results have); the
renderer and what its times mean; failures and noisy runs counted; then the table of scenes."""

from __future__ import annotations

from .. import analysis
from ..analysis import scaling
from ..machine.timing import is_software_renderer, too_noisy
from . import plots


def caveat(meta: dict, rows) -> str:
    """One line: what renderer produced the times and what they are good for."""
    gl = meta.get("gl") or {}
    renderer = gl.get("renderer") or next(
        (r for r in rows.get("renderer", []) if isinstance(r, str) and r), "an unknown renderer")
    if is_software_renderer(renderer):
        return (f"Rendered by {renderer}, a software rasteriser: its times rank CPU cost, not "
                "GPU cost; the counted work (fragments, memory, fetches) holds on any GPU.")
    timer = gl.get("timer")
    return f"Rendered by {renderer}" + (f"; times from {timer} timers." if timer else ".")


def experiments(meta: dict) -> list[str]:
    """The experiments run into the folder, each as ``path (hash)``: the manifest's
    ``experiments`` (every one kept as runs were added), else its latest."""
    listed = meta.get("experiments")
    if not isinstance(listed, list) or not listed:
        listed = [meta]
    return [f"{e.get('experiment') or '?'} ({e.get('experiment_hash') or '?'})"
            for e in listed if isinstance(e, dict)] or ["?"]


def counts(shown, current) -> dict:
    """Runs shown, ok, failed, skipped and noisy (timed with other processes busy)."""
    timed = current[plots.has_number(current, "noisy")]
    noisy = sum(bool(plots.number(v)) for v in timed["noisy"]) if len(timed) else 0
    return {"runs": len(shown), "ok": int((shown["status"] == "ok").sum()),
            "failed": int((shown["status"] == "error").sum()),
            "skipped": int((shown["status"] == "skipped").sum()),
            "noisy": noisy, "timed": len(timed),
            "noisy_warning": too_noisy(noisy, len(timed))}


def verdicts(current, shown, colours: dict[str, str]) -> list[dict]:
    """Per size band the current runs fall in (:func:`harness.analysis.scaling.size_band`, smallest
    first, unknown last): its scenes and its :func:`summaries`."""
    bands, shown_bands = scaling.size_band(current), scaling.size_band(shown)
    costs, errors = plots.cost_axes(current), plots.axes(current, plots.ERRORS)
    out = []
    for band in [label for label, _, _ in scaling.SIZE_BANDS] + [scaling.UNKNOWN_SIZE]:
        rows = current[bands == band]
        if len(rows):
            out.append({"band": band, "unknown": band == scaling.UNKNOWN_SIZE,
                        "scenes": sorted(set(rows["scene"])),
                        "tables": summaries(rows, shown[shown_bands == band], colours,
                                            costs, errors)})
    return out


def summaries(current, shown, colours: dict[str, str], costs: dict[str, str],
              errors: dict[str, str]) -> list[dict]:
    """One table per (cost, error) axis pair: per technique its front share, cost ratio to the
    baseline at equal error and worst case, with its failed and noisy runs."""
    failed = shown[shown["status"] == "error"].groupby("technique").size()
    tables = []
    for cost, cost_title in costs.items():
        for error, error_title in errors.items():
            table = analysis.summary(current, cost=cost, error=error)
            rows = []
            for r in table.to_dict("records"):
                rows.append({**r, "colour": colours.get(r["technique"], "#888"),
                             "failed": int(failed.get(r["technique"], 0))})
            tables.append({"cost": cost, "error": error, "cost_title": cost_title,
                           "error_title": error_title, "rows": rows})
    return tables


def scene_pick(cheapest, scene: str, sizes: list[tuple[int, int]]) -> dict | None:
    """The cheapest technique within 1.5 x edge_floor at the scene's largest size (else within
    1 % wrong pixels), for the table of scenes."""
    if cheapest.empty or not sizes:
        return None
    w, h = sizes[-1]
    here = cheapest[(cheapest["scene"] == scene) & (cheapest["width"] == w)
                    & (cheapest["height"] == h) & cheapest["cheapest"].astype(bool)]
    for metric, level, text in (("edge_mae", 1.5, "edge_mae ≤ 1.5 × edge_floor"),
                                ("wrong_pct", 1, "wrong_pct ≤ 1 %")):
        hit = here[(here["metric"] == metric) & (here["level"] == level)]
        if len(hit):
            r = hit.iloc[0]
            return {"technique": r["technique"], "setting": r["setting"] or "",
                    "criterion": text, "size": plots.size_label(w, h)}
    return None
