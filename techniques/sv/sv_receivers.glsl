// cull: cc (Lloyd et al. 2004): the visible receivers' light-space grid, GRID_SIZE x GRID_SIZE
// cells over their (u, v) bounds, each holding the largest light depth of the G-buffer samples
// in it (order-preserving unsigned integers, 0 where none), then a max pyramid of halved levels.
layout(std430, binding = 1) buffer Receivers { uint deepest[]; };
uniform mat3 light_basis;  // world -> u, v, depth along the light
uniform vec2 grid_low;  // (u, v) of the grid's corner
uniform vec2 grid_scale;  // cells per unit of u and v

// the first cell of pyramid level k (level 0: the grid)
uint level_first(int k) {
    uint first = 0u;
    for (int i = 0; i < k; ++i) first += uint((GRID_SIZE >> i) * (GRID_SIZE >> i));
    return first;
}

uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}

float from_ordered(uint u) {
    return uintBitsToFloat((u & 0x80000000u) != 0u ? u & 0x7fffffffu : ~u);
}

// The grid cell of light-space (u, v), not clamped.
ivec2 cell_of(vec2 uv) {
    return ivec2(floor((uv - grid_low) * grid_scale));
}

// The deepest receiver in the cells the light-space rectangle [lo, hi] touches, with one more
// cell around it (rounding may bin a receiver on the rectangle's edge next door): a
// conservative bound, read from the pyramid level where that block spans at most 2 x 2 cells.
// -inf where no receiver is there.
float deepest_receiver(vec2 lo, vec2 hi) {
    vec2 limit = vec2(-2.0, float(GRID_SIZE) + 1.0);
    ivec2 c0 = ivec2(floor(clamp((lo - grid_low) * grid_scale, limit.x, limit.y))) - 1;
    ivec2 c1 = ivec2(floor(clamp((hi - grid_low) * grid_scale, limit.x, limit.y))) + 1;
    c0 = max(c0, ivec2(0));
    c1 = min(c1, ivec2(GRID_SIZE - 1));
    if (any(greaterThan(c0, c1))) return -uintBitsToFloat(0x7f800000u);
    int k = 0;
    while (any(greaterThan((c1 >> k) - (c0 >> k), ivec2(1)))) ++k;
    int size = GRID_SIZE >> k;
    uint first = level_first(k), deep = 0u;
    for (int i = 0; i < 4; ++i) {
        ivec2 c = ivec2((i & 1) != 0 ? c1.x >> k : c0.x >> k, (i & 2) != 0 ? c1.y >> k : c0.y >> k);
        deep = max(deep, deepest[first + uint(c.y * size + c.x)]);
    }
    return deep == 0u ? -uintBitsToFloat(0x7f800000u) : from_ordered(deep);
}
