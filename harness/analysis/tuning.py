"""The verdict on tuned settings, from stored rows only (``shadowbench tune``'s folders).

A tune folder holds, per scene, technique and point of its quality curve, the technique at its
defaults (``tuning == "defaults"``) and at the setting its search chose (``"best"``), besides the
search's own runs. The verdict (fronts, equal-error ratios, the overview) is given on the tuned
runs (:func:`verdict_rows`), the defaults' beside it (:func:`defaults_rows`);
:func:`tuning_gain` says what the tuning bought, and :func:`bias_window` how much of it a
technique needs. Pure functions, like the rest of :mod:`harness.analysis`.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

GROUP = ["scene", "width", "height"]
# the limits every tuned setting is held to (docs/fairness.md): acne_pct at most ACNE_LIMIT,
# leak_pct at most the baseline's at defaults plus LEAK_MARGIN, both in percent
ACNE_LIMIT = 0.1
LEAK_MARGIN = 0.1

GAIN_COLUMNS = ["scene", "width", "height", "technique", "points", "error_defaults",
                "error_tuned", "tuning_gain", "met", "held_out_edge_mae", "bias_window"]


def bias_window(scale, acne_pct, leak_pct, *, leak_limit: float,
                acne_limit: float = ACNE_LIMIT) -> float:
    """log10 of the width of the widest range of bias scales in which a technique has neither
    acne nor leaks: ``acne_pct <= acne_limit`` and ``leak_pct <= leak_limit``; 0 where no scale
    qualifies.

    ``scale``, ``acne_pct`` and ``leak_pct`` are 1-D arrays of one length, a run each (the scale
    its bias terms were multiplied by, in any order, each once). Each scale stands for the range
    halfway (in log10) to its neighbours, the first and last as far out as their neighbour is;
    the window is the longest unbroken stretch of qualifying scales. A NaN metric does not
    qualify. One scale alone measures no width: 0."""
    scale, acne, leak = (np.asarray(a, dtype=np.float64) for a in (scale, acne_pct, leak_pct))
    if scale.ndim != 1 or acne.shape != scale.shape or leak.shape != scale.shape:
        raise ValueError(f"expected three 1-D arrays of one length, got {scale.shape}, "
                         f"{acne.shape} and {leak.shape}")
    if not np.all(np.isfinite(scale) & (scale > 0)):
        raise ValueError("scale must hold finite numbers > 0")
    order = np.argsort(scale)
    logs = np.log10(scale[order])
    if np.any(np.diff(logs) == 0):
        raise ValueError("scale lists a value more than once")
    if len(logs) < 2:
        return 0.0
    ok = (acne[order] <= acne_limit) & (leak[order] <= leak_limit)  # NaN compares False
    middles = (logs[1:] + logs[:-1]) / 2
    edges = np.concatenate([[2 * logs[0] - middles[0]], middles, [2 * logs[-1] - middles[-1]]])
    cells = np.diff(edges)
    widest = run = 0.0
    for inside, width in zip(ok, cells):
        run = run + width if inside else 0.0
        widest = max(widest, run)
    return float(widest)


def has_tuning(df: pd.DataFrame) -> bool:
    """Whether the rows hold tuned runs (a folder ``shadowbench tune`` wrote)."""
    return "tuning" in df.columns and bool((df["tuning"] == "best").any())


def defaults_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The techniques at their defaults, run beside the tuned ones (``tuning == "defaults"``)."""
    if "tuning" not in df.columns:
        return df.iloc[0:0]
    return df[df["tuning"] == "defaults"].reset_index(drop=True)


def verdict_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The rows a verdict is given on. In a tune folder: each technique's tuned runs (``best``)
    and, for a technique with none in a scene and size (one not tuned, such as the baseline
    where it was left out), its runs at defaults there, so every technique of the folder is
    judged once per point. Elsewhere ``df`` as it is."""
    if not has_tuning(df):
        return df
    best, defaults = df[df["tuning"] == "best"], df[df["tuning"] == "defaults"]
    tuned = set(zip(*(best[c] for c in GROUP + ["technique"])))
    untuned = [key not in tuned for key in zip(*(defaults[c] for c in GROUP + ["technique"]))]
    return pd.concat([best, defaults[untuned]]).reset_index(drop=True)


def tuning_gain(df: pd.DataFrame, *, error: str = "edge_mae") -> pd.DataFrame:
    """Per scene, size and technique: what tuning bought. ``error_defaults`` and
    ``error_tuned`` are the medians of ``error`` over the points of its quality curve at
    defaults and tuned, ``tuning_gain`` the median over those points of error at defaults over
    error tuned (above 1: tuning helped; points whose tuned error is 0 are left out), ``met`` how
    many of the points' best settings meet the limits, ``held_out_edge_mae`` the median of the
    best settings' edge_mae on the held-out view, ``bias_window`` the technique's (its window
    point's). No rows without tuned runs."""
    if not has_tuning(df) or error not in df.columns or "tune_point" not in df.columns:
        return pd.DataFrame(columns=GAIN_COLUMNS)
    key = GROUP + ["technique", "tune_point"]
    best = df[df["tuning"] == "best"].drop_duplicates(key, keep="last")
    defaults = df[df["tuning"] == "defaults"].drop_duplicates(key, keep="last")
    paired = best.merge(defaults[key + [error]], on=key, suffixes=("", "_defaults"))
    out = []
    for (scene, width, height, technique), g in paired.groupby(GROUP + ["technique"], sort=True):
        tuned, at_defaults = g[error].astype(float), g[f"{error}_defaults"].astype(float)
        usable = (tuned > 0) & np.isfinite(tuned) & np.isfinite(at_defaults)
        ratios = at_defaults[usable] / tuned[usable]
        out.append(dict(
            scene=scene, width=width, height=height, technique=technique, points=len(g),
            error_defaults=float(at_defaults.median()), error_tuned=float(tuned.median()),
            tuning_gain=float(ratios.median()) if len(ratios) else math.nan,
            met=int(pd.to_numeric(g.get("tuning_met"), errors="coerce").fillna(0).sum())
            if "tuning_met" in g else 0,
            held_out_edge_mae=_median(g, "held_out_edge_mae"),
            bias_window=_median(g, "bias_window")))
    return pd.DataFrame(out, columns=GAIN_COLUMNS)


def window_curves(df: pd.DataFrame) -> list[dict]:
    """The bias-window runs per scene, size and technique, in scale order: ``scale``, ``acne``,
    ``leak`` lists, the ``leak_limit`` and the ``bias_window`` they give."""
    if "tuning" not in df.columns or "bias_scale" not in df.columns:
        return []
    rows = df[df["tuning"] == "window"]
    out = []
    for (scene, width, height, technique), g in rows.groupby(GROUP + ["technique"], sort=True):
        g = g.drop_duplicates("bias_scale", keep="last").sort_values("bias_scale")
        g = g[np.isfinite(g["bias_scale"].astype(float)) & (g["bias_scale"].astype(float) > 0)]
        if g.empty:
            continue
        limit = float(g["leak_limit"].astype(float).median())
        out.append(dict(scene=scene, width=int(width), height=int(height), technique=technique,
                        scale=[float(x) for x in g["bias_scale"]],
                        acne=[float(x) for x in g["acne_pct"]],
                        leak=[float(x) for x in g["leak_pct"]], leak_limit=limit,
                        bias_window=bias_window(g["bias_scale"], g["acne_pct"], g["leak_pct"],
                                                leak_limit=limit)))
    return out


def _median(g: pd.DataFrame, column: str) -> float:
    if column not in g.columns:
        return math.nan
    values = pd.to_numeric(g[column], errors="coerce").dropna()
    return float(values.median()) if len(values) else math.nan
