// Linear light depth (view-space distance along the light axis, scene units): a bias in scene
// units then means the same thing for orthographic and perspective maps. Built with
// ALPHA_TEST (a scene with alpha-tested casters), a cut-out texel casts no depth.
in float light_depth;
layout(location = 0) out float out_depth;
#ifdef ALPHA_TEST
#include "alpha_test.glsl"
in vec2 uv;
flat in int mask;
#endif
void main() {
#ifdef ALPHA_TEST
    if (cut_out(mask, uv)) {
        discard;
    }
#endif
    out_depth = light_depth;
}
