"""A static HTML report built only from stored results (results.csv and arrays); it never renders.

Per scene: the reference visibility, then for each run its V and the signed error
V - V_ref (red: lit where the reference is shadowed, blue: shadowed where it is lit).
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np
from PIL import Image

from . import results

TABLE_COLUMNS = ["technique", "params", "width", "height", "time_ms", "mae", "edge_mae",
                 "wrong_pct", "levels", "ssim", "psnr", "flip", "mem_bytes", "fetches_per_px",
                 "overdraw", "nonfinite", "status", "error"]


def visibility_png(v: np.ndarray, covered: np.ndarray, path: Path) -> None:
    grey = np.clip(v, 0, 1) * 0.85 + 0.15
    rgb = np.where(covered[..., None], grey[..., None], np.array([0.35, 0.45, 0.6]))
    _save(rgb, path)


def error_png(v: np.ndarray, ref: np.ndarray, covered: np.ndarray, path: Path) -> None:
    d = np.clip(np.nan_to_num(v, nan=0.5) - ref, -1, 1)
    rgb = np.ones(v.shape + (3,))
    rgb[..., 1] -= np.abs(d)
    rgb[..., 2] -= np.clip(d, 0, 1)
    rgb[..., 0] -= np.clip(-d, 0, 1)
    rgb[~covered] = 0.85
    _save(rgb, path)


def _save(rgb: np.ndarray, path: Path) -> None:
    path.parent.mkdir(parents=True, exist_ok=True)
    Image.fromarray((np.clip(rgb, 0, 1) * 255).astype(np.uint8)).save(path)


def _fmt(value) -> str:
    if isinstance(value, float):
        if np.isnan(value):
            return ""
        return f"{value:.4g}"
    if isinstance(value, dict):
        return ", ".join(f"{k}={v}" for k, v in value.items())
    return str(value)


def build_report(out_dir: str | Path) -> Path:
    out_dir = Path(out_dir)
    df = results.load(out_dir)
    sections = []
    for (scene, width, height), group in df.groupby(["scene", "width", "height"], sort=False):
        ref_file = out_dir / "arrays" / scene / f"{width}x{height}" / "reference.npz"
        images = Path("images") / scene / f"{width}x{height}"
        parts = [f"<h2>{html.escape(scene)} <small>{width}x{height}</small></h2>"]
        ref = None
        if ref_file.is_file():
            with np.load(ref_file) as z:
                ref, ref_cov = z["visibility"], z["covered"]
            visibility_png(ref, ref_cov, out_dir / images / "reference.png")
            parts.append(f'<figure><img src="{images}/reference.png" alt="reference V">'
                         "<figcaption>reference V (Mitsuba)</figcaption></figure>")
        rows = []
        for _, r in group.iterrows():
            cells = "".join(f"<td>{html.escape(_fmt(r.get(c)))}</td>" for c in TABLE_COLUMNS)
            thumbs = ""
            if r["status"] == "ok" and r["array"] and ref is not None:
                with np.load(out_dir / r["array"]) as z:
                    v, cov = z["visibility"], z["covered"]
                stem = Path(r["array"]).stem
                visibility_png(v, cov, out_dir / images / f"{stem}.png")
                error_png(v, ref, cov & ref_cov, out_dir / images / f"{stem}-error.png")
                thumbs = (f'<img src="{images}/{stem}.png" alt="V {stem}">'
                          f'<img src="{images}/{stem}-error.png" alt="error {stem}">')
            rows.append(f"<tr>{cells}<td class=img>{thumbs}</td></tr>")
        head = "".join(f"<th>{c}</th>" for c in TABLE_COLUMNS) + "<th>V, V - V_ref</th>"
        parts.append(f"<table><tr>{head}</tr>{''.join(rows)}</table>")
        sections.append("\n".join(parts))
    manifest = out_dir / "manifest.json"
    meta = json.loads(manifest.read_text()) if manifest.is_file() else {}
    gl = meta.get("gl", {})
    page = f"""<!doctype html>
<html><head><meta charset="utf-8"><title>shadowbench results</title>
<style>
body{{font-family:sans-serif;margin:1.5em}} table{{border-collapse:collapse;font-size:12px}}
td,th{{border:1px solid #ccc;padding:2px 4px;vertical-align:top}} td.img img{{width:160px;margin:1px}}
figure{{display:inline-block;margin:0}} figure img{{width:256px}}
</style></head><body>
<h1>shadowbench results</h1>
<p>{html.escape(gl.get('renderer', ''))} · {html.escape(meta.get('cpu', ''))} ·
commit {html.escape(meta.get('git_commit', '')[:10])} · {len(df)} runs.
Error images: red = lit where the reference is in shadow, blue = shadowed where it is lit.</p>
{''.join(sections)}
</body></html>
"""
    index = out_dir / "index.html"
    index.write_text(page)
    return index
