// cull: cc, step 3: one level of the max pyramid from the level below (2 x 2 cells each).
#include "sv_receivers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
uniform int level;  // >= 1

void main() {
    int size = GRID_SIZE >> level;
    ivec2 cell = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(cell, ivec2(size)))) return;
    uint below = level_first(level - 1), here = level_first(level);
    int width = size * 2;
    uint deep = 0u;
    for (int k = 0; k < 4; ++k) {
        ivec2 c = cell * 2 + ivec2(k & 1, k >> 1);
        deep = max(deep, deepest[below + uint(c.y * width + c.x)]);
    }
    deepest[here + uint(cell.y * size + cell.x)] = deep;
}
