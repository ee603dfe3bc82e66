"""Per-frame cost of sm and pcf next to pyrender's own shadow-mapped render, in one process.

    .venv/bin/python benchmarks/pyrender_baseline.py [--scene castle] [--size 512] [--res 2048]
                                                     [--frames 20] [--warmup 3]

pyrender's OffscreenRenderer with SHADOWS_DIRECTIONAL draws a 2048^2 directional shadow map,
the scene, and reads the colour back; our frame is the G-buffer pass plus the technique's
passes, each timed as the harness times it (PassMeter: glFinish brackets, read-back of V
excluded). Frames are interleaved, one of each per round, so that load from other processes
falls on all of them alike; the ratios are per round: their median with a 95% interval of the
median (order statistics, harness.machine.timing.median_interval), min and max. Beside the wall clock,
the CPU time of this process per frame (llvmpipe's threads included; our read-back of V
included), which other processes disturb less.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


class PyrenderFrame:
    """pyrender's renderer on the scene: one mesh of all triangles, the matched camera, the
    directional light with its shadow map."""

    def __init__(self, scene, size: int):
        import pyrender
        import trimesh

        from harness.scene.transforms import look_at

        self.scene = pyrender.Scene(ambient_light=[0.1, 0.1, 0.1])
        # one mesh of all triangles: one draw call, as our G-buffer pass makes
        mesh = trimesh.Trimesh(scene.triangles.reshape(-1, 3),
                               np.arange(3 * len(scene.triangles)).reshape(-1, 3), process=False)
        self.scene.add(pyrender.Mesh.from_trimesh(mesh, smooth=False))
        cam = scene.config.camera
        camera = pyrender.PerspectiveCamera(yfov=np.radians(cam.yfov), znear=cam.near,
                                            zfar=cam.far, aspectRatio=1.0)
        self.scene.add(camera, pose=np.linalg.inv(look_at(cam.position, cam.target, cam.up)))
        light_pose = np.linalg.inv(look_at(np.zeros(3), scene.light.direction, [0.0, 0.0, 1.0]))
        self.scene.add(pyrender.DirectionalLight(intensity=3.0), pose=light_pose)
        self.renderer = pyrender.OffscreenRenderer(size, size)
        self.flags = pyrender.RenderFlags.SHADOWS_DIRECTIONAL

    def __call__(self) -> tuple[float, float]:
        """(wall ms, CPU ms) of one frame."""
        wall, cpu = time.perf_counter(), time.process_time()
        self.renderer.render(self.scene, flags=self.flags)
        return (time.perf_counter() - wall) * 1e3, (time.process_time() - cpu) * 1e3

    def release(self) -> None:
        self.renderer.delete()


class TechniqueFrame:
    """One technique on the harness's Frame: the G-buffer pass, then the technique's passes."""

    def __init__(self, frame, technique: str, params: dict):
        from harness.technique import registry
        from harness.gl.measure import PassMeter

        cls = registry.get(technique)
        self.frame, self.technique = frame, cls(cls.Params(**params))
        self.technique.prepare(frame)
        self.technique.update(frame)
        self.scene_meter, self.meter = PassMeter(frame.timer), PassMeter(frame.timer)

    def __call__(self) -> tuple[float, float]:
        """(wall ms of the measured passes, CPU ms of the whole frame)."""
        from harness.technique import reset_gl_state

        frame, cpu = self.frame, time.process_time()
        self.scene_meter.new_frame(True)
        with self.scene_meter.measure("scene"):
            frame.gbuffer.render(frame.geometry, frame.camera.view_proj)
        own_meter, frame.meter = frame.meter, self.meter
        self.meter.new_frame(True)
        self.technique.render(frame)
        cpu = time.process_time() - cpu
        frame.meter = own_meter
        reset_gl_state()
        return (self.scene_meter.frame_totals_ms[-1] + self.meter.frame_totals_ms[-1],
                cpu * 1e3)

    def passes(self) -> list[tuple[str, float]]:
        """Median ms per pass, the G-buffer first."""
        return [(p.name, p.ms) for p in self.scene_meter.passes() + self.meter.passes()]

    def release(self) -> None:
        self.technique.release()
        self.scene_meter.release()
        self.meter.release()


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="castle")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--res", type=int, default=2048)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=3)
    args = ap.parse_args()

    import os

    from harness.gl.context import get_context
    from harness.scene import load_scene
    from harness.technique import Frame
    from harness.machine.timing import median_interval

    context = get_context()
    scene = load_scene(args.scene).with_resolution(args.size, args.size)
    frame = Frame(scene)
    ours = {"sm": TechniqueFrame(frame, "sm", {"res": args.res}),
            "pcf k=16": TechniqueFrame(frame, "pcf", {"res": args.res, "k": 16})}
    baseline = PyrenderFrame(scene, args.size)
    times: dict[str, list[tuple[float, float]]] = {"pyrender": [], **{k: [] for k in ours}}
    load = os.getloadavg()[0]
    for i in range(args.warmup + args.frames):
        row = {"pyrender": baseline()}
        get_context()  # pyrender made its own context current
        row.update((label, run()) for label, run in ours.items())
        if i >= args.warmup:
            for label, t in row.items():
                times[label].append(t)
    baseline.release()
    get_context()
    print(f"{context.renderer}; {args.scene} {args.size}x{args.size}, map {args.res}^2, "
          f"{args.frames} interleaved frames; load average {load:.2f} -> {os.getloadavg()[0]:.2f}")
    print(f"{'':22s}{'wall ms':>9s}{'vs pyrender [95% of median]':>30s}{'min':>6s}{'max':>6s}"
          f"{'cpu ms':>9s}{'vs pyrender [95% of median]':>30s}{'min':>6s}{'max':>6s}")
    for label, t in times.items():
        cells = ""
        for clock in (0, 1):
            ratios = [a[clock] / b[clock] for a, b in zip(t, times["pyrender"])]
            ratio, low, high = median_interval(ratios)
            cells += (f"{statistics.median(x[clock] for x in t):9.2f}"
                      f"{ratio:14.3f} [{low:.3f}, {high:.3f}]"
                      f"{min(ratios):6.2f}{max(ratios):6.2f}")
        name = label if label == "pyrender" else f"{label} (+G-buffer)"
        print(f"{name:22s}{cells}")
    for label, run in ours.items():
        print(f"{label} passes (median ms): "
              + ", ".join(f"{name} {ms:.2f}" for name, ms in run.passes()))
        run.release()
    frame.release()


if __name__ == "__main__":
    main()
