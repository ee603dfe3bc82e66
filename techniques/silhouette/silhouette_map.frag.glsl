// Picks the silhouette point of one texel (Sen et al. 2003, section 3.1 and Figure 4): an
// endpoint inside the texel, else the segment's intersection with the texel's diagonals (the
// midpoint when it crosses both); no intersection kills the fragment. Coordinates are local
// to the texel, origin at its bottom-left corner. The square is enlarged by CORNER_SNAP so a
// line through a corner is stored, clamped, in all four texels around it (4-connectedness).
// The depth map samples the texel's corners; a point farther than all four is hidden and
// not stored.
#include "../common/shadow_map.glsl"

const float CORNER_SNAP = 0.01;

flat in vec2 segment_a;
flat in vec2 segment_b;
flat in vec2 segment_depths;
uniform float bias;
uniform bool center_points;  // the paper's degenerate case: every point at the texel centre
layout(location = 0) out vec2 silhouette_point;

bool in_square(vec2 p) {
    return all(greaterThanEqual(p, vec2(-CORNER_SNAP))) && all(lessThanEqual(p, vec2(1.0 + CORNER_SNAP)));
}

// Segment parameter of the hit with the line {p : dot(normal, p) = offset}, or -1 if none
// lies on the segment and inside the (enlarged) square.
float diagonal_hit(vec2 a, vec2 b, vec2 normal, float offset) {
    float denominator = dot(normal, b - a);
    if (abs(denominator) < 1e-12) return -1.0;
    float t = (offset - dot(normal, a)) / denominator;
    return t >= 0.0 && t <= 1.0 && in_square(mix(a, b, t)) ? t : -1.0;
}

float corner_depth(ivec2 t) {
    if (any(lessThan(t, ivec2(0))) || any(greaterThanEqual(t, ivec2(int(map_res))))) return 3.0e38;
    return texelFetch(shadow_map, t, 0).r;
}

void main() {
    ivec2 texel = ivec2(floor(gl_FragCoord.xy));
    vec2 a = segment_a - vec2(texel);
    vec2 b = segment_b - vec2(texel);
    float t;
    if (in_square(a)) {
        t = 0.0;
    } else if (in_square(b)) {
        t = 1.0;
    } else {
        float rising = diagonal_hit(a, b, vec2(1.0, -1.0), 0.0);   // x = y
        float falling = diagonal_hit(a, b, vec2(1.0, 1.0), 1.0);   // x + y = 1
        if (rising < 0.0 && falling < 0.0) discard;
        t = rising < 0.0 ? falling : falling < 0.0 ? rising : 0.5 * (rising + falling);
    }
    // light depth is linear along the segment in map space for an orthographic map; for a
    // perspective map its reciprocal is
    float depth = light_is_ortho ? mix(segment_depths.x, segment_depths.y, t)
                                 : 1.0 / mix(1.0 / segment_depths.x, 1.0 / segment_depths.y, t);
    // the depth map is offset half a texel: its texel (i, j) samples this texel's corner (i, j)
    float farthest_corner = max(max(corner_depth(texel), corner_depth(texel + ivec2(1, 0))),
                                max(corner_depth(texel + ivec2(0, 1)), corner_depth(texel + ivec2(1, 1))));
    if (depth - bias > farthest_corner) discard;
    silhouette_point = center_points ? vec2(0.5) : clamp(mix(a, b, t), 0.0, 1.0);
}
