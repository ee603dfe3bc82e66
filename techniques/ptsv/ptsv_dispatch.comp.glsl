// The work groups of the next traversal level, from the items queued for it (capped at the
// queue's capacity): an indirect dispatch, so the queue's length never comes back to the CPU
// between levels. Rows of at most 65535 groups (the smallest maximum GL allows).
#include "ptsv_volume.glsl"

layout(local_size_x = 1) in;
layout(std430, binding = 7) writeonly buffer Dispatch { uint groups[3]; };
uniform uint counter;  // the counter of the items (at most `limit`) to dispatch
uniform uint limit;
uniform uint items_per_group;

void main() {
    uint items = min(counters[counter], limit);
    uint total = (items + items_per_group - 1u) / items_per_group;
    uint rows = (total + 65534u) / 65535u;
    groups[0] = total == 0u ? 0u : (total + rows - 1u) / rows;
    groups[1] = rows;
    groups[2] = 1u;
}
