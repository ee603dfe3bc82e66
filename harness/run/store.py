"""Storing, after scoring: a finished run's arrays, the scene's reference (once), then its row,
inside the run folder, whose lock keeps one sweep at a time writing there."""

from __future__ import annotations

import datetime as dt
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from .. import config as cfg
from .. import results
from .plan import RunSpec


def utc_now() -> str:
    # milliseconds: an invocation's wall time (finished - started) feeds `shadowbench plan`'s
    # estimate, and a short one read in whole seconds was 0 (no estimate)
    return dt.datetime.now(dt.timezone.utc).isoformat(timespec="milliseconds")


def reference_array_path(scene: str, width: int, height: int, samples: int, seed: int) -> Path:
    """Where a run directory keeps a scene's reference: one file per sampling, so a rerun with
    other reference settings never scores against, or shows, a stale one."""
    return Path("arrays") / scene / f"{width}x{height}" / f"reference-{samples}spp-seed{seed}.npz"


@contextmanager
def exclusive(out_dir: Path):
    """Hold DIR's lock: two sweeps appending to one results.csv would lose each other's rows.
    The kernel drops the lock when the holder dies, so a killed run never leaves DIR locked."""
    import fcntl

    with (out_dir / ".lock").open("a+") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            raise cfg.ConfigError(f"{out_dir}: another shadowbench run is writing here; wait "
                                  "for it or choose another --out") from None
        yield


def record_run(out_dir: Path, spec: RunSpec, row: dict, arrays: dict[str, np.ndarray] | None,
               reference) -> None:
    """Store one finished run: the scene's reference arrays (once), its arrays, then the row.

    Arrays are written before their row: a kill between the two leaves an unreferenced array
    that the rerun overwrites. Every executor records through here, the client alone. A run
    whose scene failed has no reference (None) and no arrays."""
    store_arrays(out_dir, spec, row, arrays, reference)
    results.record_row(out_dir, row)


def record_runs(out_dir: Path, finished: list[tuple]) -> None:
    """Store several finished runs, ``(spec, row, arrays, reference)`` each, as
    :func:`record_run` does, their rows in one replacement of results.csv: many short runs
    (tune's search) would otherwise rewrite the whole file once each."""
    for spec, row, arrays, reference in finished:
        store_arrays(out_dir, spec, row, arrays, reference)
    results.record_rows(out_dir, [row for _, row, _, _ in finished])


def store_arrays(out_dir: Path, spec: RunSpec, row: dict, arrays: dict[str, np.ndarray] | None,
                 reference) -> None:
    """A finished run's arrays and its scene's reference (once), their paths into its row, and
    the row's ``finished_at``; the row itself is the caller's to record."""
    if reference is not None:
        ref_name = reference_array_path(spec.scene, spec.width, spec.height, spec.samples,
                                        spec.ref_seed)
        ref_path = results.inside(out_dir, ref_name)
        row["reference_array"] = str(ref_name)
        if not results.readable_npz(ref_path):
            results.save_arrays(ref_path, visibility=reference.visibility,
                                covered=reference.covered,
                                **({"direct": reference.direct} if reference.direct is not None
                                   else {}))
    if arrays is not None:
        array = ref_name.with_name(f"{spec.technique}-{spec.run_id}.npz")
        results.save_arrays(results.inside(out_dir, array), **arrays)
        row["array"] = str(array)
    row["finished_at"] = utc_now()
