"""The reference's cost next to Mitsuba's own ``direct`` integrator, in one process.

    .venv/bin/python benchmarks/reference_speed.py [--scene castle] [--sizes 512 1024]
                                                   [--samples 16] [--rounds 5]

``--scene`` takes a family scene at any size too, as an experiment's ``triangles`` names it
(``architecture@1e6``, ``instancing@1e6``): issue 23 asks for at most 1.0x at 10^6 triangles.

Both sides start from the same BuiltScene and pay for building and loading the Mitsuba scene:
``direct`` is ``mi.load_dict`` of the reference's scene dict plus ``mi.render`` (one shadow ray
and a BSDF evaluation per sample) and the read-back of the image; the reference is
``compute_reference(..., use_cache=False)``. Rounds run the two in turn, each round in the
other order (whichever side runs second builds its scene after the other's large trace, which
made the reference's whole 1.16x at 1024^2 in one fixed order and 0.94x alternated), after one
warm-up each (the first call compiles the Dr.Jit kernels; later processes load them from
Dr.Jit's cache).
The ratio is reference / direct per round: median, min and max over the rounds, on the wall
clock and on this process's CPU time (steadier when other processes share the machine).
``whole`` rows time all of it; ``trace`` rows only the rays, on one Mitsuba scene loaded once
(``mi.render`` against the reference's ``trace_visibility``), since the scene build is the same
work on both sides and, at 10^6 triangles, most of the whole.
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np


def timed(work) -> tuple[float, float]:
    """(wall seconds, CPU seconds of this process) of ``work()``."""
    wall, cpu = time.perf_counter(), time.process_time()
    work()
    return time.perf_counter() - wall, time.process_time() - cpu


def timed_pair(one, other, first: int):
    """(timed(one), timed(other)), run in that order when ``first`` is 0, else ``other``
    first: the rounds alternate which side follows the other's work (Mitsuba's scene build
    after the other side's large trace is slower)."""
    if first:
        b = timed(other)
        return timed(one), b
    a = timed(one)
    return a, timed(other)


def direct(scene, samples: int) -> None:
    import mitsuba as mi

    from harness.truth.reference import mitsuba_scene_dict

    mscene = mi.load_dict(mitsuba_scene_dict(scene, mi, samples))
    np.asarray(mi.render(mscene, spp=samples))


def reference(scene, samples: int) -> None:
    from harness.truth.reference import compute_reference

    compute_reference(scene, samples=samples, use_cache=False)


def traces(scene, samples: int):
    """(direct's rays, the reference's rays) on one loaded Mitsuba scene."""
    import mitsuba as mi

    from harness.truth.reference import mitsuba_scene_dict, trace_visibility

    mscene = mi.load_dict(mitsuba_scene_dict(scene, mi, samples))
    return (lambda: np.asarray(mi.render(mscene, spp=samples)),
            lambda: trace_visibility(mi, mscene, scene, samples, 0))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default="castle", help="a scene, or family@size (instancing@1e6)")
    ap.add_argument("--sizes", type=int, nargs="+", default=[512, 1024])
    ap.add_argument("--samples", type=int, default=16)
    ap.add_argument("--rounds", type=int, default=5)
    args = ap.parse_args()

    from harness.truth.reference import choose_variant, mitsuba_module
    from harness.scene import load_scene

    variant = choose_variant()
    mitsuba_module(variant)
    base = load_scene(args.scene)
    print(f"{variant}; {args.scene}, {args.samples} samples/pixel, {args.rounds} rounds; "
          f"load average {os.getloadavg()[0]:.2f}")
    print(f"{'size':>10s}{'what':>7s}{'clock':>6s}{'direct s':>10s}{'ref s':>10s}{'ref/direct':>12s}"
          f"{'min':>7s}{'max':>7s}")
    for size in args.sizes:
        scene = base.with_resolution(size, size)
        pairs = {"whole": (lambda: direct(scene, args.samples),
                           lambda: reference(scene, args.samples)),
                 "trace": traces(scene, args.samples)}
        for what, (one, other) in pairs.items():
            one(), other()  # warm-up: compiles (or loads) the kernels
            rounds = [timed_pair(one, other, first=k % 2) for k in range(args.rounds)]
            for clock, label in enumerate(("wall", "cpu")):
                d = [pair[0][clock] for pair in rounds]
                r = [pair[1][clock] for pair in rounds]
                ratios = [b / a for a, b in zip(d, r)]
                print(f"{f'{size}x{size}':>10s}{what:>7s}{label:>6s}{statistics.median(d):10.3f}"
                      f"{statistics.median(r):10.3f}{statistics.median(ratios):12.2f}"
                      f"{min(ratios):7.2f}{max(ratios):7.2f}")

if __name__ == "__main__":
    main()
