"""Microbenchmarks (pytest-benchmark): one frame of every registered technique at its defaults
at 512x512 on box_plane, and the Mitsuba reference at 256x256 with 16 samples per pixel.

``make microbench`` saves the timings as JSON under .benchmarks/; ``make microbench-compare``
compares a new run with the last saved one. A technique added through the entry point is
benchmarked with no change here.
"""

from __future__ import annotations

import numpy as np
import pytest

from harness.technique import registry
from helpers import one_frame_of

FRAME_ROUNDS = 10
REFERENCE_ROUNDS = 3


@pytest.fixture(scope="module")
def box_frame(gl_context, scene_at):
    from harness.technique import Frame

    frame = Frame(scene_at("box_plane", 512))
    yield frame
    frame.release()


@pytest.mark.parametrize("name", list(registry.techniques()))
def test_technique_frame_512(benchmark, box_frame, name):
    from harness.technique import NotApplicable, reset_gl_state

    cls = registry.get(name)
    technique = cls(cls.Params())
    box_frame.new_meter()
    try:
        technique.prepare(box_frame)
        technique.update(box_frame)

        output = benchmark.pedantic(one_frame_of(technique, box_frame), rounds=FRAME_ROUNDS,
                                    warmup_rounds=2)
    except NotApplicable as e:
        pytest.skip(f"{name} does not apply to box_plane: {e}")
    finally:
        technique.release()
        reset_gl_state()
    v = output.visibility
    assert v.shape == (512, 512) and np.isfinite(v).all()
    benchmark.extra_info.update(technique=name, params=technique.params.model_dump(mode="json"),
                                mem_bytes=output.mem_bytes, lit=float(v.mean()))


def test_reference_256_16spp(benchmark, scene_at):
    from harness.truth.reference import compute_reference

    scene = scene_at("box_plane", 256)
    ref = benchmark.pedantic(lambda: compute_reference(scene, samples=16, use_cache=False),
                             rounds=REFERENCE_ROUNDS, warmup_rounds=1)
    assert ref.visibility.shape == (256, 256) and not ref.cached
    benchmark.extra_info.update(variant=ref.variant, samples=16)
