// One level of the traversal: each queued (volume, node) item of level `level` tests the
// node's TILE x TILE children against the volume, one invocation per child. Below level 1 the
// children are samples (the G-buffer's positions at the mask's resolution): one inside the
// volume is marked shadowed. Above it they are nodes: one outside is skipped, one inside is
// marked shadowed as a whole, any other is queued for the next level down. A child already
// marked (by another volume) is skipped: marks only ever go from lit to shadowed. ITEMS_PER_GROUP
// items share a work group; nothing depends on the subgroup's size. With clusters (`slices` >
// 1) a queued node is one depth slice of its tile: its children are that slice's nodes, or at
// level 1 the tile's samples in that slice. Compiled twice, for level 1 (LEAF: sample tests)
// and for the levels above (node tests): llvmpipe runs both sides of a branch, even a uniform one.
#include "ptsv_volume.glsl"
#include "ptsv_samples.glsl"

#define CHILDREN (TILE * TILE)
layout(local_size_x = GROUP_SIZE) in;  // CHILDREN * ITEMS_PER_GROUP
uniform uint level;  // the queued nodes' level (>= 1)
uniform uvec2 node_size;  // nodes per row and column at that level (per slice)
uniform uvec2 child_size;  // children (nodes or samples) per row and column at level - 1
uniform uint child_first;  // node number of level - 1's first node (level > 1)

void main() {
    uint item = (gl_WorkGroupID.y * gl_NumWorkGroups.x + gl_WorkGroupID.x) * ITEMS_PER_GROUP
        + gl_LocalInvocationIndex / CHILDREN;
    if (item >= min(counters[COUNT_LEVELS + level], capacity)) return;
    uvec2 queued = items[(level & 1u) * capacity + item];
    uint c = gl_LocalInvocationIndex % CHILDREN;
    uint tiles = node_size.x * node_size.y, slice = queued.y / tiles, tile = queued.y % tiles;
    uvec2 child = uvec2(tile % node_size.x, tile / node_size.x) * TILE
        + uvec2(c % TILE, c / TILE);
    if (any(greaterThanEqual(child, child_size))) return;
    uint index = child.y * child_size.x + child.x;
    vec4 volume[4] = volume_planes(queued.x);
#ifdef LEAF
    vec4 p = sample_position(child);
    if (p.w < 0.5 || marks[index] != 0u) return;  // already shadowed: nothing to learn
    if (slices > 1u && sample_slices[index] != slice) return;  // another cluster's
    TALLY(COUNT_SAMPLE_TESTS);
    if (inside_volume(volume, p.xyz)) marks[index] = 1u;
#else
    index += slice * child_size.x * child_size.y;
    if (marks[sample_count + child_first + index] != 0u) return;  // shadowed whole already
    vec3 lo, hi;
    node_box(child_first + index, lo, hi);
    if (any(greaterThan(lo, hi))) return;
    TALLY(COUNT_NODE_TESTS);
    int test = classify(volume, lo, hi);
    if (test > 0) {
        mark_node(child_first + index);
        TALLY(COUNT_ACCEPTS);
    } else if (test == 0) {
        push(level - 1u, queued.x, index);
    }
#endif
}
