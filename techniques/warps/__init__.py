"""``psm``, ``lispsm``, ``gmnpr``: perspective reparameterizations of one shadow map. Each technique
module (``psm.py``, ``lispsm.py``, ``gmnpr.py``) only chooses its warp; ``warped_map.py`` is the
technique they share (passes, diagnostics columns), ``warp_fit.py`` fits a warp, ``warp_body.py``
the bodies it is fitted to, ``warp_equations.py`` the papers' equations.
"""

from .gmnpr import GeneralizedMinimumNormWarp
from .lispsm import LightSpacePerspectiveShadowMap
from .psm import PerspectiveShadowMap

__all__ = ["GeneralizedMinimumNormWarp", "LightSpacePerspectiveShadowMap", "PerspectiveShadowMap"]
