// Per job (a page to render) and caster cluster: a draw of the cluster into the job's tile
// where the cluster's box, seen from the job's level, meets the page's square (every depth:
// all casters above the page). x: the cluster, y: the job. The draws are
// DrawElementsIndirectCommands whose baseInstance names the job (vsm_page.vert.glsl).
layout(local_size_x = 64) in;
#include "vsm_levels.glsl"

layout(std430, binding = 3) buffer Counters { uint counters[]; };
layout(std430, binding = 5) readonly buffer Jobs { ivec4 jobs[]; };
layout(std430, binding = 8) readonly buffer Clusters { vec4 bounds[]; };
layout(std430, binding = 9) writeonly buffer Commands { uint commands[]; };

const int COMMANDS = 8;  // vsm_pages.comp.glsl's counter
uniform int clusters;
uniform int cluster_triangles;
uniform int triangles;
uniform uint capacity;

void main() {
    int c = int(gl_GlobalInvocationID.x);
    int j = int(gl_GlobalInvocationID.y);
    if (c >= clusters) return;
    ivec4 job = jobs[j];
    int k = job.y;
    vec3 low = bounds[2 * c].xyz, high = bounds[2 * c + 1].xyz;
    vec2 lo = vec2(1e30), hi = vec2(-1e30);
    bool behind = false;
    for (int i = 0; i < 8; ++i) {
        vec3 corner = vec3((i & 1) != 0 ? high.x : low.x, (i & 2) != 0 ? high.y : low.y,
                           (i & 4) != 0 ? high.z : low.z);
        vec4 clip = level_clip(k, corner);
        behind = behind || clip.w <= 0.0;
        lo = min(lo, clip.xy / clip.w);
        hi = max(hi, clip.xy / clip.w);
    }
    float size = 2.0 / float(levels[k].grid.z);
    vec2 page_low = -1.0 + vec2(job.z & 0xffff, job.z >> 16) * size;
    if (!behind && !(all(lessThanEqual(lo, page_low + size)) && all(greaterThanEqual(hi, page_low))))
        return;
    uint command = atomicAdd(counters[COMMANDS], 1u);
    if (command >= capacity) return;
    int first = c * cluster_triangles;
    uint n = uint(min(first + cluster_triangles, triangles) - first);
    commands[5u * command] = 3u * n;
    commands[5u * command + 1u] = 1u;
    commands[5u * command + 2u] = uint(3 * first);
    commands[5u * command + 3u] = 0u;
    commands[5u * command + 4u] = uint(j);
}
