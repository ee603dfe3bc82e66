// One invocation per caster (a scene triangle, or a planar convex quad of two: casters.py): its
// shadow volume's planes from the frame's light (its own plane and one through each side and
// the light; a triangle's fifth plane holds every point), then the root test. Edge-on casters
// cast no volume (as sv's per-triangle volumes), nor do a closed part's casters turned from the
// light; every other caster casts, turned toward the light (an open part's back-facing
// triangle shadows as much as a front-facing one). A volume the root box lies outside of, or
// whose footprint misses the screen, is culled; one that holds the root box marks the root;
// any other is queued, and its traversal starts where its footprint on the screen fits
// (footprint below): at the top level (with
// clusters, the root's children, one per depth slice of the footprint, are tested here and
// queued for the level below theirs), or, where at most 2 x 2 nodes of a lower level cover it,
// at those nodes, which ptsv_seed.comp.glsl tests (the levels above are skipped).
#include "ptsv_volume.glsl"
#include "ptsv_samples.glsl"

layout(local_size_x = 64) in;
// the scene mesh's vertices (xyz) and the casters' corners (4 indices, a triangle's fourth
// NO_CORNER), as buffer textures: one fetch a vertex or caster, where a storage buffer is read
// lane by lane on llvmpipe
uniform samplerBuffer vertex_texels;
uniform usamplerBuffer caster_texels;
// per caster: 0 in an open part; in a closed part 1 where its winding turns it outward, -1
// inward. A closed part's light-facing triangles shadow all that it does (a segment from a
// point outside it, or on it, to the light leaves it through one), so the others are culled.
layout(std430, binding = 8) readonly buffer Closed { int closed_side[]; };
// (position, 1) for a spot or point light, (-direction, 0) directional
uniform vec4 light_vector;
uniform uint first_caster;  // this batch's casters: first_caster .. caster_end - 1
uniform uint caster_end;
uniform uint root;  // the root's node number
uniform uint root_level;
uniform uint top_first;  // clusters: node number of the top level's first slice (the root's children)
uniform mat4 clip_from_scene;  // the camera's view-projection of positions relative to `origin`
uniform vec2 sample_scale;  // half the samples per row and column
uniform uvec2 sample_size;  // samples per row and column
// per queued volume: the level, nodes and slices its traversal starts at (footprint below)
layout(std430, binding = 10) writeonly buffer Starts { uvec4 starts[]; };


// The plane through the edge from p to q (p the end of smaller vertex index, so the two
// casters sharing the edge compute the same plane) and the light, turned so that `inner`
// lies on its negative side (an exact negation).
vec4 edge_plane(vec3 p, vec3 q, vec4 light, vec3 inner) {
    vec3 n = normalize(cross(q - p, light.xyz - p * light.w));
    vec4 plane = vec4(n, -dot(n, p));
    return dot(n, inner - p) > 0.0 ? -plane : plane;
}

// Where the volume can hold a view sample, all of which lie in the root box [lo, hi]: the part
// of the volume inside the box lies in the convex hull of the caster's corners p and the points
// p + t r(p), r(p) the light's ray through p (p - the light's position, or its direction), t
// the time at which the rays leave the first of the box's slabs that every corner's ray
// crosses the same way (taken over the corners: along one axis, a point's exit time is
// monotone in its coordinate). The hull's eight corners are projected to the screen and to view
// depth, and `start` set to (level, x range, y range, slice range), each range first | last <<
// 16: the lowest level at which at most 2 x 2 nodes cover the rectangle of samples they reach
// (widened by a sample each way, for rounding), those nodes, and the depth slices between the
// nearest and farthest corner (widened by 2^-12). False where the rectangle misses the screen:
// no sample is inside. `start` is left (the top level, every slice) where a corner lies behind
// the camera or no slab bounds the rays.
bool footprint(vec3 p[4], vec4 light, vec3 lo, vec3 hi, inout uvec4 start) {
    vec3 r[4];
    float t = 3.0e38;
    for (int k = 0; k < 4; ++k) r[k] = p[k] * light.w - light.xyz;
    for (int axis = 0; axis < 3; ++axis) {
        bool up = r[0][axis] > 0.0, down = r[0][axis] < 0.0;
        float slab = -3.0e38;
        for (int k = 0; k < 4; ++k) {
            up = up && r[k][axis] > 0.0;
            down = down && r[k][axis] < 0.0;
            float exit = (r[k][axis] > 0.0 ? hi[axis] : lo[axis]) - p[k][axis];
            slab = max(slab, exit / r[k][axis]);
        }
        if (up || down) t = min(t, slab);
    }
    if (t > 1.0e30) return true;
    t = max(t, 0.0) * (1.0 + 1.0 / 65536.0);
    vec2 low = vec2(3.0e38), high = vec2(-3.0e38);
    float near = 3.0e38, far = 0.0;
    for (int k = 0; k < 8; ++k) {
        vec3 q = p[k & 3] + (k < 4 ? 0.0 : t) * r[k & 3];
        vec4 clip = clip_from_scene * vec4(q, 1.0);
        float depth = dot(depth_plane.xyz, q) + depth_plane.w;
        if (clip.w <= 0.0 || depth <= 0.0) return true;
        vec2 xy = (clip.xy / clip.w + 1.0) * sample_scale;
        low = min(low, xy);
        high = max(high, xy);
        near = min(near, depth);
        far = max(far, depth);
    }
    vec2 size = vec2(sample_size);
    if (any(lessThan(high, vec2(-1.0))) || any(greaterThan(low, size + 1.0))) return false;
    uvec2 first = uvec2(clamp(floor(low) - 1.0, vec2(0.0), size - 1.0));
    uvec2 last = uvec2(clamp(floor(high) + 1.0, vec2(0.0), size - 1.0));
    uint level = 1u, bits = uint(findLSB(uint(TILE)));
    while (level < root_level
           && any(greaterThan((last >> level * bits) - (first >> level * bits), uvec2(1u)))) {
        ++level;
    }
    first >>= level * bits;
    last >>= level * bits;
    uint slice_first = slices > 1u ? slice_of_depth(near * (1.0 - 1.0 / 4096.0)) : 0u;
    uint slice_last = slices > 1u ? slice_of_depth(far * (1.0 + 1.0 / 4096.0)) : 0u;
    start = uvec4(level, first.x | last.x << 16, first.y | last.y << 16,
                  slice_first | slice_last << 16);
    return true;
}

void main() {
    uint caster = first_caster
        + (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u
        + gl_LocalInvocationIndex;
    if (caster >= caster_end) return;
    uvec4 index = texelFetch(caster_texels, int(caster));
    uint corners = index.w != NO_CORNER ? 4u : 3u;
    if (corners == 3u) index.w = index.x;  // fetched again, so the bounds below take 3 corners
    vec3 p[4] = vec3[4](texelFetch(vertex_texels, int(index.x)).xyz - origin,
                        texelFetch(vertex_texels, int(index.y)).xyz - origin,
                        texelFetch(vertex_texels, int(index.z)).xyz - origin,
                        texelFetch(vertex_texels, int(index.w)).xyz - origin);
    vec3 n = cross(p[1] - p[0], p[2] - p[0]);
    vec4 light = vec4(light_vector.xyz - origin * light_vector.w, light_vector.w);
    vec3 to_light = light.xyz - p[0] * light.w;
    float facing = dot(n, to_light);
    if (abs(facing) <= EDGE_ON * length(n) * length(to_light)
        || float(closed_side[caster]) * facing < 0.0) {
        TALLY_TRIANGLES(COUNT_CULLED, corners - 2u);
        return;
    }
    vec4 volume[VOLUME_ROWS];
    // the caster's plane: the light on its positive side, so the shadow is behind it
    vec3 toward = normalize(facing > 0.0 ? n : -n);
    volume[0] = vec4(toward, -dot(toward, p[0]));
    uint corner[4] = uint[4](index.x, index.y, index.z, index.w);
    for (uint k = 0u; k < 4u; ++k) {
        uint a = k % corners, b = (k + 1u) % corners;
        bool ordered = corner[a] < corner[b];
        volume[k + 1u] = k < corners
            ? edge_plane(p[ordered ? a : b], p[ordered ? b : a], light, p[(k + 2u) % corners])
            : vec4(0.0, 0.0, 0.0, -1.0);  // a triangle's: every point inside
    }
    // the cross-section bounds (ptsv_volume.glsl), widened for rounding: by `tie` across a
    // directional light, by 2^-20 of the largest coordinate (and of 1) after a projection
    vec4 u, v, depth = vec4(1.0);
    for (int k = 0; k < 4; ++k) {
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
    vec4 largest = max(abs(u), abs(v));
    widen += (1.0 + max(max(largest.x, largest.y), max(largest.z, largest.w)))
        * (1.0 / 1048576.0);
#endif
    volume[BOUNDS_ROW] = all(greaterThan(depth, vec4(0.0)))
        ? vec4(min(min(u.x, u.y), min(u.z, u.w)) - widen, max(max(u.x, u.y), max(u.z, u.w)) + widen,
               min(min(v.x, v.y), min(v.z, v.w)) - widen, max(max(v.x, v.y), max(v.z, v.w)) + widen)
        : vec4(1.0, -1.0, 1.0, -1.0);  // behind or beside the light along the axis: no bounds
    TALLY(COUNT_NODE_TESTS);
    vec3 lo, hi;
    node_box(root, lo, hi);
    int test = classify(volume, lo, hi);
    if (test > 0) {
        mark_node(root);
        TALLY(COUNT_ACCEPTS);
        TALLY(COUNT_ROOT_ACCEPTS);
        return;
    }
    uvec4 start = uvec4(root_level, 0u, 0u, (slices - 1u) << 16);
    if (test == 0 && !footprint(p, light, lo, hi, start)) test = -1;
    if (test < 0) {
        TALLY_TRIANGLES(COUNT_CULLED, corners - 2u);
        return;
    }
    uint queued = atomicAdd(counters[COUNT_VOLUMES], 1u);
    if (queued >= volume_capacity) return;  // counted: the caller makes room, runs again
    for (uint k = 0u; k < uint(VOLUME_ROWS); ++k) {
        planes[uint(VOLUME_ROWS) * queued + k] = volume[k];
    }
    starts[queued] = start;
    if (start.x < root_level) {  // seeded below the top (ptsv_seed.comp.glsl)
        TALLY(COUNT_SEEDED);
        atomicAdd(counters[COUNT_SEEDS + start.x], (start.w >> 16) - (start.w & 0xFFFFu) + 1u);
        return;
    }
    if (slices == 1u) {
        push(root_level, queued, 0u);
        return;
    }
    // clusters: the root's children, the top level's slices, here
    for (uint slice = start.w & 0xFFFFu; slice <= start.w >> 16; ++slice) {
        if (test_node(volume, top_first + slice) == 0) push(root_level, queued, slice);
    }
}
