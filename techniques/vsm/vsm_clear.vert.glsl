// Empties the tiles of this frame's jobs before their pages are drawn: instance i is a square
// over job i's tile at the far plane, drawn with the depth test off and depth writes on.
#include "vsm_levels.glsl"

layout(std430, binding = 5) readonly buffer Jobs { ivec4 jobs[]; };
uniform int pool_tiles;
uniform float pool_res;

void main() {
    int slot = jobs[gl_InstanceID].w;
    vec2 corner = vec2(gl_VertexID & 1, (gl_VertexID >> 1) & 1);
    float tile_size = 2.0 * float(page_size) / pool_res;
    vec2 low = -1.0 + vec2(slot % pool_tiles, slot / pool_tiles) * tile_size;
    gl_Position = vec4(low + corner * tile_size, 1.0, 1.0);
}
