"""Virtual shadow maps (issue 49)."""

from .vsm import VirtualShadowMap

__all__ = ["VirtualShadowMap"]
