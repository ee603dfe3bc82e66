"""Textures and framebuffers: float colour targets and a depth+stencil attachment."""

from __future__ import annotations

import functools

import numpy as np
from OpenGL import GL, images

# PyOpenGL 3.1.10 lacks the component count of two-channel reads (glReadPixels with GL_RG).
images.COMPONENT_COUNTS.setdefault(GL.GL_RG, 2)

# internal format -> (format, type, channels, bytes per texel)
FORMATS = {
    GL.GL_R32F: (GL.GL_RED, GL.GL_FLOAT, 1, 4),
    GL.GL_RG32F: (GL.GL_RG, GL.GL_FLOAT, 2, 8),
    GL.GL_RGBA32F: (GL.GL_RGBA, GL.GL_FLOAT, 4, 16),
    GL.GL_RGBA8: (GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, 4, 4),
    GL.GL_DEPTH24_STENCIL8: (GL.GL_DEPTH_STENCIL, GL.GL_UNSIGNED_INT_24_8, 1, 4),
    GL.GL_DEPTH_COMPONENT32F: (GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, 1, 4),
}


# llvmpipe clears a target with a plain store loop per tile (about 3 GB/s on the 2-core test
# machine), while a copy between textures is a memcpy: a 2048^2 R32F map with its depth took
# 10 ms of CPU to clear and 5 ms to copy from a cleared strip of rows. A hardware GPU clears
# almost for free and copies at memory speed, so there clears stay clears.
SOFTWARE_RENDERERS = ("llvmpipe", "softpipe", "swrast")
# rows of a strip hold at most this many bytes per attachment: small enough to stay in cache
CLEAR_STRIP_BYTES = 1 << 19


@functools.cache
def clears_by_copy() -> bool:
    """Whether :meth:`Framebuffer.clear` copies from a cleared strip (software renderers)."""
    renderer = GL.glGetString(GL.GL_RENDERER).decode().lower()
    return any(name in renderer for name in SOFTWARE_RENDERERS)


class Texture:
    def __init__(self, width: int, height: int, internal_format, *, linear: bool = False):
        self.width, self.height, self.internal_format = width, height, internal_format
        _, _, self.channels, self.texel_bytes = FORMATS[internal_format]
        self.id = GL.glGenTextures(1)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
        GL.glTexStorage2D(GL.GL_TEXTURE_2D, 1, internal_format, width, height)
        filt = GL.GL_LINEAR if linear else GL.GL_NEAREST
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MIN_FILTER, filt)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_MAG_FILTER, filt)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE)
        GL.glTexParameteri(GL.GL_TEXTURE_2D, GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)

    @property
    def nbytes(self) -> int:
        return self.width * self.height * self.texel_bytes

    def bind(self, unit: int) -> int:
        GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
        GL.glBindTexture(GL.GL_TEXTURE_2D, self.id)
        return unit

    def release(self) -> None:
        GL.glDeleteTextures([self.id])


class Framebuffer:
    """Colour textures (attachment order = ``colors``) and an optional depth+stencil texture."""

    def __init__(self, width: int, height: int, colors=(GL.GL_RGBA32F,), *,
                 depth: bool = True, linear: bool = False):
        self.width, self.height = width, height
        self.id = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        self.colors = [Texture(width, height, f, linear=linear) for f in colors]
        for i, tex in enumerate(self.colors):
            GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0 + i,
                                      GL.GL_TEXTURE_2D, tex.id, 0)
        self.depth = Texture(width, height, GL.GL_DEPTH24_STENCIL8) if depth else None
        self._strip: tuple[tuple, Framebuffer] | None = None  # (clear values, cleared strip)
        if self.depth:
            GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_DEPTH_STENCIL_ATTACHMENT,
                                      GL.GL_TEXTURE_2D, self.depth.id, 0)
        GL.glDrawBuffers(len(self.colors), [GL.GL_COLOR_ATTACHMENT0 + i
                                            for i in range(len(self.colors))])
        status = GL.glCheckFramebufferStatus(GL.GL_FRAMEBUFFER)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, 0)
        if status != GL.GL_FRAMEBUFFER_COMPLETE:
            self.release()
            raise RuntimeError(f"framebuffer {width}x{height} incomplete: status 0x{status:x}")

    @property
    def nbytes(self) -> int:
        return sum(t.nbytes for t in self.colors) + (self.depth.nbytes if self.depth else 0)

    def bind(self) -> "Framebuffer":
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        GL.glViewport(0, 0, self.width, self.height)
        return self

    def clear(self, *colors, depth: float = 1.0, stencil: int = 0) -> None:
        """Clear each colour attachment to the given RGBA (or scalar) and depth/stencil, every
        texel whatever the write masks, and bind the framebuffer. On a software renderer the
        values come from a strip of rows cleared once (:func:`clears_by_copy`)."""
        rgbas = [np.broadcast_to(np.asarray(v, np.float32), (4,)).copy() for v in colors]
        if not clears_by_copy():
            self._clear_attachments(rgbas, depth, stencil)
            return
        values = (tuple(tuple(v.tolist()) for v in rgbas), depth, stencil)
        if self._strip is None or self._strip[0] != values:
            self._release_strip()
            texel_bytes = max(t.texel_bytes for t in self.colors + [self.depth] if t)
            rows = max(1, min(self.height, CLEAR_STRIP_BYTES // (self.width * texel_bytes)))
            strip = Framebuffer(self.width, rows, [t.internal_format for t in self.colors],
                                depth=self.depth is not None)
            strip._clear_attachments(rgbas, depth, stencil)
            self._strip = values, strip
        strip = self._strip[1]
        pairs = list(zip(strip.colors, self.colors[:len(colors)]))
        pairs += [(strip.depth, self.depth)] if self.depth else []
        for y in range(0, self.height, strip.height):
            rows = min(strip.height, self.height - y)
            for source, target in pairs:
                GL.glCopyImageSubData(source.id, GL.GL_TEXTURE_2D, 0, 0, 0, 0,
                                      target.id, GL.GL_TEXTURE_2D, 0, 0, y, 0,
                                      self.width, rows, 1)
        self.bind()

    def _clear_attachments(self, rgbas: list[np.ndarray], depth: float, stencil: int) -> None:
        self.bind()
        GL.glColorMask(GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE, GL.GL_TRUE)
        for i, rgba in enumerate(rgbas):
            GL.glClearBufferfv(GL.GL_COLOR, i, rgba)
        if self.depth:
            GL.glDepthMask(GL.GL_TRUE)
            GL.glStencilMask(0xFF)
            GL.glClearBufferfi(GL.GL_DEPTH_STENCIL, 0, depth, stencil)

    def _release_strip(self) -> None:
        if self._strip is not None:
            self._strip[1].release()
            self._strip = None

    def read(self, attachment: int = 0) -> np.ndarray:
        """Attachment as float32 (H, W, C) or (H, W), row 0 at the top of the image."""
        tex = self.colors[attachment]
        fmt, typ, channels, _ = FORMATS[tex.internal_format]
        self.bind()
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0 + attachment)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        dtype = np.float32 if typ == GL.GL_FLOAT else np.uint8
        raw = GL.glReadPixels(0, 0, self.width, self.height, fmt, typ)
        a = np.frombuffer(raw, dtype=dtype) if isinstance(raw, bytes) else np.asarray(raw, dtype)
        a = a.reshape(self.height, self.width, channels)[::-1]
        a = a.astype(np.float32) / 255.0 if dtype == np.uint8 else a
        return np.ascontiguousarray(a[..., 0] if channels == 1 else a)

    def read_stencil(self) -> np.ndarray:
        self.bind()
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        raw = GL.glReadPixels(0, 0, self.width, self.height, GL.GL_STENCIL_INDEX,
                              GL.GL_UNSIGNED_BYTE)
        a = np.frombuffer(raw, np.uint8) if isinstance(raw, bytes) else np.asarray(raw, np.uint8)
        return np.ascontiguousarray(a.reshape(self.height, self.width)[::-1])

    def release(self) -> None:
        self._release_strip()
        for t in self.colors + ([self.depth] if self.depth else []):
            t.release()
        GL.glDeleteFramebuffers(1, [self.id])
