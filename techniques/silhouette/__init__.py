"""``silhouette``: shadow silhouette maps (Sen, Cammarano, Hanrahan 2003). ``silhouette.py`` is the
technique; ``silhouette_edges.py`` builds the edge mesh once and finds silhouette edges on the GPU
each frame (its NumPy path is the tests' oracle); the shaders are named after their pass.
"""

from .silhouette import SilhouetteMap

__all__ = ["SilhouetteMap"]
