// The percentage-closer sample grid (Reeves, Salesin, Cook 1987), shared by every technique that
// filters a shadow test over a grid of map samples. grid_n x grid_n samples, one per sub-region
// of side `spacing` texels, centred on the point; with jitter, each sample moves uniformly inside
// its sub-region. A bias is drawn per sample from [bias_min, bias_max] (the paper's Figure 4).
// The including shader defines sample_test(): the per-sample outcome in [0, 1], 1 = lit.
#include "gbuffer_read.glsl"
#include "shadow_map.glsl"

uniform int grid_n;
uniform float spacing;
uniform float bias_min;
uniform float bias_max;
uniform bool jitter;
uniform uint seed;

float sample_test(vec2 texel, float depth, float bias);

uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

float random01(uint pixel, uint sample_index, uint stream) {
    return float(pcg(pcg(pcg(pixel ^ seed) + sample_index) + stream)) / 4294967296.0;
}

// V of this fragment's G-buffer pixel: the mean of sample_test over the grid.
float filtered_visibility() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) return 1.0;
    LightSample s = to_light(p);
    if (!s.in_front) return 1.0;
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
            lit += sample_test(s.texel + offset, s.depth, bias + slope);
        }
    }
    return lit / float(grid_n * grid_n);
}
