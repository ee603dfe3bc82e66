// One invocation per scene triangle: its shadow volume's four planes from the frame's light,
// then the root test. Edge-on triangles cast no volume (as sv's per-triangle volumes), nor do a
// closed part's triangles turned from the light; every other triangle casts, turned toward the
// light (an open part's back-facing triangle shadows as much as a front-facing one). A volume
// the root box lies outside of is culled; one that holds the root box marks the root; any
// other is queued for the level below the root (with clusters, the root's children, one per
// depth slice, are tested here and queued for the level below theirs).
#include "ptsv_volume.glsl"

layout(local_size_x = 64) in;
// the scene mesh's vertex (xyz) and index (3 per triangle) buffers, as buffer textures: one
// fetch a vertex or triangle, where a storage buffer is read lane by lane on llvmpipe
uniform samplerBuffer vertex_texels;
uniform usamplerBuffer index_texels;
// per triangle: 0 in an open part; in a closed part 1 where its winding turns it outward, -1
// inward. A closed part's light-facing triangles shadow all that it does (a segment from a
// point outside it, or on it, to the light leaves it through one), so the others are culled.
layout(std430, binding = 8) readonly buffer Closed { int closed_side[]; };
// (position, 1) for a spot or point light, (-direction, 0) directional
uniform vec4 light_vector;
uniform uint first_triangle;  // this batch's triangles: first_triangle .. triangle_end - 1
uniform uint triangle_end;
uniform uint root;  // the root's node number
uniform uint root_level;
uniform uint top_first;  // clusters: node number of the top level's first slice (the root's children)


// The plane through the edge from p to q (p the end of smaller vertex index, so the two
// triangles sharing the edge compute the same plane) and the light, turned so that `inner`
// lies on its negative side (an exact negation).
vec4 edge_plane(vec3 p, vec3 q, vec4 light, vec3 inner) {
    vec3 n = normalize(cross(q - p, light.xyz - p * light.w));
    vec4 plane = vec4(n, -dot(n, p));
    return dot(n, inner - p) > 0.0 ? -plane : plane;
}

void main() {
    uint triangle = first_triangle
        + (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u
        + gl_LocalInvocationIndex;
    if (triangle >= triangle_end) return;
    uvec3 index = texelFetch(index_texels, int(triangle)).xyz;
    vec3 p[3] = vec3[3](texelFetch(vertex_texels, int(index.x)).xyz - origin,
                        texelFetch(vertex_texels, int(index.y)).xyz - origin,
                        texelFetch(vertex_texels, int(index.z)).xyz - origin);
    vec3 n = cross(p[1] - p[0], p[2] - p[0]);
    vec4 light = vec4(light_vector.xyz - origin * light_vector.w, light_vector.w);
    vec3 to_light = light.xyz - p[0] * light.w;
    float facing = dot(n, to_light);
    if (abs(facing) <= EDGE_ON * length(n) * length(to_light)
        || float(closed_side[triangle]) * facing < 0.0) {
        TALLY(COUNT_CULLED);
        return;
    }
    vec4 volume[VOLUME_ROWS];
    // the triangle's plane: the light on its positive side, so the shadow is behind it
    vec3 toward = normalize(facing > 0.0 ? n : -n);
    volume[0] = vec4(toward, -dot(toward, p[0]));
    for (int k = 0; k < 3; ++k) {
        int a = k, b = (k + 1) % 3;
        bool ordered = index[a] < index[b];
        volume[k + 1] = edge_plane(p[ordered ? a : b], p[ordered ? b : a], light, p[(k + 2) % 3]);
    }
    // the cross-section bounds (ptsv_volume.glsl), widened for rounding: by `tie` across a
    // directional light, by 2^-20 of the largest coordinate (and of 1) after a projection
    vec3 u, v, depth = vec3(1.0);
    for (int k = 0; k < 3; ++k) {
#ifdef POSITIONAL_LIGHT
        vec3 d = p[k] - light_point;
        depth[k] = dot(light_axis, d);
#else
        vec3 d = p[k];
#endif
        u[k] = dot(light_u, d) / depth[k];
        v[k] = dot(light_v, d) / depth[k];
    }
    float widen = tie;
#ifdef POSITIONAL_LIGHT
    widen += (1.0 + max(max(max(abs(u.x), abs(u.y)), abs(u.z)),
                        max(max(abs(v.x), abs(v.y)), abs(v.z)))) * (1.0 / 1048576.0);
#endif
    volume[4] = all(greaterThan(depth, vec3(0.0)))
        ? vec4(min(min(u.x, u.y), u.z) - widen, max(max(u.x, u.y), u.z) + widen,
               min(min(v.x, v.y), v.z) - widen, max(max(v.x, v.y), v.z) + widen)
        : vec4(1.0, -1.0, 1.0, -1.0);  // behind or beside the light along the axis: no bounds
    TALLY(COUNT_NODE_TESTS);
    vec3 lo, hi;
    node_box(root, lo, hi);
    int test = classify(volume, lo, hi);
    if (test < 0) {
        TALLY(COUNT_CULLED);
    } else if (test > 0) {
        mark_node(root);
        TALLY(COUNT_ACCEPTS);
        TALLY(COUNT_ROOT_ACCEPTS);
    } else {
        uint queued = atomicAdd(counters[COUNT_VOLUMES], 1u);
        if (queued >= volume_capacity) return;  // counted: the caller makes room, runs again
        for (uint k = 0u; k < uint(VOLUME_ROWS); ++k) {
            planes[uint(VOLUME_ROWS) * queued + k] = volume[k];
        }
        if (slices == 1u) {
            push(root_level, queued, 0u);
            return;
        }
        for (uint slice = 0u; slice < slices; ++slice) {  // clusters: the root's children here
            node_box(top_first + slice, lo, hi);
            if (any(greaterThan(lo, hi))) continue;
            TALLY(COUNT_NODE_TESTS);
            test = classify(volume, lo, hi);
            if (test > 0) {
                mark_node(top_first + slice);
                TALLY(COUNT_ACCEPTS);
            } else if (test == 0) {
                push(root_level, queued, slice);
            }
        }
    }
}
