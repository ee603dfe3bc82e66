// One vertex of an edge's thin quad built on the CPU by edge_quads, all in silhouette-map texel
// coordinates: the tests' oracle for the quads silhouette_edges.geom.glsl builds.
layout(location = 0) in vec2 corner;
layout(location = 1) in vec2 endpoint_a;
layout(location = 2) in vec2 endpoint_b;
layout(location = 3) in vec2 endpoint_depths;
uniform float map_res;
flat out vec2 segment_a;
flat out vec2 segment_b;
flat out vec2 segment_depths;
void main() {
    segment_a = endpoint_a;
    segment_b = endpoint_b;
    segment_depths = endpoint_depths;
    gl_Position = vec4(corner / map_res * 2.0 - 1.0, 0.0, 1.0);
}
