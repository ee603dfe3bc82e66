"""Config's alpha textures, above limits and yaml_source: the ``alpha`` key of an object (a PNG
file's alpha, or a procedural pattern the harness writes) and the check that a texture file
can be used: a regular file, a PNG, 8 bits a channel, at least 1x1 and at most
``MAX_TEXTURE_SIDE`` on a side (read from its header before any pixel is decoded).

Which channel: the alpha channel of an image that has one (LA, RGBA, a palette with
transparency), else the first channel (grey, or red of an RGB image). The texture is kept as
stored, first row at the top (harness/scene/alpha.py's uv convention)."""

from __future__ import annotations

import struct
from pathlib import Path
from typing import Literal, Union

import numpy as np
from pydantic import Field, model_validator

from .field_types import Strict
from .yaml_source import check_regular_file

MAX_TEXTURE_SIDE = 8192
PNG_SIGNATURE = b"\x89PNG\r\n\x1a\n"
# PIL's modes of 8 bits a channel (P: 8-bit palette indices)
EIGHT_BIT_MODES = ("L", "LA", "RGB", "RGBA", "P", "PA")
PATTERNS = ("checker", "bars", "leaf", "disc")


class Alpha(Strict):
    """A cut-out: the surface is there where the texture's alpha at the point's texture
    coordinates is at least ``cutoff``. Either ``texture`` (a PNG, relative to the scene file)
    or ``pattern`` (written by the harness, ``texels`` wide and high: one number or [width,
    height])."""

    texture: str | None = Field(None, min_length=1)
    pattern: Literal["checker", "bars", "leaf", "disc"] | None = None
    texels: Union[int, tuple[int, int]] = 64
    cutoff: float = Field(0.5, ge=0, le=1)

    @model_validator(mode="after")
    def _one_source(self):
        if (self.texture is None) == (self.pattern is None):
            raise ValueError("give either texture: (a PNG file) or pattern: (one of "
                             f"{', '.join(PATTERNS)})")
        if self.texture is not None and "texels" in self.model_fields_set:
            raise ValueError("texels: only a pattern takes texels (a texture file has its own "
                             "size)")
        if not all(1 <= n <= MAX_TEXTURE_SIDE for n in self.size):
            raise ValueError(f"texels: each must be in [1, {MAX_TEXTURE_SIDE}], got "
                             f"{self.texels}")
        return self

    @property
    def size(self) -> tuple[int, int]:
        """A pattern's (width, height) in texels."""
        return (self.texels, self.texels) if isinstance(self.texels, int) else self.texels


def resolve_texture_path(scene_path: Path, texture: str) -> Path:
    p = Path(texture)
    return p if p.is_absolute() else Path(scene_path).parent / p


def check_png_header(head: bytes, name: str) -> None:
    """A ValueError unless ``head`` (a file's first 26 bytes or more) starts a PNG of at least
    1x1 and at most MAX_TEXTURE_SIDE a side, 8 bits a channel: read from its IHDR chunk, so
    a huge image is refused before any of it is decoded."""
    if not head:
        raise ValueError(f"{name}: empty file (0 bytes), not a PNG")
    if not head.startswith(PNG_SIGNATURE):
        raise ValueError(f"{name}: not a PNG (its first bytes are not the PNG signature)")
    if len(head) < len(PNG_SIGNATURE) + 18 or head[12:16] != b"IHDR":
        raise ValueError(f"{name}: not a PNG that can be read (no IHDR chunk first)")
    width, height, depth = struct.unpack(">IIB", head[16:25])
    if min(width, height) < 1:
        raise ValueError(f"{name}: {width}x{height} texels, zero-sized")
    if max(width, height) > MAX_TEXTURE_SIDE:
        raise ValueError(f"{name}: {width}x{height} texels, over the limit of "
                         f"{MAX_TEXTURE_SIDE}x{MAX_TEXTURE_SIDE}")
    if depth != 8:
        raise ValueError(f"{name}: {depth} bits a channel; an alpha texture has 8")


def read_alpha_texture(path: Path) -> np.ndarray:
    """The alpha (or grey) channel of the PNG at ``path``, (H, W) uint8, first row at the top;
    a ValueError (an OSError for an unreadable file) saying what is wrong."""
    from PIL import Image, UnidentifiedImageError

    check_regular_file(path)
    with open(path, "rb") as f:
        head = f.read(len(PNG_SIGNATURE) + 18)
        check_png_header(head, str(path))
        f.seek(0)
        try:
            image = Image.open(f, formats=["PNG"])
            if image.mode not in EIGHT_BIT_MODES:
                raise ValueError(f"{path}: a PNG of mode {image.mode}; an alpha texture has 8 "
                                 "bits a channel (grey, grey+alpha, RGB, RGBA or a palette)")
            if image.mode in ("P", "PA"):
                image = image.convert("RGBA")
            bands = image.getbands()
            channel = image.getchannel("A" if "A" in bands else bands[0])
            return np.asarray(channel, dtype=np.uint8).copy()
        except (UnidentifiedImageError, SyntaxError, EOFError, Image.DecompressionBombError) \
                as e:
            raise ValueError(f"{path}: not a PNG that can be read ({e})") from None
        except OSError as e:  # a truncated or corrupt PNG
            raise ValueError(f"{path}: not a PNG that can be read ({e})") from None
