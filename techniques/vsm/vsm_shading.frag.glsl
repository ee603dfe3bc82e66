// V through the page table: each pixel takes its level (choose_level, as marking did) and
// makes Williams' test (or, with PCF, pcf_samples.glsl's reads over the pixel's footprint,
// across page borders: every read goes through the table) on that level's virtual texels, with
// shadow_map.glsl's bias in that level's texels. A read of a page the pool does not hold counts as lit.
#define MAP_PER_PIXEL 1
#include "vsm_levels.glsl"

mat4 light_view;
mat4 light_proj;
float map_res;
int level;
uniform sampler2D pool;  // depth: the level's window depth of the nearest caster
uniform int pool_tiles;

// Light depth (view-space distance) from level k's window depth z: its projection inverted
// (orthographic: z is affine in the distance; perspective: a ratio).
float light_distance(int k, float z) {
    mat4 p = levels[k].proj;
    float ndc = 2.0 * z - 1.0;
    return p[3][3] == 1.0 ? (p[3][2] - ndc) / p[2][2] : p[3][2] / (ndc + p[2][2]);
}

float map_depth(ivec2 cell) {
    int index;
    ivec2 global;
    if (!page_entry(level, cell, index, global)) return EMPTY_DEPTH;
    Entry e = entries[index];
    if (e.slot < 0 || e.gx != global.x || e.gy != global.y) return EMPTY_DEPTH;
    ivec2 tile = ivec2(e.slot % pool_tiles, e.slot / pool_tiles);
    float z = texelFetch(pool, tile * page_size + cell % page_size, 0).r;
    return z >= 1.0 ? EMPTY_DEPTH : light_distance(level, z);
}

// included here, not in a branch: an include is expanded once, where it first appears
#include "gbuffer_read.glsl"
#include "../common/shadow_map.glsl"
#include "../common/receives_light.glsl"
#ifdef PCF
#include "../common/pcf_samples.glsl"
float sample_test(vec2 texel, float depth, float bias, float window_bias) {
    return depth_test(texel, depth, bias);
}
#endif

uniform float bias;
layout(location = 0) out float visibility;

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    // marking requested no page for a side the light does not reach (as rt, V = 0 there)
    if (!faces_light(p, visible_side(n, p, eye_position), light_vector)) {
        visibility = 0.0;
        return;
    }
    level = choose_level(p, n);
    light_view = levels[level].view;
    light_proj = levels[level].proj;
    map_res = levels[level].res.x;
#ifdef PCF
    visibility = filtered_visibility();
#else
    Receiver r = receiver(p, n);
    visibility = r.in_front ? receiver_test(r, r.texel, bias) : 1.0;
#endif
}
