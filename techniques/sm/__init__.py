"""``sm``: Williams' shadow map, the baseline. ``sm.py`` is the technique, ``sm_shading.frag.glsl``
its one shading pass; the map itself is ``techniques.common``'s. The smallest technique here:
the template for a new one.
"""

from .sm import ShadowMap

__all__ = ["ShadowMap"]
