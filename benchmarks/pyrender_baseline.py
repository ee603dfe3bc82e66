"""Per-frame cost of sm and pcf next to pyrender's own shadow-mapped render, in one process.

    .venv/bin/python benchmarks/pyrender_baseline.py [--scene castle] [--size 512] [--res 2048]

pyrender's OffscreenRenderer with SHADOWS_DIRECTIONAL draws a 2048^2 directional shadow map,
the scene, and reads the colour back; our frame is the G-buffer pass plus the technique's
passes (read-back excluded). Both are medians over the same number of frames.
"""

from __future__ import annotations

import argparse
import statistics
import time

import numpy as np


def pyrender_frame_ms(scene, size: int, frames: int, warmup: int) -> float:
    import pyrender
    import trimesh

    from harness.transforms import look_at

    pr_scene = pyrender.Scene(ambient_light=[0.1, 0.1, 0.1])
    # one mesh of all triangles: one draw call, as our G-buffer pass makes
    mesh = trimesh.Trimesh(scene.triangles.reshape(-1, 3),
                           np.arange(3 * len(scene.triangles)).reshape(-1, 3), process=False)
    pr_scene.add(pyrender.Mesh.from_trimesh(mesh, smooth=False))
    cam = scene.config.camera
    camera = pyrender.PerspectiveCamera(yfov=np.radians(cam.yfov), znear=cam.near,
                                        zfar=cam.far, aspectRatio=size / size)
    pr_scene.add(camera, pose=np.linalg.inv(look_at(cam.position, cam.target, cam.up)))
    light_pose = np.linalg.inv(look_at(np.zeros(3), scene.light.direction, [0.0, 0.0, 1.0]))
    pr_scene.add(pyrender.DirectionalLight(intensity=3.0), pose=light_pose)
    renderer = pyrender.OffscreenRenderer(size, size)
    flags = pyrender.RenderFlags.SHADOWS_DIRECTIONAL
    times = []
    for i in range(warmup + frames):
        start = time.perf_counter()
        renderer.render(pr_scene, flags=flags)
        if i >= warmup:
            times.append((time.perf_counter() - start) * 1e3)
    renderer.delete()
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="castle")
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--res", type=int, default=2048)
    ap.add_argument("--frames", type=int, default=20)
    ap.add_argument("--warmup", type=int, default=3)
    args = ap.parse_args()

    from harness.gl.context import get_context
    from harness.runner import evaluate
    from harness.scene import load_scene

    context = get_context()
    scene = load_scene(args.scene).with_resolution(args.size, args.size)
    rows = {}
    for label, technique, params in (("sm", "sm", {"res": args.res}),
                                     ("pcf k=16", "pcf", {"res": args.res, "k": 16})):
        rows[label] = evaluate(scene, technique, params, frames=args.frames,
                               warmup=args.warmup).row
    from harness.technique import Frame

    frame = Frame(scene)
    scene_ms, _ = frame.measure_scene_pass(args.frames, args.warmup)
    frame.release()
    baseline = pyrender_frame_ms(scene, args.size, args.frames, args.warmup)
    get_context()  # pyrender made its own context current
    print(f"{context.renderer}; {args.scene} {args.size}x{args.size}, map {args.res}^2, "
          f"median of {args.frames} frames")
    print(f"{'':22s}{'ms/frame':>10s}{'vs pyrender':>13s}")
    print(f"{'pyrender SHADOWS_DIR.':22s}{baseline:10.2f}{1.0:13.2f}")
    print(f"{'G-buffer (no shadow)':22s}{scene_ms:10.2f}{scene_ms / baseline:13.2f}")
    for label, row in rows.items():
        total = row["time_ms"] + scene_ms
        print(f"{label + ' (+G-buffer)':22s}{total:10.2f}{total / baseline:13.2f}")


if __name__ == "__main__":
    main()
