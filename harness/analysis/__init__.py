"""Answers at equal error and equal time, from stored results only.

Pure functions over the DataFrame of ``harness.results.load(DIR)``; pass them ``current(df)``,
the rows that count. Each groups runs by scene and image size (``width``, ``height``): runs are
compared only with runs that shade the same pixels. ``cost`` names the cost column (``time_ms``
by default; any other, e.g. ``gpu_estimate_ms``, works the same), ``error`` the error column.
Rows whose cost or error is missing or not finite take no part; a column the results lack gives
an empty answer (the right columns, no rows), never an error. No HTML here: the dashboard renders
these frames.

- :func:`pareto_front`: the runs no other run of their scene and size beats.
- :func:`curves`: each technique's points along each knob it was run at, in knob order.
- :func:`cheapest_at_error`: the cheapest setting of each technique within an error threshold
  (multiples of ``edge_floor``, the best score a 0/1 technique can reach; ``wrong_pct`` levels).
- :func:`best_within_budget`: the most accurate setting within a multiple of the G-buffer time.
- :func:`summary`: per technique across scenes, its share of fronts and its cost ratio to the
  baseline technique (``registry.baseline()``: sm among the built-ins) at equal error.

:mod:`harness.analysis.tuning` gives the rows of a tune folder these are computed on (the tuned
runs, the defaults' beside), ``tuning_gain`` and ``bias_window``.
"""

from __future__ import annotations

import json
import math

import numpy as np
import pandas as pd

GROUP = ["scene", "width", "height"]
# passed through by curves() where the results have them: what a plot of a curve may show
PLOT_COLUMNS = ("time_ms", "time_ms_ci_low", "time_ms_ci_high", "noisy", "edge_mae", "edge_floor",
                "edge_ratio", "acne_pct", "leak_pct", "mae", "wrong_pct", "mem_bytes")


def current(df: pd.DataFrame) -> pd.DataFrame:
    """The rows that count: status ok, run by the technique's code as installed now (a row of
    an older version, or of a technique not installed here, is left out), and of several rows of
    one scene, size, technique and parameters (a rerun with other frames, or after a metrics
    change) the last one written."""
    from ..technique import registry

    version = {name: cls.code_version() for name, cls in registry.techniques().items()}
    rows = df[(df["status"] == "ok") & (df["code_version"] == df["technique"].map(version))]
    key = rows["params"].map(_params_key)
    # a tuned folder's runs of one setting in two parts (best and defaults) are two runs
    roles = [c for c in ("tuning", "tuned_on") if c in rows.columns]
    return (rows.assign(_params=key)
            .drop_duplicates(subset=GROUP + ["technique", "_params"] + roles, keep="last")
            .drop(columns="_params").reset_index(drop=True))


def pareto_front(df: pd.DataFrame, *, cost: str = "time_ms", error: str = "edge_mae") -> pd.Series:
    """True for each run that no other run of its scene and size beats: none has cost and error
    both at most its own and one of them lower. Two runs with equal cost and error are both on
    the front. False for rows without a finite cost and error; aligned with ``df``'s index."""
    on_front = np.zeros(len(df), dtype=bool)
    positions = np.flatnonzero(_finite(df, cost, error).to_numpy())
    if len(positions):
        frame = df[GROUP + [cost, error]].reset_index(drop=True).loc[positions]
        for _, g in frame.groupby(GROUP, sort=False):
            c, e = g[cost].to_numpy(float), g[error].to_numpy(float)
            at_most = (c[None, :] <= c[:, None]) & (e[None, :] <= e[:, None])
            lower = (c[None, :] < c[:, None]) | (e[None, :] < e[:, None])
            beaten = (at_most & lower).any(axis=1)
            on_front[g.index.to_numpy()[~beaten]] = True
    return pd.Series(on_front, index=df.index, name="on_front")


CURVE_COLUMNS = ["scene", "width", "height", "technique", "knob", "base", "order", "setting",
                 "value", "on_front", "run_id", "params"]


def curves(df: pd.DataFrame, *, cost: str = "time_ms", error: str = "edge_mae") -> pd.DataFrame:
    """Each technique's curves: per scene, size, technique and knob, the runs that differ only
    in that knob, in knob order (numbers ascending; other values, e.g. sv's ``buffer``, by
    cost), one row per point.

    A knob is a parameter whose value differs between the technique's runs of that scene and
    size (parameters some runs lack, like mdsm's ``extra``, are ignored); the runs that agree on
    every other such parameter form one curve, ``base`` naming those (``"k=16"``) and
    ``setting`` the point (``"res=1024"``). A run that lies on two curves (the defaults, where a
    res curve and a k curve cross) is a point of each. A run on no curve is a point of its own,
    with ``knob`` and ``base`` empty and ``setting`` naming its varying parameters. Columns:
    ``CURVE_COLUMNS``, the cost and error columns, ``on_front`` (across all techniques of the
    scene and size) and those of ``PLOT_COLUMNS`` the results have."""
    extra = [c for c in dict.fromkeys((cost, error) + PLOT_COLUMNS) if c in df.columns]
    rows = _rows(df, _finite(df, cost, error), "params", "run_id", *extra)
    if rows.empty:
        return pd.DataFrame(columns=CURVE_COLUMNS + extra)
    rows = rows.assign(on_front=pareto_front(rows, cost=cost, error=error))
    points = []
    for _, g in rows.groupby(GROUP + ["technique"], sort=True):
        varying = _varying(g["params"])
        on_a_curve = set()
        for knob in varying:
            others = [k for k in varying if k != knob]
            lines: dict[tuple, list[int]] = {}
            for i, p in g["params"].items():
                lines.setdefault(tuple(_params_key(p[k]) for k in others), []).append(i)
            for members in lines.values():
                values = [rows.at[i, "params"][knob] for i in members]
                if len({_params_key(v) for v in values}) < 2:
                    continue
                numeric = all(_is_number(v) for v in values)
                members = sorted(members, key=lambda i: (
                    rows.at[i, "params"][knob] if numeric else rows.at[i, cost]))
                base = _label(rows.at[members[0], "params"], others)
                for order, i in enumerate(members):
                    value = rows.at[i, "params"][knob]
                    points.append((i, knob, base, order, _label({knob: value}, [knob]), value))
                    on_a_curve.add(i)
        for i in g.index.difference(sorted(on_a_curve)):
            points.append((i, "", "", 0, _label(rows.at[i, "params"], varying), None))
    index = [p[0] for p in points]
    out = rows.loc[index, GROUP + ["technique"]].reset_index(drop=True)
    for position, name in enumerate(("knob", "base", "order", "setting", "value"), start=1):
        out[name] = [p[position] for p in points]
    for name in ["on_front", "run_id", "params"] + extra:
        if name in rows.columns:
            out[name] = rows.loc[index, name].to_numpy()
    return out


CHEAPEST_COLUMNS = ["scene", "width", "height", "metric", "level", "threshold", "technique",
                    "met", "setting", "value", "cheapest", "run_id"]


def cheapest_at_error(df: pd.DataFrame, *, multiples=(1.1, 1.25, 1.5, 2, 3),
                      metric: str = "edge_mae", wrong_pct=(0.1, 0.5, 1, 2),
                      cost: str = "time_ms") -> pd.DataFrame:
    """Per scene and size, per technique and threshold: the cheapest run whose error is within
    the threshold.

    Thresholds: ``metric`` <= m x the row's ``edge_floor`` for each m of ``multiples`` (``level``
    = m, ``threshold`` = m x the group's median floor), and ``wrong_pct`` <= each of
    ``wrong_pct`` (``level`` = ``threshold`` = that percentage). A technique that meets a
    threshold with no run has ``met`` False and no ``setting``, cost or ``value``; ``cheapest``
    marks the cheapest technique of each scene, size and threshold (equal costs: the lower
    error). Results without ``edge_floor`` (or ``wrong_pct``) give no rows for those thresholds.
    ``setting`` names the run's parameters that vary among its technique's runs there
    (:func:`setting_labels`); ``value`` is its error in the threshold's metric."""
    criteria = []
    if {metric, "edge_floor"} <= set(df.columns):
        criteria += [(metric, m, df[metric], m * df["edge_floor"]) for m in multiples]
    if "wrong_pct" in df.columns:
        criteria += [("wrong_pct", t, df["wrong_pct"], pd.Series(float(t), index=df.index))
                     for t in wrong_pct]
    return _choose(df, cost, criteria, CHEAPEST_COLUMNS, minimise=cost)


BUDGET_COLUMNS = ["scene", "width", "height", "budget", "budget_ms", "technique", "met",
                  "setting", "most_accurate", "run_id"]


def best_within_budget(df: pd.DataFrame, *, budgets=(1, 2, 4, 8), error: str = "edge_mae",
                       cost: str = "time_ms", base: str = "scene_ms") -> pd.DataFrame:
    """Per scene and size, per technique and budget: the most accurate run whose cost is at most
    budget x the G-buffer pass's time (``base``; the median of the scene and size's runs, as
    ``budget_ms``). Equal errors: the cheaper. ``met`` False where no run fits;
    ``most_accurate`` marks the best technique within each budget."""
    if any(column not in df.columns for column in (base, cost, error)):
        return pd.DataFrame(columns=BUDGET_COLUMNS + [cost, error])
    base_ms = df.groupby(GROUP)[base].transform("median")
    criteria = [(error, b, df[cost], b * base_ms) for b in budgets]
    out = _choose(df, cost, criteria, CHEAPEST_COLUMNS, minimise=error)
    out = out.rename(columns={"level": "budget", "threshold": "budget_ms",
                              "cheapest": "most_accurate"})
    return out.drop(columns=["metric", "value"])[BUDGET_COLUMNS + [cost, error]]


SUMMARY_COLUMNS = ["technique", "groups", "front_groups", "front_share", "ratio_median",
                   "ratio_count", "unreached", "worst_ratio", "worst_scene", "worst_size",
                   "worst_error"]


def summary(df: pd.DataFrame, *, cost: str = "time_ms", error: str = "edge_mae",
            reference: str | None = None) -> pd.DataFrame:
    """One row per technique across every scene and size it ran at.

    ``groups``: the scene/size groups where it has runs; ``front_groups``: those where at least
    one of its runs is on the Pareto front; ``front_share`` = front_groups / groups.

    Cost ratio to ``reference`` at equal error: in each group where both ran, each error the
    reference reaches with one of its runs is a level L; at L the ratio is the cheapest cost of
    the technique's runs with error <= L over the cheapest cost of the reference's runs with
    error <= L (so the two are compared at the same error, each at its cheapest setting that
    reaches it). ``ratio_median`` is the median over all (group, level) pairs the technique
    reaches, ``ratio_count`` their number, ``unreached`` the number of levels none of its runs
    reaches; ``worst_ratio`` is the largest, at ``worst_scene``, ``worst_size`` ("WxH") and
    ``worst_error`` (L). The reference's own ratio is 1; without reference runs the ratio
    columns are empty. ``reference`` defaults to the registered baseline technique."""
    from ..technique import registry

    reference = reference or registry.baseline(among=set(df["technique"]))
    rows = _rows(df, _finite(df, cost, error), cost, error)
    if rows.empty:
        return pd.DataFrame(columns=SUMMARY_COLUMNS)
    rows = rows.assign(on_front=pareto_front(rows, cost=cost, error=error))
    records = {}
    for technique, g in rows.groupby("technique", sort=True):
        fronts = g.groupby(GROUP)["on_front"].any()
        records[technique] = dict(technique=technique, groups=len(fronts),
                                  front_groups=int(fronts.sum()),
                                  front_share=float(fronts.mean()), ratios=[], unreached=0)
    for (scene, width, height), g in rows.groupby(GROUP, sort=True):
        ref = g[g["technique"] == reference]
        for level in sorted(set(ref[error])):
            ref_cost = ref.loc[ref[error] <= level, cost].min()
            for technique, t in g.groupby("technique"):
                reached = t.loc[t[error] <= level, cost]
                if reached.empty:
                    records[technique]["unreached"] += 1
                elif ref_cost > 0:
                    records[technique]["ratios"].append(
                        (reached.min() / ref_cost, scene, f"{width}x{height}", level))
    out = []
    for record in records.values():
        ratios = record.pop("ratios")
        worst = max(ratios, default=(math.nan, None, None, math.nan))
        out.append({**record, "ratio_median": float(np.median([r[0] for r in ratios]))
                    if ratios else math.nan, "ratio_count": len(ratios),
                    "worst_ratio": worst[0], "worst_scene": worst[1], "worst_size": worst[2],
                    "worst_error": worst[3]})
    return pd.DataFrame(out, columns=SUMMARY_COLUMNS)


def setting_labels(df: pd.DataFrame) -> pd.Series:
    """A readable setting per row: ``name=value`` for each parameter that varies among its
    technique's rows of the same scene and size (``"k=4 res=2048"``); empty where none does."""
    labels = pd.Series("", index=df.index, dtype=object)
    for _, g in df.groupby(GROUP + ["technique"], sort=False):
        names = _varying(g["params"])
        labels[g.index] = [_label(p, names) for p in g["params"]]
    return labels


# --- helpers -----------------------------------------------------------------------------------

def _choose(df, cost: str, criteria, columns: list[str], *, minimise: str) -> pd.DataFrame:
    """For each group, technique and criterion (metric, level, values, limits): among the rows
    with values <= limits, the one with the least ``minimise`` (ties: the least of the other of
    cost and the criterion's metric)."""
    names = [n for n in dict.fromkeys([cost, minimise]) if n in df.columns]
    if cost not in df.columns or minimise not in df.columns or not criteria:
        return pd.DataFrame(columns=columns + names)
    metrics = [metric for metric, *_ in criteria]
    usable = _rows(df, _finite(df, cost, minimise), "params", "run_id", *names, *metrics,
                   keep_index=True)
    labels = setting_labels(usable)
    groups = [(key, g, list(g.groupby("technique", sort=True)))
              for key, g in usable.groupby(GROUP, sort=True)]
    out = []
    for metric, level, values, limits in criteria:
        fits = np.isfinite(values.astype(float)) & (values <= limits)
        for key, g, by_technique in groups:
            threshold = float(limits[g.index].median())
            found = []
            for technique, t in by_technique:
                within = t[fits[t.index].to_numpy()]
                record = dict(zip(GROUP, key), metric=metric, level=level, threshold=threshold,
                              technique=technique, met=not within.empty, setting=None,
                              value=math.nan, cheapest=False, run_id=None,
                              **{n: math.nan for n in names})
                if not within.empty:
                    other = metric if minimise == cost else cost
                    best = within.sort_values([minimise, other], kind="stable").iloc[0]
                    record.update(setting=labels[best.name], value=float(values[best.name]),
                                  run_id=best.get("run_id"), **{n: best[n] for n in names})
                    found.append((best[minimise], best[other], len(out)))
                out.append(record)
            if found:
                out[min(found)[2]]["cheapest"] = True
    return pd.DataFrame(out, columns=columns + names)


def _rows(df: pd.DataFrame, keep: pd.Series, *columns: str,
          keep_index: bool = False) -> pd.DataFrame:
    """The kept rows with only the grouping columns and ``columns`` (those ``df`` has): a
    results table has about a hundred columns, and copying them all on every selection was
    most of the dashboard's time."""
    names = [c for c in dict.fromkeys(GROUP + ["technique", *columns]) if c in df.columns]
    rows = df.loc[keep, names]
    return rows if keep_index else rows.reset_index(drop=True)


def _finite(df: pd.DataFrame, *columns: str) -> pd.Series:
    """Rows whose every named column exists and holds a finite number."""
    keep = pd.Series(True, index=df.index)
    for name in columns:
        if name not in df.columns:
            return pd.Series(False, index=df.index)
        keep &= np.isfinite(pd.to_numeric(df[name], errors="coerce").astype(float))
    return keep


def _varying(params: pd.Series) -> list[str]:
    """Parameter names every one of ``params`` has and whose values differ between them."""
    dicts = list(params)
    if not dicts:
        return []
    common = set.intersection(*(set(p) for p in dicts))
    return [name for name in sorted(common) if len({_params_key(p[name]) for p in dicts}) > 1]


def _label(params: dict, names: list[str]) -> str:
    return " ".join(f"{name}={_show(params[name])}" for name in names)


def _show(value) -> str:
    return str(value).lower() if isinstance(value, bool) else str(value)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _params_key(value) -> str:
    return json.dumps(value, sort_keys=True)
