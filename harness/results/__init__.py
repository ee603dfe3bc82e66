"""The results record (versioned), its CSV storage, and loading as a pandas DataFrame.

``results.csv`` and the arrays are replaced whole (write a temporary file, fsync, rename), or
results.csv has new runs' rows appended in one write that is undone when it falls short, so a
killed run leaves either the old or the new file, never a truncated one. Paths under a results
folder are resolved and kept inside it (:func:`inside`).
"""

from __future__ import annotations

import csv
import errno
import json
import math
import os
from pathlib import Path

from .columns import COLUMNS, JSON_COLUMNS, RENAMED
from ..config import ConfigError

SCHEMA_VERSION = 1

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
        except OSError as e:  # the user's path, not the temporary name they never gave
            raise OSError(e.errno, e.strerror, str(path)) from e
    try:
        with os.fdopen(fd, "wb") as f:
            write(f)
            f.flush()
            os.fsync(f.fileno())
        os.replace(tmp, path)
    except BaseException as e:
        tmp.unlink(missing_ok=True)
        if isinstance(e, OSError) and e.filename in (None, str(tmp)):
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
    renamed = {old: new for old, new in RENAMED.items() if old in columns and new not in columns}
    if renamed:  # a folder written before a column was renamed: its rows under the new name
        rows = [{renamed.get(k, k): v for k, v in row.items()} for row in rows]
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
    record_rows(out_dir, [row])


def record_rows(out_dir: str | Path, rows: list[dict]) -> None:
    """Add runs' rows, each replacing an earlier row of its run: appended when no run has one
    and the file's columns hold every value, else in one replacement of the file."""
    if not rows:
        return
    new = {row["run_id"] for row in rows}
    stored = read_rows(out_dir)
    if stored and not any(r["run_id"] in new for r in stored) and _append(out_dir, rows):
        return
    write_rows(out_dir, [r for r in stored if r["run_id"] not in new] + rows)


def _append(out_dir: str | Path, rows: list[dict]) -> bool:
    """Append ``rows`` to results.csv under its own header, in one write (a killed process
    leaves the file with all of them or none; a short write, a full disk, is cut off again):
    whether it could. Not where a row has a value for a column the file lacks (a new column,
    or one of its old names), nor after a last line without its line end (edited by hand).
    A sweep of n runs rewrote n (n + 1) / 2 rows before: make bench's 563 runs 160,000."""
    import io

    path = Path(out_dir) / RESULTS_FILE
    with path.open("rb") as f:
        header = f.readline()
        f.seek(0, os.SEEK_END)
        size = f.tell()
        f.seek(size - 1)
        ends_a_line = f.read(1) == b"\n"
    fields = next(csv.reader([header.decode("utf-8")]))
    cells = [{k: _cell(v) for k, v in row.items()} for row in rows]
    if not ends_a_line or any(v for c in cells for k, v in c.items() if k not in fields):
        return False
    text = io.StringIO(newline="")
    writer = csv.DictWriter(text, fieldnames=fields, extrasaction="ignore")
    writer.writerows(cells)
    data = text.getvalue().encode("utf-8")
    fd = os.open(path, os.O_WRONLY | os.O_APPEND)
    try:
        try:
            written = os.write(fd, data)
        except OSError as e:
            os.ftruncate(fd, size)
            raise OSError(e.errno, e.strerror, str(path)) from e
        if written < len(data):
            os.ftruncate(fd, size)
            raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC), str(path))
        os.fsync(fd)
    finally:
        os.close(fd)
    return True


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


def load(out_dir: str | Path, *, stale: str = "drop"):
    """Results of a run directory as a DataFrame: known columns typed (docs/results.md), the
    JSON columns (``params``, ``frame_ms``, ``passes``) parsed, old column names read as their
    new ones (``res`` as ``map_res``).

    Stale rows: a row is stale when a later row of the same scene, size, technique and
    parameters has another ``code_version`` (the technique changed and the run was made again).
    ``stale="drop"`` (the default) leaves them out; ``"flag"`` keeps every row and adds a
    boolean ``stale`` column."""
    import pandas as pd

    if stale not in ("drop", "flag"):
        raise ValueError(f"stale: 'drop' or 'flag', got {stale!r}")
    path = Path(out_dir) / RESULTS_FILE
    if not path.is_file():
        raise FileNotFoundError(f"{path}: no results here (run `shadowbench run --out {out_dir}`)")
    rows = read_rows(out_dir)
    if not rows:
        raise ConfigError(f"{path}: no results in it yet")
    raw = pd.DataFrame.from_records(rows).fillna("")
    # every column typed on its own, then the frame made once: a column replaced in place
    # gets a block of its own, and a frame of a hundred-odd blocks warns (PerformanceWarning)
    # at the next column anyone adds
    columns = {}
    for name in raw.columns:
        column, kind = raw[name], COLUMNS.get(name)
        if kind in (int, float) or (kind is None and _numeric(column)):
            column = pd.to_numeric(column.replace("", None), errors="coerce")
            if kind is int and column.notna().all():
                column = column.astype("int64")
            elif kind is float:  # "8388608" parses as an integer; the column is still float
                column = column.astype("float64")
        elif name in JSON_COLUMNS:
            empty = {} if name == "params" else None
            try:
                column = column.map(lambda s, empty=empty: json.loads(s) if s else empty)
            except ValueError as e:
                raise _not_ours(path, f"a {name} cell is not JSON: {e}") from None
        columns[name] = column
    key = [c for c in ("scene", "width", "height", "technique") if c in raw.columns]
    same_run = raw[key].astype(str).agg("|".join, axis=1) + "|" + columns["params"].map(
        lambda p: json.dumps(p, sort_keys=True))
    if "code_version" in raw.columns:
        latest = raw["code_version"].groupby(same_run).transform("last")
        columns["stale"] = raw["code_version"] != latest
    else:
        columns["stale"] = pd.Series(False, index=raw.index)
    df = pd.DataFrame(columns, index=raw.index)
    if stale == "drop":
        df = df[~df["stale"]].drop(columns="stale").reset_index(drop=True)
    return df


def _numeric(series) -> bool:
    import pandas as pd

    values = series[series != ""]
    return len(values) > 0 and pd.to_numeric(values, errors="coerce").notna().all()
