"""The faster frame (issue 13 item 6) gives the same V: sm's own shader, clears by
glClearTexImage, shading only the covered pixels, the G-buffer's normal left uncleared.

The timings themselves are benchmarks/pyrender_baseline.py's; here only exactness. About 10 s.
"""

import numpy as np
import pytest
from OpenGL import GL

SCENES = ("castle", "terrain_long")
SIZE, MAP = 128, 1024


def clear_as_before(self, *colors, stencil: int = 0) -> None:
    """Framebuffer.clear as it was: framebuffer clears (glClearBuffer)."""
    self.bind()
    for i, value in enumerate(colors):
        GL.glClearBufferfv(GL.GL_COLOR, i, np.broadcast_to(np.float32(value), (4,)).copy())
    if self.depth:
        GL.glDepthMask(GL.GL_TRUE)
        GL.glStencilMask(0xFF)
        GL.glClearBufferfi(GL.GL_DEPTH_STENCIL, 0, 1.0, stencil)


def render_v(frame, technique: str, params: dict) -> np.ndarray:
    from harness.technique import registry
    from harness.technique import reset_gl_state

    cls = registry.get(technique)
    run = cls(cls.Params(**params))
    run.prepare(frame)
    run.update(frame)
    try:
        frame.gbuffer.render(frame.geometry, frame.camera.view_proj)
        return run.render(frame).visibility
    finally:
        run.release()
        reset_gl_state()


def sm_as_before(frame, params: dict) -> np.ndarray:
    """sm as it was: the map and pcf's shading shader with one grid sample and one bias."""
    from harness.technique import reset_gl_state
    from techniques.common.light_maps import FilteredShadowMap, Sampling
    from techniques.pcf.pcf import SHADING

    passes = FilteredShadowMap(frame, params["res"], SHADING)
    try:
        frame.gbuffer.render(frame.geometry, frame.camera.view_proj)
        passes.update(frame)
        passes.render(frame, Sampling(bias_min=params["bias"], bias_max=params["bias"],
                                      slope_bias=params["slope_bias"]))
        return frame.visibility_target.read()
    finally:
        passes.release()
        reset_gl_state()


@pytest.mark.parametrize("scene_name", SCENES)
def test_sm_and_pcf_give_the_v_they_gave_before(scene_name, scene_at, gl_context, monkeypatch):
    """V of sm and pcf (default grid and jittered) now, and with the frame as it was: clears
    by glClearBuffer, every pixel shaded, the G-buffer's normal texture cleared, sm through the
    general PCF shader. Bit for bit, on two shipped scenes. (Every technique at its defaults on
    castle 512, terrain_long 256 and box_plane 256, and sm and pcf at map 2048, were also
    compared once against main's code: all equal.)

    Catches: sm's shader dropping the constant bias or the slope term, or testing another
    texel (seen: receiver_test(r, r.texel, 0.0) differs here); covered-only shading that leaves
    out covered pixels (GL_LESS instead of GL_GREATER: V 1 everywhere)."""
    from harness.gl.gbuffer import GBuffer
    from harness.gl.framebuffer import Framebuffer
    from harness.technique import Frame

    frame = Frame(scene_at(scene_name, SIZE))
    sm = {"res": MAP, "bias": 0.02, "slope_bias": 1.0}
    runs = [("pcf", {"res": MAP}), ("pcf", {"res": MAP, "sampling": "jitter", "seed": 5})]
    try:
        now = [render_v(frame, "sm", sm)] + [render_v(frame, *run) for run in runs]
        with monkeypatch.context() as before:
            before.setattr(Framebuffer, "clear", clear_as_before)
            before.setattr(Frame, "draw_fullscreen", lambda self, covered_only=False:
                           self.fullscreen_triangle.draw())
            render_gbuffer = GBuffer.render

            def gbuffer_cleared(self, geometry, view_proj):
                self.fbo.clear((0, 0, 0, 0), (0, 0, 0, 0))
                render_gbuffer(self, geometry, view_proj)

            before.setattr(GBuffer, "render", gbuffer_cleared)
            then = [sm_as_before(frame, sm)] + [render_v(frame, *run) for run in runs]
        no_slope = render_v(frame, "sm", {**sm, "slope_bias": 0.0})
        covered = frame.arrays.covered
    finally:
        frame.release()
    for a, b in zip(now, then):
        assert np.array_equal(a, b)
    # not vacuous: shadows, uncovered pixels (left unshaded now), and pixels the slope term of
    # sm's own shader decides
    assert 0.02 < (now[0][covered] < 1).mean() < 0.9
    assert 0.05 < (~covered).mean()
    assert np.count_nonzero(no_slope != now[0]) > 10


def test_covered_only_draws_exactly_the_covered_pixels(scene_at, gl_context, tmp_path):
    """Frame.draw_fullscreen(covered_only=True) with a shader writing 0: V is 0 exactly where
    the G-buffer arrays say covered, still 1 (its clear value) elsewhere, and the depth state
    is back to begin_visibility's.

    Catches: GL_GEQUAL (the far plane's own pixels pass: all 0), no depth range (the triangle
    at depth 0.5 fails behind near surfaces), a depth test left on."""
    from harness.gl.shaders import HARNESS_GLSL, Program
    from harness.technique import Frame

    (tmp_path / "zero.frag.glsl").write_text(
        "layout(location = 0) out float v;\nvoid main() { v = 0.0; }\n")
    program = Program(HARNESS_GLSL / "fullscreen.vert.glsl", tmp_path / "zero.frag.glsl")
    frame = Frame(scene_at("castle", 96))
    try:
        frame.begin_visibility()
        program.use()
        frame.draw_fullscreen(covered_only=True)
        v = frame.visibility_target.read()
        depth_test = GL.glIsEnabled(GL.GL_DEPTH_TEST)
        depth_range = GL.glGetFloatv(GL.GL_DEPTH_RANGE)
        covered = frame.arrays.covered
    finally:
        frame.release()
        program.release()
        GL.glEnable(GL.GL_DEPTH_TEST)
    assert 0.05 < covered.mean() < 0.95
    assert np.array_equal(v, np.where(covered, 0.0, 1.0))
    assert not depth_test
    assert np.array_equal(depth_range, [0.0, 1.0])


@pytest.mark.parametrize("internal_format, value, expected", [
    (GL.GL_R32F, 3.0e38, [np.float32(3.0e38)]),
    (GL.GL_RG32F, (-1.5, 0.1, 0.0, 0.0), [-1.5, np.float32(0.1)]),
    (GL.GL_RGBA32F, (0.0, 1.0, 2.0, 0.25), [0.0, 1.0, 2.0, 0.25]),
    (GL.GL_RGBA8, 0.25, [64 / 255] * 4),  # round(0.25 * 255) = 64
])
def test_clear_sets_every_texel(internal_format, value, expected, gl_context):
    """Framebuffer.clear: every texel of a colour attachment to the value (as the texture
    format stores it), depth to the far plane (24 bits set) and the stencil, whatever the
    colour mask. Read back by glReadPixels, the depth and stencil packed as GL defines
    GL_UNSIGNED_INT_24_8 (depth high, stencil low).

    Catches: the clear data in the wrong format or type (RGBA8 taken as bytes: 0.25 -> 0), the
    stencil in the wrong word of GL_FLOAT_32_UNSIGNED_INT_24_8_REV (stencil 0), depth left
    alone, a clear that obeys the colour mask (glClearBuffer does)."""
    from OpenGL.raw.GL.VERSION.GL_1_0 import glReadPixels

    from harness.gl.framebuffer import Framebuffer

    target = Framebuffer(24, 20, (internal_format,), depth=True)
    try:
        target.bind()
        GL.glClearBufferfv(GL.GL_COLOR, 0, np.full(4, 0.75, np.float32))
        GL.glClearBufferfi(GL.GL_DEPTH_STENCIL, 0, 0.5, 9)
        GL.glColorMask(GL.GL_FALSE, GL.GL_FALSE, GL.GL_FALSE, GL.GL_FALSE)
        target.clear(value, stencil=5)
        GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
        colour = target.read(0).reshape(24 * 20, -1)
        depth_stencil = np.zeros(24 * 20, np.uint32)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        glReadPixels(0, 0, 24, 20, GL.GL_DEPTH_STENCIL, GL.GL_UNSIGNED_INT_24_8, depth_stencil)
    finally:
        target.release()
    assert np.array_equal(colour, np.broadcast_to(np.float32(expected), colour.shape))
    assert np.all(depth_stencil == 0xFFFFFF05)


def test_gbuffer_normal_is_zero_where_no_surface(scene_at, gl_context):
    """The G-buffer's normal texture is not cleared; read() gives normal and albedo 0 where no
    surface is and the drawn ones where one is, and sm's V does not depend on what the texture
    held before.

    Catches: read() returning the texture as it is (the junk 7.0 shows where not covered); a
    map shader reading the normal without testing coverage and drawn over every pixel (seen:
    sm_shading.frag.glsl without its gbuffer_fetch test, covered_only off)."""
    from harness.technique import Frame

    frame = Frame(scene_at("castle", 64))
    try:
        clean = frame.gbuffer.read()
        v_clean = render_v(frame, "sm", {"res": 512})
        frame.gbuffer.normal_texture.clear(7.0)
        v_junk = render_v(frame, "sm", {"res": 512})  # renders the G-buffer again
        after = frame.gbuffer.read()
    finally:
        frame.release()
    covered = clean.covered
    assert 0.05 < covered.mean() < 0.95
    assert np.all(after.normal[~covered] == 0) and np.all(after.albedo[~covered] == 0)
    assert np.array_equal(after.normal, clean.normal)
    assert np.array_equal(after.albedo, clean.albedo)
    assert np.allclose(np.linalg.norm(clean.normal[covered], axis=-1), 1.0, atol=1e-5)
    assert np.array_equal(v_clean, v_junk)
