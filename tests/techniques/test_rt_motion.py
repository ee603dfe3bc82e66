"""rt follows moving objects through its top level: a moved caster's frame equals a still run
with the caster already there, bit for bit; the top level is rebuilt inside the timed ``tlas``
pass; the bottom levels are built once, in ``prepare``."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from harness import config, registry
from harness.scene import build_scene
from harness.technique import Frame, reset_gl_state
from techniques.rt import levels

STILL = {"resolution": [96, 72],
         "camera": {"position": [0, -6, 4], "target": [0, 0, 0], "up": [0, 0, 1]},
         "light": {"type": "spot", "position": [-3, -4, 5], "target": [0, 0, 0], "fov": 90},
         "objects": [{"shape": "plane", "size": [10, 10]},
                     {"shape": "box", "name": "caster", "size": [1, 2, 0.5],
                      "translate": [1, 0, 1.5]},
                     {"shape": "sphere", "radius": 0.5, "translate": [-1.5, 1, 0.8]}]}
# the caster spins a quarter turn and orbits 60 degrees about the vertical through the origin
MOVING = {**STILL, "motion": {"frames": 3, "objects": [
    {"object": "caster", "spin": 90, "orbit": 60, "centre": [0, 0, 0]}]}}


def render(technique, frame) -> np.ndarray:
    frame.meter.new_frame(True)
    try:
        technique.update(frame)
        return technique.render(frame).visibility
    finally:
        reset_gl_state()


def test_moved_caster_equals_a_still_run_and_only_the_top_level_is_rebuilt(gl_context,
                                                                            monkeypatch):
    """Frame 2 of MOVING (prepared at frame 0, updated at each frame) gives bit for bit the V
    of a fresh run on the still scene of frame 2, and differs from frame 0's. After prepare
    the only builds are top-level ones, each inside the timed ``tlas`` pass, one per frame.
    Catches the top level never rebuilt (update a no-op after the first: frame 2 shows frame
    0's shadow), the rebuild moved out of the timed pass, and bottom levels rebuilt each
    frame (the builder called with ``sah`` after prepare)."""
    cls = registry.get("rt")
    params = cls.Params(build="sah")
    moving = build_scene("moving", config.Scene(**MOVING))
    frame, still = Frame(moving), Frame(moving.at_frame(2))
    moved, fresh = cls(params), cls(params)
    builds, active = [], []
    real_build, real_build_all, real_measure = levels.bvh.build, levels.bvh.build_all, frame.measure

    def spy_build(lo, hi, method="lbvh", leaf_size=4):
        builds.append((method, leaf_size, tuple(active)))
        return real_build(lo, hi, method, leaf_size)

    def spy_build_all(boxes, method="lbvh", leaf_size=4):
        builds.append((method, leaf_size, tuple(active), len(boxes)))
        return real_build_all(boxes, method, leaf_size)

    @contextmanager
    def spy_measure(name):
        active.append(name)
        try:
            with real_measure(name):
                yield
        finally:
            active.pop()

    try:
        monkeypatch.setattr(levels.bvh, "build", spy_build)
        monkeypatch.setattr(levels.bvh, "build_all", spy_build_all)
        monkeypatch.setattr(frame, "measure", spy_measure)
        moved.prepare(frame)
        assert builds == [("sah", 4, (), 3)]  # the three parts' bottom levels, one forest
        builds.clear()
        first = render(moved, frame)
        for t in (1, 2):
            frame.move_to(t)
            followed = render(moved, frame)
        assert builds == [("lbvh", 1, ("tlas",))] * 3  # frames 0, 1, 2: the top level alone
        assert [p.name for p in frame.meter.passes()] == ["tlas", "trace", "visibility"]
        fresh.prepare(still)
        expected = render(fresh, still)
        np.testing.assert_array_equal(followed, expected)
        assert np.count_nonzero(followed != first) > 20
    finally:
        for resource in (moved, fresh, frame, still):
            resource.release()
        reset_gl_state()
