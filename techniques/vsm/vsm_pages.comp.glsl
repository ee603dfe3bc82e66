// The page table's passes, one invocation per entry, one STAGE each (vsm/pages.py runs them):
// COUNT: how many requested pages have no pool tile (need) and how many tiles unrequested
//   pages hold (release): whether the requests fit the pool;
// RELEASE: unrequested pages give their tiles back to the free ring (at its tail);
// ALLOCATE: requested pages without a tile take one from the ring's head; one holding another
//   page of the same slot (the window moved) keeps its tile for the new page; each requested
//   page whose depths are not current becomes a job (rendered this frame), the rest are hits;
// INVALIDATE: pages whose light-space box meets one of the moving boxes (or all, on a light
//   change) lose their depths but keep their tiles.
layout(local_size_x = 64) in;
#include "vsm_levels.glsl"

layout(std430, binding = 2) buffer Requests { uint requests[]; };
layout(std430, binding = 3) buffer Counters { uint counters[]; };
layout(std430, binding = 4) buffer FreeRing { int free_slots[]; };
layout(std430, binding = 5) buffer Jobs { ivec4 jobs[]; };  // entry, level, local x | y << 16, slot

// counters (pages.py's COUNTERS)
const int NEED = 0, RELEASE = 1, HEAD = 2, TAIL = 3, MARKED = 4, ALLOCATED = 5, JOBS = 6,
          HITS = 7, COMMANDS = 8, INVALIDATED = 9;

uniform int table_size;
uniform int pool_pages;
#define MAX_BOXES 32
uniform bool invalidate_all;
uniform int boxes;
uniform vec3 box_low[MAX_BOXES];
uniform vec3 box_high[MAX_BOXES];

// A count over every level, not a loop down from the last that each entry leaves at its own
// level: llvmpipe (Mesa 22) then read levels[k] of the last level as zeros (pages 0), so the
// one-page level's entry held page (-1, -1) and its pixels read no depth (all lit).
int level_of(int index) {
    int k = 0;
    for (int j = 1; j < level_count; ++j) k += int(index >= levels[j].grid.w);
    return k;
}

// The page of the current window that entry `index` of level k holds when requested.
ivec2 window_page(int k, int index) {
    int pages = levels[k].grid.z, slot = index - levels[k].grid.w;
    ivec2 origin = levels[k].grid.xy;
    ivec2 m = ivec2(slot % pages, slot / pages);
    return origin + ivec2(positive_mod(m.x - origin.x, pages), positive_mod(m.y - origin.y, pages));
}

// Whether the world box [low, high] seen from level k meets the column of the level's page at
// global coordinates g (every depth: a caster anywhere above the page shades it).
bool meets(int k, ivec2 g, vec3 low, vec3 high) {
    vec2 lo = vec2(1e30), hi = vec2(-1e30);
    for (int c = 0; c < 8; ++c) {
        vec3 corner = vec3((c & 1) != 0 ? high.x : low.x, (c & 2) != 0 ? high.y : low.y,
                           (c & 4) != 0 ? high.z : low.z);
        vec4 clip = level_clip(k, corner);
        if (clip.w <= 0.0) return true;
        lo = min(lo, clip.xy / clip.w);
        hi = max(hi, clip.xy / clip.w);
    }
    float size = 2.0 / float(levels[k].grid.z);
    vec2 page_low = -1.0 + vec2(g - levels[k].grid.xy) * size;
    return all(lessThanEqual(lo, page_low + size)) && all(greaterThanEqual(hi, page_low));
}

void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= table_size) return;
    Entry e = entries[i];
    bool requested = requests[i] != 0u;
#if STAGE == 0
    if (requested) {
        atomicAdd(counters[MARKED], 1u);
        if (e.slot < 0) atomicAdd(counters[NEED], 1u);
    } else if (e.slot >= 0) {
        atomicAdd(counters[RELEASE], 1u);
    }
#elif STAGE == 1
    if (requested || e.slot < 0) return;
    uint tail = atomicAdd(counters[TAIL], 1u);
    free_slots[tail % uint(pool_pages)] = e.slot;
    entries[i] = Entry(-1, 0, 0, 0u);
#elif STAGE == 2
    if (!requested) return;
    int k = level_of(i);
    ivec2 g = window_page(k, i);
    if (e.slot < 0) {
        uint head = atomicAdd(counters[HEAD], 1u);
        e = Entry(free_slots[head % uint(pool_pages)], g.x, g.y, 0u);
        atomicAdd(counters[ALLOCATED], 1u);
    } else if (e.gx != g.x || e.gy != g.y) {
        e = Entry(e.slot, g.x, g.y, 0u);
    }
    if (e.valid != 0u) {
        atomicAdd(counters[HITS], 1u);
        return;
    }
    uint job = atomicAdd(counters[JOBS], 1u);
    ivec2 local = g - levels[k].grid.xy;
    jobs[job] = ivec4(i, k, local.x | (local.y << 16), e.slot);
    e.valid = 1u;
    entries[i] = e;
#else
    if (e.slot < 0 || e.valid == 0u) return;
    bool stale = invalidate_all;
    int k = level_of(i);
    for (int b = 0; b < boxes && !stale; ++b) stale = meets(k, ivec2(e.gx, e.gy), box_low[b], box_high[b]);
    if (stale) {
        entries[i].valid = 0u;
        atomicAdd(counters[INVALIDATED], 1u);
    }
#endif
}
