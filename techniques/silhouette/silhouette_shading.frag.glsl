// Shadow determination with a silhouette map (Sen et al. 2003, sections 2 and 3.2). The depth
// map is offset half a texel, so its samples sit at the corners of silhouette-map texels. If
// the four corner depth tests agree, that is V. Otherwise the lines from this texel's
// silhouette point to its four neighbours' points split the texel into four skewed quadrants
// (Figure 5); eight line tests against the rays to the neighbours and to the corners place
// the shaded point in one of eight pie-shaped regions, hence in a quadrant, and V is that
// quadrant's corner test. With COUNT_PIXELS defined (the untimed repeat of the pass), atomic
// counters count shaded pixels and those that took the silhouette path (P in the paper's Table 1).
#include "gbuffer_read.glsl"
#include "../common/shadow_map.glsl"

uniform sampler2D silhouette_map;
uniform float bias;
#ifdef COUNT_PIXELS
layout(binding = 0, offset = 0) uniform atomic_uint shaded_pixels;
layout(binding = 0, offset = 4) uniform atomic_uint silhouette_pixels;
#define COUNT(counter) atomicCounterIncrement(counter)
#else
#define COUNT(counter)
#endif
layout(location = 0) out float visibility;

// Texel-local point; texels outside the map hold the default, the centre.
vec2 silhouette_point(ivec2 t) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(int(map_res))))) return vec2(0.5);
    return texelFetch(silhouette_map, t, 0).rg;
}

// Counter-clockwise around the texel: right neighbour, corner (1,1), top, corner (0,1), left,
// corner (0,0), bottom, corner (1,0). Pie k lies between ray k and ray k + 1.
const vec2 RAY_NOMINAL[8] = vec2[8](vec2(1, 0), vec2(1, 1), vec2(0, 1), vec2(-1, 1),
                                    vec2(-1, 0), vec2(-1, -1), vec2(0, -1), vec2(1, -1));
const int PIE_CORNER[8] = int[8](3, 3, 2, 2, 0, 0, 1, 1);  // corners 0:(0,0) 1:(1,0) 2:(0,1) 3:(1,1)

int skewed_quadrant(ivec2 cell, vec2 local) {
    vec2 p = silhouette_point(cell);
    vec2 ends[8] = vec2[8](
        silhouette_point(cell + ivec2(1, 0)) + vec2(1, 0), vec2(1, 1),
        silhouette_point(cell + ivec2(0, 1)) + vec2(0, 1), vec2(0, 1),
        silhouette_point(cell - ivec2(1, 0)) - vec2(1, 0), vec2(0, 0),
        silhouette_point(cell - ivec2(0, 1)) - vec2(0, 1), vec2(1, 0));
    vec2 o = local - p;
    float side[8];
    for (int k = 0; k < 8; ++k) {
        vec2 ray = ends[k] - p;
        // a point clamped onto a corner, or a neighbour's point on ours: keep the ray's order
        if (dot(ray, ray) < 1e-12) ray = RAY_NOMINAL[k];
        side[k] = ray.x * o.y - ray.y * o.x;   // > 0: o is counter-clockwise of the ray
    }
    for (int k = 0; k < 8; ++k) {
        if (side[k] >= 0.0 && side[(k + 1) & 7] < 0.0) return PIE_CORNER[k];
    }
    // o at the silhouette point itself: the nearest corner, as a shadow map would
    return int(local.x >= 0.5) + 2 * int(local.y >= 0.5);
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    COUNT(shaded_pixels);
    Receiver r = receiver(p, n);
    if (!r.in_front) { visibility = 1.0; return; }
    vec2 u = r.texel - 0.5;   // silhouette-map coordinates
    vec2 cell = floor(u);
    // the corner samples lie up to a texel from the point in each axis: each gets the slope
    // bias of its own distance (shadow_map.glsl)
    float corner[4] = float[4](receiver_test(r, cell + vec2(0.5, 0.5), bias),
                               receiver_test(r, cell + vec2(1.5, 0.5), bias),
                               receiver_test(r, cell + vec2(0.5, 1.5), bias),
                               receiver_test(r, cell + vec2(1.5, 1.5), bias));
    if (corner[0] == corner[1] && corner[0] == corner[2] && corner[0] == corner[3]) {
        visibility = corner[0];
        return;
    }
    COUNT(silhouette_pixels);
    visibility = corner[skewed_quadrant(ivec2(cell), u - cell)];
}
