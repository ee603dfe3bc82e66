// A light depth pass's fragment on a scene with alpha-tested casters (ALPHA_TEST): its
// vertex shader passes each corner's texture coordinates (uv) and cut-out (mask, -1: opaque);
// discard_cut_out() drops a cut-out texel by alpha_test.glsl's rule, so it writes no depth.
// With COUNT_ALPHA_TESTS each alpha test is counted (atomic counter binding 0, untimed
// repeats only). Without ALPHA_TEST it does nothing.
#ifdef ALPHA_TEST
#include "alpha_test.glsl"
in vec2 uv;
flat in int mask;
#endif
#ifdef COUNT_ALPHA_TESTS
layout(binding = 0, offset = 0) uniform atomic_uint alpha_tests;
#endif

void discard_cut_out() {
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
}
