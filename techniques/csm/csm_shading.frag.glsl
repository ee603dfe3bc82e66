// Cascaded shadow maps: each pixel takes the first cascade whose slice of view depth holds it
// (no blending, so the shadow stays hard) and makes Williams' test in that cascade's map, with
// the bias rule of shadow_map.glsl in that map's own texels.
#define MAP_PER_PIXEL 1
#define MAX_CASCADES 4
uniform sampler2D cascade_maps[MAX_CASCADES];
uniform mat4 cascade_views[MAX_CASCADES];
uniform mat4 cascade_projs[MAX_CASCADES];
uniform float cascade_ends[MAX_CASCADES];  // the far view depth of each cascade's slice
uniform int cascades;
uniform float cascade_res;
uniform mat4 camera_view;

mat4 light_view;
mat4 light_proj;
float map_res;
int cascade;

// sampler arrays take constant indices only (GLSL 4.30 allows dynamically uniform ones; a
// pixel's cascade is not)
float map_depth(ivec2 cell) {
    switch (cascade) {
        case 0: return texelFetch(cascade_maps[0], cell, 0).r;
        case 1: return texelFetch(cascade_maps[1], cell, 0).r;
        case 2: return texelFetch(cascade_maps[2], cell, 0).r;
        default: return texelFetch(cascade_maps[3], cell, 0).r;
    }
}

#include "gbuffer_read.glsl"
#include "../common/shadow_map.glsl"

uniform float bias;
layout(location = 0) out float visibility;

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    float depth = -(camera_view * vec4(p, 1.0)).z;
    cascade = cascades - 1;
    for (int i = cascades - 2; i >= 0; --i) {
        if (depth <= cascade_ends[i]) cascade = i;
    }
    light_view = cascade_views[cascade];
    light_proj = cascade_projs[cascade];
    map_res = cascade_res;
    Receiver r = receiver(p, n);
    visibility = r.in_front ? receiver_test(r, r.texel, bias) : 1.0;
}
