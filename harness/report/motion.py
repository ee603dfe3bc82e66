"""A moving scene's part of its section (scenes with ``motion``, runs with per-frame series):
error, flicker and world flicker against frame, one line per run, and each run's worst frame beside that
frame's reference, with its error and the frames around it. The viewer above shows frame 0,
the frame the scene's stored reference is of."""

from __future__ import annotations

import numpy as np

from .. import analysis
from . import images as im
from . import plots
from .stored import Folder

# per-frame series -> facet title
SERIES = {
    "mae": "mae: mean |V − V_ref| per frame",
    "edge_mae": "edge_mae per frame",
    "flicker": "flicker: mean |ΔV − ΔV_ref| from the frame before",
    "world_flicker": "world_flicker: flicker at the same world points (shimmer)",
}
STRIP_PX = 96  # the longer side of a strip frame as shown
MARKERS_UP_TO = 12  # frames; longer series are drawn as lines alone


def moving_runs(rows):
    """The rows of runs on a moving scene that finished (they carry ``worst_frame``)."""
    return rows[(rows["status"] == "ok") & plots.has_number(rows, "worst_frame")]


def motion_part(folder: Folder, rows, colours: dict[str, str]) -> dict | None:
    """The chart of per-frame series and the worst frames of one scene's shown runs; None
    when none of them ran on a moving scene."""
    runs = moving_runs(rows)
    if runs.empty:
        return None
    labels = analysis.setting_labels(runs)
    facets = {name: [] for name in SERIES}
    worst = []
    for (_, row), setting in zip(runs.iterrows(), labels):
        name = " ".join(filter(None, [row["technique"], plots.size_label(row["width"],
                                                                          row["height"]),
                                      setting]))
        z = folder.arrays(row.get("array") or "", "worst_frame", "worst_visibility",
                          "worst_reference", "worst_error", "worst_covered", "strip_frames",
                          "strip_visibility", "strip_covered",
                          what=f"{row['scene']} {name}: its frames")
        if z is None:
            continue
        for metric in SERIES:
            values = z.get(f"series_{metric}")
            if values is None:
                continue
            points = [{"x": t, "y": float(y), "tip": f"{name}\nframe {t}\n{metric} {y:.4g}"}
                      for t, y in enumerate(values) if plots.number(y) is not None]
            facets[metric].append({"name": name, "group": row["technique"],
                                   "colour": colours[row["technique"]], "points": points,
                                   "markers": len(values) <= MARKERS_UP_TO})
        worst.append(_worst_frame(row, name, z))
    if not worst:
        return None
    chart = {"facets": [{"title": title, "series": facets[m]} for m, title in SERIES.items()
                        if facets[m]],
             "legend": [{"name": t, "colour": colours[t]} for t in sorted(set(runs["technique"]))],
             "x": {"title": "frame", "log": False}, "y": {"title": "per frame", "shared": False,
                                                          "log": False}}
    return {"chart": chart, "worst": worst}


def _worst_frame(row, name: str, z) -> dict:
    """One run's worst frame as the page shows it: reference, V and signed error at that
    frame, and V at the frames of the strip around it."""
    v, ref, error = (np.asarray(z[k], np.float64) for k in ("worst_visibility",
                                                           "worst_reference", "worst_error"))
    covered, frame = z["worst_covered"], int(z["worst_frame"])
    signed = im.signed_error(v, ref, ~np.isnan(error))
    strip = [{"frame": int(t), "worst": int(t) == frame,
              "uri": im.data_uri(im.shrink_mean(im.visibility(np.asarray(strip_v, np.float64),
                                                              strip_covered), STRIP_PX),
                                 im.VISIBILITY)}
             for t, strip_v, strip_covered in zip(z["strip_frames"], z["strip_visibility"],
                                                  z["strip_covered"])]
    return {"name": name, "technique": row["technique"], "frame": frame,
            "flicker": plots.number(row.get("flicker")),
            "flicker_max": plots.number(row.get("flicker_max")),
            "pop_frames": plots.number(row.get("pop_frames")),
            "world_flicker": plots.number(row.get("world_flicker")),
            "world_changed_pct": plots.number(row.get("world_changed_pct")),
            "mae": plots.number(row.get("mae")), "mae_max": plots.number(row.get("mae_max")),
            "ref": im.data_uri(im.shrink_mean(im.visibility(ref, covered)), im.VISIBILITY),
            "v": im.data_uri(im.shrink_mean(im.visibility(v, covered)), im.VISIBILITY),
            "err": im.data_uri(im.shrink_error(signed), im.ERROR), "strip": strip}
