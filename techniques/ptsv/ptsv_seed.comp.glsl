// The volumes whose footprint starts below the top level (ptsv_setup.comp.glsl counted, per
// level, the depth slices they span): their (volume, slice) seeds sorted by start level, then
// tested there, one level at a time, right before that level's traversal. Three programs:
// OFFSETS (one invocation: each level's first seed, its count cleared to be counted again),
// SCATTER (one invocation per caster of the batch: a queued volume's seeds written in its
// level's run), and neither: one invocation per seed of `level` tests the at most 2 x 2 nodes
// of its slice that the footprint reaches, queueing the partly covered ones for this level's
// traversal and marking the ones covered whole.
#include "ptsv_volume.glsl"

#ifdef OFFSETS
layout(local_size_x = 1) in;
#else
layout(local_size_x = 64) in;
#endif
layout(std430, binding = 10) buffer Starts { uvec4 starts[]; };
layout(std430, binding = 11) buffer Seeds { uvec2 seeds[]; };  // (volume, slice)
uniform uint seed_capacity;
uniform uint level;
uniform uvec2 node_size;  // nodes per row and column at `level` (per slice)
uniform uint node_first;  // node number of its first node

void main() {
#if defined(OFFSETS)
    uint first = 0u;
    for (uint k = 1u; k < LEVELS; ++k) {
        counters[SEED_FIRST + k] = first;
        first += counters[COUNT_SEEDS + k];
        counters[COUNT_SEEDS + k] = 0u;
    }
#else
    uint index = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * 64u
        + gl_LocalInvocationIndex;
#if defined(SCATTER)
    if (index >= min(counters[COUNT_VOLUMES], volume_capacity)) return;
    uvec4 start = starts[index];
    if (start.x >= LEVELS) return;
    uint first = start.w & 0xFFFFu, count = (start.w >> 16) - first + 1u;
    uint slot = counters[SEED_FIRST + start.x] + atomicAdd(counters[COUNT_SEEDS + start.x], count);
    for (uint k = 0u; k < count && slot + k < seed_capacity; ++k) {
        seeds[slot + k] = uvec2(index, first + k);
    }
#else
    if (index >= counters[COUNT_SEEDS + level]) return;
    index += counters[SEED_FIRST + level];
    if (index >= seed_capacity) return;
    uvec2 seed = seeds[index];
    uvec4 start = starts[seed.x];
    vec4 volume[VOLUME_ROWS] = volume_planes(seed.x);
    uint tiles = node_size.x * node_size.y;
    uvec2 first = uvec2(start.y, start.z) & 0xFFFFu, last = uvec2(start.y, start.z) >> 16;
    for (uint c = 0u; c < 4u; ++c) {
        uvec2 at = first + uvec2(c & 1u, c >> 1);
        if (any(greaterThan(at, last))) continue;
        uint node = seed.y * tiles + at.y * node_size.x + at.x;
        if (test_node(volume, node_first + node) == 0) push(level, seed.x, node);
    }
#endif
#endif
}
