"""How cost grows with the scene's triangle count, from stored results only.

The scale experiment runs scene families (``family`` names the family, empty for an ordinary
scene; each size is a scene of its own, e.g. ``arch@1e5``) and every run records its
``triangles``. Pure functions over ``harness.analysis.current(df)``, like ``harness.analysis``:

- :func:`size_band`: each row's band of scene size (below 10^4, 10^4 to 10^5, above 10^5
  triangles, or unknown), for verdicts that do not pool toy scenes with production ones.
- :func:`scaling`: the exponent of ``time_ms``, ``frags_shadow`` and ``vertex_invocations``
  against triangles (log-log least squares, with its confidence interval), per family,
  technique, setting and pass.
- :func:`equal_error_costs` and :func:`crossover`: two techniques' cheapest costs at equal
  error at each size of a family, and the triangle count above which the first costs more.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from .. import analysis

# The families' sizes land within 5 % of their target, so each edge is widened by 5 % on the
# side that keeps a scene made at exactly 10^4 or 10^5 triangles in the middle band.
SIZE_BANDS = (("below 10⁴ triangles", 0.0, 0.95e4), ("10⁴ to 10⁵ triangles", 0.95e4, 1.05e5),
              ("above 10⁵ triangles", 1.05e5, math.inf))
UNKNOWN_SIZE = "unknown size"
FRAME = ""  # pass_name of the whole frame's totals
# frame column -> the key of the same count in each entry of the ``passes`` column
PASS_KEYS = {"time_ms": "ms", "frags_shadow": "fragments",
             "vertex_invocations": "vertex_invocations"}
SCALING_COLUMNS = ["family", "width", "height", "technique", "setting", "pass_name", "metric",
                   "exponent", "ci_low", "ci_high", "stderr", "prefactor", "points",
                   "triangles_min", "triangles_max"]
EQUAL_ERROR_COLUMNS = ["scene", "triangles", "cost_a", "setting_a", "cost_b", "setting_b",
                       "ratio"]


def size_band(df: pd.DataFrame) -> pd.Series:
    """Each row's size band (a label of ``SIZE_BANDS``) from its scene's ``triangles`` (the
    largest count its rows hold, so a failed run that counted none joins its scene); scenes
    without a positive count (results from before it was recorded) are ``UNKNOWN_SIZE``."""
    triangles = _positive(df, "triangles")
    if "scene" in df.columns:
        triangles = triangles.groupby(df["scene"]).transform("max")
    band = pd.Series(UNKNOWN_SIZE, index=df.index, dtype=object)
    for label, low, high in SIZE_BANDS:
        band[(triangles >= low) & (triangles < high)] = label
    return band


def family_rows(df: pd.DataFrame) -> pd.DataFrame:
    """The rows of family scenes: a non-empty ``family`` and a positive ``triangles``."""
    if "family" not in df.columns:
        return df.iloc[0:0]
    named = df["family"].fillna("").astype(str).str.len() > 0
    return df[named & _positive(df, "triangles").notna()]


def scaling(df: pd.DataFrame, *, metrics=tuple(PASS_KEYS),
            confidence: float = 0.95) -> pd.DataFrame:
    """Per family, image size, technique, setting and pass: ``metric`` ≈ ``prefactor`` x
    triangles ^ ``exponent``, fitted by least squares on log10 of both over the family's sizes.

    ``setting`` names the parameters that vary among the technique's runs of the family
    (``"res=2048"``; empty where one setting ran), so each fit follows one setting across
    sizes. ``pass_name`` is ``FRAME`` for the frame's totals (the row's own columns) and a
    pass's name for its entry in ``passes`` (entries of one name summed). ``ci_low`` and
    ``ci_high`` bound the exponent at ``confidence`` (its standard error times Student's t
    quantile with points - 2 degrees of freedom); NaN with two points. Values that are not
    positive and finite take no part; a fit needs two distinct sizes."""
    from scipy import stats

    if not 0 < confidence < 1:
        raise ValueError(f"confidence must be between 0 and 1, not {confidence}")
    unknown = sorted(set(metrics) - set(PASS_KEYS))
    if unknown:
        raise ValueError(f"no scaling for {', '.join(unknown)}: choose from {', '.join(PASS_KEYS)}")
    rows = family_rows(df)
    if rows.empty:
        return pd.DataFrame(columns=SCALING_COLUMNS)
    settings = analysis.setting_labels(rows.assign(scene=rows["family"]))
    samples = []
    for i, row in rows.iterrows():
        key = (row["family"], row["width"], row["height"], row["technique"], settings[i])
        for metric in metrics:
            if metric in rows.columns:
                samples.append((*key, FRAME, metric, row["triangles"], row[metric]))
        for name, counts in _passes(row.get("passes")).items():
            for metric in metrics:
                if PASS_KEYS[metric] in counts:
                    samples.append((*key, name, metric, row["triangles"],
                                    counts[PASS_KEYS[metric]]))
    group = SCALING_COLUMNS[:7]
    points = pd.DataFrame(samples, columns=group + ["triangles", "value"])
    points["value"] = pd.to_numeric(points["value"], errors="coerce")
    points = points[np.isfinite(points["value"]) & (points["value"] > 0)]
    out = []
    for key, g in points.groupby(group, sort=True):
        x, y = np.log10(g["triangles"].to_numpy(float)), np.log10(g["value"].to_numpy(float))
        if len(np.unique(x)) < 2:
            continue
        fit = stats.linregress(x, y)
        n = len(x)
        half = stats.t.ppf((1 + confidence) / 2, n - 2) * fit.stderr if n > 2 else math.nan
        out.append((*key, fit.slope, fit.slope - half, fit.slope + half,
                    fit.stderr if n > 2 else math.nan, 10 ** fit.intercept, n,
                    g["triangles"].min(), g["triangles"].max()))
    return pd.DataFrame(out, columns=SCALING_COLUMNS)


def equal_error_costs(df: pd.DataFrame, a: str, b: str, *, level: float = 1.5,
                      metric: str = "edge_mae", cost: str = "time_ms") -> pd.DataFrame:
    """At each size of one family (and one image size): a's and b's cheapest ``cost`` among
    their runs within ``level`` x edge_floor in ``metric``
    (:func:`harness.analysis.cheapest_at_error`), and ``ratio`` = cost_a / cost_b; sizes
    where either reaches no run within the level are left out. Sorted by ``triangles``.
    ValueError when ``df``'s family rows span several families or image sizes."""
    if a == b:
        raise ValueError(f"crossover needs two techniques, not {a} twice")
    if not level > 0:
        raise ValueError(f"level must be a positive multiple of edge_floor, not {level}")
    rows = family_rows(df)
    if rows.empty:
        return pd.DataFrame(columns=EQUAL_ERROR_COLUMNS)
    groups = sorted({(f, int(w), int(h)) for f, w, h in
                     zip(rows["family"], rows["width"], rows["height"])})
    if len(groups) > 1:
        raise ValueError("equal_error_costs compares within one family and image size; these "
                         f"rows hold {', '.join(f'{f} {w}x{h}' for f, w, h in groups)}")
    pair = rows[rows["technique"].isin([a, b])]
    cheapest = analysis.cheapest_at_error(pair, multiples=(level,), metric=metric,
                                          wrong_pct=(), cost=cost)
    met = cheapest[cheapest["met"].astype(bool)]
    triangles = pair.groupby("scene")["triangles"].median()
    out = []
    for scene, g in met.groupby("scene", sort=False):
        found = {r["technique"]: r for r in g.to_dict("records")}
        if a in found and b in found:
            cost_a, cost_b = float(found[a][cost]), float(found[b][cost])
            out.append((scene, float(triangles[scene]), cost_a, found[a]["setting"] or "",
                        cost_b, found[b]["setting"] or "",
                        cost_a / cost_b if cost_b > 0 else math.nan))
    return (pd.DataFrame(out, columns=EQUAL_ERROR_COLUMNS)
            .sort_values("triangles", kind="stable").reset_index(drop=True))


@dataclass(frozen=True)
class Crossing:
    """Where a starts to cost more than b: ``triangles`` interpolated between the bracketing
    sizes ``below`` (a costs at most b) and ``above`` (a costs more), rows of
    :func:`equal_error_costs` as dicts."""

    triangles: float
    below: dict
    above: dict


def crossover(df: pd.DataFrame, a: str, b: str, **options) -> Crossing | None:
    """The triangle count above which technique ``a`` costs more than ``b`` at equal error, in
    one family and image size (``options`` as for :func:`equal_error_costs`).

    The crossing lies between the last size where a costs at most b and the next, provided a
    costs more at every size after it; log10 of the ratio is interpolated linearly in log10 of
    triangles to where it is 0 (a ratio of exactly 1 at the lower size is the crossing). None
    when a costs more at every size, when it costs at most b's at the largest size, or when the
    two share fewer than two sizes: they do not cross within the sizes run."""
    costs = equal_error_costs(df, a, b, **options)
    ratios = costs["ratio"].astype(float)
    costs = costs[np.isfinite(ratios) & (ratios > 0)].reset_index(drop=True)
    at_most = np.flatnonzero(costs["ratio"].to_numpy() <= 1)
    if not len(at_most) or at_most[-1] == len(costs) - 1:
        return None
    below, above = costs.iloc[at_most[-1]], costs.iloc[at_most[-1] + 1]
    x1, x2 = math.log10(below["triangles"]), math.log10(above["triangles"])
    y1, y2 = math.log10(below["ratio"]), math.log10(above["ratio"])
    crossing = 10 ** (x1 - y1 * (x2 - x1) / (y2 - y1))
    return Crossing(triangles=crossing, below=below.to_dict(), above=above.to_dict())


def _positive(df: pd.DataFrame, column: str) -> pd.Series:
    """The column as floats, NaN where it is missing, not a number or not positive."""
    if column not in df.columns:
        return pd.Series(math.nan, index=df.index, dtype=float)
    values = pd.to_numeric(df[column], errors="coerce").astype(float)
    return values.where(np.isfinite(values) & (values > 0))


def _passes(cell) -> dict[str, dict[str, float]]:
    """A row's ``passes`` (JSON text as stored, or the list itself) as pass name -> counts,
    entries of one name summed (a technique may draw a pass of one name several times)."""
    if isinstance(cell, str):
        cell = json.loads(cell) if cell.strip() else []
    if not isinstance(cell, list):
        return {}
    out: dict[str, dict[str, float]] = {}
    for entry in cell:
        counts = out.setdefault(str(entry.get("name", "")), {})
        for key in PASS_KEYS.values():
            value = entry.get(key)
            if isinstance(value, (int, float)) and not isinstance(value, bool):
                counts[key] = counts.get(key, 0.0) + float(value)
    return out
