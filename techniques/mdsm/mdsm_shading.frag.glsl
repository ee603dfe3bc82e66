// PCF(k, n) of multiple-depth shadow maps (Pagot, Comba, Oliveira): the percentage-closer grid
// of pcf, each sample an n-shadow test on one RGBA32F texel holding the cell's N_DEPTHS depths.
#include "../common/pcf_samples.glsl"

layout(location = 0) out float visibility;

// The n-shadow test: the fraction of the cell's depths not closer to the light than the biased
// point, so n + 1 equally spaced outcomes; for n = 1 exactly depth_test(). The cell's own depth
// (channel BASE_CHANNEL, -1 where no channel is fixed) takes `bias`, the texel's own reach; the
// depths chosen from the selection window take `window_bias`, the window's farthest texel.
float sample_test(vec2 texel, float depth, float bias, float window_bias) {
    ivec2 t;
    if (!map_cell(texel, t)) return 1.0;
    vec4 depths = texelFetch(shadow_map, t, 0);
    float lit = 0.0;
    for (int i = 0; i < N_DEPTHS; ++i) {
        float b = i == BASE_CHANNEL ? bias : window_bias;
        lit += depth - b - depth_precision > depths[i] ? 0.0 : 1.0;
    }
    return lit / float(N_DEPTHS);
}

void main() {
    visibility = filtered_visibility();
}
