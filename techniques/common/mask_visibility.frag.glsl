// V from a shadow mask: sv's normalised shadow-volume mask, rt's ray mask. Each mask texel is
// snapped to 0 (shadow) or 1 (lit) at lit_threshold in channel mask_channel (for sv, the
// midpoint between the two levels the normalisation leaves, so 8-bit rounding never shows);
// a mask smaller than the image (compiled with MAGNIFY: llvmpipe would run the bilinear path's
// four taps for a full mask too) is magnified bilinearly (Roettger et al. section 4.5), which
// gives fractional V near shadow edges.
#include "gbuffer_read.glsl"

uniform sampler2D shadow_mask;
uniform int mask_channel;
uniform float lit_threshold;
layout(location = 0) out float visibility;

float lit(ivec2 texel) {
    ivec2 size = textureSize(shadow_mask, 0);
    texel = clamp(texel, ivec2(0), size - 1);
    return texelFetch(shadow_mask, texel, 0)[mask_channel] > lit_threshold ? 1.0 : 0.0;
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
#ifndef MAGNIFY
    visibility = lit(ivec2(gl_FragCoord.xy));
#else
    vec2 scale = vec2(textureSize(shadow_mask, 0)) / vec2(textureSize(gbuffer_position, 0));
    vec2 t = gl_FragCoord.xy * scale - 0.5;
    ivec2 i = ivec2(floor(t));
    vec2 w = t - floor(t);
    visibility = mix(mix(lit(i), lit(i + ivec2(1, 0)), w.x),
                     mix(lit(i + ivec2(0, 1)), lit(i + ivec2(1, 1)), w.x), w.y);
#endif
}
