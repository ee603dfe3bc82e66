"""rt: ray-traced hard shadows, one any-hit shadow ray per G-buffer pixel through a two-level BVH.

Start at ``rt.py`` (the technique and its parameters); ``bvh.py`` builds one level (LBVH, SAH),
``levels.py`` the two levels in buffer textures, ``rt_trace.comp.glsl`` traverses them,
``embree.py`` traces the same rays with Mitsuba on the CPU, ``counters.py`` counts their work.
"""

from .rt import RayTraced

__all__ = ["RayTraced"]
