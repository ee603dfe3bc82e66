// Page marking: every G-buffer pixel whose visible side faces the light requests the page of
// its level holding its texel, and, where a filter reads around it (reach texels each way),
// the pages its reads fall in. The texel is the shading pass's: receiver() of
// shadow_map.glsl on the point's level (its normal offset included).
#define MAP_PER_PIXEL 1
layout(local_size_x = 8, local_size_y = 8) in;
#include "vsm_levels.glsl"

mat4 light_view;
mat4 light_proj;
float map_res;
float map_depth(ivec2 cell) { return 0.0; }  // marking reads no depth

#include "../common/shadow_map.glsl"
#include "../common/receives_light.glsl"

uniform sampler2D gbuffer_position;
uniform sampler2D gbuffer_normal;
uniform float reach;

layout(std430, binding = 2) buffer Requests { uint requests[]; };

void request(int k, vec2 texel) {
    int index;
    ivec2 global;
    if (page_entry(k, ivec2(floor(texel)), index, global)) requests[index] = 1u;
}

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, textureSize(gbuffer_position, 0)))) return;
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    if (p.w < 0.5) return;
    vec3 n = texelFetch(gbuffer_normal, pixel, 0).xyz;
    if (!faces_light(p.xyz, visible_side(n, p.xyz, eye_position), light_vector)) return;
    int k = choose_level(p.xyz, n);
    light_view = levels[k].view;
    light_proj = levels[k].proj;
    map_res = levels[k].res.x;
    Receiver r = receiver(p.xyz, n);
    if (!r.in_front) return;
    request(k, r.texel + vec2(-reach, -reach));
    if (reach > 0.0) {
        request(k, r.texel + vec2(reach, -reach));
        request(k, r.texel + vec2(-reach, reach));
        request(k, r.texel + vec2(reach, reach));
    }
}
