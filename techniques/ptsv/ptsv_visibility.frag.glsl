// V from the marks: a sample is shadowed where it, or any node above it, was marked (a node
// inside a volume is marked whole, never its samples); with clusters, the nodes of the
// sample's depth slice, then the root. A mask smaller than the image (compiled with MAGNIFY,
// as common/mask_visibility.frag.glsl) is magnified bilinearly, as sv's, giving fractional V
// near edges.
#include "gbuffer_read.glsl"

// the marks and the samples' slices (clusters'), as buffer textures (hierarchy.py's TEXELS): a
// storage buffer is read lane by lane on llvmpipe, a texel in one fetch
uniform usamplerBuffer mark_texels;
uniform usamplerBuffer slice_texels;
uniform uvec2 mask_size;  // samples per row and column
uniform int levels;  // node levels above the samples
uniform uint slices;  // depth slices per tile (ptsv_volume.glsl); > 1: a root above the levels
layout(location = 0) out float visibility;

float lit(ivec2 texel) {
    uvec2 s = uvec2(clamp(texel, ivec2(0), ivec2(mask_size) - 1));
    uint index = s.y * mask_size.x + s.x;
    if (texelFetch(mark_texels, int(index)).x != 0u) return 0.0;
    uint slice = slices > 1u ? texelFetch(slice_texels, int(index)).x : 0u;
    uint first = mask_size.x * mask_size.y;  // the level's first mark
    uvec2 size = mask_size;
    for (int k = 1; k <= levels; ++k) {
        s /= uint(TILE);
        size = (size + uint(TILE) - 1u) / uint(TILE);
        if (texelFetch(mark_texels, int(first + (slice * size.y + s.y) * size.x + s.x)).x != 0u) {
            return 0.0;
        }
        first += size.x * size.y * slices;
    }
    return slices > 1u && texelFetch(mark_texels, int(first)).x != 0u ? 0.0 : 1.0;
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
#ifndef MAGNIFY
    visibility = lit(ivec2(gl_FragCoord.xy));
#else
    vec2 t = gl_FragCoord.xy * vec2(mask_size) / vec2(textureSize(gbuffer_position, 0)) - 0.5;
    ivec2 i = ivec2(floor(t));
    vec2 w = t - floor(t);
    visibility = mix(mix(lit(i), lit(i + ivec2(1, 0)), w.x),
                     mix(lit(i + ivec2(0, 1)), lit(i + ivec2(1, 1)), w.x), w.y);
#endif
}
