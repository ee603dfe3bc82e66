"""The results record (versioned), its CSV storage, and loading as a pandas DataFrame.

``results.csv`` is only ever replaced whole (write a temporary file, fsync, rename), so a
killed run leaves either the old or the new file, never a truncated one.
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

SCHEMA_VERSION = 1

# name -> type; these keep their names and meaning (DESIGN.md). Techniques may add columns.
COLUMNS: dict[str, type] = {
    "run_id": str, "schema": int, "scene": str, "technique": str, "params": str,
    "width": int, "height": int, "res": float,
    "time_ms": float, "time_ms_min": float, "time_ms_max": float, "frames": int,
    "time_ms_ci_low": float, "time_ms_ci_high": float, "frame_ms": str,
    "cpu_contention": float, "noisy": int,
    "scene_ms": float,
    "frags_scene": float, "frags_shadow": float, "overdraw": float, "mem_bytes": float,
    "fetches_per_px": float, "covered_px": float,
    "vertex_invocations": float, "fragment_invocations": float, "primitives": float,
    "gpu_estimate_ms": float,
    "mae": float, "rmse": float, "wrong_pct": float, "edge_mae": float, "ssim": float,
    "psnr": float, "flip": float, "levels": float,
    "acne_pct": float, "leak_pct": float, "edge_floor": float, "edge_ratio": float,
    "nonfinite": float, "v_min": float, "v_max": float,
    "passes": str, "renderer": str, "status": str, "error": str, "warnings": str,
    "code_version": str, "ref_samples": int, "ref_seconds": float, "array": str,
    "reference_array": str,
    "finished_at": str,
}
RESULTS_FILE = "results.csv"


def save_arrays(path: str | Path, **arrays) -> None:
    """Write an .npz whole or not at all: a temporary file of its own (processes sharing a
    folder never collide), then a rename."""
    import tempfile

    import numpy as np

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, suffix=".tmp.npz")
    with os.fdopen(fd, "wb") as f:
        np.savez_compressed(f, **arrays)
    os.replace(tmp, path)


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float) and math.isnan(value):
        return ""
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True)
    return str(value)


def read_rows(out_dir: str | Path) -> list[dict[str, str]]:
    path = Path(out_dir) / RESULTS_FILE
    if not path.is_file():
        return []
    with path.open(newline="") as f:
        return list(csv.DictReader(f))


def write_rows(out_dir: str | Path, rows: list[dict]) -> None:
    """Replace results.csv atomically with ``rows`` (known columns first, extras sorted)."""
    out_dir = Path(out_dir)
    extras = sorted({k for r in rows for k in r} - set(COLUMNS))
    fields = list(COLUMNS) + extras
    tmp = out_dir / f".{RESULTS_FILE}.tmp"
    with tmp.open("w", newline="") as f:
        writer = csv.DictWriter(f, fieldnames=fields)
        writer.writeheader()
        for row in rows:
            writer.writerow({k: _cell(row.get(k)) for k in fields})
        f.flush()
        os.fsync(f.fileno())
    os.replace(tmp, out_dir / RESULTS_FILE)


def record_row(out_dir: str | Path, row: dict) -> None:
    """Add a run's row, replacing an earlier row of the same run (a failed run retried)."""
    kept = [r for r in read_rows(out_dir) if r["run_id"] != row["run_id"]]
    write_rows(out_dir, kept + [row])


def done_ids(out_dir: str | Path) -> set[str]:
    """Runs that need no rendering again: finished ok or skipped. Failed runs are retried."""
    return {r["run_id"] for r in read_rows(out_dir) if r["status"] in ("ok", "skipped")}


def load(out_dir: str | Path):
    """Results of a run directory as a DataFrame: known columns typed, ``params`` parsed."""
    import pandas as pd

    path = Path(out_dir) / RESULTS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no results here (run `shadowbench run --out {out_dir}`)")
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    for name in df.columns:
        kind = COLUMNS.get(name)
        if kind in (int, float) or (kind is None and _numeric(df[name])):
            df[name] = pd.to_numeric(df[name].replace("", None), errors="coerce")
            if kind is int and df[name].notna().all():
                df[name] = df[name].astype("int64")
            elif kind is float:  # "8388608" parses as an integer; the column is still float
                df[name] = df[name].astype("float64")
    df["params"] = df["params"].map(lambda s: json.loads(s) if s else {})
    return df


def _numeric(series) -> bool:
    import pandas as pd

    values = series[series != ""]
    return len(values) > 0 and pd.to_numeric(values, errors="coerce").notna().all()
