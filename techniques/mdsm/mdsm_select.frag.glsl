// MDSM selection pass: for each cell of the base map, N_DEPTHS depths chosen from the WINDOW x
// WINDOW samples around it, the cell's own depth always among them, stored in descending order
// (the paper's Z_1 >= ... >= Z_n). Window offsets run from -(WINDOW - 1) / 2 (integer division)
// so odd windows are centred; coordinates clamp to the map edge, so a cell always reads q samples.
// SELECT_SORT 0: min/max (EXTRA_MAX for n = 2: the maximum, else the minimum; n = 3: both).
// SELECT_SORT 1: the samples sorted and split into N_DEPTHS near-equal groups, each represented
// by its lower median, the base depth replacing its own group's representative.
uniform sampler2D base_map;
layout(location = 0) out vec4 depths;

const int Q = WINDOW * WINDOW;

void main() {
    ivec2 cell = ivec2(gl_FragCoord.xy);
    ivec2 last = textureSize(base_map, 0) - 1;
    float base = texelFetch(base_map, cell, 0).r;
    float samples[Q];
    for (int j = 0; j < WINDOW; ++j) {
        for (int i = 0; i < WINDOW; ++i) {
            ivec2 t = clamp(cell + ivec2(i, j) - (WINDOW - 1) / 2, ivec2(0), last);
            samples[j * WINDOW + i] = texelFetch(base_map, t, 0).r;
        }
    }
    depths = vec4(base);
#if SELECT_SORT == 0
    float lo = samples[0], hi = samples[0];
    for (int s = 1; s < Q; ++s) {
        lo = min(lo, samples[s]);
        hi = max(hi, samples[s]);
    }
#if N_DEPTHS == 2 && EXTRA_MAX
    depths.xy = vec2(hi, base);
#elif N_DEPTHS == 2
    depths.xy = vec2(base, lo);
#elif N_DEPTHS == 3
    depths.xyz = vec3(hi, base, lo);
#endif
#else
    // insertion sort, descending
    for (int s = 1; s < Q; ++s) {
        float v = samples[s];
        int t = s - 1;
        while (t >= 0 && samples[t] < v) {
            samples[t + 1] = samples[t];
            --t;
        }
        samples[t + 1] = v;
    }
    // the base depth's first position in the descending order
    int rank = 0;
    for (int s = 0; s < Q; ++s) {
        rank += samples[s] > base ? 1 : 0;
    }
    for (int g = 0; g < N_DEPTHS; ++g) {
        int first = g * Q / N_DEPTHS, end = (g + 1) * Q / N_DEPTHS;
        depths[g] = rank >= first && rank < end ? base : samples[(first + end - 1) / 2];
    }
#endif
}
