"""The CPU time each technique spends per frame outside its timed passes under cost: dynamic.

    .venv/bin/python benchmarks/untimed_cpu.py [--scenes box_plane,castle] [--size 256]
                                               [--frames 15] [--warmup 2]

Each frame is what the harness runs under ``cost: dynamic``: the technique's ``update`` and
``render``. The process CPU time (time.process_time, llvmpipe's threads included) of the whole
frame, minus the CPU time inside its timed passes (``frame.measure`` blocks, counted by
wrapping PassMeter.measure), is the work no pass was charged for. Part of it is the harness's:
``render`` returns V read back from the visibility target, timed alone here and shown apart
(``of it V read-back``); the rest is the technique's own untimed work, which should be about 0:
only diagnostics stay outside (the warps' aliasing map and coverage, silhouette's and sv's
counting repeats). Medians over the measured frames, in ms.
"""

from __future__ import annotations

import argparse
import statistics
import time
from contextlib import contextmanager


def main() -> None:
    p = argparse.ArgumentParser()
    p.add_argument("--scenes", default="box_plane,castle")
    p.add_argument("--size", type=int, default=256)
    p.add_argument("--frames", type=int, default=15)
    p.add_argument("--warmup", type=int, default=2)
    args = p.parse_args()

    from harness.technique import registry
    from harness.gl import measure
    from harness.gl.context import get_context
    from harness.scene import load_scene
    from harness.technique import Frame, NotApplicable, reset_gl_state

    get_context()
    inside = [0.0]
    original = measure.PassMeter.measure

    @contextmanager
    def counted(self, name):
        start = time.process_time()
        try:
            with original(self, name):
                yield
        finally:
            inside[0] += time.process_time() - start

    measure.PassMeter.measure = counted
    print(f"{'scene':14s} {'technique':11s} {'frame CPU':>10s} {'in passes':>10s} "
          f"{'outside':>9s} {'of it V read-back':>18s} {'technique untimed':>18s}")
    for scene_name in args.scenes.split(","):
        scene = load_scene(scene_name).with_resolution(args.size, args.size)
        frame = Frame(scene)
        readback = []
        for _ in range(args.frames):
            start = time.process_time()
            frame.visibility_target.read()
            readback.append(time.process_time() - start)
        v_read_ms = 1e3 * statistics.median(readback)
        for name, cls in sorted(registry.techniques().items()):
            technique = cls(cls.Params())
            try:
                technique.prepare(frame)
            except NotApplicable:
                continue
            totals, passes = [], []
            try:
                for i in range(args.warmup + args.frames):
                    frame.meter.new_frame(False)
                    inside[0] = 0.0
                    start = time.process_time()
                    technique.update(frame)
                    technique.render(frame)
                    total = time.process_time() - start
                    reset_gl_state()
                    if i >= args.warmup:
                        totals.append(total)
                        passes.append(inside[0])
            finally:
                technique.release()
                reset_gl_state()
            outside = [t - q for t, q in zip(totals, passes)]
            ms = [1e3 * statistics.median(x) for x in (totals, passes, outside)]
            print(f"{scene_name:14s} {name:11s} {ms[0]:10.2f} {ms[1]:10.2f} {ms[2]:9.2f} "
                  f"{v_read_ms:18.2f} {ms[2] - v_read_ms:18.2f}", flush=True)
        frame.release()


if __name__ == "__main__":
    main()
