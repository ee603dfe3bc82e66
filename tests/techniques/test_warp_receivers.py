"""The warps' visible receivers reduced on the GPU (techniques/warps/warp_receivers.py) against the
NumPy oracle on the CPU copy of the G-buffer (warp_body.receiver_points)."""

from __future__ import annotations

import numpy as np
import pytest
from helpers import light_at, variant

from harness.technique import registry
from harness.technique import Frame, reset_gl_state
from techniques.warps import warped_map as W

# float32 rounding of a view depth computed from float32 positions: the quantity's own
# rounding (half a unit in the last place, 2^-24) plus that of the dot product's terms
FLOAT32_RANGE = 2.0 ** -22
# shipped scenes: a spot light (sphere_plane) and directional ones near and far
SCENES = ("sphere_plane", "castle", "crowd", "terrain_long")


@pytest.fixture
def reduction(gl_context):
    found = W.ReceiverReduction()
    yield found
    found.release()


def warp_v(technique: str, frame, find, monkeypatch) -> np.ndarray | None:
    """V of ``technique`` on ``frame`` with its receivers from ``find``; None where it does not
    apply."""
    from harness.technique import NotApplicable

    monkeypatch.setattr(W, "view_setup", lambda f, _find, real=W.view_setup: real(f, find))
    cls = registry.get(technique)
    run = cls(cls.Params())
    try:
        run.prepare(frame)
        frame.meter.new_frame(False)
        return run.render(frame).visibility.copy()
    except NotApplicable:
        return None
    finally:
        run.release()
        reset_gl_state()
        monkeypatch.undo()


@pytest.mark.parametrize("name", SCENES)
def test_gpu_receivers_give_the_oracles_ranges_and_the_warps_v(scene_at, shipped_scenes,
                                                               reduction, monkeypatch, name):
    """On shipped scenes at their size: the reduced view-depth range (and a spot light's range
    in its clip space) equals the NumPy one to float32 rounding (within 2^-22 relative; seen:
    at most 8.2e-8), and psm, lispsm and gmnpr give the same V but for at most 2 pixels of the
    image (seen: 0 or 1 of 262144, where n or f moved by that rounding shifts a map texel
    boundary across a pixel's depth test). Catches a reduction over uncovered pixels (their
    position is 0: a depth range from the camera's distance to the origin), one that ignores
    a spot light's frustum, and a wrong component or encoding read back."""
    scene = scene_at(name, *shipped_scenes[name].resolution)
    frame = Frame(scene)
    try:
        spot = W.view_setup(frame, W.receiver_points).spot
        gpu, cpu = reduction.find(frame, spot), W.receiver_points(frame, spot)
        view = frame.camera.view
        np.testing.assert_allclose(gpu.depth_range(view), cpu.depth_range(view),
                                   rtol=FLOAT32_RANGE)
        if spot is not None:
            space = W.light_space(W.view_setup(frame, W.receiver_points))
            along = cpu.range_along(space.to_space, space.eye, space.forward)
            np.testing.assert_allclose(gpu.range_along(space.to_space, space.eye, space.forward),
                                       along, rtol=FLOAT32_RANGE,
                                       atol=FLOAT32_RANGE * np.abs(along).max())
        for technique in ("psm", "lispsm", "gmnpr"):
            v_gpu = warp_v(technique, frame, reduction.find, monkeypatch)
            v_cpu = warp_v(technique, frame, W.receiver_points, monkeypatch)
            assert (v_gpu is None) == (v_cpu is None)
            if v_gpu is not None:
                assert np.count_nonzero(v_gpu != v_cpu) <= 2, technique
    finally:
        frame.release()


@pytest.mark.parametrize("theta_deg,behind,fallback", [(0.0, True, True), (10.0, False, True),
                                                       (30.0, True, False)])
def test_gpu_receivers_take_psms_fallback_where_the_oracle_does(shipped_scenes, reduction,
                                                                theta_deg, behind, fallback):
    """PSM's fallback cases on terrain_long (test_psm_falls_back_where_its_warp_cannot_hold_the
    _receivers): the reduced "any receiver outside the map" decides as the NumPy one. Catches
    the outside test reading the wrong component, or a sign of w flipped."""
    scene = variant(shipped_scenes, "terrain_long", 96,
                    direction=light_at(shipped_scenes["terrain_long"], theta_deg, behind=behind))
    frame = Frame(scene)
    try:
        psm_gpu = W.post_perspective_warp(W.view_setup(frame, reduction.find), 512)
        psm_cpu = W.post_perspective_warp(W.view_setup(frame, W.receiver_points), 512)
        assert psm_gpu.fallback == psm_cpu.fallback == fallback
        assert reduction.find(frame, None).any_outside(psm_gpu.camera) == \
            W.receiver_points(frame, None).any_outside(psm_gpu.camera)
    finally:
        frame.release()
