// A cluster drawn for one job: the scene's vertex in the job's level, its page's square
// mapped onto the job's pool tile, everything outside the square clipped (gl_ClipDistance),
// so texel centres are tested as a full map of the level would test them; the depth is the
// level's own window depth. With ALPHA_TEST the vertex's texture coordinates and cut-out go
// on to vsm_page.frag.glsl.
#extension GL_ARB_shader_draw_parameters : require
layout(location = 0) in vec3 position;
#include "vsm_levels.glsl"

layout(std430, binding = 5) readonly buffer Jobs { ivec4 jobs[]; };
uniform int pool_tiles;
uniform float pool_res;  // texels per side of the pool
out gl_PerVertex { vec4 gl_Position; float gl_ClipDistance[4]; };
#include "cutout_vertex.glsl"

void main() {
    ivec4 job = jobs[gl_BaseInstanceARB];
    vec4 clip = level_clip(job.y, position);
    float size = 2.0 / float(levels[job.y].grid.z);
    vec2 low = -1.0 + vec2(job.z & 0xffff, job.z >> 16) * size;
    vec2 from_low = clip.xy - low * clip.w;
    gl_ClipDistance[0] = from_low.x;
    gl_ClipDistance[1] = size * clip.w - from_low.x;
    gl_ClipDistance[2] = from_low.y;
    gl_ClipDistance[3] = size * clip.w - from_low.y;
    float tile_size = 2.0 * float(page_size) / pool_res;
    vec2 tile_low = -1.0 + vec2(job.w % pool_tiles, job.w / pool_tiles) * tile_size;
    gl_Position = vec4(from_low * (tile_size / size) + tile_low * clip.w, clip.z, clip.w);
    pass_cutout();
}
