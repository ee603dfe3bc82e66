// Williams' test alone: the receiver against the one map texel holding it, with the constant
// bias and the slope term of that texel (shadow_map.glsl). The same arithmetic as
// pcf_samples.glsl with one grid sample, no jitter and a single bias, without its loop and
// random numbers (tests/test_frame_speed.py holds them bit for bit equal): half the pass.
#include "gbuffer_read.glsl"
#include "../common/shadow_map.glsl"

uniform float bias;
layout(location = 0) out float visibility;

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    Receiver r = receiver(p, n);
    visibility = r.in_front ? receiver_test(r, r.texel, bias) : 1.0;
}
