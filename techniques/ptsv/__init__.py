"""ptsv: per-triangle shadow volumes tested against a hierarchy of the view samples (Sintorn et al.
2011), in compute shaders. Start at ``ptsv.py`` (the passes), then ``hierarchy.py`` (the
buffers and dispatches) and ``ptsv_volume.glsl`` (the plane tests every kernel shares)."""

from .ptsv import PerTriangleShadowVolumes

__all__ = ["PerTriangleShadowVolumes"]
