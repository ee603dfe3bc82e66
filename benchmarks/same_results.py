"""Whether two results folders hold the same runs with the same results (not a CI test).

    .venv/bin/python benchmarks/same_results.py BEFORE AFTER [--common] [--ignore COLUMN ...]

Pairs the rows of BEFORE/results.csv and AFTER/results.csv by scene, image size, technique and
parameters and compares every column that does not depend on the clock: what each run measured
(error, counts, fragments, maps' bytes, status), not its times or load, nor what names the code
(a technique's code version, and so its run id and the path of its arrays, follows any edit of
its package). ``passes`` is compared without its times (each pass's name and counts). Prints
each difference and exits 1 if there is one, a run found in one folder only included (with
``--common``, the runs both folders hold are compared and the others only counted).
``--ignore`` leaves a column out, one that varies between two runs of the same code (ptsv's
traversal counts do: which of llvmpipe's threads finds a sample shadowed first). Issue 53
used it to check that bounding a sweep's memory (batches sized by memory, contexts made anew,
sv's buffers built in place) changed no result of make scale's groups.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness import results

# what the clock, the machine's load or the moment gives, and what names the code
NOT_COMPARED = {"run_id", "code_version", "array", "time_ms", "time_ms_min", "time_ms_max",
                "time_ms_ci_low", "time_ms_ci_high", "frame_ms", "prepare_ms", "setup_ms",
                "setup_ms_ci_low", "setup_ms_ci_high", "cpu_contention", "noisy", "scene_ms",
                "ref_seconds", "ref_build_seconds", "finished_at"}
# pass keys that are times (the rest: name and counts)
PASS_TIMES = {"ms", "ms_ci_low", "ms_ci_high"}


def _untimed(row: dict, ignored: set[str]) -> dict:
    out = {k: v for k, v in row.items() if k not in NOT_COMPARED | ignored}
    if out.get("passes"):
        out["passes"] = [{k: v for k, v in p.items() if k not in PASS_TIMES}
                         for p in json.loads(out["passes"])]
    return out


def _run(row: dict) -> tuple:
    return row["scene"], row["width"], row["height"], row["technique"], row["params"]


def differences(before: Path, after: Path,
                ignored: set[str] = frozenset()) -> tuple[list[str], list[str], int]:
    """(the runs in one folder only, each difference of a run in both, how many are in both)."""
    # the rows as written (text): equal numbers are equal strings
    rows = [{_run(row): row for row in results.read_rows(folder)} for folder in (before, after)]
    only = [f"{' '.join(run)}: in {folder} only" for folder, own, other in
            ((before, rows[0], rows[1]), (after, rows[1], rows[0]))
            for run in sorted(set(own) - set(other))]
    common, out = sorted(set(rows[0]) & set(rows[1])), []
    for run in common:
        a, b = (_untimed(r[run], ignored) for r in rows)
        for column in sorted(set(a) | set(b)):
            if a.get(column) != b.get(column):
                out.append(f"{a['scene']} {a['technique']} {a['params']}: {column} "
                           f"{a.get(column)!r} -> {b.get(column)!r}")
    return only, out, len(common)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    ap.add_argument("--common", action="store_true", help="compare the runs both folders hold")
    ap.add_argument("--ignore", action="append", default=[], metavar="COLUMN",
                    help="a column not compared (one that varies between runs of the same code)")
    args = ap.parse_args()
    only, changed, common = differences(args.before, args.after, set(args.ignore))
    found = changed + ([] if args.common else only)
    print("\n".join(found + [f"{common} runs in both folders, {len(only)} in one only: "
                             f"{'differences above' if found else 'every non-timing column equal'}"]))
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
