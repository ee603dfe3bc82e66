// Lookups into a linear-depth shadow map made by light_depth.*.glsl.
uniform sampler2D shadow_map;
uniform mat4 light_view;
uniform mat4 light_proj;
uniform float map_res;
uniform bool light_is_ortho;
uniform float texel_world;   // world size of a texel (orthographic) or at unit depth (perspective)
uniform vec4 light_vector;   // w = 0: direction light travels; w = 1: light position
uniform float slope_bias;

struct LightSample {
    vec2 texel;      // continuous map coordinates, in texels
    float depth;     // light view-space distance
    bool in_front;   // false behind a perspective light
};

LightSample to_light(vec3 world) {
    vec4 v = light_view * vec4(world, 1.0);
    vec4 clip = light_proj * v;
    LightSample s;
    s.depth = -v.z;
    s.in_front = clip.w > 0.0;
    s.texel = (clip.xy / clip.w * 0.5 + 0.5) * map_res;
    return s;
}

vec3 direction_to_light(vec3 world) {
    return light_vector.w == 0.0 ? -light_vector.xyz : normalize(light_vector.xyz - world);
}

// The depth change across one texel on a surface tilted away from the light, times slope_bias.
float slope_scaled_bias(vec3 normal, vec3 world, float depth) {
    float c = clamp(abs(dot(normal, direction_to_light(world))), 1e-3, 1.0);
    float tan_theta = min(sqrt(1.0 - c * c) / c, 10.0);
    float texel = light_is_ortho ? texel_world : texel_world * depth;
    return slope_bias * texel * tan_theta;
}

// The map cell holding continuous map coordinates; false outside the map, where samples count
// as lit (Reeves et al.'s convention).
bool map_cell(vec2 texel, out ivec2 cell) {
    cell = ivec2(floor(texel));
    return all(greaterThanEqual(cell, ivec2(0))) && all(lessThan(cell, ivec2(int(map_res))));
}

// 1 = lit.
float depth_test(vec2 texel, float depth, float bias) {
    ivec2 t;
    if (!map_cell(texel, t)) return 1.0;
    return depth - bias > texelFetch(shadow_map, t, 0).r ? 0.0 : 1.0;
}
