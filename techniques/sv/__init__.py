"""``sv``: shadow volumes counted in the stencil, alpha or screen buffer (Crow 1977; Roettger et
al.). Start at ``sv.py`` (the passes and buffers); the volume geometry is ``sv_volumes.py`` (cleaned
parts), ``sv_gpu.py`` (extruded on the GPU each frame: ``sv_edge``, ``sv_cap``, ``sv_polygon``
shaders) and ``sv_cpu.py`` (the near-plane clip polygons and the tests' CPU path).
"""

from .sv import ShadowVolumes

__all__ = ["ShadowVolumes"]
