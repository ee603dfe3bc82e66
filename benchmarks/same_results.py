"""Whether two results folders hold the same runs with the same results (not a CI test).

    .venv/bin/python benchmarks/same_results.py BEFORE AFTER

Pairs the rows of BEFORE/results.csv and AFTER/results.csv by run id and compares every column
that does not depend on the clock: what each run measured (error, counts, fragments, maps'
bytes, status), not its times, load or the paths it was stored at. ``passes`` is compared
without its times (each pass's name and counts). Prints each difference and exits 1 if there is
one, a run found in one folder only included. Issue 53 used it to check that bounding a sweep's
memory (batches sized by memory, contexts made anew) changed no result of make scale's groups.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

from harness import results

# what the clock, the machine's load or the moment gives
TIMED = {"time_ms", "time_ms_min", "time_ms_max", "time_ms_ci_low", "time_ms_ci_high", "frame_ms",
         "prepare_ms", "setup_ms", "setup_ms_ci_low", "setup_ms_ci_high", "cpu_contention",
         "noisy", "scene_ms", "ref_seconds", "ref_build_seconds", "finished_at"}
# pass keys that are times (the rest: name and counts)
PASS_TIMES = {"ms", "ms_ci_low", "ms_ci_high"}


def _untimed(row: dict) -> dict:
    out = {k: v for k, v in row.items() if k not in TIMED}
    if out.get("passes"):
        out["passes"] = [{k: v for k, v in p.items() if k not in PASS_TIMES}
                         for p in json.loads(out["passes"])]
    return out


def differences(before: Path, after: Path) -> list[str]:
    # the rows as written (text): equal numbers are equal strings
    rows = [{row["run_id"]: row for row in results.read_rows(folder)} for folder in (before, after)]
    out = [f"{run_id}: in {folder} only" for folder, own, other in
           ((before, rows[0], rows[1]), (after, rows[1], rows[0]))
           for run_id in sorted(set(own) - set(other))]
    for run_id in sorted(set(rows[0]) & set(rows[1])):
        a, b = (_untimed(r[run_id]) for r in rows)
        for column in sorted(set(a) | set(b)):
            if a.get(column) != b.get(column):
                out.append(f"{a['scene']} {a['technique']} {a['params']}: {column} "
                           f"{a.get(column)!r} -> {b.get(column)!r}")
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("before", type=Path)
    ap.add_argument("after", type=Path)
    args = ap.parse_args()
    found = differences(args.before, args.after)
    count = len(results.read_rows(args.before))
    print("\n".join(found) or f"{count} runs: every non-timing column equal")
    sys.exit(1 if found else 0)


if __name__ == "__main__":
    main()
