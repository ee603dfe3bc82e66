// Empties the tiles of this frame's jobs before their pages are drawn.
layout(local_size_x = 8, local_size_y = 8) in;
layout(r32ui, binding = 0) uniform writeonly uimage2D pool;
layout(std430, binding = 5) readonly buffer Jobs { ivec4 jobs[]; };
uniform int page_size;
uniform int pool_tiles;  // tiles per row of the pool
const float EMPTY_DEPTH = 3.0e38;

void main() {
    ivec4 job = jobs[gl_GlobalInvocationID.z];
    ivec2 tile = ivec2(job.w % pool_tiles, job.w / pool_tiles);
    imageStore(pool, tile * page_size + ivec2(gl_GlobalInvocationID.xy),
               uvec4(floatBitsToUint(EMPTY_DEPTH)));
}
