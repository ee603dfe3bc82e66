"""Vertex arrays: the scene's unrolled triangles, and technique-owned dynamic geometry."""

from __future__ import annotations

import ctypes

import numpy as np
from OpenGL import GL


class VertexArray:
    """Interleaved float32 vertices; attribute i has ``sizes[i]`` floats (location i)."""

    def __init__(self, data: np.ndarray, sizes: tuple[int, ...], mode=GL.GL_TRIANGLES):
        self.sizes, self.mode = tuple(sizes), mode
        self.stride = sum(self.sizes)
        self.vao = GL.glGenVertexArrays(1)
        self.vbo = GL.glGenBuffers(1)
        GL.glBindVertexArray(self.vao)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.vbo)
        offset = 0
        for location, size in enumerate(self.sizes):
            GL.glEnableVertexAttribArray(location)
            GL.glVertexAttribPointer(location, size, GL.GL_FLOAT, GL.GL_FALSE, self.stride * 4,
                                     ctypes.c_void_p(offset * 4))
            offset += size
        GL.glBindVertexArray(0)
        self.count = 0
        self.update(data)

    def update(self, data: np.ndarray) -> None:
        data = np.ascontiguousarray(data, dtype=np.float32).reshape(-1, self.stride)
        self.count = len(data)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.vbo)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, max(data.nbytes, 4), data if len(data) else None,
                        GL.GL_DYNAMIC_DRAW)

    def draw(self, first: int = 0, count: int | None = None) -> None:
        if self.count == 0:
            return
        GL.glBindVertexArray(self.vao)
        GL.glDrawArrays(self.mode, first, self.count - first if count is None else count)
        GL.glBindVertexArray(0)

    def release(self) -> None:
        GL.glDeleteBuffers(1, [self.vbo])
        GL.glDeleteVertexArrays(1, [self.vao])


def scene_vertex_array(triangles: np.ndarray, normals: np.ndarray,
                       albedo: np.ndarray) -> VertexArray:
    """Position (loc 0), flat normal (loc 1) and albedo (loc 2) per unrolled vertex."""
    t = len(triangles)
    data = np.concatenate([
        triangles.reshape(t, 3, 3),
        np.repeat(normals[:, None, :], 3, axis=1),
        np.repeat(albedo[:, None, None], 3, axis=1),
    ], axis=2)
    return VertexArray(data, (3, 3, 1))


class FullscreenTriangle:
    """One triangle covering the viewport; the vertex shader makes it from gl_VertexID."""

    def __init__(self):
        self.vao = GL.glGenVertexArrays(1)

    def draw(self) -> None:
        GL.glBindVertexArray(self.vao)
        GL.glDrawArrays(GL.GL_TRIANGLES, 0, 3)
        GL.glBindVertexArray(0)

    def release(self) -> None:
        GL.glDeleteVertexArrays(1, [self.vao])
