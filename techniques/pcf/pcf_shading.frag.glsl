// Percentage-closer filtering (Reeves, Salesin, Cook 1987): compare first, then average.
// Each grid sample is Williams' binary test; grid_n = 1 without jitter is Williams' shadow map.
#include "../common/pcf_samples.glsl"

layout(location = 0) out float visibility;

float sample_test(vec2 texel, float depth, float bias, float window_bias) {
    return depth_test(texel, depth, bias);
}

void main() {
    visibility = filtered_visibility();
}
