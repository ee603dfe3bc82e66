// PCF(k, n) of multiple-depth shadow maps (Pagot, Comba, Oliveira): the percentage-closer grid
// of pcf, each sample an n-shadow test on one RGBA32F texel holding the cell's N_DEPTHS depths.
#include "pcf_samples.glsl"

layout(location = 0) out float visibility;

// The n-shadow test: the fraction of the cell's depths not closer to the light than the biased
// point, so n + 1 equally spaced outcomes; for n = 1 exactly depth_test().
float sample_test(vec2 texel, float depth, float bias) {
    ivec2 t;
    if (!map_cell(texel, t)) return 1.0;
    vec4 depths = texelFetch(shadow_map, t, 0);
    float lit = 0.0;
    for (int i = 0; i < N_DEPTHS; ++i) {
        lit += depth - bias - depth_precision > depths[i] ? 0.0 : 1.0;
    }
    return lit / float(N_DEPTHS);
}

void main() {
    visibility = filtered_visibility();
}
