"""Vertex arrays: the scene's indexed mesh, and technique-owned dynamic geometry."""

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


class BufferTexture:
    """A buffer texture (``samplerBuffer`` / ``usamplerBuffer``, read by ``texelFetch``) over
    ``data``, one texel per row in ``texel_format``. Preferred to a shader storage buffer for
    per-element reads: llvmpipe's storage-buffer load made the G-buffer pass 1.9x slower (castle
    512^2: 56.7 against 30.7 ms, the unshared vertices' 29.2). More rows than the driver's
    GL_MAX_TEXTURE_BUFFER_SIZE is a ValueError."""

    def __init__(self, data: np.ndarray, texel_format: int, dynamic: bool = False):
        if len(data) > int(GL.glGetIntegerv(GL.GL_MAX_TEXTURE_BUFFER_SIZE)):
            raise ValueError(f"{len(data)} texels: over the driver's buffer-texture size")
        data = np.ascontiguousarray(data)
        self.buffer = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_TEXTURE_BUFFER, self.buffer)
        GL.glBufferData(GL.GL_TEXTURE_BUFFER, max(data.nbytes, 16), data if data.size else None,
                        GL.GL_DYNAMIC_DRAW if dynamic else GL.GL_STATIC_DRAW)
        GL.glBindBuffer(GL.GL_TEXTURE_BUFFER, 0)
        self.texture = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_BUFFER, self.texture)
        GL.glTexBuffer(GL.GL_TEXTURE_BUFFER, texel_format, self.buffer)
        GL.glBindTexture(GL.GL_TEXTURE_BUFFER, 0)

    def write(self, data: np.ndarray) -> None:
        """Replace the first rows with ``data`` (same texel layout)."""
        data = np.ascontiguousarray(data)
        GL.glBindBuffer(GL.GL_TEXTURE_BUFFER, self.buffer)
        GL.glBufferSubData(GL.GL_TEXTURE_BUFFER, 0, data.nbytes, data)
        GL.glBindBuffer(GL.GL_TEXTURE_BUFFER, 0)

    def bind(self, unit: int) -> int:
        """Bind to texture ``unit``; returns the unit (for the sampler uniform)."""
        GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
        GL.glBindTexture(GL.GL_TEXTURE_BUFFER, self.texture)
        return unit

    def release(self) -> None:
        GL.glDeleteTextures(1, [self.texture])
        GL.glDeleteBuffers(1, [self.buffer])


def cut_out_corners(vertices: np.ndarray, faces: np.ndarray, face_mask: np.ndarray,
                    face_texcoords: np.ndarray):
    """The indexed mesh with the alpha-tested faces' corners given their own vertices where
    their texture coordinates differ (a texture seam), and each vertex's ``(u, v, mask)``
    (mask -1: opaque): ``(vertices, faces, cutout)``. Face order, and so ``gl_PrimitiveID``,
    is kept; opaque faces keep their shared vertices."""
    tested = np.flatnonzero(face_mask >= 0)
    uv = np.ascontiguousarray(face_texcoords[tested], np.float32)
    corners = np.column_stack([faces[tested].reshape(-1).astype(np.int64),
                               uv.reshape(-1, 2).view(np.int32).astype(np.int64),
                               np.repeat(face_mask[tested], 3).astype(np.int64)])
    keys, first, inverse = np.unique(corners, axis=0, return_index=True, return_inverse=True)
    cutout = np.zeros((len(vertices) + len(keys), 3), np.float32)
    cutout[:, 2] = -1.0
    cutout[len(vertices):, :2] = uv.reshape(-1, 2)[first]
    cutout[len(vertices):, 2] = keys[:, 3]
    faces = faces.copy()
    faces[tested] = (len(vertices) + inverse.reshape(-1)).reshape(-1, 3)
    return np.concatenate([vertices, vertices[keys[:, 0]]]), faces, cutout


class SceneMesh:
    """The scene as engines draw it: shared vertices (position, loc 0) drawn by index
    (glDrawElements), so each vertex is shaded once however many triangles share it. What is
    flat per face (normal, albedo) is a buffer texture of RGBA32F (xyz normal, w albedo) that
    a fragment shader reads at ``gl_PrimitiveID``, the face's index in the draw (the
    G-buffer's), bound by :meth:`bind_face_attributes`.

    A scene with alpha-tested casters passes ``cutouts`` = (face_mask, face_texcoords) of
    :class:`harness.scene.BuiltScene`: each vertex then also has ``(u, v, mask)`` at location
    1 (:func:`cut_out_corners`), which a shader built with ``ALPHA_TEST`` reads; a scene
    without has no such attribute, so its draws fetch nothing more."""

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, normals: np.ndarray,
                 albedo: np.ndarray, cutouts: tuple[np.ndarray, np.ndarray] | None = None):
        cutout = None
        if cutouts is not None:
            vertices, faces, cutout = cut_out_corners(vertices, faces, *cutouts)
        self.vertex_count, self.index_count = len(vertices), faces.size
        self.vao = GL.glGenVertexArrays(1)
        self.vbo, self.ebo = GL.glGenBuffers(2)
        GL.glBindVertexArray(self.vao)
        GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.vbo)
        positions = np.ascontiguousarray(vertices, dtype=np.float32)
        GL.glBufferData(GL.GL_ARRAY_BUFFER, max(positions.nbytes, 4),
                        positions if len(positions) else None, GL.GL_STATIC_DRAW)
        GL.glEnableVertexAttribArray(0)
        GL.glVertexAttribPointer(0, 3, GL.GL_FLOAT, GL.GL_FALSE, 12, ctypes.c_void_p(0))
        self.cutout_vbo = None
        if cutout is not None:
            self.cutout_vbo = GL.glGenBuffers(1)
            GL.glBindBuffer(GL.GL_ARRAY_BUFFER, self.cutout_vbo)
            GL.glBufferData(GL.GL_ARRAY_BUFFER, cutout.nbytes, cutout, GL.GL_STATIC_DRAW)
            GL.glEnableVertexAttribArray(1)
            GL.glVertexAttribPointer(1, 3, GL.GL_FLOAT, GL.GL_FALSE, 12, ctypes.c_void_p(0))
        GL.glBindBuffer(GL.GL_ELEMENT_ARRAY_BUFFER, self.ebo)  # recorded in the VAO
        indices = np.ascontiguousarray(faces, dtype=np.uint32)
        GL.glBufferData(GL.GL_ELEMENT_ARRAY_BUFFER, max(indices.nbytes, 4),
                        indices if indices.size else None, GL.GL_STATIC_DRAW)
        GL.glBindVertexArray(0)
        self.face_attributes = BufferTexture(
            np.column_stack([normals, albedo]).astype(np.float32), GL.GL_RGBA32F)

    def bind_face_attributes(self, unit: int) -> int:
        """Bind the per-face buffer texture to texture ``unit``; returns the unit (for a
        ``samplerBuffer`` uniform)."""
        return self.face_attributes.bind(unit)

    def draw(self) -> None:
        if self.index_count == 0:
            return
        GL.glBindVertexArray(self.vao)
        GL.glDrawElements(GL.GL_TRIANGLES, self.index_count, GL.GL_UNSIGNED_INT, None)
        GL.glBindVertexArray(0)

    def release(self) -> None:
        self.face_attributes.release()
        GL.glDeleteBuffers(2, [self.vbo, self.ebo])
        if self.cutout_vbo is not None:
            GL.glDeleteBuffers(1, [self.cutout_vbo])
        GL.glDeleteVertexArrays(1, [self.vao])


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
