"""Code shared by the map-based techniques, not a technique: the light depth map (directional,
spot, cube) and the passes that shade from it (``light_maps.py``), the depth lookup and bias
rule every map shares (``shadow_map.glsl``), cube-face selection and the PCF sample loop
(``pcf_samples.glsl``), and the mask-to-V pass of the mask techniques (``mask.py``). Start at
``light_maps.MapShading``.
"""
