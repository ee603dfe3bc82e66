// The hierarchy over the view samples, one level per dispatch: each node's box is the
// axis-aligned bounds (world space) of its TILE x TILE children, samples for level 1 (their
// G-buffer positions, covered ones only), nodes of the level below otherwise. A node without a
// covered sample gets an empty box (lo > hi), which every test skips. The box's fourth lane
// (lo.w) holds, as bits, which of its children are not empty (bit y * TILE + x; at level 1 the
// samples it bounds): the traversal visits only those (ptsv_traverse.comp.glsl). With clusters
// (`slices` > 1) a node is one depth slice of its tile: its box bounds that slice's samples or
// child nodes only. At level 1 one invocation takes a tile's every slice (each sample read
// once, its slice stored and its position added to its slice's box); above it, one invocation
// per node (its slice gl_GlobalInvocationID.z); a last dispatch (MERGE_SLICES) bounds the
// root over the top level's slices. Compiled once per kind of dispatch (SAMPLES: level 1,
// with CLUSTERS when `slices` > 1; MERGE_SLICES; neither: the levels above): llvmpipe runs
// every branch's code, so one program for all made each level pay for the others.
#include "ptsv_volume.glsl"
#include "ptsv_samples.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
uniform uvec2 node_size;  // nodes per row and column at this level
uniform uvec2 child_size;
uniform uint node_first;  // node number of this level's first node
uniform uint child_first;  // of the level below's (level > 1)

uint child_bit(uint x, uint y) {
    return 1u << (y * uint(TILE) + x);
}

void main() {
    uvec2 node = gl_GlobalInvocationID.xy;
    if (any(greaterThanEqual(node, node_size))) return;
    vec3 lo = vec3(3.0e38), hi = vec3(-3.0e38);
    uint children = 0u;  // the children that are not empty, a bit each
    uint tiles = node_size.x * node_size.y, tile = node.y * node_size.x + node.x;
#if defined(MERGE_SLICES)
    // the root: node_first's box over child_first's `slices` nodes
    for (uint s = 0u; s < slices; ++s) {
        vec3 child_lo, child_hi;
        node_box(child_first + s, child_lo, child_hi);
        lo = min(lo, child_lo);
        hi = max(hi, child_hi);
    }
    boxes[2u * node_first] = vec4(lo, 0.0);
    boxes[2u * node_first + 1u] = vec4(hi, 0.0);
#elif defined(SAMPLES) && defined(CLUSTERS)
    for (uint s = 0u; s < slices; ++s) {
        boxes[2u * (node_first + s * tiles + tile)] = vec4(lo, 0.0);
        boxes[2u * (node_first + s * tiles + tile) + 1u] = vec4(hi, 0.0);
    }
    for (uint y = 0u; y < uint(TILE); ++y) {
        for (uint x = 0u; x < uint(TILE); ++x) {
            uvec2 child = node * uint(TILE) + uvec2(x, y);
            if (any(greaterThanEqual(child, child_size))) continue;
            vec4 p = sample_position(child);
            if (p.w > 0.5 && !receives_light(child)) {
                marks[child.y * child_size.x + child.x] = 1u;
                p.w = 0.0;
            }
            uint s = p.w < 0.5 ? 0u : depth_slice(p.xyz);
            sample_slices[child.y * child_size.x + child.x] = s;
            if (p.w < 0.5) continue;
            uint index = 2u * (node_first + s * tiles + tile);
            boxes[index] = vec4(min(boxes[index].xyz, p.xyz),
                                uintBitsToFloat(floatBitsToUint(boxes[index].w)
                                                | child_bit(x, y)));
            boxes[index + 1u] = vec4(max(boxes[index + 1u].xyz, p.xyz), 0.0);
        }
    }
#else
    for (uint y = 0u; y < uint(TILE); ++y) {
        for (uint x = 0u; x < uint(TILE); ++x) {
            uvec2 child = node * uint(TILE) + uvec2(x, y);
            if (any(greaterThanEqual(child, child_size))) continue;
#ifdef SAMPLES
            vec4 p = sample_position(child);
            if (p.w < 0.5) continue;
            if (!receives_light(child)) {
                marks[child.y * child_size.x + child.x] = 1u;
                continue;
            }
            lo = min(lo, p.xyz);
            hi = max(hi, p.xyz);
            children |= child_bit(x, y);
#else
            uint slice = gl_GlobalInvocationID.z;
            uint index = child_first + (slice * child_size.y + child.y) * child_size.x + child.x;
            vec3 child_lo, child_hi;
            node_box(index, child_lo, child_hi);
            lo = min(lo, child_lo);
            hi = max(hi, child_hi);
            if (!box_empty(child_lo, child_hi)) children |= child_bit(x, y);
#endif
        }
    }
    uint index = node_first + gl_GlobalInvocationID.z * tiles + tile;
    boxes[2u * index] = vec4(lo, uintBitsToFloat(children));
    boxes[2u * index + 1u] = vec4(hi, 0.0);
#endif
}
