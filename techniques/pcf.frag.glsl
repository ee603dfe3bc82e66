// Percentage-closer filtering (Reeves, Salesin, Cook 1987): compare first, then average.
// grid_n x grid_n samples, one per sub-region of side `spacing` texels, centred on the point;
// with jitter, each sample moves uniformly inside its sub-region. A bias is drawn per sample
// from [bias_min, bias_max] (the paper's Figure 4). grid_n = 1 without jitter is Williams' test.
#include "gbuffer_read.glsl"
#include "shadow_map.glsl"

uniform int grid_n;
uniform float spacing;
uniform float bias_min;
uniform float bias_max;
uniform bool jitter;
uniform uint seed;
layout(location = 0) out float visibility;

uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

float random01(uint pixel, uint sample_index, uint stream) {
    return float(pcg(pcg(pcg(pixel ^ seed) + sample_index) + stream)) / 4294967296.0;
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    LightSample s = to_light(p);
    if (!s.in_front) { visibility = 1.0; return; }
    float slope = slope_scaled_bias(n, p, s.depth);
    uint pixel = uint(gl_FragCoord.y) * 65536u + uint(gl_FragCoord.x);
    float lit = 0.0;
    for (int j = 0; j < grid_n; ++j) {
        for (int i = 0; i < grid_n; ++i) {
            uint index = uint(j * grid_n + i);
            vec2 offset = (vec2(i, j) + 0.5 - 0.5 * float(grid_n)) * spacing;
            if (jitter) {
                offset += (vec2(random01(pixel, index, 0u), random01(pixel, index, 1u)) - 0.5)
                          * spacing;
            }
            float bias = bias_min + (bias_max - bias_min) * random01(pixel, index, 2u);
            lit += depth_test(s.texel + offset, s.depth, bias + slope);
        }
    }
    visibility = lit / float(grid_n * grid_n);
}
