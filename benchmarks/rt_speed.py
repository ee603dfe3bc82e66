"""rt's costs: its bottom-level builds, and its frame next to other techniques' on the same scene.

    .venv/bin/python benchmarks/rt_speed.py build [--scene tessellation@1e6] [--leaf-size 4]
    .venv/bin/python benchmarks/rt_speed.py frames [--scenes architecture@1e5,foliage@1e5]
        [--runs 'rt;rt:{"backend": "embree"};sv;sm'] [--size 512] [--frames 3]

``build``: each builder's bottom levels of the scene (every part, as ``prepare`` builds them),
wall and CPU seconds of this process (each the best of ``--rounds``: CPU time is the steadier
figure on shared cores) and bytes (nodes and triangles as uploaded). ``frames``:
each run through ``harness.run.evaluate`` (cost: dynamic, one warm-up frame), its median
``time_ms``, the timed passes, ``prepare_ms`` and the machine's load; a run is
``technique[:json params]``. A scene is a name of scenes.yaml, a family one at any size as an
experiment's ``triangles`` names it (``architecture@1e6``). Timings on llvmpipe rank CPU cost.
"""

from __future__ import annotations

import argparse
import json
import os
import time


def load(name: str, size: int | None = None):
    from harness import config
    from harness.scene import build_scene

    base, _, triangles = name.partition("@")
    declared = config.load_scenes("scenes.yaml")[base]
    if triangles:
        declared = declared.at_triangles(int(float(triangles)))
    scene = build_scene(name, declared, "scenes.yaml")
    return scene.with_resolution(size, size) if size else scene


def build(args) -> None:
    from techniques.rt import bvh, levels

    scene = load(args.scene)
    parts = [p for p in scene.parts if len(p.faces)]
    triangles = sum(len(p.faces) for p in parts)
    print(f"{args.scene}: {triangles:,} triangles in {len(parts)} parts, leaf_size "
          f"{args.leaf_size}; bound checked against budget_mib: "
          f"{levels.bound_bytes(triangles) / 2**20:.1f} MiB")
    for method in bvh.BUILDERS:
        best, best_cpu, nodes, records = float("inf"), float("inf"), 0, 0
        for _ in range(args.rounds):
            start, cpu = time.perf_counter(), time.process_time()
            trees = bvh.build_all([bvh.triangle_boxes(p.vertices[p.faces]) for p in parts], method,
                                  args.leaf_size)
            best = min(best, time.perf_counter() - start)
            best_cpu = min(best_cpu, time.process_time() - cpu)
            nodes = sum(t.nodes for t in trees)
            records = sum(t.record_count for t in trees)
        nbytes = records * bvh.RECORD_BYTES + triangles * levels.TRIANGLE_BYTES
        depth = max(t.depth for t in trees)
        print(f"  {method}: {best:.3f} s, CPU {best_cpu:.3f} s (best of {args.rounds}), {nodes:,} "
              f"nodes, depth {depth}, {nbytes / 2**20:.1f} MiB, load average "
              f"{os.getloadavg()[0]:.2f}")


def frames(args) -> None:
    from harness.run import evaluate

    for name in args.scenes.split(","):
        scene = load(name, args.size)
        for run in args.runs.split(";"):
            technique, _, params = run.partition(":")
            row = evaluate(scene, technique, json.loads(params) if params else {},
                           frames=args.frames, warmup=1, samples=1).row
            passes = ", ".join(f"{p['name']} {p['ms']:.1f}" for p in row.get("passes") or [])
            print(f"{name} {args.size}^2 {technique} {params or '{}'}: {row['status']} "
                  f"time_ms {row['time_ms'] or float('nan'):.1f} ({passes}) prepare_ms "
                  f"{row.get('prepare_ms')} cpu_contention {row.get('cpu_contention')} "
                  f"{row.get('error') or ''}", flush=True)


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    sub = p.add_subparsers(dest="what", required=True)
    b = sub.add_parser("build")
    b.add_argument("--scene", default="tessellation@1e6")
    b.add_argument("--leaf-size", type=int, default=4)
    b.add_argument("--rounds", type=int, default=3)
    f = sub.add_parser("frames")
    f.add_argument("--scenes", default="architecture@1e5,foliage@1e5")
    f.add_argument("--runs", default='rt;rt:{"backend": "embree"};sv;sm')
    f.add_argument("--size", type=int, default=512)
    f.add_argument("--frames", type=int, default=3)
    args = p.parse_args()
    if args.what == "frames":
        from harness.gl.context import get_context

        get_context()
    (build if args.what == "build" else frames)(args)


if __name__ == "__main__":
    main()
