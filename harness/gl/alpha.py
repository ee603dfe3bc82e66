"""The scene's cut-outs on the GL side, read by ``glsl/alpha_test.glsl`` (the one GLSL copy of
the sampling rule of :mod:`harness.scene.alpha`): every mask's texels in one RGBA8UI buffer
texture, row by row, each with its right, lower and lower-right neighbours (repeat wrap: the
four texels a bilinear sample reads, in one fetch), and a table with one RGBA32UI texel per
mask (its first texel, width, height, the cutoff's float bits). Buffer textures and explicit
texel reads, rather than a texture array and the sampler's filtering, so fragment and compute
shaders read them the same way on every driver and masks of any size share one binding."""

from __future__ import annotations

import numpy as np
from OpenGL import GL

from .geometry import BufferTexture


def texel_quads(texture: np.ndarray) -> np.ndarray:
    """Each texel of ``texture`` (H, W) with its right, lower and lower-right neighbours,
    wrapping: (H * W, 4) uint8, row by row."""
    right = np.roll(texture, -1, axis=1)
    return np.stack([texture, right, np.roll(texture, -1, axis=0), np.roll(right, -1, axis=0)],
                    axis=-1).reshape(-1, 4)


class AlphaTextures:
    """``masks`` (a sequence of :class:`harness.scene.alpha.AlphaMask`) uploaded once."""

    def __init__(self, masks):
        sizes = np.array([m.texture.size for m in masks], np.int64)
        first = np.concatenate([[0], np.cumsum(sizes)[:-1]])
        table = np.zeros((len(masks), 4), np.uint32)
        table[:, 0] = first
        table[:, 1] = [m.texture.shape[1] for m in masks]
        table[:, 2] = [m.texture.shape[0] for m in masks]
        table[:, 3] = np.array([m.cutoff for m in masks], np.float32).view(np.uint32)
        self.texels = BufferTexture(np.concatenate([texel_quads(m.texture) for m in masks]),
                                    GL.GL_RGBA8UI)
        self.table = BufferTexture(table, GL.GL_RGBA32UI)
        self.nbytes = 4 * int(sizes.sum()) + table.nbytes

    def bind(self, program, first_unit: int) -> int:
        """Bind both buffers to ``program``'s samplers (it is in use); returns the next unit."""
        program.set(alpha_texels=self.texels.bind(first_unit),
                    alpha_table=self.table.bind(first_unit + 1))
        return first_unit + 2

    def release(self) -> None:
        self.texels.release()
        self.table.release()
