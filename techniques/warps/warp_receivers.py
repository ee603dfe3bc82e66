"""The warps' visible receivers on the GPU: each question of :class:`warp_body.Receivers` is one
reduction over the frame's G-buffer (``warp_receivers.comp.glsl`` on ``harness.gl.reduction``),
32 bytes read back, instead of the covered pixels' positions in NumPy.

The shader computes in float32 what :class:`warp_body.ReceiverPoints` computes in float64 from
the same float32 positions, so a range agrees to float32 rounding of the quantity (a few 1e-7
of it), and a receiver within that rounding of a cube face may count on either side of it."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from harness.gl.reduction import CoveredRange
from harness.scene.transforms import LightFrustum

from .warp_body import Receivers

SHADER = Path(__file__).parent / "warp_receivers.comp.glsl"
# the uniforms of the quantities a question does not read
_IDENTITY = np.eye(4)
_ZERO = np.zeros(3)


class ReceiverReduction:
    """The compute program and its result buffer, made once per run (``release`` frees them)."""

    def __init__(self):
        self.reduction = CoveredRange(SHADER)

    def find(self, frame, spot: LightFrustum | None) -> Receivers:
        """The visible receivers of ``frame``: covered pixels inside ``spot`` (None: all)."""
        return FrameReceivers(self.reduction, frame, spot)

    def release(self) -> None:
        self.reduction.release()


@dataclass(frozen=True)
class FrameReceivers:
    reduction: CoveredRange
    frame: object  # harness.technique.Frame
    spot: LightFrustum | None

    def _reduce(self, *, camera_view=_IDENTITY, space_eye=_ZERO, space_forward=_ZERO,
                test_clip=_IDENTITY):
        gbuffer = self.frame.gbuffer
        spot_clip = _IDENTITY if self.spot is None else self.spot.view_proj
        found = self.reduction.reduce(
            gbuffer.position_texture, gbuffer.normal_texture, camera_view=camera_view,
            spot=self.spot is not None, spot_clip=spot_clip, space_eye=space_eye,
            space_forward=space_forward, test_clip=test_clip)
        return None if found.empty else found

    def depth_range(self, view):
        found = self._reduce(camera_view=view)
        return None if found is None else (float(found.low[0]), float(found.high[0]))

    def range_along(self, clip, eye, forward):
        # the quantity projects with spot_clip: ``clip`` is the spot light's clip space, the
        # frustum the receivers are filtered by (space_depth_range's only use)
        found = self._reduce(space_eye=eye, space_forward=forward)
        return None if found is None else (float(found.low[1]), float(found.high[1]))

    def any_outside(self, clip):
        found = self._reduce(test_clip=clip)
        return found is not None and bool(found.high[2] > 0 or found.high[3] >= 0)
