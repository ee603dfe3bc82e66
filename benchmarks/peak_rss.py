"""Peak resident memory of a whole run process, per technique, on one scene (not a CI test).

    .venv/bin/python benchmarks/peak_rss.py [--scene architecture@1e6] [--size 1024]
                                            [--techniques sm,pcf,silhouette,sv] [--frames 3]
                                            [--samples 16]

Issue 23's bound: at 10^6 triangles and 1024 x 1024 the whole process stays under 4 GiB for
every technique. Each technique runs in a fresh process, as ``harness.run.evaluate`` runs it
(build the scene, the G-buffer pass, the technique's warm-up and measured frames, scoring
against the reference), and reports its own peak (``ru_maxrss``) and CPU time. The reference
is traced first, in a process of its own, into the reference cache (``SHADOWBENCH_CACHE``), so
a technique's process reads it from disk; that process's peak is printed too (the Mitsuba
build and trace of the same triangles), since a cold run pays it once per scene.
"""

from __future__ import annotations

import argparse
import json
import resource
import subprocess
import sys
import time
from pathlib import Path

SCENE_FILE = Path(__file__).resolve().parent.parent / "scenes.yaml"
GIB = 1024 ** 3


def _usage() -> dict:
    me = resource.getrusage(resource.RUSAGE_SELF)
    return {"peak_gib": me.ru_maxrss * 1024 / GIB, "cpu_s": me.ru_utime + me.ru_stime}


def child(args) -> None:
    """One measurement in this process; prints one JSON line."""
    from harness.scene import load_scene

    scene = load_scene(args.scene, SCENE_FILE).with_resolution(args.size, args.size)
    start = time.perf_counter()
    if args.one == "reference":
        from harness.truth.reference import compute_reference

        ref = compute_reference(scene, samples=args.samples)
        extra = {"trace_s": ref.seconds, "build_s": ref.build_seconds, "cached": ref.cached}
    else:
        from harness.run import evaluate

        row = evaluate(scene, args.one, frames=args.frames, warmup=1, samples=args.samples).row
        extra = {"time_ms": row.get("time_ms"), "scene_ms": row.get("scene_ms"),
                 "mem_bytes": row.get("mem_bytes"), "status": row.get("status"),
                 "error": row.get("error") or ""}
    print(json.dumps({"what": args.one, "triangles": sum(len(p.faces) for p in scene.parts),
                      "wall_s": time.perf_counter() - start, **extra, **_usage()}))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="architecture@1e6")
    ap.add_argument("--size", type=int, default=1024)
    ap.add_argument("--techniques", default="sm,pcf,silhouette,sv")
    ap.add_argument("--frames", type=int, default=3)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--one", help=argparse.SUPPRESS)  # the child's own measurement
    args = ap.parse_args()
    if args.one:
        return child(args)
    print(f"{args.scene} at {args.size}x{args.size}, {args.frames} frames, reference "
          f"{args.samples} spp; peak RSS of each process")
    print("| process | peak RSS GiB | CPU s | wall s | time_ms | status |")
    print("|---|---|---|---|---|---|")
    for what in ["reference", *args.techniques.split(",")]:
        out = subprocess.run([sys.executable, __file__, "--one", what, "--scene", args.scene,
                              "--size", str(args.size), "--frames", str(args.frames),
                              "--samples", str(args.samples)],
                             capture_output=True, text=True)
        lines = [line for line in out.stdout.splitlines() if line.startswith("{")]
        if out.returncode or not lines:
            tail = (out.stderr.strip().splitlines() or ["(no output)"])[-1]
            print(f"| {what} | failed (exit {out.returncode}): {tail} | | | | |")
            continue
        r = json.loads(lines[-1])
        status = (f"trace {r['trace_s']:.1f} s, build {r['build_s']:.1f} s"
                  + (" (cached)" if r["cached"] else "")) if what == "reference" else (
            r["status"] + (f": {r['error']}" if r["error"] else ""))
        time_ms = "" if r.get("time_ms") is None else f"{r['time_ms']:.0f}"
        print(f"| {what} | {r['peak_gib']:.2f} | {r['cpu_s']:.1f} | {r['wall_s']:.1f} "
              f"| {time_ms} | {status} |", flush=True)


if __name__ == "__main__":
    main()
