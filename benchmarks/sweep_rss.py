"""Resident memory of one sweep process between its scenes' groups (not a CI test).

    .venv/bin/python benchmarks/sweep_rss.py EXPERIMENT [--out DIR]

Plans the experiment and renders it as ``shadowbench run`` does (harness.run.render_serial, in
this process), printing the process's resident memory as each scene's group begins (after the
previous group ended and returned what it freed) and its peak at the end. Memory that a
finished group leaves behind shows as growth from one line to the next. Issue 34: four families
at 10^6 triangles, sm and silhouette at 256 x 256, grew to 1.24 GiB between groups (peak 1.74
GiB) before the sweep returned freed heap pages after each group, 0.74 GiB (peak 1.55) after.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
from pathlib import Path

from harness import run
from harness.gl.context import get_context
from harness.run.measure import resident_bytes

MIB = 2 ** 20


class _Lines:
    """A progress (harness.run.sweep.RunProgress's renderer side) that prints the resident
    memory as each group begins."""

    def stage(self, text: str) -> None:
        print(f"{text:32s} {resident_bytes() / MIB:7.0f} MiB resident as it begins", flush=True)

    def status(self, text: str) -> None:
        pass

    def frame_done(self, specs) -> None:
        pass


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("experiment")
    ap.add_argument("--out", help="results folder (default: a temporary one)")
    args = ap.parse_args()
    plan = run.plan_runs(experiment_path=args.experiment, scene_file="scenes.yaml", scenes=None,
                         techniques=None, overrides={})
    print(f"{len(plan.runs)} runs planned, {resident_bytes() / MIB:.0f} MiB resident", flush=True)
    out = Path(args.out or tempfile.mkdtemp(prefix="sweep_rss_"))
    failed = 0
    for _, row in run.render_serial(plan, plan.runs, out, get_context(), _Lines()):
        failed += row["status"] != "ok"
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / MIB
    print(f"end: {resident_bytes() / MIB:.0f} MiB resident, peak {peak:.0f} MiB, "
          f"{failed} runs not ok; results in {out}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
