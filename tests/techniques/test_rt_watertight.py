"""Watertightness of rt's traversal: shadow rays aimed exactly at the vertices and the edges of
a closed tessellated sphere, from outside it towards a point light at its centre, never pass
through. The rays start where the test puts them (G-buffer points written by hand, normals 0:
no origin offset), so each ray's line passes exactly through its vertex, or through the
float32 midpoint of its edge."""

from __future__ import annotations

import numpy as np
import pytest
from OpenGL import GL

from harness import config
from harness.technique import registry
from harness.scene import build_scene
from harness.technique import Frame, reset_gl_state

SIZE = 32  # 1024 rays: 162 vertices and 480 edges of a twice-subdivided icosphere


def sphere_scene(subdivisions: int):
    data = {"resolution": [SIZE, SIZE],
            "camera": {"position": [0, -6, 0], "target": [0, 0, 0], "up": [0, 0, 1]},
            "light": {"type": "point", "position": [0, 0, 0]},
            "objects": [{"shape": "sphere", "radius": 1.0, "subdivisions": subdivisions}]}
    return build_scene("sphere", config.Scene(**data))


def targets(part) -> np.ndarray:
    """Every vertex and the float32 midpoint of every edge of the mesh."""
    faces = part.faces
    edges = np.unique(np.sort(np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]],
                                              faces[:, [2, 0]]]), axis=1), axis=0)
    v = part.vertices.astype(np.float32)
    return np.concatenate([v, (v[edges[:, 0]] + v[edges[:, 1]]) * np.float32(0.5)])


def write_gbuffer(frame: Frame, points: np.ndarray) -> None:
    """G-buffer texels 0 .. N-1 (row by row from the bottom): ``points`` covered, normal 0;
    the others uncovered."""
    position = np.zeros((SIZE * SIZE, 4), np.float32)
    position[:len(points), :3], position[:len(points), 3] = points, 1.0
    for texture, data in ((frame.gbuffer.position_texture, position),
                          (frame.gbuffer.normal_texture, np.zeros_like(position))):
        GL.glBindTexture(GL.GL_TEXTURE_2D, texture.id)
        GL.glTexSubImage2D(GL.GL_TEXTURE_2D, 0, 0, 0, SIZE, SIZE, GL.GL_RGBA, GL.GL_FLOAT,
                           data.reshape(SIZE, SIZE, 4))
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)


def read_mask(texture) -> np.ndarray:
    out = np.empty((texture.height, texture.width), np.float32)
    GL.glBindTexture(GL.GL_TEXTURE_2D, texture.id)
    GL.glGetTexImage(GL.GL_TEXTURE_2D, 0, GL.GL_RED, GL.GL_FLOAT, out)
    GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
    return out.ravel()


@pytest.mark.parametrize("build", ["lbvh", "sah"])
def test_rays_at_vertices_and_edges_never_pass_through(build, gl_context):
    """From 2 x each vertex and edge midpoint of a closed icosphere (162 vertices, 480 edges;
    2 x is exact in float32) towards a point light at its centre: every ray meets the sphere
    (V = 0), whatever the builder. Run against the Moller-Trumbore test in float32 (edge
    tests u >= 0, v >= 0, u + v <= 1 each rounded on its own; a temporary rt_watertight.glsl)
    it let 43 of the 642 rays through, with both builders."""
    scene = sphere_scene(2)
    points = targets(scene.parts[0])
    assert len(points) == 162 + 480
    frame = Frame(scene)
    cls = registry.get("rt")
    technique = cls(cls.Params(build=build, leaf_size=1))
    try:
        technique.prepare(frame)
        technique.update(frame)
        write_gbuffer(frame, 2 * points)
        frame.meter.new_frame(True)
        technique.render(frame)
        mask = read_mask(technique.mask)
    finally:
        technique.release()
        reset_gl_state()
        frame.release()
    through = np.flatnonzero(mask[:len(points)] != 0)
    assert len(through) == 0, f"{len(through)} rays passed through: {points[through][:5]}"
    assert (mask[len(points):] == 1).all()  # uncovered texels: no ray, lit
