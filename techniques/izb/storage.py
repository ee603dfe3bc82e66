"""The irregular z-buffer's GL storage: shader storage buffers, integer images, the raster
target without attachments."""

from __future__ import annotations

import numpy as np
from OpenGL import GL


class StorageBuffer:
    """A shader storage buffer of ``nbytes``."""

    def __init__(self, nbytes: int):
        self.nbytes = max(int(nbytes), 16)
        self.id = GL.glGenBuffers(1)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        GL.glBufferData(GL.GL_SHADER_STORAGE_BUFFER, self.nbytes, None, GL.GL_DYNAMIC_COPY)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def bind(self, binding: int) -> None:
        GL.glBindBufferBase(GL.GL_SHADER_STORAGE_BUFFER, binding, self.id)

    def write(self, data: np.ndarray) -> None:
        data = np.ascontiguousarray(data)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        GL.glBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, data.nbytes, data)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)

    def read(self, dtype, count: int) -> np.ndarray:
        GL.glMemoryBarrier(GL.GL_BUFFER_UPDATE_BARRIER_BIT)
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, self.id)
        nbytes = count * np.dtype(dtype).itemsize
        out = np.asarray(GL.glGetBufferSubData(GL.GL_SHADER_STORAGE_BUFFER, 0, nbytes))
        GL.glBindBuffer(GL.GL_SHADER_STORAGE_BUFFER, 0)
        return out.view(dtype)[:count].copy()

    def release(self) -> None:
        GL.glDeleteBuffers(1, [self.id])


class IntegerImage:
    """A ``size`` x ``size`` R32UI texture for image load, store and atomics."""

    def __init__(self, size: int):
        self.size = size
        self.id = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
        GL.glTexStorage2D(GL.GL_TEXTURE_2D, 1, GL.GL_R32UI, size, size)
        for which in (GL.GL_TEXTURE_MIN_FILTER, GL.GL_TEXTURE_MAG_FILTER):  # integer: nearest
            GL.glTexParameteri(GL.GL_TEXTURE_2D, which, GL.GL_NEAREST)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)

    @property
    def nbytes(self) -> int:
        return 4 * self.size * self.size

    def fill(self, value: int) -> None:
        GL.glClearTexImage(self.id, 0, GL.GL_RED_INTEGER, GL.GL_UNSIGNED_INT,
                           np.array([value], np.uint32))

    def bind(self, unit: int) -> None:
        GL.glBindImageTexture(unit, self.id, 0, GL.GL_FALSE, 0, GL.GL_READ_WRITE, GL.GL_R32UI)

    def read(self) -> np.ndarray:
        GL.glMemoryBarrier(GL.GL_TEXTURE_UPDATE_BARRIER_BIT)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
        out = np.empty((self.size, self.size), np.uint32)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        GL.glGetTexImage(GL.GL_TEXTURE_2D, 0, GL.GL_RED_INTEGER, GL.GL_UNSIGNED_INT, out)
        GL.glBindTexture(GL.GL_TEXTURE_2D, 0)
        return out

    def release(self) -> None:
        GL.glDeleteTextures([self.id])


class EmptyTarget:
    """A framebuffer with no attachments, ``size`` x ``size``: the grid the casters are
    rasterised into (their fragments write only storage)."""

    def __init__(self, size: int):
        self.size = size
        self.id = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        GL.glFramebufferParameteri(GL.GL_FRAMEBUFFER, GL.GL_FRAMEBUFFER_DEFAULT_WIDTH, size)
        GL.glFramebufferParameteri(GL.GL_FRAMEBUFFER, GL.GL_FRAMEBUFFER_DEFAULT_HEIGHT, size)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)

    def bind(self) -> None:
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        GL.glViewport(0, 0, self.size, self.size)

    def release(self) -> None:
        GL.glDeleteFramebuffers(1, [self.id])
