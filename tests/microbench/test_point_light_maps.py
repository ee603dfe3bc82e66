"""Point lights (issue 24): a frame of each technique that treats them on hard_point_ring (a
point light inside a ring of casters) at 512x512, and the cost of the cube map's six faces in
units of one map pass: sm's spot-light map at the same res on the same ring, the spot at the
same point aimed down with a 150-degree cone.

Each round of the faces benchmark renders the spot's map just before the six faces (untimed
``setup``), so both see the same machine load; the ratio is the median of the rounds' ratios,
in ``extra_info`` (``faces_per_map_pass``) and printed, with the fragments each drew.
``pytest tests/microbench/test_point_light_maps.py -s`` prints them; llvmpipe times rank CPU
cost only.
"""

from __future__ import annotations

import time

import numpy as np
import pytest
from helpers import ROOT, one_frame_of

ROUNDS = 10
IMAGE_PX = 512
MAP_RES = 1024
HARD_CASES = ROOT / "experiments" / "hard_cases" / "scenes.yaml"
FRAME_TECHNIQUES = ("sm", "pcf", "sv")


def ring_scene(light=None):
    from harness import config
    from harness.scene import build_scene

    ring = config.load_scenes(HARD_CASES)["hard_point_ring"]
    if light is not None:
        ring = ring.model_copy(update={"light": light})
    return build_scene("hard_point_ring", ring, HARD_CASES).with_resolution(IMAGE_PX, IMAGE_PX)


@pytest.mark.parametrize("name", FRAME_TECHNIQUES)
def test_ring_frame(benchmark, gl_context, name):
    from harness.technique import registry
    from harness.technique import Frame, NotApplicable, reset_gl_state

    cls = registry.get(name)
    frame = Frame(ring_scene())
    try:
        cls.check_light(frame.scene.light)
    except NotApplicable as e:
        frame.release()
        pytest.skip(str(e))
    technique = cls(cls.Params())
    try:
        technique.prepare(frame)
        technique.update(frame)

        output = benchmark.pedantic(one_frame_of(technique, frame), rounds=ROUNDS,
                                    warmup_rounds=2)
    finally:
        technique.release()
        frame.release()
        reset_gl_state()
    assert np.isfinite(output.visibility).all() and output.visibility.min() == 0
    benchmark.extra_info.update(technique=name, mem_bytes=output.mem_bytes)


def test_six_faces_in_map_passes(benchmark, gl_context):
    from OpenGL import GL

    from harness import config
    from harness.gl.measure import PassMeter
    from harness.technique import Frame, reset_gl_state
    from techniques.common.light_maps import CubeDepthMap, LightDepthMap

    spot_light = config.SpotLight(type="spot", position=(0, 0, 1.2), target=(0, 0, 0), fov=150)
    point, spot = Frame(ring_scene()), Frame(ring_scene(spot_light))
    cube, single = CubeDepthMap(point, MAP_RES), LightDepthMap(spot, MAP_RES)
    spot_ms, faces_ms = [], []

    def one_map_pass():
        start = time.perf_counter()
        single.render(spot)
        GL.glFinish()
        spot_ms.append((time.perf_counter() - start) * 1000)

    def six_faces():
        start = time.perf_counter()
        point.meter.new_frame(measuring=False)
        cube.render(point)
        GL.glFinish()
        faces_ms.append((time.perf_counter() - start) * 1000)

    try:
        benchmark.pedantic(six_faces, rounds=ROUNDS, warmup_rounds=1, setup=one_map_pass)
        counted = PassMeter(point.timer, counters=False)
        with point.metered(counted):
            counted.new_frame(True)
            cube.render(point)
        face_fragments = sum(p.fragments for p in counted.passes())
        with spot.metered(counted):
            counted.new_frame(True)
            with spot.measure("shadow_map"):
                single.render(spot)
        map_fragments = counted.passes()[0].fragments
        counted.release()
    finally:
        cube.release()
        single.release()
        point.release()
        spot.release()
        reset_gl_state()
    rounds = min(len(faces_ms), len(spot_ms))  # one of each when benchmarks are disabled
    faces_ms, spot_ms = np.array(faces_ms[-rounds:]), np.array(spot_ms[-rounds:])
    ratio = float(np.median(faces_ms / spot_ms))
    assert face_fragments > map_fragments > 0
    benchmark.extra_info.update(res=MAP_RES, faces_ms=float(np.median(faces_ms)),
                                map_pass_ms=float(np.median(spot_ms)), faces_per_map_pass=ratio,
                                face_fragments=face_fragments, map_fragments=map_fragments)
    print(f"\nsix {MAP_RES}^2 faces {np.median(faces_ms):.1f} ms = {ratio:.2f} map passes "
          f"({np.median(spot_ms):.1f} ms); fragments {face_fragments} vs {map_fragments}")
