// The thin quad of one kept edge (Sen et al. 2003, section 3.1; edge_quads on the CPU): the
// segment widened perpendicular and lengthened at both ends by QUAD_HALF_WIDTH texels (a define
// from Python), each vertex carrying both endpoints and their depths for
// silhouette_map.frag.glsl. An edge seen end-on from the light projects to a point: any
// direction covers it.
layout(points) in;
layout(triangle_strip, max_vertices = 4) out;

in EdgeData {
    flat int kept;
    vec2 a;
    vec2 b;
    vec2 depths;
} edge[];

uniform float map_res;
flat out vec2 segment_a;
flat out vec2 segment_b;
flat out vec2 segment_depths;

void main() {
    if (edge[0].kept == 0) return;
    vec2 a = edge[0].a, b = edge[0].b;
    float span = length(b - a);
    vec2 along = span > 1e-9 ? (b - a) / span : vec2(1.0, 0.0);
    vec2 across = vec2(-along.y, along.x);
    float e = QUAD_HALF_WIDTH;
    vec2 corners[4] = vec2[4](a - e * along - e * across, b + e * along - e * across,
                              a - e * along + e * across, b + e * along + e * across);
    for (int k = 0; k < 4; ++k) {
        segment_a = a;
        segment_b = b;
        segment_depths = edge[0].depths;
        gl_Position = vec4(corners[k] / map_res * 2.0 - 1.0, 0.0, 1.0);
        EmitVertex();
    }
    EndPrimitive();
}
