"""What alpha-tested casters cost sm and rt (issue 48: at most 1.5x and 2x): the ``cards``
family (leaf cards cut out by its leaf texture) against the same triangles opaque, timed in one
run.

    .venv/bin/python benchmarks/alpha_cost.py [--scene cards@1e5] [--size 512]
        [--runs 'sm;rt;rt:{"backend": "embree"}'] [--frames 5]

The opaque twin is reference_alpha.opaque_twin's: the same BuiltScene with every cut-out taken
away. Each run is prepared on both scenes and their frames (cost: dynamic, update and render,
one warm-up) alternate round by round, so load hits both alike; printed: each run's median
time_ms and passes with and without the cut-outs, their ratio, and the load average. Timings on
llvmpipe rank CPU cost, not GPU time.
"""

from __future__ import annotations

import argparse
import json
import os
import statistics

from reference_alpha import opaque_twin


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default="cards@1e5")
    parser.add_argument("--size", type=int, default=512)
    parser.add_argument("--runs", default="sm;rt")
    parser.add_argument("--frames", type=int, default=5)
    args = parser.parse_args()

    from harness.gl.context import get_context
    from harness.scene import load_scene
    from harness.technique import Frame, registry, reset_gl_state
    from OpenGL import GL

    get_context()
    cut = load_scene(args.scene).with_resolution(args.size, args.size)
    opaque = opaque_twin(cut)
    print(f"{args.scene} at {args.size}^2: {len(cut.triangles):,} triangles, "
          f"{int((cut.face_mask >= 0).sum()):,} alpha-tested")
    frames = {"opaque": Frame(opaque), "alpha": Frame(cut)}
    runs = []
    for text in args.runs.split(";"):
        name, _, params = text.partition(":")
        cls = registry.get(name)
        for kind, frame in frames.items():
            technique = cls(cls.Params(**json.loads(params or "{}")))
            technique.prepare(frame)
            reset_gl_state()
            runs.append((text, kind, frame, technique, frame.new_meter()))
    for i in range(1 + args.frames):  # one warm-up
        for text, kind, frame, technique, meter in runs[i % len(runs):] + runs[:i % len(runs)]:
            with frame.metered(meter):
                meter.new_frame(i > 0)
                technique.update(frame)
                technique.render(frame)
                GL.glFinish()
            reset_gl_state()
    times = {}
    for text, kind, frame, technique, meter in runs:
        times[text, kind] = statistics.median(meter.frame_totals_ms)
        passes = ", ".join(f"{p.name} {p.ms:.1f}" for p in meter.passes())
        print(f"  {text:28s} {kind:6s} {times[text, kind]:9.1f} ms  ({passes})")
        technique.release()
        meter.release()
    for text in dict.fromkeys(t for t, _ in times):
        print(f"  {text}: alpha / opaque = {times[text, 'alpha'] / times[text, 'opaque']:.2f}")
    print(f"  load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} CPUs")
    for frame in frames.values():
        frame.release()


if __name__ == "__main__":
    main()
