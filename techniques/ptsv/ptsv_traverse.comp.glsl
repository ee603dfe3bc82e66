// One level of the traversal: each queued (volume, node) item of level `level` has its node's
// TILE x TILE children tested against the volume by one invocation, in a loop (the volume and
// the item read once; llvmpipe runs a work group 8 invocations at a time and every branch of
// the code for all of them, so one invocation per child repeated the item's work per child).
// Below level 1 the children are samples (the G-buffer's positions at the mask's resolution):
// one inside the volume is marked shadowed. Above it they are nodes: one outside is skipped,
// one inside is marked shadowed as a whole, any other is queued for the next level down, the
// item's queued children reserved with one atomicAdd. A child already marked (by another
// volume) is skipped: marks only ever go from lit to shadowed. Nothing depends on the
// subgroup's size. With clusters (`slices` > 1) a queued node is one depth slice of its tile:
// its children are that slice's nodes, or at level 1 the tile's samples in that slice.
// Compiled twice, for level 1 (LEAF: sample tests) and for the levels above (node tests):
// llvmpipe runs both sides of a branch, even a uniform one.
#include "ptsv_volume.glsl"
#include "ptsv_samples.glsl"

#define CHILDREN (TILE * TILE)
layout(local_size_x = GROUP_SIZE) in;  // one item per invocation
uniform uint level;  // the queued nodes' level (>= 1)
uniform uvec2 node_size;  // nodes per row and column at that level (per slice)
uniform uvec2 child_size;  // children (nodes or samples) per row and column at level - 1
uniform uint child_first;  // node number of level - 1's first node (level > 1)

void main() {
    uint item = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * GROUP_SIZE
        + gl_LocalInvocationIndex;
    if (item >= min(counters[COUNT_LEVELS + level], capacity)) return;
    uvec2 queued = texelFetch(item_texels, int((level & 1u) * capacity + item)).xy;
    uint tiles = node_size.x * node_size.y, slice = queued.y / tiles, tile = queued.y % tiles;
    uvec2 first = uvec2(tile % node_size.x, tile / node_size.x) * TILE;
    vec4 volume[VOLUME_ROWS] = volume_planes(queued.x);
#ifdef LEAF
    for (uint c = 0u; c < CHILDREN; ++c) {
        uvec2 child = first + uvec2(c % TILE, c / TILE);
        if (any(greaterThanEqual(child, child_size))) continue;
        uint index = child.y * child_size.x + child.x;
        vec4 p = sample_position(child);
        // already shadowed: nothing to learn
        if (p.w < 0.5 || texelFetch(mark_texels, int(index)).x != 0u) continue;
        // another cluster's
        if (slices > 1u && texelFetch(slice_texels, int(index)).x != slice) continue;
        TALLY(COUNT_SAMPLE_TESTS);
        if (inside_volume(volume, p.xyz)) marks[index] = 1u;
    }
#else
    uint base = slice * child_size.x * child_size.y;  // the slice's first child, from child_first
    uint partial[(CHILDREN + 31) / 32];  // the children to queue, a bit each
    uint queue = 0u;
    for (uint c = 0u; c < CHILDREN; ++c) {
        if (c % 32u == 0u) partial[c / 32u] = 0u;
        uvec2 child = first + uvec2(c % TILE, c / TILE);
        if (any(greaterThanEqual(child, child_size))) continue;
        if (test_node(volume, child_first + base + child.y * child_size.x + child.x) == 0) {
            partial[c / 32u] |= 1u << (c % 32u);
            ++queue;
        }
    }
    if (queue == 0u) return;
    // counted even past the capacity, so the caller sees an overflow and runs again with room
    uint slot = atomicAdd(counters[COUNT_LEVELS + level - 1u], queue);
    uint region = ((level - 1u) & 1u) * capacity;
    for (uint c = 0u; c < CHILDREN && slot < capacity; ++c) {
        if ((partial[c / 32u] & (1u << (c % 32u))) == 0u) continue;
        uvec2 child = first + uvec2(c % TILE, c / TILE);
        items[region + slot++] = uvec2(queued.x, base + child.y * child_size.x + child.x);
    }
#endif
}
