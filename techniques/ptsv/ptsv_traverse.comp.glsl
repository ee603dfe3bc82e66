// One level of the traversal: each queued (volume, node) item of level `level` has its node's
// TILE x TILE children tested against the volume by one invocation, in a loop over the children
// that are not empty (the node's bits, node_children: llvmpipe runs a loop as often as the
// busiest of its 8 lanes needs, not TILE x TILE times). The volume and the item are read once:
// llvmpipe runs a work group 8 invocations at a time and every branch of the code for all of
// them, so one invocation per child repeated the item's work per child.
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

layout(local_size_x = GROUP_SIZE) in;  // one item per invocation
uniform uint level;  // the queued nodes' level (>= 1)
uniform uvec2 node_size;  // nodes per row and column at that level (per slice)
uniform uvec2 child_size;  // children (nodes or samples) per row and column at level - 1
uniform uint node_first;  // node number of the level's first node
uniform uint child_first;  // node number of level - 1's first node (level > 1)

void main() {
    uint item = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * GROUP_SIZE
        + gl_LocalInvocationIndex;
    if (item >= min(counters[COUNT_LEVELS + level], capacity)) return;
    uvec2 queued = texelFetch(item_texels, int((level & 1u) * capacity + item)).xy;
    uint tiles = node_size.x * node_size.y, slice = queued.y / tiles, tile = queued.y % tiles;
    uvec2 first = uvec2(tile % node_size.x, tile / node_size.x) * TILE;
    vec4 volume[VOLUME_ROWS] = volume_planes(queued.x);
    uint children = node_children(node_first + queued.y);
#ifdef LEAF
    // the node's samples: covered, facing the light and (clusters) in its slice
    for (; children != 0u; children &= children - 1u) {
        uint c = uint(findLSB(children));
        uvec2 child = first + uvec2(c % TILE, c / TILE);
        uint index = child.y * child_size.x + child.x;
        // already shadowed: nothing to learn
        if (texelFetch(mark_texels, int(index)).x != 0u) continue;
        vec4 p = sample_position(child);
        TALLY(COUNT_SAMPLE_TESTS);
        if (inside_volume(volume, p.xyz)) marks[index] = 1u;
    }
#else
    uint base = slice * child_size.x * child_size.y;  // the slice's first child, from child_first
    uint partial = 0u;  // the children to queue, a bit each
    for (; children != 0u; children &= children - 1u) {
        uint c = uint(findLSB(children));
        uvec2 child = first + uvec2(c % TILE, c / TILE);
        if (test_node(volume, child_first + base + child.y * child_size.x + child.x) == 0) {
            partial |= 1u << c;
        }
    }
    if (partial == 0u) return;
    // counted even past the capacity, so the caller sees an overflow and runs again with room
    uint slot = atomicAdd(counters[COUNT_LEVELS + level - 1u], uint(bitCount(partial)));
    uint region = ((level - 1u) & 1u) * capacity;
    for (; partial != 0u && slot < capacity; partial &= partial - 1u) {
        uint c = uint(findLSB(partial));
        uvec2 child = first + uvec2(c % TILE, c / TILE);
        items[region + slot++] = uvec2(queued.x, base + child.y * child_size.x + child.x);
    }
#endif
}
