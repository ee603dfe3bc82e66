"""What ``shadowbench run`` says when it ends, on stdout (its progress went to stderr): the
runs of the plan in DIR by status, rendered now or already done, and the time; each failed
run with its error. The warning that too many runs were timed on a busy machine goes to
stderr. Each line is flushed as written, so that a log of both streams keeps their order."""

from __future__ import annotations

import sys
from pathlib import Path

from ..machine.timing import NOISY_CONTENTION, too_noisy


def print_run(plan, out: Path, seconds: float) -> None:
    from .. import results, run

    ids = {r.run_id for r in plan.runs}
    mine = [r for r in results.read_rows(out) if r["run_id"] in ids]
    counts = {s: sum(r["status"] == s for r in mine) for s in ("ok", "skipped", "error")}
    rendered = run.read_manifest(out)["invocations"][-1]["runs_rendered"]
    print(f"{len(mine)} runs in {out}/results.csv ({counts['ok']} ok, {counts['skipped']} "
          f"skipped, {counts['error']} failed; {rendered} rendered now, "
          f"{len(mine) - rendered} already done) in {seconds:.1f} s", flush=True)
    timed = [r for r in mine if r["status"] == "ok" and r.get("noisy", "") != ""]
    noisy = sum(r["noisy"] == "1" for r in timed)
    if too_noisy(noisy, len(timed)):
        print(f"warning: {noisy} of {len(timed)} runs are noisy (other processes used more than "
              f"{NOISY_CONTENTION:.0%} of the CPU while they were timed: cpu_contention); their "
              f"times are inflated: run again on a quiet machine, or add --retime-noisy",
              file=sys.stderr, flush=True)
    for r in mine:
        if r["status"] == "error":
            print(f"  failed: {r['scene']} {r['technique']} {r['params']}: {r['error']}",
                  flush=True)
