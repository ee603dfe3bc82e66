// cull, step 2: each covered G-buffer sample raises its light-space cell's deepest receiver;
// with CLAMP (cull: cc) each pixel's light depth is stored for the clamp (sv_volume.frag.glsl),
// +inf where none is covered.
#include "sv_receivers.glsl"

layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D gbuffer_position;  // w = 1 where covered
#ifdef CLAMP
layout(r32f, binding = 0) writeonly uniform image2D receiver_depth;
#endif

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(pixel, textureSize(gbuffer_position, 0)))) return;
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    vec3 l = light_basis * p.xyz;
#ifdef CLAMP
    imageStore(receiver_depth, pixel, vec4(p.w < 0.5 ? uintBitsToFloat(0x7f800000u) : l.z));
#endif
    if (p.w < 0.5) return;
    ivec2 cell = clamp(cell_of(l.xy), ivec2(0), ivec2(GRID_SIZE - 1));
    atomicMax(deepest[cell.y * GRID_SIZE + cell.x], ordered(l.z));
}
