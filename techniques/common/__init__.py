"""Code shared by the map-based techniques, not a technique: the light depth map (directional,
spot, cube) and the passes that shade from it (``light_maps.py``), the depth lookup and bias
rule every map shares (``shadow_map.glsl``), cube-face selection and the PCF sample loop
(``pcf_samples.glsl``), the mask-to-V pass of the mask techniques (``mask.py``), and whether a
sample's visible side faces the light, which rt and ptsv ask before they test it
(``receives_light.glsl``). Start at ``light_maps.MapShading``.
"""
