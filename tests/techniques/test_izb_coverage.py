"""izb's conservative rasterisation of casters (izb_casters.geom.glsl and .frag.glsl): every
grid texel a triangle touches gets a fragment, checked against an exact 2D overlap of the
triangle and the texel's square in NumPy (float64, the separating axes: x, y and the
triangle's three edge normals), on random thin triangles, which plain rasterisation misses
wherever they pass between texel centres."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from harness.gl.geometry import SceneMesh
from techniques.izb.izb import PLAIN_BOUNDS, caster_program
from techniques.izb.storage import EmptyTarget, IntegerImage, StorageBuffer

RES = 64


def overlaps(triangle: np.ndarray, res: int, grow: float = 0.0) -> np.ndarray:
    """(res, res) bool, [row y, column x]: whether texel square [x, x + 1] x [y, y + 1], grown
    by ``grow`` on each side, meets ``triangle`` (3, 2) in grid units (closed sets)."""
    y, x = np.mgrid[0:res, 0:res].astype(np.float64)
    lo_x, lo_y, hi_x, hi_y = x - grow, y - grow, x + 1 + grow, y + 1 + grow
    t = triangle.astype(np.float64)
    touch = ((lo_x <= t[:, 0].max()) & (hi_x >= t[:, 0].min()) & (lo_y <= t[:, 1].max())
             & (hi_y >= t[:, 1].min()))
    e1, e2 = t[1] - t[0], t[2] - t[0]
    area = e1[0] * e2[1] - e1[1] * e2[0]
    for i in range(3):
        p, q = t[i], t[(i + 1) % 3]
        normal = np.sign(area) * np.array([q[1] - p[1], p[0] - q[0]])  # outward
        corners = [(cx, cy) for cx in (lo_x, hi_x) for cy in (lo_y, hi_y)]
        nearest = np.min([normal[0] * (cx - p[0]) + normal[1] * (cy - p[1])
                          for cx, cy in corners], axis=0)
        touch &= nearest <= 0
    return touch


def thin_triangles(rng, n: int) -> np.ndarray:
    """(n, 3, 2) in grid units: long slivers a few hundredths of a texel wide at random
    angles, and small ones between texel centres."""
    out = []
    for k in range(n):
        start = rng.uniform(4, RES - 4, 2)
        angle = rng.uniform(0, np.pi)
        length = rng.uniform(0.3, 20) if k % 2 else rng.uniform(0.05, 0.5)
        end = np.clip(start + length * np.array([np.cos(angle), np.sin(angle)]), 1, RES - 1)
        width = rng.uniform(0.001, 0.05)
        side = np.array([-np.sin(angle), np.cos(angle)]) * width
        out.append([start, end, (start + end) / 2 + side])
    return np.array(out)


def fragments_per_texel(gl_context, triangles: np.ndarray) -> np.ndarray:
    """(RES, RES) fragments per texel from the caster raster of ``triangles`` (grid units),
    drawn one at a time (one draw each), a light frustum that is the identity (world x, y in
    [-1, 1] are the grid's NDC), no samples in the lists."""
    program = caster_program({"SAMPLES": 1, "TEXEL_FRAGMENTS": 1})
    heads, counts = IntegerImage(RES), IntegerImage(RES)
    buffers = [StorageBuffer(16) for _ in range(4)]
    target = EmptyTarget(RES)
    out = []
    try:
        heads.fill(0)
        buffers[3].write(PLAIN_BOUNDS)
        for binding, buffer in enumerate(buffers):
            buffer.bind(binding)
        GL.glActiveTexture(GL.GL_TEXTURE0)
        GL.glBindTexture(GL.GL_TEXTURE_2D, heads.id)
        target.bind()
        GL.glDisable(GL.GL_DEPTH_TEST)
        GL.glDisable(GL.GL_CULL_FACE)
        program.use().set(heads=0, light_view_proj=np.eye(4), min_w=0.0, grid_res=RES,
                          light=np.array([0.0, 0.0, 1.0, 0.0]))
        for triangle in triangles:
            counts.fill(0)
            counts.bind(1)
            world = np.column_stack([triangle / RES * 2 - 1, np.zeros(3)])
            mesh = SceneMesh(world, np.array([[0, 1, 2]]), np.array([[0.0, 0, 1]]),
                             np.array([1.0]))
            mesh.draw()
            mesh.release()
            out.append(counts.read())
        return np.array(out)
    finally:
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        GL.glUseProgram(0)
        for resource in (program, heads, counts, target, *buffers):
            resource.release()


def test_every_texel_a_thin_triangle_touches_gets_a_fragment(gl_context):
    """On 60 random slivers (0.001 to 0.05 texels wide) every texel the exact overlap finds has
    a fragment, and none more than 1/16 texel beyond the triangle (the raster's margin is
    1/32). Catches plain rasterisation (the geometry shader emitting the triangle itself,
    tried: it fails), a quad grown by less than half a texel (MARGIN alone, tried: fails)
    and the edge test's outward normal reversed (tried: fails, the texels the triangle
    covers are dropped)."""
    triangles = thin_triangles(np.random.default_rng(50), 60)
    got = fragments_per_texel(gl_context, triangles) > 0
    for triangle, fragments in zip(triangles, got):
        touched = overlaps(triangle, RES)
        assert touched.any()
        missed = touched & ~fragments
        assert not missed.any(), (triangle, np.argwhere(missed)[:5])
        extra = fragments & ~overlaps(triangle, RES, grow=1 / 16)
        assert not extra.any(), (triangle, np.argwhere(extra)[:5])
