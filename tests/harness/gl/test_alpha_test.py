"""alpha_test.glsl, the GLSL copy of the sampling rule (harness/scene/alpha.py), against
sample_alpha's NumPy float64 at texel centres, corners and edges, beyond [0, 1] (repeat wrap),
on textures that are not square, several masks in one upload; and the cut-out decision at the
cutoff."""

from __future__ import annotations

import numpy as np
import pytest
from OpenGL import GL

from harness.gl.alpha import AlphaTextures
from harness.gl.geometry import BufferTexture
from harness.gl.shaders import ComputeProgram
from harness.scene.alpha import AlphaMask, sample_alpha

from helpers import DATA

RNG = np.random.default_rng(48)
# a 5-wide, 3-high texture of random bytes, and a 4 x 4 one after it in the same upload (its
# texels start at 15: an offset into the shared buffer)
MASKS = (AlphaMask(RNG.integers(0, 256, (3, 5), dtype=np.uint8), 0.5, "random 5x3"),
         AlphaMask(RNG.integers(0, 256, (4, 4), dtype=np.uint8), 0.25, "random 4x4"))


def probe_uv(mask: AlphaMask) -> np.ndarray:
    """Texel centres ((j + 0.5) / W), corners and edge midpoints (j / W), points a quarter
    texel off them, and the same shifted by -2 .. +2 whole textures (the wrap)."""
    h, w = mask.texture.shape
    u = np.arange(-1, 2 * w + 2) / (2 * w)
    v = np.arange(-1, 2 * h + 2) / (2 * h)
    uv = np.stack(np.meshgrid(u, v), axis=-1).reshape(-1, 2)
    uv = np.concatenate([uv, uv + 0.25 / np.array([w, h])])
    return np.concatenate([uv + shift for shift in (-2.0, -1.0, 0.0, 1.0, 2.0)])


def glsl_alpha(masks, mask_index: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """(alpha, cut out) per probe from alpha_test.glsl in a compute shader."""
    textures = AlphaTextures(masks)
    probes = np.zeros((len(uv), 4), np.float32)
    probes[:, :2], probes[:, 2] = uv, mask_index
    probe_buffer = BufferTexture(probes, GL.GL_RGBA32F)
    program = ComputeProgram(DATA / "alpha_probe.comp.glsl")
    ssbo = GL.glGenBuffers(1)
    try:
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, ssbo)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, len(uv) * 8, None, GL.GL_DYNAMIC_READ)
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, 0, ssbo)
        program.use()
        unit = textures.bind(program, 0)
        program.set(probes=probe_buffer.bind(unit), count=len(uv))
        GL.glDispatchCompute(-(-len(uv) // 64), 1, 1)
        GL.glMemoryBarrier(GL.GL_BUFFER_UPDATE_BARRIER_BIT)
        out = np.frombuffer(GL.glGetBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, len(uv) * 8),
                            np.float32).reshape(-1, 2)
        GL.glUseProgram(0)
        return out.copy()
    finally:
        GL.glDeleteBuffers(1, [ssbo])
        for resource in (program, probe_buffer, textures):
            resource.release()


@pytest.mark.parametrize("which", [0, 1])
def test_glsl_rule_equals_sample_alpha(gl_context, which):
    """At every probe (centres, corners, edges, a quarter texel off, wrapped two textures either
    way) the GLSL alpha equals sample_alpha (float64) to float32 rounding, for the first mask
    of the upload and for the second (its texels at an offset). Catches: clamp instead of
    repeat (probes beyond [0, 1]), texel centres at integers instead of half-integers (every
    probe moves half a texel), the second mask read at the first's offset, or a width/height
    swap on the 5 x 3 texture."""
    mask = MASKS[which]
    uv = probe_uv(mask)
    got = glsl_alpha(MASKS, np.full(len(uv), which), uv)
    expected = sample_alpha(mask.texture, uv)
    np.testing.assert_allclose(got[:, 0], expected, atol=2e-6)
    # a hand value: at a corner shared by four texels the mean of the four
    t = mask.texture.astype(np.float64) / 255
    h, w = t.shape
    corner = glsl_alpha(MASKS, np.array([which]), np.array([[1.0 / w, 1.0 / h]]))[0, 0]
    assert corner == pytest.approx(t[:2, :2].mean(), abs=2e-6)


def test_cut_out_follows_the_cutoff(gl_context):
    """cut_out is alpha < cutoff, each mask its own cutoff; a negative mask index is opaque.
    A uniform texture at 128/255 lies above 0.5 and below 0.51. Catches the comparison
    inverted, one mask's cutoff used for the other, or mask -1 read as a mask."""
    grey = np.full((2, 2), 128, np.uint8)
    masks = (AlphaMask(grey, 0.5, "at 0.5"), AlphaMask(grey, 0.51, "at 0.51"))
    uv = np.array([[0.3, 0.7]] * 3)
    out = glsl_alpha(masks, np.array([0, 1, -1]), uv)
    assert out[:, 1].tolist() == [0.0, 1.0, 0.0]
