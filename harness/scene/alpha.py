"""Alpha-tested casters: a surface is opaque where its texture's alpha at the point's texture
coordinates reaches the cutoff.

One sampling rule on every side (this module, the GLSL in harness/gl/glsl/alpha_test.glsl, the
reference's ray loop): bilinear at mip level 0, wrapping by repeat, texel centres at
half-integers. Texture coordinates follow glTF: (0, 0) is the top-left corner of the image as
stored (its first row), u grows to the right, v downward; readers of formats whose v grows
upward (OBJ, PLY) flip it on load.
"""

from __future__ import annotations

import hashlib
from dataclasses import dataclass
from functools import cached_property

import numpy as np


@dataclass(frozen=True, eq=False)
class AlphaMask:
    """An object's cut-out: ``texture`` (H, W) uint8, the alpha (or grey) channel as stored,
    first row at the top; ``cutoff`` in [0, 1]; ``source`` says where it came from (a file's
    path, or the procedural pattern) for messages."""

    texture: np.ndarray
    cutoff: float
    source: str

    def __post_init__(self):
        t = self.texture
        if t.ndim != 2 or t.dtype != np.uint8 or min(t.shape) < 1:
            raise ValueError(f"{self.source}: an alpha texture is (H, W) uint8, got "
                             f"{t.dtype} {t.shape}")
        if not 0.0 <= self.cutoff <= 1.0:
            raise ValueError(f"{self.source}: cutoff {self.cutoff} outside [0, 1]")

    @cached_property
    def digest(self) -> str:
        """Hash of the texture's bytes, its shape and the cutoff (a reference's cache key)."""
        h = hashlib.sha256(np.ascontiguousarray(self.texture).tobytes())
        h.update(repr((self.texture.shape, float(self.cutoff))).encode())
        return h.hexdigest()[:16]

    def alpha(self, uv: np.ndarray) -> np.ndarray:
        """The texture's alpha in [0, 1] at texture coordinates ``uv`` (..., 2), by the rule."""
        return sample_alpha(self.texture, uv)

    def opaque(self, uv: np.ndarray) -> np.ndarray:
        """Whether the surface is there (alpha >= cutoff) at ``uv`` (..., 2): bool (...)."""
        return self.alpha(uv) >= self.cutoff


def sample_alpha(texture: np.ndarray, uv: np.ndarray) -> np.ndarray:
    """Bilinear sample of ``texture`` (H, W) uint8 at ``uv`` (..., 2), in float64, mip level 0,
    repeat wrap, texel (i, j) centred at ((j + 0.5) / W, (i + 0.5) / H)."""
    uv = np.asarray(uv, dtype=np.float64)
    if uv.shape[-1:] != (2,):
        raise ValueError(f"uv must have shape (..., 2), got {uv.shape}")
    h, w = texture.shape
    x = uv[..., 0] * w - 0.5
    y = uv[..., 1] * h - 0.5
    x0, y0 = np.floor(x), np.floor(y)
    fx, fy = x - x0, y - y0
    c0, r0 = np.mod(x0, w).astype(np.int64), np.mod(y0, h).astype(np.int64)
    c1, r1 = (c0 + 1) % w, (r0 + 1) % h
    t = texture.astype(np.float64) / 255.0
    top = t[r0, c0] * (1 - fx) + t[r0, c1] * fx
    bottom = t[r1, c0] * (1 - fx) + t[r1, c1] * fx
    return top * (1 - fy) + bottom * fy
