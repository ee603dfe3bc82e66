"""Textures and framebuffers: float colour targets and a depth+stencil attachment."""

from __future__ import annotations

import numpy as np
from OpenGL import GL
from OpenGL.raw.GL.VERSION.GL_1_0 import glReadPixels as read_pixels_into

# internal format -> (format, type, channels, bytes per texel)
FORMATS = {
    GL.GL_R32F: (GL.GL_RED, GL.GL_FLOAT, 1, 4),
    GL.GL_RG32F: (GL.GL_RG, GL.GL_FLOAT, 2, 8),
    GL.GL_RGBA32F: (GL.GL_RGBA, GL.GL_FLOAT, 4, 16),
    GL.GL_RGBA8: (GL.GL_RGBA, GL.GL_UNSIGNED_BYTE, 4, 4),
    GL.GL_DEPTH24_STENCIL8: (GL.GL_DEPTH_STENCIL, GL.GL_UNSIGNED_INT_24_8, 1, 4),
    GL.GL_DEPTH_COMPONENT32F: (GL.GL_DEPTH_COMPONENT, GL.GL_FLOAT, 1, 4),
}


class Texture:
    """A 2D texture, or with ``layers`` > 1 a 2D array texture of that many layers."""

    def __init__(self, width: int, height: int, internal_format, *, linear: bool = False,
                 layers: int = 1):
        self.width, self.height, self.internal_format = width, height, internal_format
        self.layers = layers
        _, _, self.channels, self.texel_bytes = FORMATS[internal_format]
        self.target = GL.GL_TEXTURE_2D_ARRAY if layers > 1 else GL.GL_TEXTURE_2D
        self.id = GL.glGenTextures(1)
        GL.glBindTexture(self.target, self.id)
        if layers > 1:
            GL.glTexStorage3D(self.target, 1, internal_format, width, height, layers)
        else:
            GL.glTexStorage2D(self.target, 1, internal_format, width, height)
        filt = GL.GL_LINEAR if linear else GL.GL_NEAREST
        GL.glTexParameteri(self.target, GL.GL_TEXTURE_MIN_FILTER, filt)
        GL.glTexParameteri(self.target, GL.GL_TEXTURE_MAG_FILTER, filt)
        GL.glTexParameteri(self.target, GL.GL_TEXTURE_WRAP_S, GL.GL_CLAMP_TO_EDGE)
        GL.glTexParameteri(self.target, GL.GL_TEXTURE_WRAP_T, GL.GL_CLAMP_TO_EDGE)

    @property
    def nbytes(self) -> int:
        return self.width * self.height * self.texel_bytes * self.layers

    # glClearTexImage rather than a framebuffer clear: llvmpipe clears a render target with a
    # store loop per tile (about 3 GB/s on the 2-core test machine) and a texture near memset
    # speed; a 2048^2 R32F map with its depth took 11 ms of CPU the first way, 4 ms this way.
    def clear(self, value, layer: int | None = None) -> None:
        """Set every texel of a colour texture (of one ``layer`` of an array) to ``value``,
        RGBA or a scalar for all four."""
        rgba = np.broadcast_to(np.asarray(value, np.float32), (4,)).copy()
        if layer is None:
            GL.glClearTexImage(self.id, 0, GL.GL_RGBA, GL.GL_FLOAT, rgba)
        else:
            GL.glClearTexSubImage(self.id, 0, 0, 0, layer, self.width, self.height, 1,
                                  GL.GL_RGBA, GL.GL_FLOAT, rgba)

    def clear_depth_stencil(self, stencil: int) -> None:
        """Set every texel of a depth+stencil texture to the far plane (depth 1) and
        ``stencil``. Depth 1 only: other depths round here otherwise than in a framebuffer
        clear."""
        texel = np.array([np.float32(1.0).view(np.uint32), stencil], np.uint32)
        GL.glClearTexImage(self.id, 0, GL.GL_DEPTH_STENCIL,
                           GL.GL_FLOAT_32_UNSIGNED_INT_24_8_REV, texel)

    def bind(self, unit: int) -> int:
        GL.glActiveTexture(GL.GL_TEXTURE0 + unit)
        GL.glBindTexture(self.target, self.id)
        return unit

    def release(self) -> None:
        GL.glDeleteTextures([self.id])


class Framebuffer:
    """Colour textures (attachment order = ``colors``) and an optional depth+stencil texture.
    With ``layers`` > 1 the colour textures are arrays, drawn one layer at a time
    (:meth:`attach_layer`) over the one depth+stencil texture."""

    def __init__(self, width: int, height: int, colors=(GL.GL_RGBA32F,), *,
                 depth: bool = True, linear: bool = False, layers: int = 1):
        self.width, self.height = width, height
        self.id = GL.glGenFramebuffers(1)
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        self.colors = [Texture(width, height, f, linear=linear, layers=layers) for f in colors]
        self._attach_colors(0)
        self.depth = Texture(width, height, GL.GL_DEPTH24_STENCIL8) if depth else None
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

    def _attach_colors(self, layer: int) -> None:
        for i, tex in enumerate(self.colors):
            if tex.layers > 1:
                GL.glFramebufferTextureLayer(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0 + i,
                                             tex.id, 0, layer)
            else:
                GL.glFramebufferTexture2D(GL.GL_FRAMEBUFFER, GL.GL_COLOR_ATTACHMENT0 + i,
                                          GL.GL_TEXTURE_2D, tex.id, 0)

    def attach_layer(self, layer: int) -> "Framebuffer":
        """Bind the framebuffer drawing into ``layer`` of its colour arrays."""
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        self._attach_colors(layer)
        return self.bind()

    @property
    def nbytes(self) -> int:
        return sum(t.nbytes for t in self.colors) + (self.depth.nbytes if self.depth else 0)

    def bind(self) -> "Framebuffer":
        GL.glBindFramebuffer(GL.GL_FRAMEBUFFER, self.id)
        GL.glViewport(0, 0, self.width, self.height)
        return self

    def clear(self, *colors, stencil: int = 0) -> None:
        """Clear each colour attachment to the given RGBA (or scalar), depth to the far plane
        (1) and stencil, every texel whatever the write masks and scissor; then bind the
        framebuffer with depth and stencil writes on."""
        for texture, value in zip(self.colors, colors):
            texture.clear(value)
        self.bind()
        if self.depth:
            self.depth.clear_depth_stencil(stencil)
            GL.glDepthMask(GL.GL_TRUE)
            GL.glStencilMask(0xFF)

    def read(self, attachment: int = 0) -> np.ndarray:
        """Attachment as float32 (H, W, C) or (H, W), row 0 at the top of the image."""
        tex = self.colors[attachment]
        fmt, typ, channels, _ = FORMATS[tex.internal_format]
        self.bind()
        GL.glReadBuffer(GL.GL_COLOR_ATTACHMENT0 + attachment)
        a = self._read_pixels(fmt, typ, np.float32 if typ == GL.GL_FLOAT else np.uint8,
                              channels)
        a = a.astype(np.float32) / 255.0 if a.dtype == np.uint8 else a
        return np.ascontiguousarray(a[..., 0] if channels == 1 else a)

    def _read_pixels(self, fmt, typ, dtype, channels: int) -> np.ndarray:
        """(H, W, channels) of the bound read buffer, row 0 at the top (a view)."""
        pixels = np.empty((self.height, self.width, channels), dtype)
        GL.glPixelStorei(GL.GL_PACK_ALIGNMENT, 1)
        # PyOpenGL's own glReadPixels wrapper costs 1.7 ms of a 0.1 ms read of 512^2 floats
        read_pixels_into(0, 0, self.width, self.height, fmt, typ, pixels)
        return pixels[::-1]

    def release(self) -> None:
        for t in self.colors + ([self.depth] if self.depth else []):
            t.release()
        GL.glDeleteFramebuffers(1, [self.id])
