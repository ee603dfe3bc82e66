"""The GPU reduction over a G-buffer (harness/gl/reduction.py) against numpy on its arrays."""

from __future__ import annotations

import numpy as np

from harness.gl.reduction import CoveredRange, decode
from harness.gl.shaders import HARNESS_GLSL
from harness.technique import Frame, reset_gl_state

POSITION_UPWARD = """
bool quantity(vec3 position, vec3 normal, out vec4 value) {
    value = vec4(position, dot(normal, vec3(0.0, 0.0, 1.0)));
    return normal.z > 0.5;
}
#include "covered_range.glsl"
"""


def test_decode_inverts_the_order_preserving_encoding():
    """covered_range.glsl's encoding, written here independently: negative floats all bits
    flipped, others the sign bit set. Catches a decode that forgets the negative branch."""
    values = np.array([-3.5e7, -1.0, -0.0, 0.0, 2.5e-30, 7.0, np.inf, -np.inf], np.float32)
    bits = values.view(np.uint32)
    encoded = np.where(bits & 0x80000000, ~bits, bits | 0x80000000).astype(np.uint32)
    assert np.all(np.diff(encoded[np.argsort(values, kind="stable")].astype(np.int64)) >= 0)
    np.testing.assert_array_equal(decode(encoded), values)


def test_view_depth_range_and_a_filtered_quantity_match_numpy(gl_context, scene_at, tmp_path):
    """The visible view-depth range, and the range of position (x negative on part of the view)
    over upward-facing covered pixels only, equal numpy's on the read-back G-buffer (float32 to a
    few units in the last place). terrain_long's camera is 2 units above the world origin, which
    it does not see: an uncovered pixel's cleared position (0, 0, 0) would give min y = 0.
    Catches a reduction counting uncovered pixels, ignoring the quantity's false, or one work
    group's result only (the image is 100 x 70, not a multiple of 16)."""
    shader = tmp_path / "position_upward.comp.glsl"
    shader.write_text(POSITION_UPWARD.replace('"covered_range.glsl"',
                                              f'"{HARNESS_GLSL / "covered_range.glsl"}"'))
    frame = Frame(scene_at("terrain_long", 100, 70))
    depth_range, upward = CoveredRange(), CoveredRange(shader)
    try:
        depth = depth_range.reduce(frame.gbuffer.position_texture, frame.gbuffer.normal_texture,
                                   camera_view=frame.camera.view)
        found = upward.reduce(frame.gbuffer.position_texture, frame.gbuffer.normal_texture)
        a = frame.arrays
    finally:
        depth_range.release()
        upward.release()
        frame.release()
        reset_gl_state()
    view = frame.camera.view
    d = -(a.position[a.covered].astype(np.float64) @ view[2, :3] + view[2, 3])
    np.testing.assert_allclose([depth.low[0], depth.high[0]], [d.min(), d.max()], rtol=1e-6)
    mask = a.covered & (a.normal[..., 2] > 0.5)
    assert 0 < mask.sum() < a.covered.sum()  # the filter leaves out the blocks' sides
    p = a.position[mask]
    np.testing.assert_allclose(found.low[:3], p.min(axis=0), rtol=1e-6)
    np.testing.assert_allclose(found.high[:3], p.max(axis=0), rtol=1e-6)
    assert found.low[0] < 0 < found.high[0] and found.low[1] > 1.0
    assert not found.empty and not depth.empty
