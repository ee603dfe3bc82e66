"""Resident memory of one sweep process, group by group (not a CI test).

    .venv/bin/python benchmarks/sweep_rss.py EXPERIMENT [--out DIR] [--table FILE]

Plans the experiment and renders it as ``shadowbench run`` does (harness.run.render_serial, in
this process), printing for each scene's group the process's resident memory as it begins
(what the groups before it left), the peak of each phase of the group (its reference and
G-buffer, its interleaved rounds) sampled every 20 ms by a thread, and the whole process's
peak so far (the kernel's high-water mark, what ``/usr/bin/time -v`` reports as maximum
resident set size); at the end the whole process's peak and the same as a Markdown table
(``--table FILE`` writes it there too), and per technique and scene the most one run's start
(prepare, warm-up) took over what the process held, what the sweep sizes its batches by.
Memory that a finished group leaves behind shows as
growth from one line to the next. Issue 34: four families at 10^6 triangles, sm and
silhouette at 256 x 256, grew to 1.24 GiB between groups (peak 1.74 GiB) before the sweep
returned freed heap pages after each group, 0.74 GiB (peak 1.55) after. Issue 53: the 10^6
groups of make scale (experiments/scale.yaml) and their figures: docs/benchmarks.md.
"""

from __future__ import annotations

import argparse
import sys
import tempfile
import threading
import time
from pathlib import Path

from harness import run
from harness.gl.context import get_context
from harness.machine.memory import peak_resident_bytes, resident_bytes

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
    the resident memory as it begins, the peak of its reference and of its rounds, and the
    whole process's peak so far; :meth:`table` gives them all as Markdown."""

    def __init__(self) -> None:
        self.sampler = _PeakSampler()
        self.sampler.start()
        self.group, self.phase = None, None
        self.peaks: dict[str, dict[str, float]] = {}

    def stage(self, text: str) -> None:
        self.close_phase()
        self.group, self.phase = text.split(":")[0], None
        self.peaks[self.group] = {"start": resident_bytes() / MIB}

    def status(self, text: str) -> None:
        self.close_phase()
        self.phase = "reference" if text == "reference" else "rounds"

    def close_phase(self) -> None:
        peak = self.sampler.take() / MIB
        if self.group is None or self.phase is None:
            return
        group = self.peaks[self.group]
        group[self.phase] = max(group.get(self.phase, 0), peak)
        group["process"] = peak_resident_bytes() / MIB
        if self.phase == "rounds":
            print(f"{self.group:26s} {group['start']:6.0f} MiB as it begins, reference peak "
                  f"{group.get('reference', 0):6.0f}, rounds peak {group['rounds']:6.0f} MiB, "
                  f"process peak so far {group['process']:6.0f} MiB", flush=True)

    def frame_done(self, specs) -> None:
        pass

    def table(self) -> str:
        lines = ["| group | as it begins (MiB) | reference peak (MiB) | rounds peak (MiB) "
                 "| process peak so far (MiB) |", "|---|---|---|---|---|"]
        for name, group in self.peaks.items():
            lines.append(f"| {name} | {group['start']:.0f} | {group.get('reference', 0):.0f} "
                         f"| {group.get('rounds', 0):.0f} | {group.get('process', 0):.0f} |")
        return "\n".join(lines)


def _starts_table(plan) -> str:
    """Per technique and group, the most one run's start (prepare, setup, warm-up) took the
    process over what it held just before (harness.run.measure.FOOTPRINTS, what the batches
    are sized by), as Markdown."""
    from harness.run.measure import FOOTPRINTS

    groups = {(spec.scene_key, spec.width, spec.height): spec.scene for spec in plan.runs}
    order = list(dict.fromkeys(scene for seen in FOOTPRINTS.seen.values() for scene in seen))
    order.sort(key=lambda scene: list(groups).index(scene) if scene in groups else len(groups))
    lines = ["| technique | " + " | ".join(groups.get(s, s[0]) for s in order) + " |",
             "|---|" + "---|" * len(order)]
    for technique, seen in sorted(FOOTPRINTS.seen.items()):
        cells = [f"{seen[s][1] / MIB:.0f}" if s in seen else "" for s in order]
        lines.append(f"| {technique} | " + " | ".join(cells) + " |")
    return "the most a run's start took over what the process held (MiB):\n\n" + "\n".join(lines)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("experiment")
    ap.add_argument("--out", help="results folder (default: a temporary one)")
    ap.add_argument("--table", help="also write the Markdown table to this file")
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
    peak = peak_resident_bytes() / MIB
    table = (f"{lines.table()}\n\nwhole process: peak {peak:.0f} MiB ({peak / 1024:.2f} GiB), "
             f"{resident_bytes() / MIB:.0f} MiB resident at the end\n\n{_starts_table(plan)}")
    print(f"end: {resident_bytes() / MIB:.0f} MiB resident, whole-process peak {peak:.0f} MiB, "
          f"{failed} runs not ok; results in {out}\n\n{table}")
    if args.table:
        Path(args.table).write_text(table + "\n")
    sys.exit(1 if failed else 0)


if __name__ == "__main__":
    main()
