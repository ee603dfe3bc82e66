"""Resident memory of one sweep process between its scenes' groups (not a CI test).

    .venv/bin/python benchmarks/sweep_rss.py EXPERIMENT [--out DIR]

Plans the experiment and renders it as ``shadowbench run`` does (harness.run.render_serial, in
this process), printing the process's resident memory as each scene's group begins (after the
previous group ended and returned what it freed), the peak of each phase of the group (its
reference, its interleaved rounds) sampled every 20 ms by a thread, and the whole process's
peak at the end. Memory that a
finished group leaves behind shows as growth from one line to the next. Issue 34: four families
at 10^6 triangles, sm and silhouette at 256 x 256, grew to 1.24 GiB between groups (peak 1.74
GiB) before the sweep returned freed heap pages after each group, 0.74 GiB (peak 1.55) after.
"""

from __future__ import annotations

import argparse
import resource
import sys
import tempfile
import threading
import time
from pathlib import Path

from harness import run
from harness.gl.context import get_context
from harness.run.measure import resident_bytes

MIB = 2 ** 20


class _PeakSampler(threading.Thread):
    """The highest resident memory seen since the last ``take()``, sampled every 20 ms."""

    def __init__(self) -> None:
        super().__init__(daemon=True)
        self.peak = 0
        self.lock = threading.Lock()

    def run(self) -> None:
        while True:
            now = resident_bytes()
            with self.lock:
                self.peak = max(self.peak, now)
            time.sleep(0.02)

    def take(self) -> int:
        with self.lock:
            peak, self.peak = max(self.peak, resident_bytes()), resident_bytes()
        return peak


class _Lines:
    """A progress (harness.run.sweep.RunProgress's renderer side) that prints, per scene group,
    the resident memory as it begins and the peak of its reference and of its rounds."""

    def __init__(self) -> None:
        self.sampler = _PeakSampler()
        self.sampler.start()
        self.group, self.phase = None, None
        self.peaks: dict[str, dict[str, float]] = {}

    def stage(self, text: str) -> None:
        self.close_phase()
        self.group, self.phase = text, None
        self.peaks[text] = {"start": resident_bytes() / MIB}

    def status(self, text: str) -> None:
        self.close_phase()
        self.phase = "reference" if text == "reference" else "rounds"

    def close_phase(self) -> None:
        peak = self.sampler.take() / MIB
        if self.group is None or self.phase is None:
            return
        group = self.peaks[self.group]
        group[self.phase] = max(group.get(self.phase, 0), peak)
        if self.phase == "rounds":
            print(f"{self.group:32s} {group['start']:7.0f} MiB as it begins, reference peak "
                  f"{group.get('reference', 0):7.0f}, rounds peak {group['rounds']:7.0f} MiB",
                  flush=True)

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
    lines = _Lines()
    for _, row in run.render_serial(plan, plan.runs, out, get_context(), lines):
        failed += row["status"] != "ok"
    lines.close_phase()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss * 1024 / MIB
    print(f"end: {resident_bytes() / MIB:.0f} MiB resident, peak {peak:.0f} MiB, "
          f"{failed} runs not ok; results in {out}")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
