"""Each pass's time over the G-buffer pass of the same scene (not a CI test).

    .venv/bin/python benchmarks/pass_ratios.py [--scene instancing@1e6] [--size 512]
                                               [--techniques sm] [--frames 5] [--warmup 1]

Issue 23: at 10^6 triangles, sm's map pass draws the same triangles as the G-buffer pass
(``scene_ms``), so it should cost at most 1.1x. Each technique runs as
``harness.run.evaluate`` runs it (median of ``frames`` frames after ``warmup``); the G-buffer
pass is timed over as many frames. Prints a Markdown table: pass, its median ms, fragments,
vertex invocations and its ratio to ``scene_ms``.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from harness.run import evaluate
from harness.scene import load_scene

SCENE_FILE = Path(__file__).resolve().parent.parent / "scenes.yaml"


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="instancing@1e6")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--techniques", default="sm")
    ap.add_argument("--frames", type=int, default=5)
    ap.add_argument("--warmup", type=int, default=1)
    ap.add_argument("--samples", type=int, default=16)
    args = ap.parse_args()

    scene = load_scene(args.scene, SCENE_FILE).with_resolution(args.size, args.size)
    print(f"{args.scene} ({sum(len(p.faces) for p in scene.parts):,} triangles) at "
          f"{args.size}x{args.size}; medians of {args.frames} frames after {args.warmup}")
    print("| technique | pass | ms | fragments | vertex invocations | / scene_ms |")
    print("|---|---|---|---|---|---|")
    for technique in args.techniques.split(","):
        row = evaluate(scene, technique, frames=args.frames, warmup=args.warmup,
                       samples=args.samples).row
        scene_ms = row["scene_ms"]
        print(f"| {technique} | scene (G-buffer) | {scene_ms:.1f} | {row['frags_scene']:,.0f} "
              f"| | 1.00 |")
        passes = row["passes"]
        for p in json.loads(passes) if isinstance(passes, str) else passes:
            print(f"| {technique} | {p['name']} | {p['ms']:.1f} | {p.get('fragments', 0):,.0f} "
                  f"| {p.get('vertex_invocations', 0):,.0f} | {p['ms'] / scene_ms:.2f} |")
        print(f"| {technique} | (frame total, time_ms) | {row['time_ms']:.1f} | | "
              f"| {row['time_ms'] / scene_ms:.2f} |", flush=True)


if __name__ == "__main__":
    main()
