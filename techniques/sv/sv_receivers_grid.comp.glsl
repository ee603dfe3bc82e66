// cull: cc, step 2: each covered G-buffer sample raises its light-space cell's deepest receiver.
#include "sv_receivers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D gbuffer_position;  // w = 1 where covered

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, textureSize(gbuffer_position, 0)))) return;
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    if (p.w < 0.5) return;
    vec3 l = light_basis * p.xyz;
    ivec2 cell = clamp(cell_of(l.xy), ivec2(0), ivec2(GRID_SIZE - 1));
    atomicMax(deepest[cell.y * GRID_SIZE + cell.x], ordered(l.z));
}
