// Linear light depth (view-space distance along the light axis, scene units): a bias in scene
// units then means the same thing for orthographic and perspective maps. Built with
// ALPHA_TEST (a scene with alpha-tested casters), a cut-out texel casts no depth; with
// COUNT_ALPHA_TESTS too, each alpha test is counted (light_maps.py, untimed).
in float light_depth;
layout(location = 0) out float out_depth;
#ifdef ALPHA_TEST
#include "alpha_test.glsl"
in vec2 uv;
flat in int mask;
#endif
#ifdef COUNT_ALPHA_TESTS
layout(binding = 0, offset = 0) uniform atomic_uint alpha_tests;
#endif
void main() {
#ifdef ALPHA_TEST
#ifdef COUNT_ALPHA_TESTS
    if (mask >= 0) {
        atomicCounterIncrement(alpha_tests);
    }
#endif
    if (cut_out(mask, uv)) {
        discard;
    }
#endif
    out_depth = light_depth;
}
