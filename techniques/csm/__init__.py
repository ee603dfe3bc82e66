"""``csm``: cascaded (parallel-split) shadow maps with the sample-distribution fit. ``csm.py`` fits
the cascades per view and draws their maps; ``csm_bounds.comp.glsl`` reduces the visible depth
range, ``csm_shading.frag.glsl`` picks a cascade per pixel.
"""

from .csm import CascadedShadowMap

__all__ = ["CascadedShadowMap"]
