// Lookup of a perspective-warped directional shadow map (psm, lispsm, gmnpr): k x k texel-grid
// PCF around the point, with a constant bias plus a slope bias scaled by the world size of a
// texel *at this point* (a warped texel is small near the viewer and large far away, so the
// single texel_world of an unwarped map does not apply).
#include "gbuffer_read.glsl"
#include "shadow_map.glsl"

uniform int grid_n;
uniform float bias;
layout(location = 0) out float visibility;

// Largest world extent of one texel across the light: 1 / sigma_min of d(texel)/d(world),
// whose rows are perpendicular to the light because a texel is one light ray.
float texel_world_at(vec3 world) {
    mat4 m = light_proj * light_view;
    vec4 c = m * vec4(world, 1.0);
    vec3 row_x = vec3(m[0].x, m[1].x, m[2].x);
    vec3 row_y = vec3(m[0].y, m[1].y, m[2].y);
    vec3 row_w = vec3(m[0].w, m[1].w, m[2].w);
    vec3 gx = (row_x - c.x / c.w * row_w) * (0.5 * map_res / c.w);
    vec3 gy = (row_y - c.y / c.w * row_w) * (0.5 * map_res / c.w);
    float a = dot(gx, gx), b = dot(gx, gy), d = dot(gy, gy);
    float smallest = 0.5 * (a + d) - sqrt(max(0.25 * (a - d) * (a - d) + b * b, 0.0));
    return inversesqrt(max(smallest, 1e-30));
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    LightSample s = to_light(p);
    if (!s.in_front) { visibility = 1.0; return; }
    // slope_scaled_bias runs with a unit orthographic texel, scaled here by the local one
    float total_bias = bias + slope_scaled_bias(n, p, s.depth) * texel_world_at(p);
    float lit = 0.0;
    for (int j = 0; j < grid_n; ++j) {
        for (int i = 0; i < grid_n; ++i) {
            vec2 offset = vec2(i, j) + 0.5 - 0.5 * float(grid_n);
            lit += depth_test(s.texel + offset, s.depth, total_bias);
        }
    }
    visibility = lit / float(grid_n * grid_n);
}
