// Conservative rasterisation of a caster triangle into the irregular grid by geometry-shader
// expansion: the triangle becomes the quad of its bounding box in grid texels, grown by half
// a texel and MARGIN, so the centre of every texel the triangle touches lies inside the quad;
// izb_casters.frag.glsl then drops the texels the triangle does not touch (its three edges as
// separating axes). A triangle crossing a spot light's near plane is clipped to it first
// (points nearer than it are not gridded and cannot be shadowed through the rest); its box
// is then the clipped polygon's and the edge test is skipped (conservative). With ALPHA_TEST
// the corners' texture coordinates and the cut-out go with the triangle.
layout(triangles) in;
layout(triangle_strip, max_vertices = 4) out;

in vec3 world[];
flat out vec3 a, b, c;        // the triangle, world space (the exact test)
flat out vec2 ga, gb, gc;     // the triangle in grid texels
flat out int edge_test;       // 0: the box alone decides
#ifdef ALPHA_TEST
in vec3 corner_cutout[];
flat out vec2 ta, tb, tc;     // the corners' texture coordinates
flat out int mask;            // the cut-out's index, -1: opaque
#endif

#include "izb_grid.glsl"

void main() {
    vec2 low, scale;
    grid_rectangle(low, scale);
    if (isinf(low.x)) {
        return;  // no sample was gridded
    }
    vec4 clip[3];
    for (int i = 0; i < 3; ++i) {
        clip[i] = light_view_proj * vec4(world[i], 1.0);
    }
    // the polygon on the near side of w = min_w (Sutherland-Hodgman, one plane)
    vec2 lo = vec2(3.0e38), hi = vec2(-3.0e38);
    int kept = 0;
    for (int i = 0; i < 3; ++i) {
        vec4 p = clip[i], q = clip[(i + 1) % 3];
        bool p_in = p.w > min_w, q_in = q.w > min_w;
        if (p_in) {
            vec2 g = (p.xy / p.w - low) * scale;
            lo = min(lo, g);
            hi = max(hi, g);
            kept++;
        }
        if (p_in != q_in) {
            vec4 x = mix(p, q, (min_w - p.w) / (q.w - p.w));
            vec2 g = (x.xy / max(x.w, min_w) - low) * scale;
            lo = min(lo, g);
            hi = max(hi, g);
        }
    }
    if (kept == 0) {
        return;
    }
    float grow = 0.5 + MARGIN;
    lo = max(lo - grow, vec2(0.0));
    hi = min(hi + grow, vec2(float(grid_res)));
    if (any(greaterThanEqual(lo, hi))) {
        return;  // outside the grid
    }
    a = world[0];
    b = world[1];
    c = world[2];
    ga = (clip[0].xy / clip[0].w - low) * scale;
    gb = (clip[1].xy / clip[1].w - low) * scale;
    gc = (clip[2].xy / clip[2].w - low) * scale;
    edge_test = kept == 3 ? 1 : 0;
#ifdef ALPHA_TEST
    ta = corner_cutout[0].xy;
    tb = corner_cutout[1].xy;
    tc = corner_cutout[2].xy;
    mask = int(corner_cutout[0].z);
#endif
    vec2 to_ndc = 2.0 / vec2(float(grid_res));
    vec2 corners[4] = vec2[4](lo, vec2(hi.x, lo.y), vec2(lo.x, hi.y), hi);
    for (int i = 0; i < 4; ++i) {
        gl_Position = vec4(corners[i] * to_ndc - 1.0, 0.0, 1.0);
        EmitVertex();
    }
    EndPrimitive();
}
