"""``mdsm``: multiple-depth shadow maps and PCF(k, n) (Pagot, Comba, Oliveira). ``mdsm.py`` is the
technique; ``mdsm_select.frag.glsl`` picks the n depths of each cell, ``mdsm_shading.frag.glsl``
filters them with the shared PCF sample loop.
"""

from .mdsm import MultipleDepthShadowMap

__all__ = ["MultipleDepthShadowMap"]
