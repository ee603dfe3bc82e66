"""ptsv: per-triangle shadow volumes tested against a hierarchy of the view samples (Sintorn et al.
2011), in compute shaders: screen tiles (``hierarchy: tiles``) or clusters of a tile's samples
per depth slice (``hierarchy: clusters``, Sintorn et al. 2014; ``slices`` of them). Start at
``ptsv.py`` (the passes), then ``hierarchy.py`` (the buffers and dispatches) and
``ptsv_volume.glsl`` (the plane tests every kernel shares)."""

from .ptsv import PerTriangleShadowVolumes

__all__ = ["PerTriangleShadowVolumes"]
