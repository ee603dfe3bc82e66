"""izb: the irregular z-buffer, frustum-traced raster shadows with sub-pixel samples.

Start at ``izb.py`` (the technique, its parameters and passes); ``patterns.py`` places the
sub-pixel samples, ``izb_samples.comp.glsl`` puts them on the pixels' planes,
``izb_lists.comp.glsl`` links them into the light-space grid, ``izb_casters.*.glsl``
rasterise the casters conservatively and test samples with ``izb_frustum.glsl``;
``storage.py`` holds the GL buffers.
"""

from .izb import IrregularZBuffer

__all__ = ["IrregularZBuffer"]
