// Linear light depth (view-space distance along the light axis, scene units): a bias in scene
// units then means the same thing for orthographic and perspective maps. Built with
// ALPHA_TEST (a scene with alpha-tested casters), a cut-out texel casts no depth; with
// COUNT_ALPHA_TESTS too, each alpha test is counted (light_maps.py, untimed).
in float light_depth;
layout(location = 0) out float out_depth;
#include "cut_out_texel.glsl"
void main() {
    discard_cut_out();
    out_depth = light_depth;
}
