"""texels_per_pixel (techniques/common/footprint.py) against the texels a pixel's corners
land on: each corner's camera ray meets the receiver's plane, the hit is projected into the
map, and the quad's area in texels is the shoelace sum (float64, no derivatives)."""

from __future__ import annotations

import numpy as np
import pytest

from harness.scene.transforms import fit_light
from harness.technique import Frame
from techniques.common.footprint import receivers, texel_over_pixel, texels_per_pixel


def corner_ratio(frame, view_proj, res, rows, cols) -> np.ndarray:
    """1 / sqrt(texel area of the pixel's quad) for pixels (rows, cols)."""
    a = frame.arrays
    inverse = np.linalg.inv(frame.camera.view_proj)
    origin = frame.camera.position
    point = a.position[rows, cols].astype(np.float64)
    normal = a.normal[rows, cols].astype(np.float64)
    corners = []
    for dx, dy in ((-0.5, -0.5), (0.5, -0.5), (0.5, 0.5), (-0.5, 0.5)):
        x = cols + 0.5 + dx
        y = frame.height - 1 - rows + 0.5 + dy  # window y grows upward
        ndc = np.c_[2 * x / frame.width - 1, 2 * y / frame.height - 1, np.zeros_like(x),
                    np.ones_like(x)]
        far = ndc @ inverse.T
        ray = far[:, :3] / far[:, 3:] - origin
        t = (normal * (point - origin)).sum(1) / (normal * ray).sum(1)
        hit = origin + t[:, None] * ray
        clip = np.c_[hit, np.ones(len(hit))] @ view_proj.T
        corners.append((clip[:, :2] / clip[:, 3:] * 0.5 + 0.5) * res)
    c = np.array(corners)
    area = 0.5 * np.abs(sum(c[i, :, 0] * c[(i + 1) % 4, :, 1] - c[(i + 1) % 4, :, 0] * c[i, :, 1]
                            for i in range(4)))
    return 1.0 / np.sqrt(area)


@pytest.mark.parametrize("scene_name, res", [("castle", 2048), ("sphere_plane", 1024)])
def test_texel_over_pixel_matches_the_pixels_corners_in_the_map(scene_name, res, gl_context,
                                                                scene_at):
    """castle (directional, oblique walls and ground) and sphere_plane (spot: a perspective
    map) at 64 x 64, sm's frustum: on every receiver pixel the derivative form equals the
    corner quad's within 1 % (the quad is exact, the derivative is its first order). Catches
    the hit's slide along the ray left out of d point / d window (t dr alone: off on every
    oblique receiver) or the perspective division's term of the map's Jacobian."""
    frame = Frame(scene_at(scene_name, 64))
    try:
        frustum = fit_light(frame.scene, res)
        mask = receivers(frame)
        rows, cols = np.nonzero(mask)
        ours = texel_over_pixel(frame, frustum.view_proj, res)
        expected = corner_ratio(frame, frustum.view_proj, res, rows, cols)
        columns = texels_per_pixel(frame, [(frustum.view_proj, res)])
    finally:
        frame.release()
    assert len(rows) > 1000
    np.testing.assert_allclose(ours, expected, rtol=0.01)
    assert columns["texels_per_pixel_median"] == pytest.approx(np.median(expected), rel=0.01)
    assert columns["texels_per_pixel_p95"] == pytest.approx(np.percentile(expected, 95),
                                                            rel=0.01)


def test_a_runs_frames_share_one_computation_and_another_camera_pass_gets_its_own(gl_context,
                                                                                  scene_at):
    """The columns are computed once per camera pass, light and maps (a run's frames repeat
    them): the same map over castle at 64 and at 32 pixels (the same matrix, another camera
    pass) gives each pass its own columns, those of a fresh computation, and a repeat gives the
    same. Catches the memo keyed on the maps alone (the 32-pixel pass got the 64's columns)."""
    frustum = fit_light(scene_at("castle", 64), 1024)
    maps = [(frustum.view_proj, 1024)]
    found = {}
    for size in (64, 32, 64):
        frame = Frame(scene_at("castle", size))
        try:
            first, again = texels_per_pixel(frame, maps), texels_per_pixel(frame, maps)
            ratio = texel_over_pixel(frame, frustum.view_proj, 1024)
        finally:
            frame.release()
        assert first == again
        assert first["texels_per_pixel_median"] == pytest.approx(np.median(ratio[np.isfinite(ratio)]))
        found.setdefault(size, first)
    assert found[64]["texels_per_pixel_median"] > 1.5 * found[32]["texels_per_pixel_median"]


def test_runs_taking_turns_each_find_their_own_columns(gl_context, scene_at, monkeypatch):
    """An interleaved batch's runs render a frame each in turn, each with its own maps: the
    second round of three runs computes nothing, and a level map given as a function (vsm's)
    is not asked for again. Catches a memo of the last camera pass's maps alone (every frame
    of make bench's batches computed again: 30 % of its time)."""
    from techniques.common import footprint

    computed = []
    real = footprint._texels_per_pixel
    monkeypatch.setattr(footprint, "_texels_per_pixel",
                        lambda *a: computed.append(1) or real(*a))
    frame = Frame(scene_at("castle", 32))
    asked = []

    def choice():
        asked.append(1)
        return np.zeros((32, 32), np.int64)

    try:
        maps = [[(fit_light(frame.scene, res).view_proj, res)] for res in (256, 1024, 4096)]
        for _ in range(2):
            columns = [texels_per_pixel(frame, m) for m in maps]
            columns.append(texels_per_pixel(frame, maps[0], choice, choice_key=b"one"))
    finally:
        frame.release()
    assert len(computed) == 4 and len(asked) == 1
    assert columns[0] == columns[3]
