"""rt follows moving objects through its top level: a moved caster's frame equals a still run
with the caster already there, bit for bit; the top level is rebuilt inside the timed ``tlas``
pass; the bottom levels are built once, in ``prepare``."""

from __future__ import annotations

from contextlib import contextmanager

import numpy as np

from harness import config
from harness.technique import registry
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


def away_from_the_origin(scene: dict, offset) -> dict:
    """``scene`` (STILL's keys, MOVING's motion) moved by ``offset``."""
    def at(point):
        return (np.asarray(point, float) + offset).tolist()

    moved = {**scene, "objects": [{**o, "translate": at(o.get("translate", [0, 0, 0]))}
                                  for o in scene["objects"]],
             "camera": {**scene["camera"], "position": at(scene["camera"]["position"]),
                        "target": at(scene["camera"]["target"])},
             "light": {**scene["light"], "position": at(scene["light"]["position"]),
                       "target": at(scene["light"]["target"])}}
    moved["motion"] = {**scene["motion"], "objects": [
        {**path, "centre": at(path["centre"])} for path in scene["motion"]["objects"]]}
    return moved


def render(technique, frame) -> np.ndarray:
    frame.meter.new_frame(True)
    try:
        technique.update(frame)
        return technique.render(frame).visibility
    finally:
        reset_gl_state()


def follow_then_still(params, frame, still, after_prepare=None, after_frames=None):
    """rt with ``params`` prepared on ``frame`` (frame 0 of a moving scene), then frames 0, 1
    and 2 rendered; then a fresh rt on ``still`` (that scene's frame 2 as a still scene).
    ``after_prepare()`` and ``after_frames()`` run between the steps. Returns frame 0's V,
    frame 2's V and the still run's V; both techniques and both frames are released."""
    cls = registry.get("rt")
    moved, fresh = cls(params), cls(params)
    try:
        moved.prepare(frame)
        if after_prepare:
            after_prepare()
        first = render(moved, frame)
        for t in (1, 2):
            frame.move_to(t)
            followed = render(moved, frame)
        if after_frames:
            after_frames()
        fresh.prepare(still)
        return first, followed, render(fresh, still)
    finally:
        for resource in (moved, fresh, frame, still):
            resource.release()
        reset_gl_state()


def test_moved_caster_equals_a_still_run_and_only_the_top_level_is_rebuilt(gl_context,
                                                                            monkeypatch):
    """Frame 2 of MOVING (prepared at frame 0, updated at each frame) gives bit for bit the V
    of a fresh run on the still scene of frame 2, and differs from frame 0's. After prepare
    the only builds are top-level ones, each inside the timed ``tlas`` pass, one per frame.
    Catches the top level never rebuilt (update a no-op after the first: frame 2 shows frame
    0's shadow), the rebuild moved out of the timed pass, and bottom levels rebuilt each
    frame (the builder called with ``sah`` after prepare)."""
    params = registry.get("rt").Params(build="sah")
    moving = build_scene("moving", config.Scene(**MOVING))
    frame, still = Frame(moving), Frame(moving.at_frame(2))
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

    def prepared():
        assert builds == [("sah", 4, (), 3)]  # the three parts' bottom levels, one forest
        builds.clear()

    def followed_to_frame_2():
        assert builds == [("lbvh", 1, ("tlas",))] * 3  # frames 0, 1, 2: the top level alone
        assert [p.name for p in frame.meter.passes()] == ["tlas", "trace", "visibility"]

    monkeypatch.setattr(levels.bvh, "build", spy_build)
    monkeypatch.setattr(levels.bvh, "build_all", spy_build_all)
    monkeypatch.setattr(frame, "measure", spy_measure)
    first, followed, expected = follow_then_still(params, frame, still, prepared,
                                                  followed_to_frame_2)
    np.testing.assert_array_equal(followed, expected)
    assert np.count_nonzero(followed != first) > 20


def test_the_embree_backend_moves_instances_and_builds_once(gl_context, monkeypatch):
    """``backend: embree`` on MOVING: the caster's parts are Mitsuba instances moved by their
    poses in the timed ``tlas`` pass, and Mitsuba's scene is loaded once (prepare); frame 2's
    V equals, bit for bit, a fresh run on the still scene of frame 2 (which differs from
    frame 0's). The scene is MOVING moved 40 units away from the origin, so that Mitsuba's
    copy is shifted back by (40, 20, 0). Catches poses never applied (frame 2 shows frame 0's
    shadow), a pose applied without Mitsuba's shift, and the scene loaded again per moved
    frame (the backend's first version: 3 loads). All three seen failing."""
    from harness.truth import reference

    params = registry.get("rt").Params(backend="embree")
    moving = build_scene("moving", config.Scene(**away_from_the_origin(MOVING, [40, 20, 0])))
    frame, still = Frame(moving), Frame(moving.at_frame(2))
    mi = reference.mitsuba_module(reference.choose_variant())
    loads, real_load = [], mi.load_dict
    monkeypatch.setattr(mi, "load_dict",
                        lambda d: loads.append(d["type"]) or real_load(d))

    def followed_to_frame_2():
        assert loads.count("scene") == 1
        assert [p.name for p in frame.meter.passes()] == [
            "tlas", "readback", "trace", "upload", "visibility"]

    first, followed, expected = follow_then_still(params, frame, still,
                                                  after_frames=followed_to_frame_2)
    np.testing.assert_array_equal(followed, expected)
    assert np.count_nonzero(followed != first) > 20


def test_moved_boxes_hold_every_moved_corner_and_no_more():
    """The top level's instance boxes (Arvo's centre and absolute-rotation extents, widened to
    the next float32): for 200 random boxes under random rigid poses, every one of the 8
    corners moved in float64 lies inside, and each face lies within 4 float32 ulps of the
    corners' bounds. Catches half extents rotated by R instead of |R| (corners outside), and
    the float64 bounds cast without widening (a corner outside by rounding)."""
    from harness.scene.motion import rotation

    rng = np.random.default_rng(3)
    lo = rng.uniform(-50, 50, (200, 3)).astype(np.float32)
    hi = lo + rng.uniform(0, 10, (200, 3)).astype(np.float32)
    poses = np.tile(np.eye(4), (200, 1, 1))
    for pose in poses:
        pose[:3, :3] = rotation(rng.normal(size=3), rng.uniform(0, 360))
        pose[:3, 3] = rng.uniform(-100, 100, 3)
    low, high = levels._moved_boxes(lo, hi, poses)
    pick = np.array([[i >> 2 & 1, i >> 1 & 1, i & 1] for i in range(8)], bool)
    corners = np.where(pick[None], hi[:, None].astype(np.float64), lo[:, None])
    moved = np.einsum("pij,pcj->pci", poses[:, :3, :3], corners) + poses[:, None, :3, 3]
    assert (low[:, None] <= moved).all() and (moved <= high[:, None]).all()
    ulp = np.spacing(np.maximum(np.abs(low), np.abs(high)).astype(np.float32))
    assert (low >= moved.min(1) - 4 * ulp).all() and (high <= moved.max(1) + 4 * ulp).all()
