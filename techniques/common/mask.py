"""The mask-to-V pass that sv and rt share (``mask_visibility.frag.glsl``)."""

from __future__ import annotations

from harness.gl.shaders import Program
from harness.technique import Technique


def mask_visibility_program(divisor: int) -> Program:
    """The pass for a mask of one texel per ``divisor`` x ``divisor`` pixels: magnifying
    (MAGNIFY) only a mask smaller than the image, compiled apart since llvmpipe would run the
    magnification's four taps for a full mask too."""
    return Technique.shader(__file__, "fullscreen.vert.glsl", "mask_visibility.frag.glsl",
                            **({"MAGNIFY": 1} if divisor > 1 else {}))
