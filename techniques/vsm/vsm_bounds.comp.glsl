// The world box of each caster cluster: `cluster_triangles` consecutive triangles of the
// scene's index buffer (the last cluster holds the rest), read from the scene's own vertex
// and index buffers, so moved objects are boxed where they are now.
layout(local_size_x = 64) in;
layout(std430, binding = 6) readonly buffer Vertices { float xyz[]; };
layout(std430, binding = 7) readonly buffer Indices { uint corner[]; };
layout(std430, binding = 8) writeonly buffer Clusters { vec4 bounds[]; };  // low, high per cluster

uniform int clusters;
uniform int cluster_triangles;
uniform int triangles;

void main() {
    int c = int(gl_GlobalInvocationID.x);
    if (c >= clusters) return;
    vec3 low = vec3(3.0e38), high = vec3(-3.0e38);
    int last = min((c + 1) * cluster_triangles, triangles) * 3;
    for (int i = c * cluster_triangles * 3; i < last; ++i) {
        uint v = corner[i] * 3u;
        vec3 p = vec3(xyz[v], xyz[v + 1u], xyz[v + 2u]);
        low = min(low, p);
        high = max(high, p);
    }
    bounds[2 * c] = vec4(low, 0.0);
    bounds[2 * c + 1] = vec4(high, 0.0);
}
