"""``pcf``: percentage-closer filtering (Reeves, Salesin, Cook 1987). ``pcf.py`` holds the
parameters and the technique; ``pcf_shading.frag.glsl`` runs the shared sample loop
(``techniques/common/pcf_samples.glsl``) with a 0/1 test per sample.
"""

from .pcf import PercentageCloserFiltering

__all__ = ["PercentageCloserFiltering"]
