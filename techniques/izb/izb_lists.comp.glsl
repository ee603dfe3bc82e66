// One invocation per sample slot: a sample to insert is linked into the list of the grid
// texel it falls in (the head-pointer image holds the link to the list's first slot, `next`
// each slot's link to its successor; a link is a slot + 1, END = 0 ends a list:
// izb_casters.frag.glsl says why), by one atomic exchange. With COUNT, each texel's list length
// is counted too.
layout(local_size_x = 256) in;

layout(std430, binding = 0) readonly buffer Positions { vec4 positions[]; };
layout(std430, binding = 1) writeonly buffer Next { uint next[]; };
layout(r32ui, binding = 0) coherent uniform uimage2D heads;
#ifdef COUNT
layout(r32ui, binding = 1) coherent uniform uimage2D lengths;
#endif
uniform uint slots;

#include "izb_grid.glsl"

void main() {
    uint slot = gl_GlobalInvocationID.x;
    if (slot >= slots) {
        return;
    }
    vec4 q = positions[slot];
    vec2 ndc;
    if (q.w == 0.0 || !light_ndc(q.xyz, ndc)) {
        return;
    }
    vec2 g = grid_position(ndc);
    // a sample on the grid's far edge (the rectangle's bound) belongs to the last texel
    if (any(lessThan(g, vec2(0.0))) || any(greaterThan(g, vec2(float(grid_res))))) {
        return;
    }
    ivec2 texel = min(ivec2(g), ivec2(grid_res - 1));
    next[slot] = imageAtomicExchange(heads, texel, slot + 1u);
#ifdef COUNT
    imageAtomicAdd(lengths, texel, 1u);
#endif
}
