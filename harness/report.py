"""The dashboard: a static ``DIR/index.html`` built only from stored results; it never renders.

The page answers the project's three questions from ``results.csv``, ``manifest.json`` and the
stored arrays, for whatever techniques the rows name:

- *what does accuracy cost in time*: per scene a cost-accuracy scatter (an error metric against
  ``time_ms``, one marker per run, coloured by technique, the Pareto front drawn), and the fill
  rate and memory of every run as bars;
- *which technique should I use for this scene*: per scene, for a set of error budgets, the
  cheapest run that meets each;
- *does it stay stable in the hard cases*: scenes x techniques with failures, NaN/Inf and V
  outside [0, 1] marked.

Plots are plotly figures; plotly.js is embedded once in the page, so index.html works offline
from the file system. Images are PNGs under ``DIR/images`` referenced by relative paths.
"""

from __future__ import annotations

import datetime as dt
import html
import json
import math
from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw

from . import metrics, results

# Error metrics the scatter can show (lower is better); flip exists only for shaded scenes.
ERROR_METRICS = ["edge_mae", "mae", "wrong_pct", "flip"]
# Error budgets of the "which technique" table: metric -> thresholds (metric <= threshold).
BUDGETS = {"edge_mae": [0.02, 0.05, 0.1, 0.2, 0.3], "wrong_pct": [0.1, 0.5, 1.0, 2.0, 5.0]}
# Fill rate and memory bars: column -> (axis title, scale applied to the stored value).
COST_BARS = {
    "frags_scene": ("scene fragments", 1.0),
    "frags_shadow": ("shadow fragments", 1.0),
    "overdraw": ("overdraw (shadow / scene fragments)", 1.0),
    "mem_bytes": ("memory (MiB)", 1.0 / 2**20),
    "fetches_per_px": ("texture fetches per pixel", 1.0),
}
TABLE_COLUMNS = ["technique", "params", "width", "height", "time_ms", "mae", "edge_mae",
                 "wrong_pct", "levels", "ssim", "psnr", "flip", "mem_bytes", "fetches_per_px",
                 "overdraw", "nonfinite", "status", "error"]
V_TOLERANCE = 1e-6  # V outside [0 - tol, 1 + tol] is a defect, not rounding
RESOLUTION_SYMBOLS = ["circle", "square", "diamond", "triangle-up", "x", "star"]
THUMB_PX = 256  # displayed width of every image in the grid
PLOT_CONFIG = {"displaylogo": False, "responsive": True}


# --- images ------------------------------------------------------------------------------------

def visibility_png(v: np.ndarray, covered: np.ndarray, path: Path) -> None:
    _save(_visibility_rgb(v, covered), path)


def error_rgb(v: np.ndarray, ref: np.ndarray, covered: np.ndarray) -> np.ndarray:
    """Signed error V - V_ref: red where lit but the reference is shadowed, blue the reverse."""
    d = np.clip(np.nan_to_num(v, nan=0.5) - ref, -1, 1)
    rgb = np.ones(v.shape + (3,))
    rgb[..., 1] -= np.abs(d)
    rgb[..., 2] -= np.clip(d, 0, 1)
    rgb[..., 0] -= np.clip(-d, 0, 1)
    rgb[~covered] = 0.85
    return rgb


def _visibility_rgb(v: np.ndarray, covered: np.ndarray) -> np.ndarray:
    grey = np.clip(np.nan_to_num(v, nan=0.5), 0, 1) * 0.85 + 0.15
    return np.where(covered[..., None], grey[..., None], np.array([0.35, 0.45, 0.6]))


def _viridis_lut() -> np.ndarray:
    from plotly.colors import sample_colorscale, unlabel_rgb

    colours = sample_colorscale("Viridis", list(np.linspace(0, 1, 256)))
    return np.array([unlabel_rgb(c) for c in colours]) / 255.0


def map_rgb(values: np.ndarray) -> tuple[np.ndarray, float, float]:
    """A technique's diagnostic map in Viridis between its 1st and 99th percentiles (NaN grey);
    returns the image and that range."""
    finite = np.isfinite(values)
    if not finite.any():
        return np.full(values.shape + (3,), 0.85), float("nan"), float("nan")
    lo, hi = np.percentile(values[finite], [1, 99])
    t = np.clip((np.where(finite, values, lo) - lo) / max(hi - lo, 1e-12), 0, 1)
    rgb = _viridis_lut()[np.round(t * 255).astype(int)]
    rgb[~finite] = 0.85
    return rgb, float(lo), float(hi)


def _save(rgb: np.ndarray, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8)).save(path)


def edge_crop(ref: np.ndarray, covered: np.ndarray) -> tuple[int, int, int] | None:
    """(row, col, size) of the square window holding the most reference shadow-edge pixels,
    or None when the reference has no shadow edge. The window is an eighth of the image's
    shorter side (at least 24 px), small enough that stair-stepping shows when enlarged."""
    from scipy import ndimage

    band = metrics.edge_band(ref, mask=covered)
    if not band.any():
        return None
    h, w = ref.shape
    size = min(h, w, max(24, min(h, w) // 8))
    counts = ndimage.uniform_filter(band.astype(np.float64), size=size, mode="constant")
    half = size // 2
    # only centres whose window lies inside the image
    inner = counts[half:h - size + half + 1, half:w - size + half + 1]
    r, c = np.unravel_index(np.argmax(inner), inner.shape)
    return int(r), int(c), size


def _crop_png(rgb: np.ndarray, crop: tuple[int, int, int], path: Path) -> None:
    r, c, size = crop
    path.parent.mkdir(parents=True, exist_ok=True)
    img = Image.fromarray((np.clip(rgb[r:r + size, c:c + size], 0, 1) * 255).astype(np.uint8))
    img.resize((THUMB_PX, THUMB_PX), Image.NEAREST).save(path)


def _with_box(rgb: np.ndarray, crop: tuple[int, int, int] | None, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    img = Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8))
    if crop is not None:
        r, c, size = crop
        width = max(1, rgb.shape[1] // 256)
        ImageDraw.Draw(img).rectangle([c - width, r - width, c + size + width - 1,
                                       r + size + width - 1], outline=(230, 120, 0), width=width)
    img.save(path)


# --- selecting rows ----------------------------------------------------------------------------

def current_rows(df):
    """The latest row of each (scene, resolution, technique, parameters): a rerun after a
    technique's code changed appends new rows; the older ones are superseded."""
    key = ["scene", "width", "height", "technique", "params_json"]
    df = df.assign(params_json=df["params"].map(lambda p: json.dumps(p, sort_keys=True)))
    return df.drop_duplicates(subset=key, keep="last").reset_index(drop=True)


def _default_params(technique: str) -> dict | None:
    from . import registry

    try:
        return registry.get(technique).Params().model_dump(mode="json")
    except KeyError:  # results from a technique not installed here
        return None


def _default_runs(rows) -> dict:
    """technique -> the row of its run at default parameters (else its first ok run)."""
    chosen = {}
    for technique, group in rows.groupby("technique", sort=True):
        ok = group[(group["status"] == "ok") & (group["array"] != "")]
        if ok.empty:
            continue
        defaults = _default_params(technique)
        at_default = ok[[p == defaults for p in ok["params"]]] if defaults else ok.iloc[:0]
        chosen[technique] = (at_default if not at_default.empty else ok).iloc[0]
    return chosen


def _varying(rows) -> dict[str, list[str]]:
    """technique -> names of the parameters that differ between its runs in ``rows``."""
    out = {}
    for technique, group in rows.groupby("technique"):
        names = sorted({k for p in group["params"] for k in p})
        out[technique] = [n for n in names
                          if len({json.dumps(p.get(n)) for p in group["params"]}) > 1]
    return out


def _short_params(params: dict, names: list[str]) -> str:
    return " ".join(f"{n}={params.get(n)}" for n in names)


def _finite(value) -> bool:
    return isinstance(value, (int, float, np.integer, np.floating)) and math.isfinite(value)


def _fmt(value) -> str:
    if isinstance(value, (float, np.floating)):
        return "" if np.isnan(value) else f"{value:.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}={v}" for k, v in value.items())
    return str(value)


def pareto_front(times, errors) -> list[int]:
    """Indices of the runs no other run beats in both time and error, fastest first."""
    order = sorted(range(len(times)), key=lambda i: (times[i], errors[i]))
    front, best = [], math.inf
    for i in order:
        if errors[i] < best:
            front.append(i)
            best = errors[i]
    return front


# --- figures -----------------------------------------------------------------------------------

def _colours(techniques) -> dict[str, str]:
    from plotly.colors import qualitative

    palette = qualitative.Plotly + qualitative.D3
    return {t: palette[i % len(palette)] for i, t in enumerate(sorted(techniques))}


def _hover(r, varying: list[str]) -> str:
    params = "<br>".join(f"  {k} = {v}" for k, v in r["params"].items())
    errors = " · ".join(f"{m} {_fmt(r[m])}" for m in ERROR_METRICS if _finite(r.get(m)))
    return (f"<b>{html.escape(r['technique'])}</b> {r['width']}x{r['height']}<br>"
            f"time {r['time_ms']:.3g} ms<br>{errors}<br>{params}")


def cost_accuracy_figure(rows, colours: dict[str, str]):
    """Error against time, one marker per ok run; buttons switch the error metric. Each
    metric has its own traces (markers and, per resolution, the Pareto front); a button shows
    one metric's traces, so the figure needs no script of its own."""
    import plotly.graph_objects as go

    ok = rows[(rows["status"] == "ok") & rows["time_ms"].map(_finite)]
    resolutions = sorted({(w, h) for w, h in zip(ok["width"], ok["height"])})
    symbols = {res: RESOLUTION_SYMBOLS[i % len(RESOLUTION_SYMBOLS)]
               for i, res in enumerate(resolutions)}
    varying = _varying(ok)
    available = [m for m in ERROR_METRICS if m in ok and ok[m].map(_finite).any()]
    fig = go.Figure()
    owner: list[str] = []  # metric of each trace
    for metric in available:
        have = ok[ok[metric].map(_finite)]
        for (technique, w, h), g in have.groupby(["technique", "width", "height"], sort=True):
            fig.add_trace(go.Scatter(
                x=g["time_ms"], y=g[metric], mode="markers", name=f"{technique} {w}x{h}",
                legendgroup=technique, visible=metric == available[0],
                marker=dict(color=colours[technique], symbol=symbols[(w, h)], size=10,
                            line=dict(width=1, color="#333")),
                text=[_hover(r, varying[technique]) for _, r in g.iterrows()],
                hovertemplate="%{text}<extra></extra>"))
            owner.append(metric)
        for w, h in resolutions:
            g = have[(have["width"] == w) & (have["height"] == h)]
            if len(g) < 2:
                continue
            times, errs = list(g["time_ms"]), list(g[metric])
            front = pareto_front(times, errs)
            fig.add_trace(go.Scatter(
                x=[times[i] for i in front], y=[errs[i] for i in front], mode="lines",
                line=dict(shape="hv", dash="dot", color="#555", width=1.5),
                name=f"Pareto front {w}x{h}", visible=metric == available[0],
                hoverinfo="skip"))
            owner.append(metric)
    buttons = [dict(label=m, method="update",
                    args=[{"visible": [o == m for o in owner]},
                          {"yaxis.title.text": f"{m} (lower is better)"}])
               for m in available]
    fig.update_layout(
        height=460, margin=dict(l=60, r=20, t=50, b=50), template="plotly_white",
        xaxis=dict(title="time_ms (median of the technique's passes, log scale)", type="log"),
        yaxis=dict(title=f"{available[0]} (lower is better)" if available else ""),
        legend=dict(font=dict(size=11)),
        updatemenus=[dict(type="buttons", direction="right", buttons=buttons, x=0, y=1.13,
                          xanchor="left", yanchor="top", showactive=True)] if buttons else [])
    return fig


def cost_bars_figure(rows, colours: dict[str, str]):
    """Fill rate and memory of every ok run: one row of bars per cost column."""
    import plotly.graph_objects as go
    from plotly.subplots import make_subplots

    ok = rows[rows["status"] == "ok"].sort_values(["technique", "width", "params_json"])
    varying = _varying(ok)
    labels, seen = [], {}
    for _, r in ok.iterrows():
        label = " ".join(filter(None, (r["technique"], f"{r['width']}x{r['height']}",
                                       _short_params(r["params"], varying[r["technique"]]))))
        seen[label] = seen.get(label, 0) + 1
        labels.append(label if seen[label] == 1 else f"{label} #{seen[label]}")
    ok = ok.assign(label=labels)
    columns = [c for c in COST_BARS if c in ok and ok[c].map(_finite).any()]
    fig = make_subplots(rows=max(1, len(columns)), cols=1, shared_xaxes=True,
                        vertical_spacing=0.04,
                        subplot_titles=[COST_BARS[c][0] for c in columns])
    for i, column in enumerate(columns, start=1):
        scale = COST_BARS[column][1]
        for technique, g in ok.groupby("technique", sort=True):
            fig.add_trace(go.Bar(
                x=g["label"], y=g[column] * scale, name=technique, legendgroup=technique,
                showlegend=i == 1, marker_color=colours[technique],
                hovertemplate=f"%{{x}}<br>{column} %{{y:.4g}}<extra></extra>"), row=i, col=1)
    fig.update_layout(height=170 * max(1, len(columns)) + 120, template="plotly_white",
                      margin=dict(l=60, r=20, t=40, b=120), bargap=0.25)
    fig.update_xaxes(categoryorder="array", categoryarray=labels, tickangle=-35)
    return fig


def _figure_html(fig, div_id: str) -> str:
    import plotly.io as pio

    return pio.to_html(fig, full_html=False, include_plotlyjs=False, div_id=div_id,
                       config=PLOT_CONFIG)


# --- tables ------------------------------------------------------------------------------------

def cheapest_runs(rows) -> dict[tuple[str, float, tuple[int, int]], object]:
    """(metric, budget, (width, height)) -> the fastest ok run with metric <= budget at that
    resolution, or None when no run meets the budget."""
    ok = rows[(rows["status"] == "ok") & rows["time_ms"].map(_finite)]
    resolutions = sorted({(w, h) for w, h in zip(ok["width"], ok["height"])})
    out = {}
    for metric, budgets in BUDGETS.items():
        if metric not in ok or not ok[metric].map(_finite).any():
            continue
        for budget in budgets:
            for w, h in resolutions:
                g = ok[(ok["width"] == w) & (ok["height"] == h) & (ok[metric] <= budget)]
                out[(metric, budget, (w, h))] = None if g.empty else g.loc[g["time_ms"].idxmin()]
    return out


def budget_table(rows) -> str:
    """For each error budget and resolution, the cheapest ok run within the budget."""
    cheapest = cheapest_runs(rows)
    if not cheapest:
        return "<p>No successful runs with error metrics.</p>"
    resolutions = sorted({res for _, _, res in cheapest})
    varying = _varying(rows[rows["status"] == "ok"])
    head = "".join(f"<th>{w}x{h}</th>" for w, h in resolutions)
    body = []
    for metric, budget in dict.fromkeys((m, b) for m, b, _ in cheapest):
        unit = " %" if metric == "wrong_pct" else ""
        cells = []
        for res in resolutions:
            r = cheapest[(metric, budget, res)]
            if r is None:
                cells.append('<td class="none">none meets it</td>')
                continue
            short = _short_params(r["params"], varying[r["technique"]])
            cells.append(
                f'<td title="{html.escape(_fmt(r["params"]))}"><b>'
                f'{html.escape(r["technique"])}</b> {html.escape(short)}<br>'
                f'{r["time_ms"]:.3g} ms · {metric} {r[metric]:.3g}{unit}</td>')
        body.append(f"<tr><th>{metric} ≤ {budget:g}{unit}</th>{''.join(cells)}</tr>")
    return f'<table class="budget"><tr><th>error budget</th>{head}</tr>{"".join(body)}</table>'


def stability_cells(rows) -> dict[tuple[str, str], dict]:
    """(scene, technique) -> counts of runs, failures, NaN/Inf and V outside [0, 1], the worst
    wrong_pct, and whether the cell fails (any failure, NaN/Inf or V out of range)."""
    cells = {}
    for (scene, technique), g in rows.groupby(["scene", "technique"], sort=True):
        ok = g[g["status"] == "ok"]
        errors = g[g["status"] == "error"]
        nonfinite = int((g["nonfinite"].fillna(0) > 0).sum()) if "nonfinite" in g else 0
        out_of_range = int(((g["v_min"] < -V_TOLERANCE) | (g["v_max"] > 1 + V_TOLERANCE)).sum())
        wrong = ok["wrong_pct"].dropna()
        cells[(scene, technique)] = dict(
            runs=len(g), ok=len(ok), errors=len(errors),
            skipped=int((g["status"] == "skipped").sum()), nonfinite=nonfinite,
            out_of_range=out_of_range, worst_wrong_pct=float(wrong.max()) if len(wrong) else None,
            first_error=errors["error"].iloc[0] if len(errors) else "",
            fails=bool(len(errors) or nonfinite or out_of_range))
    return cells


def stability_table(rows) -> str:
    cells = stability_cells(rows)
    scenes = list(dict.fromkeys(rows["scene"]))
    techniques = sorted(set(rows["technique"]))
    head = "".join(f"<th>{html.escape(t)}</th>" for t in techniques)
    body = []
    for scene in scenes:
        tds = []
        for technique in techniques:
            c = cells.get((scene, technique))
            if c is None:
                tds.append('<td class="none">not run</td>')
                continue
            lines = [f"ok {c['ok']}/{c['runs']}"]
            if c["errors"]:
                lines.append(f"<b>failed {c['errors']}</b>")
            if c["skipped"]:
                lines.append(f"skipped {c['skipped']}")
            if c["nonfinite"]:
                lines.append(f"<b>NaN/Inf in {c['nonfinite']}</b>")
            if c["out_of_range"]:
                lines.append(f"<b>V outside [0,1] in {c['out_of_range']}</b>")
            if c["worst_wrong_pct"] is not None:
                lines.append(f"worst wrong {c['worst_wrong_pct']:.3g} %")
            kind = "fail" if c["fails"] else "skip" if c["ok"] == 0 else "pass"
            title = f' title="{html.escape(c["first_error"])}"' if c["first_error"] else ""
            tds.append(f'<td class="{kind}"{title}>{"<br>".join(lines)}</td>')
        body.append(f"<tr><th>{html.escape(scene)}</th>{''.join(tds)}</tr>")
    return (f'<table class="stability"><tr><th>scene</th>{head}</tr>{"".join(body)}</table>')


def _results_table(rows) -> str:
    head = "".join(f"<th>{c}</th>" for c in TABLE_COLUMNS)
    body = []
    for _, r in rows.iterrows():
        kind = ' class="fail"' if r["status"] == "error" else ""
        body.append(f"<tr{kind}>" + "".join(
            f"<td>{html.escape(_fmt(r.get(c)))}</td>" for c in TABLE_COLUMNS) + "</tr>")
    return f'<table class="runs"><tr>{head}</tr>{"".join(body)}</table>'


# --- the image grid ----------------------------------------------------------------------------

def image_grid(out_dir: Path, scene: str, rows) -> str:
    """At the scene's largest resolution with a stored reference: the reference, each
    technique's V at its defaults, its error, and the same enlarged edge crop of each."""
    ok = rows[(rows["status"] == "ok") & (rows["array"] != "")]
    for w, h in sorted({(w, h) for w, h in zip(ok["width"], ok["height"])},
                       key=lambda r: -r[0] * r[1]):
        at_size = ok[(ok["width"] == w) & (ok["height"] == h)]
        ref_file = out_dir / at_size["reference_array"].iloc[0]
        if ref_file.is_file():
            break
    else:
        return "<p>No stored reference for this scene.</p>"
    with np.load(ref_file) as z:
        ref, ref_cov = z["visibility"], z["covered"]
    images = Path("images") / scene / f"{w}x{h}"
    crop = edge_crop(ref, ref_cov)
    ref_rgb = _visibility_rgb(ref, ref_cov)
    _with_box(ref_rgb, crop, out_dir / images / "reference.png")
    band = metrics.edge_band(ref, mask=ref_cov)
    _save(np.where(band[..., None], np.array([0.9, 0.45, 0.0]), ref_rgb * 0.6 + 0.4),
          out_dir / images / "edge-band.png")

    def img(name: str, alt: str) -> str:
        return f'<img src="{images}/{name}" alt="{html.escape(alt)}" width="{THUMB_PX}">'

    def crop_cell(rgb, name: str, alt: str) -> str:
        if crop is None:
            return "<td>no shadow edge</td>"
        _crop_png(rgb, crop, out_dir / images / name)
        return f"<td>{img(name, alt)}</td>"

    trs = [f"<tr><th>reference<br><small>Mitsuba, {w}x{h}</small></th>"
           f"<td>{img('reference.png', 'reference V')}</td>"
           f"<td>{img('edge-band.png', 'reference edge band')}</td>"
           + crop_cell(ref_rgb, "reference-crop.png", "reference edge crop") + "</tr>"]
    chosen = _default_runs(ok[(ok["width"] == w) & (ok["height"] == h)])
    for technique, r in chosen.items():
        with np.load(out_dir / r["array"]) as z:
            v, cov = z["visibility"], z["covered"]
            maps = {k.removeprefix("map_"): z[k] for k in z.files if k.startswith("map_")}
        stem = Path(r["array"]).stem
        v_rgb = _visibility_rgb(v, cov)
        _save(v_rgb, out_dir / images / f"{stem}.png")
        err_rgb = error_rgb(v, ref, cov & ref_cov)
        _save(err_rgb, out_dir / images / f"{stem}-error.png")
        label = "defaults" if r["params"] == _default_params(technique) else "first run"
        trs.append(
            f'<tr><th title="{html.escape(_fmt(r["params"]))}">{html.escape(technique)}<br>'
            f"<small>{label}; edge_mae {_fmt(r['edge_mae'])}</small></th>"
            f"<td>{img(stem + '.png', f'{technique} V')}</td>"
            f"<td>{img(stem + '-error.png', f'{technique} error')}</td>"
            + crop_cell(v_rgb, f"{stem}-crop.png", f"{technique} edge crop")
            + _maps_cell(out_dir, images, stem, maps) + "</tr>")
    crop_note = (f"rows {crop[0]}–{crop[0] + crop[2]}, columns {crop[1]}–{crop[1] + crop[2]}, "
                 f"enlarged {THUMB_PX / crop[2]:.3g}x" if crop else "no shadow edge")
    return ('<table class="grid"><tr><th></th><th>V</th><th>error V − V<sub>ref</sub> '
            '(reference: its edge band)</th><th>edge crop (' + crop_note + ")</th>"
            "<th>the technique's own maps</th></tr>"
            + "".join(trs) + "</table>")


def _maps_cell(out_dir: Path, images: Path, stem: str, maps: dict[str, np.ndarray]) -> str:
    cells = []
    for name, values in maps.items():
        rgb, lo, hi = map_rgb(values)
        file = f"{stem}-map-{_slug(name)}.png"
        _save(rgb, out_dir / images / file)
        cells.append(f'<figure><img src="{images}/{file}" alt="{html.escape(name)}" '
                     f'width="{THUMB_PX}"><figcaption><small>{html.escape(name)}: '
                     f"{_fmt(lo)} (dark) to {_fmt(hi)} (yellow); grey: none</small>"
                     "</figcaption></figure>")
    return f"<td>{''.join(cells)}</td>"


# --- the page ----------------------------------------------------------------------------------

STYLE = """
body{font-family:system-ui,sans-serif;margin:1.2em 2em;color:#222;max-width:1500px}
h2{border-top:2px solid #ddd;padding-top:.6em;margin-top:1.6em}
table{border-collapse:collapse;font-size:13px;margin:.4em 0}
td,th{border:1px solid #ccc;padding:3px 6px;vertical-align:top;text-align:left}
td.fail,tr.fail td{background:#fbd5d5} td.pass{background:#e3f4e1} td.skip,td.none{color:#888}
table.grid img{display:block;image-rendering:pixelated} table.grid figure{margin:0}
table.runs{font-size:11px} details{margin:.6em 0} .meta{font-size:13px;color:#444}
nav a{margin-right:1em} small{color:#666}
"""


def _meta_html(meta: dict, n_rows: int, n_current: int) -> str:
    gl = meta.get("gl", {})
    versions = ", ".join(f"{k} {v}" for k, v in meta.get("versions", {}).items() if v)
    superseded = n_rows - n_current
    parts = [
        f"{n_current} runs" + (f" ({superseded} superseded rows hidden)" if superseded else ""),
        f"GL: {gl.get('vendor', '?')} · {gl.get('renderer', '?')} · {gl.get('version', '?')}",
        f"CPU: {meta.get('cpu', '?')}",
        (f"shadowbench {meta.get('shadowbench', '?')} · commit {meta.get('git_commit', '')[:10]}"
         f" · experiment {meta.get('experiment_hash', '?')}"),
        f"started {meta.get('started', '?')} · finished {meta.get('finished') or 'not yet'}",
        versions,
    ]
    return '<p class="meta">' + "<br>".join(html.escape(p) for p in parts if p) + "</p>"


def _slug(text: str) -> str:
    return "".join(ch if ch.isalnum() or ch in "_-" else "-" for ch in text)


def build_report(out_dir: str | Path) -> Path:
    """Write ``out_dir/index.html`` (and its images) from the stored results; returns its path."""
    from plotly.offline import get_plotlyjs

    out_dir = Path(out_dir)
    everything = results.load(out_dir)
    rows = current_rows(everything)
    manifest = out_dir / "manifest.json"
    meta = json.loads(manifest.read_text()) if manifest.is_file() else {}
    colours = _colours(rows["technique"].unique())
    scenes = list(dict.fromkeys(rows["scene"]))
    sections = []
    for scene in scenes:
        group = rows[rows["scene"] == scene]
        slug = _slug(scene)
        resolutions = ", ".join(f"{w}x{h}" for w, h in
                                sorted({(w, h) for w, h in zip(group["width"], group["height"])}))
        has_ok = (group["status"] == "ok").any()
        sections.append(f"""
<section id="{slug}">
<h2>{html.escape(scene)} <small>{resolutions} · {len(group)} runs</small></h2>
<h3>What accuracy costs in time</h3>
{_figure_html(cost_accuracy_figure(group, colours), f"{slug}-cost-accuracy") if has_ok
 else "<p>No successful runs.</p>"}
<h3>Which technique: the cheapest run within each error budget</h3>
{budget_table(group)}
<h3>Fill rate and memory</h3>
{_figure_html(cost_bars_figure(group, colours), f"{slug}-costs") if has_ok else ""}
<h3>Images</h3>
{image_grid(out_dir, scene, group)}
<details><summary>all {len(group)} runs of {html.escape(scene)}</summary>
{_results_table(group)}</details>
</section>""")
    nav = " ".join(f'<a href="#{_slug(s)}">{html.escape(s)}</a>' for s in scenes)
    papers = _papers_link(out_dir)
    if papers:
        nav += f' <a href="{papers}">Papers</a>'
    built = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>shadowbench: {html.escape(str(out_dir))}</title>
<link rel="icon" href="data:,">
<style>{STYLE}</style>
<script type="text/javascript">{get_plotlyjs()}</script>
</head><body>
<h1>shadowbench results</h1>
{_meta_html(meta, len(everything), len(rows))}
<nav>{nav} <a href="#stability">stability</a></nav>
<p>Errors compare each technique's light visibility V (1 = lit) with a ray-traced Mitsuba
reference on the pixels both cover and the light reaches (surfaces facing it, inside a spot's
cone; elsewhere V changes nothing). Error images: red = lit where the reference is in shadow,
blue = shadowed where it is lit. Built {built} from stored results.</p>
{''.join(sections)}
<section id="stability">
<h2>Stability</h2>
<p>Scenes x techniques over every run: failures, NaN/Inf (<code>nonfinite</code> &gt; 0) and V
outside [0, 1] (<code>v_min</code>, <code>v_max</code>) mark a cell as failing (red); the worst
<code>wrong_pct</code> is the largest share of pixels more than 0.5 off. Hover a failing cell for
the first error.</p>
{stability_table(rows)}
</section>
</body></html>
"""
    index = out_dir / "index.html"
    tmp = out_dir / ".index.html.tmp"
    tmp.write_text(page)
    tmp.replace(index)
    return index


# --- the Papers page ---------------------------------------------------------------------------
# ROOT/papers.json (written by whatever evaluates paper claims; this module knows no paper):
# {"schema": 1, "renderer": str, "claims": [{paper, where, claim, reported, measured, tolerance,
#  agrees, why_not, experiment, images: [{label, array, reference}], table: {columns, rows},
#  plot: {x_title, y_title, log_x, log_y, series: [{name, x, y, dash}]}}]}; paths relative to ROOT.

PAPERS_JSON = "papers.json"
PAPERS_HTML = "papers.html"
CLAIM_KEYS = ("paper", "where", "claim", "reported", "measured", "tolerance", "agrees", "why_not")


def _papers_link(out_dir: Path) -> str | None:
    """Relative link to the Papers page of a run directory (or of the directory holding it)."""
    if (out_dir / PAPERS_JSON).is_file():
        return PAPERS_HTML
    if (out_dir.parent / PAPERS_JSON).is_file():
        return f"../{PAPERS_HTML}"
    return None


def _claim_images(root: Path, index: int, images: list[dict]) -> str:
    """The claim's runs side by side: V of each, and beneath it the same enlarged edge crop
    (chosen on the first run's reference), the reference first."""
    if not images:
        return ""
    with np.load(root / images[0]["reference"]) as z:
        ref, ref_cov = z["visibility"], z["covered"]
    crop = edge_crop(ref, ref_cov)
    folder = Path("images") / "papers" / f"claim-{index}"
    cells = [("reference", _visibility_rgb(ref, ref_cov))]
    for image in images:
        with np.load(root / image["array"]) as z:
            cells.append((image["label"], _visibility_rgb(z["visibility"], z["covered"])))
    heads, fulls, crops = [], [], []
    for j, (label, rgb) in enumerate(cells):
        name = folder / f"{j}.png"
        _with_box(rgb, crop, root / name)
        heads.append(f"<th>{html.escape(label)}</th>")
        fulls.append(f'<td><img src="{name}" alt="{html.escape(label)}" width="{THUMB_PX}"></td>')
        if crop is not None:
            _crop_png(rgb, crop, root / folder / f"{j}-crop.png")
            crops.append(f'<td><img src="{folder}/{j}-crop.png" alt="{html.escape(label)} crop" '
                         f'width="{THUMB_PX}"></td>')
    crop_row = f"<tr>{''.join(crops)}</tr>" if crops else ""
    return (f'<table class="grid"><tr>{"".join(heads)}</tr><tr>{"".join(fulls)}</tr>'
            f"{crop_row}</table>")


def _claim_table(table: dict | None) -> str:
    if not table:
        return ""
    head = "".join(f"<th>{html.escape(str(c))}</th>" for c in table["columns"])
    body = "".join("<tr>" + "".join(f"<td>{html.escape(str(c))}</td>" for c in row) + "</tr>"
                   for row in table["rows"])
    return f"<table><tr>{head}</tr>{body}</table>"


def _claim_plot(plot: dict | None, div_id: str) -> str:
    if not plot:
        return ""
    import plotly.graph_objects as go

    fig = go.Figure()
    for s in plot["series"]:
        fig.add_trace(go.Scatter(x=s["x"], y=s["y"], name=s["name"], mode="lines+markers"
                                 if len(s["x"]) <= 12 else "lines",
                                 line=dict(dash=s.get("dash", "solid"))))
    fig.update_layout(height=380, template="plotly_white", margin=dict(l=60, r=20, t=20, b=50),
                      xaxis=dict(title=plot["x_title"], type="log" if plot.get("log_x") else None),
                      yaxis=dict(title=plot["y_title"], type="log" if plot.get("log_y") else None))
    return _figure_html(fig, div_id)


def build_papers_page(root: str | Path) -> Path:
    """Write ``root/papers.html`` from ``root/papers.json``: a table of every claim (reported,
    measured, tolerance, agrees, why not), then each claim with its table, plot and images."""
    from plotly.offline import get_plotlyjs

    root = Path(root)
    doc = json.loads((root / PAPERS_JSON).read_text())
    claims = doc["claims"]
    rows, details = [], []
    for i, c in enumerate(claims):
        verdict = "yes" if c["agrees"] else "no"
        rows.append(f'<tr class="{"pass" if c["agrees"] else "fail"}">'
                    + "".join(f"<td>{html.escape(str(c[k]))}</td>" for k in CLAIM_KEYS[:6])
                    + f'<td><a href="#claim-{i}">{verdict}</a></td>'
                    + f"<td>{html.escape(c.get('why_not') or '')}</td></tr>")
        experiment = c.get("experiment")
        runs = (f' · runs: <a href="{html.escape(experiment)}/index.html">'
                f"{html.escape(experiment)}</a>" if experiment else " · analytic")
        details.append(f"""
<section id="claim-{i}">
<h3>{html.escape(c['paper'])}, {html.escape(c['where'])}: {html.escape(c['claim'])}
 <small>{'agrees' if c['agrees'] else 'does not agree'}{runs}</small></h3>
<p><b>Reported:</b> {html.escape(c['reported'])}<br><b>Measured:</b> {html.escape(c['measured'])}
<br><b>Tolerance:</b> {html.escape(c['tolerance'])}
{f"<br><b>Why not:</b> {html.escape(c['why_not'])}" if not c['agrees'] else ""}</p>
{_claim_table(c.get('table'))}
{_claim_plot(c.get('plot'), f'claim-{i}-plot')}
{_claim_images(root, i, c.get('images') or [])}
</section>""")
    experiments = sorted({c["experiment"] for c in claims if c.get("experiment")})
    links = " ".join(f'<a href="{html.escape(e)}/index.html">{html.escape(e)}</a>'
                     for e in experiments)
    agree = sum(bool(c["agrees"]) for c in claims)
    built = dt.datetime.now(dt.timezone.utc).isoformat(timespec="seconds")
    head = "".join(f"<th>{k}</th>" for k in CLAIM_KEYS)
    page = f"""<!doctype html>
<html lang="en"><head><meta charset="utf-8"><title>shadowbench: papers</title>
<link rel="icon" href="data:,">
<style>{STYLE}</style>
<script type="text/javascript">{get_plotlyjs()}</script>
</head><body>
<h1>Paper reproductions</h1>
<p class="meta">{agree} of {len(claims)} claims agree · renderer
{html.escape(doc.get('renderer') or '?')} · built {built}</p>
<nav>experiment dashboards: {links}</nav>
<p>Each claim: what the paper reports, what we measure, the tolerance it is judged by, and why
not where it does not agree (another machine explains absolute times, not a reversed
ordering). Images: the reference, then each run's V; beneath, the same enlarged edge crop.</p>
<table class="claims"><tr>{head}</tr>{''.join(rows)}</table>
{''.join(details)}
</body></html>
"""
    path = root / PAPERS_HTML
    tmp = root / f".{PAPERS_HTML}.tmp"
    tmp.write_text(page)
    tmp.replace(path)
    return path
