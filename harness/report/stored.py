"""Reading a results folder for the report: rows, the manifest, and run arrays, each read only
from inside the folder. Whatever cannot be read becomes a note on the page, never a traceback."""

from __future__ import annotations

import hashlib
import json
import re
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import results
from ..config import ConfigError

SAFE_NAME = re.compile(r"[A-Za-z0-9_][A-Za-z0-9_.-]*")
# What np.load raises on a missing, truncated or foreign .npz, or one without a needed array.
UNREADABLE = (OSError, ValueError, EOFError, KeyError, zipfile.BadZipFile)
REQUIRED = {"run_id", "schema", "scene", "technique", "params", "width", "height", "time_ms",
            "status"}


def read_results(folder: Path):
    """``folder``'s results as a DataFrame; ConfigError naming the folder when it holds no
    results.csv, or one of another tool (:func:`harness.results.load` says why) or another
    results version, or no runs."""
    import pandas as pd

    folder = Path(folder)
    path = folder / results.RESULTS_FILE
    if not path.is_file():
        raise ConfigError(f"{folder}: no {results.RESULTS_FILE} here (not a results folder)")
    try:
        rows = results.load(folder, stale="flag")  # analysis.current leaves out the old
    except (OSError, ValueError, pd.errors.ParserError) as e:
        raise ConfigError(f"{path}: cannot be read as results ({type(e).__name__})") from None
    missing = sorted(REQUIRED - set(rows.columns))
    if missing:
        raise ConfigError(f"{path}: not a shadowbench results file (no column "
                          f"{', '.join(missing)})")
    versions = set(pd.to_numeric(rows["schema"], errors="coerce").dropna().astype(int))
    if versions != {results.SCHEMA_VERSION}:
        raise ConfigError(f"{path}: results version {sorted(versions) or 'missing'}; this "
                          f"shadowbench reads version {results.SCHEMA_VERSION}")
    return rows


@dataclass
class Folder:
    """A results folder as the report reads it; ``notes`` collects what it could not use."""

    root: Path
    notes: list[str] = field(default_factory=list)

    def __post_init__(self):
        self.root = Path(self.root)
        self._inside = self.root.resolve()

    def rows(self):
        return read_results(self.root)

    def manifest(self) -> dict:
        path = self.root / "manifest.json"
        if not path.is_file():
            return {}
        try:
            meta = json.loads(path.read_text())
        except (OSError, ValueError) as e:
            self.notes.append(f"manifest.json cannot be read ({type(e).__name__}); "
                              "the versions and renderer are unknown")
            return {}
        return meta if isinstance(meta, dict) else {}

    def inside(self, relative: str) -> Path | None:
        """The path ``relative`` names under the folder, or None (with a note) when it leads
        outside it: results.csv is data, and data does not choose which files are read."""
        if not relative:
            return None
        path = (self.root / relative).resolve()
        if not path.is_relative_to(self._inside):
            self.notes.append(f"{relative!r} points outside {self.root}; ignored")
            return None
        return path

    def arrays(self, relative: str, *names: str, what: str) -> dict[str, np.ndarray] | None:
        """The named arrays of a stored .npz (and every ``map_*`` and optional array it has),
        or None with a note naming ``what`` when the file is missing, damaged or outside."""
        path = self.inside(relative)
        if path is None:
            return None
        try:
            with np.load(path) as z:
                found = {name: z[name] for name in names}
                found.update({k: z[k] for k in z.files if k not in found})
        except UNREADABLE as e:
            self.notes.append(f"{what}: {relative} cannot be read ({type(e).__name__}); "
                              "shown as unavailable")
            return None
        return found


def slug(name: str) -> str:
    """A name fit for an HTML id and a file name: the name itself when it is one already, else
    its safe characters and a hash of the whole (two names never share a slug)."""
    if SAFE_NAME.fullmatch(name) and len(name) <= 80:
        return name
    safe = re.sub(r"[^A-Za-z0-9_-]+", "-", name).strip("-")[:40]
    return f"{safe or 'x'}-{hashlib.sha256(name.encode()).hexdigest()[:8]}"
