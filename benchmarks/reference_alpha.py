"""The reference with cut-outs next to the same scene opaque, in one process (issue 48: at most
2x).

    .venv/bin/python benchmarks/reference_alpha.py [--scenes cards@1e5 alpha_fence]
                                                   [--size 512] [--samples 16] [--rounds 3]

The opaque twin is the same BuiltScene with every part's cut-out taken away: the same
triangles, so Mitsuba's build is the same work, and its shadow rays go through ``ray_test``
(the opaque path) instead of the cut-out loop of ``ray_intersect`` and the sampling rule.
Both are ``compute_reference(..., use_cache=False)``, the Mitsuba build included; rounds
alternate which side runs first, after one warm-up each (Dr.Jit compiles its kernels then).
The ratio is cut-out / opaque per round: median, min and max, on the wall clock and on this
process's CPU time.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics

from reference_speed import timed_pair


def opaque_twin(scene):
    """``scene`` with no cut-out: the same triangles, light and camera."""
    from harness.scene import BuiltScene

    parts = [dataclasses.replace(p, alpha=None, texcoords=None) for p in scene.parts]
    return BuiltScene(scene.name, scene.config, parts, scene.light, scene.key, scene.source)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", nargs="+", default=["cards@1e5", "alpha_fence"])
    ap.add_argument("--size", type=int, default=512)
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=3)
    args = ap.parse_args()

    from harness.scene import load_scene
    from harness.truth.reference import compute_reference

    print("scene | triangles | bounded rays | opaque s | cut-out s | ratio wall (min-max) | "
          "ratio CPU (min-max)")
    for name in args.scenes:
        scene = load_scene(name).with_resolution(args.size, args.size)
        opaque = opaque_twin(scene)
        runs = {}

        def trace(which, s=scene, o=opaque):
            ref = compute_reference(s if which == "alpha" else o, samples=args.samples,
                                    use_cache=False)
            runs.setdefault(which, []).append(ref.bounded_rays)

        trace("alpha"), trace("opaque")  # warm-up: kernels compiled
        walls, cpus, seconds = [], [], []
        for r in range(args.rounds):
            (aw, ac), (ow, oc) = timed_pair(lambda: trace("alpha"), lambda: trace("opaque"),
                                            r % 2)
            walls.append(aw / ow)
            cpus.append(ac / oc)
            seconds.append((ow, aw))
        opaque_s = statistics.median(o for o, _ in seconds)
        alpha_s = statistics.median(a for _, a in seconds)
        print(f"{name} | {len(scene.triangles):,} | {runs['alpha'][-1]} | "
              f"{opaque_s:.2f} | {alpha_s:.2f} | {statistics.median(walls):.2f} "
              f"({min(walls):.2f}-{max(walls):.2f}) | {statistics.median(cpus):.2f} "
              f"({min(cpus):.2f}-{max(cpus):.2f})")


if __name__ == "__main__":
    main()
