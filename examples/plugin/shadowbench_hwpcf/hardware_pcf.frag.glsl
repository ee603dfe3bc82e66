// One texture() on a sampler2DShadow with GL_LINEAR filtering: the texture unit compares the
// receiver's window depth with the 4 texels around it and blends the 4 outcomes bilinearly
// (2x2 percentage-closer filtering in one fetch instruction).
//
// No depth slope is computed: the point moves off its surface along the normal by
// normal_offset texels (world size of one map texel at its light depth) before it is projected.
// The 4 texel centres read lie within sqrt(2) texels of the point, across which its plane's
// depth changes by at most sqrt(2) texels x tan(angle to the light); a point k above the plane
// is k / cos(angle) nearer the light than it, so k >= sqrt(2) texels x sin(angle) keeps the
// plane lit at every angle: 1.5 texels covers them all. `bias`, in scene units toward the
// light, covers the depth buffer's rounding.
#include "gbuffer_read.glsl"

uniform sampler2DShadow shadow_map;
uniform mat4 light_view;
uniform mat4 light_proj;
uniform bool light_is_ortho;
uniform vec3 light_direction;  // the way light travels (directional)
uniform vec3 light_position;   // spot
uniform float map_res;
uniform float normal_offset;
uniform float bias;

layout(location = 0) out float visibility;

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    float light_depth = -(light_view * vec4(p, 1.0)).z;
    float texel_size = 2.0 * (light_is_ortho ? 1.0 : light_depth) / (light_proj[0][0] * map_res);
    vec3 toward_light = light_is_ortho ? -light_direction : normalize(light_position - p);
    vec3 moved = p + normalize(n) * normal_offset * texel_size + toward_light * bias;
    vec4 clip = light_proj * light_view * vec4(moved, 1.0);
    vec3 window = clip.xyz / clip.w * 0.5 + 0.5;
    // behind the light or outside the map: lit (Reeves et al.'s convention)
    bool in_map = clip.w > 0.0 && all(greaterThanEqual(window.xy, vec2(0.0)))
                  && all(lessThanEqual(window.xy, vec2(1.0)));
    visibility = in_map ? texture(shadow_map, window) : 1.0;
}
