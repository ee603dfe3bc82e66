"""The results record (versioned), its CSV storage, and loading as a pandas DataFrame.

``results.csv`` and the arrays are only ever replaced whole (write a temporary file, fsync,
rename), so a killed run leaves either the old or the new file, never a truncated one. Paths
under a results folder are resolved and kept inside it (:func:`inside`).
"""

from __future__ import annotations

import csv
import json
import math
import os
from pathlib import Path

from .config import ConfigError

SCHEMA_VERSION = 1

# name -> type; these keep their names and meaning (DESIGN.md). Techniques may add columns.
COLUMNS: dict[str, type] = {
    "run_id": str, "schema": int, "scene": str, "technique": str, "params": str,
    "family": str,
    "width": int, "height": int, "res": float,
    "triangles": int, "parts": int, "open_parts": int, "shadow_edges": int,
    "time_ms": float, "time_ms_min": float, "time_ms_max": float, "frames": int,
    "time_ms_ci_low": float, "time_ms_ci_high": float, "frame_ms": str,
    "cost": str, "prepare_ms": float, "setup_ms": float, "setup_ms_ci_low": float, "setup_ms_ci_high": float,
    "cpu_contention": float, "noisy": int,
    "scene_ms": float,
    "frags_scene": float, "frags_shadow": float, "overdraw": float, "mem_bytes": float,
    "fetches_per_px": float, "covered_px": float,
    "vertex_invocations": float, "fragment_invocations": float, "primitives": float,
    "compute_invocations": float, "traversal_nodes": float, "triangle_tests": float,
    "gpu_estimate_ms": float,
    "mae": float, "rmse": float, "wrong_pct": float, "edge_mae": float, "ssim": float,
    "psnr": float, "flip": float, "levels": float,
    "acne_pct": float, "leak_pct": float, "edge_floor": float, "edge_ratio": float,
    # moving scenes: flicker at fixed world points (metrics.world_flicker)
    "world_flicker": float, "world_flicker_max": float, "world_changed_pct": float,
    "world_changed_pct_max": float,
    "nonfinite": float, "v_min": float, "v_max": float,
    "passes": str, "renderer": str, "status": str, "error": str, "warnings": str,
    "code_version": str, "ref_samples": int, "ref_seconds": float,
    "ref_build_seconds": float, "array": str,
    "reference_array": str,
    "finished_at": str,
}
RESULTS_FILE = "results.csv"


TEMPORARY_SUFFIX = ".tmp"


def replace_atomically(path: str | Path, write) -> None:
    """Write ``path`` whole or not at all: ``write(binary_file)`` fills a temporary file of its
    own beside it (processes sharing a folder never collide; the umask gives its mode, as for
    any file), which is synced and renamed over ``path``. The temporary file is removed when
    writing fails; a killed writer leaves it for :func:`remove_temporaries`. An OSError names
    ``path`` (a full disk fails in a write, which knows no file name)."""
    import secrets

    path = Path(path)
    while True:
        tmp = path.with_name(f".{path.name}.{secrets.token_hex(4)}{TEMPORARY_SUFFIX}")
        try:
            fd = os.open(tmp, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
            break
        except FileExistsError:
            continue
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, OSError) and e.filename is None:
            raise OSError(e.errno, e.strerror, str(path)) from e
        raise


def remove_temporaries(out_dir: str | Path, names: tuple[str, ...]) -> int:
    """Remove what killed writers left in a results folder: the temporary files of the files
    ``names`` at its top and of the arrays under ``arrays/``, named as this version or older
    ones name them; the number removed. Only while no writer runs (under the folder's lock)."""
    out_dir = Path(out_dir)
    stale = [p for name in names for p in out_dir.glob(f".{name}*{TEMPORARY_SUFFIX}")]
    stale += [p for pattern in (f".*.npz.*{TEMPORARY_SUFFIX}", "*.tmp.npz")
              for p in (out_dir / "arrays").rglob(pattern)]
    for p in stale:
        if p.is_file():
            p.unlink()
    return len(stale)


def save_arrays(path: str | Path, **arrays) -> None:
    """Write an .npz whole or not at all (:func:`replace_atomically`)."""
    import numpy as np

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    replace_atomically(path, lambda f: np.savez_compressed(f, **arrays))


def inside(out_dir: str | Path, relative: str | Path) -> Path:
    """``out_dir / relative`` resolved; a ConfigError when it leads outside ``out_dir`` (an
    absolute path, ``..``, or a link out). Every path under ``--out`` goes through here."""
    root = Path(out_dir).resolve()
    path = (root / relative).resolve()
    if not path.is_relative_to(root):
        raise ConfigError(f"{out_dir}: {str(relative)!r} leads outside this folder")
    return path


def _cell(value) -> str:
    if value is None:
        return ""
    if isinstance(value, float) and math.isnan(value):
        return ""
    if isinstance(value, (dict, list)):
        return json.dumps(value, sort_keys=True)
    return str(value)


# results.csv without these columns is not ours: refuse to append to it or report on it
OWN_COLUMNS = ("run_id", "scene", "technique", "params", "status")


def read_rows(out_dir: str | Path) -> list[dict[str, str]]:
    """The rows of DIR/results.csv (none when it is missing or empty); a ConfigError when the
    file is not a shadowbench results file."""
    path = Path(out_dir) / RESULTS_FILE
    if not path.is_file():
        return []
    try:
        with path.open(newline="", encoding="utf-8") as f:
            reader = csv.DictReader(f)
            rows = list(reader)
            columns = reader.fieldnames
    except (UnicodeDecodeError, csv.Error) as e:
        raise _not_ours(path, " ".join(str(e).split())[:120]) from None
    if columns is None:
        return []
    missing = [c for c in OWN_COLUMNS if c not in columns]
    if missing:
        raise _not_ours(path, f"no {', '.join(missing)} column")
    return rows


def _not_ours(path: Path, reason: str) -> ConfigError:
    return ConfigError(f"{path}: not a shadowbench results file ({reason}); use another folder "
                       "or move the file away")


def write_rows(out_dir: str | Path, rows: list[dict]) -> None:
    """Replace results.csv atomically with ``rows`` (known columns first, extras sorted)."""
    import io

    extras = sorted({k for r in rows for k in r} - set(COLUMNS))
    fields = list(COLUMNS) + extras
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=fields)
    writer.writeheader()
    for row in rows:
        writer.writerow({k: _cell(row.get(k)) for k in fields})
    replace_atomically(Path(out_dir) / RESULTS_FILE,
                       lambda f: f.write(text.getvalue().encode("utf-8")))


def record_row(out_dir: str | Path, row: dict) -> None:
    """Add a run's row, replacing an earlier row of the same run (a failed run retried)."""
    kept = [r for r in read_rows(out_dir) if r["run_id"] != row["run_id"]]
    write_rows(out_dir, kept + [row])


def done_ids(out_dir: str | Path) -> set[str]:
    """Runs that need no rendering again: finished ok or skipped. Failed runs are retried."""
    return {r["run_id"] for r in read_rows(out_dir) if r["status"] in ("ok", "skipped")}


def readable_npz(path: Path) -> bool:
    """Whether an .npz opens (its zip directory, at the end, survives no truncation)."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as z:
            return bool(z.namelist())
    except (OSError, zipfile.BadZipFile):
        return False


def mark_damaged_runs(out_dir: str | Path) -> list[dict]:
    """Rows whose stored arrays are missing, unreadable or outside DIR become failed runs
    (status ``error``, the error naming the file), so the next run renders them again; the
    rows marked."""
    rows = read_rows(out_dir)
    damaged = []
    for row in rows:
        if row["status"] != "ok":
            continue
        for column in ("array", "reference_array"):
            name = row.get(column) or ""
            if not name:
                continue
            try:
                readable = readable_npz(inside(out_dir, name))
            except ConfigError:
                readable = False
            if not readable:
                row.update(status="error", error=f"stored array {name} is missing or damaged; "
                                                 "the next run renders it again")
                damaged.append(row)
                break
    if damaged:
        write_rows(out_dir, rows)
    return damaged


def load(out_dir: str | Path):
    """Results of a run directory as a DataFrame: known columns typed, ``params`` parsed."""
    import pandas as pd

    path = Path(out_dir) / RESULTS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no results here (run `shadowbench run --out {out_dir}`)")
    if not read_rows(out_dir):
        raise ConfigError(f"{path}: no results in it yet")
    df = pd.read_csv(path, dtype=str, keep_default_na=False)
    for name in df.columns:
        kind = COLUMNS.get(name)
        if kind in (int, float) or (kind is None and _numeric(df[name])):
            df[name] = pd.to_numeric(df[name].replace("", None), errors="coerce")
            if kind is int and df[name].notna().all():
                df[name] = df[name].astype("int64")
            elif kind is float:  # "8388608" parses as an integer; the column is still float
                df[name] = df[name].astype("float64")
    try:
        df["params"] = df["params"].map(lambda s: json.loads(s) if s else {})
    except ValueError as e:
        raise _not_ours(path, f"a params cell is not JSON: {e}") from None
    return df


def _numeric(series) -> bool:
    import pandas as pd

    values = series[series != ""]
    return len(values) > 0 and pd.to_numeric(values, errors="coerce").notna().all()
