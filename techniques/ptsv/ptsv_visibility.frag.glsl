// V from the marks: a sample is shadowed where it, or any node above it, was marked (a node
// inside a volume is marked whole, never its samples). A mask smaller than the image is
// magnified bilinearly, as sv's (sv_visibility.frag.glsl), giving fractional V near edges.
#include "gbuffer_read.glsl"

layout(std430, binding = 4) readonly buffer Marks { uint marks[]; };
uniform uvec2 mask_size;  // samples per row and column
uniform int levels;  // node levels above the samples
uniform bool magnify;
layout(location = 0) out float visibility;

float lit(ivec2 texel) {
    uvec2 s = uvec2(clamp(texel, ivec2(0), ivec2(mask_size) - 1));
    if (marks[s.y * mask_size.x + s.x] != 0u) return 0.0;
    uint first = mask_size.x * mask_size.y;  // the level's first mark
    uvec2 size = mask_size;
    for (int k = 1; k <= levels; ++k) {
        s /= uint(TILE);
        size = (size + uint(TILE) - 1u) / uint(TILE);
        if (marks[first + s.y * size.x + s.x] != 0u) return 0.0;
        first += size.x * size.y;
    }
    return 1.0;
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    if (!magnify) { visibility = lit(ivec2(gl_FragCoord.xy)); return; }
    vec2 t = gl_FragCoord.xy * vec2(mask_size) / vec2(textureSize(gbuffer_position, 0)) - 0.5;
    ivec2 i = ivec2(floor(t));
    vec2 w = t - floor(t);
    visibility = mix(mix(lit(i), lit(i + ivec2(1, 0)), w.x),
                     mix(lit(i + ivec2(0, 1)), lit(i + ivec2(1, 1)), w.x), w.y);
}
