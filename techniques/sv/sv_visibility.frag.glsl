// V from the normalised shadow mask. Each mask texel is snapped to 0 (shadow) or 1 (lit) at
// the midpoint between the two levels the normalisation leaves, so 8-bit rounding never
// shows; a mask smaller than the image is magnified bilinearly (section 4.5), which gives
// fractional V near shadow edges.
#include "gbuffer_read.glsl"

uniform sampler2D shadow_mask;
uniform int mask_channel;
uniform float lit_threshold;
uniform bool magnify;
layout(location = 0) out float visibility;

float lit(ivec2 texel) {
    ivec2 size = textureSize(shadow_mask, 0);
    texel = clamp(texel, ivec2(0), size - 1);
    return texelFetch(shadow_mask, texel, 0)[mask_channel] > lit_threshold ? 1.0 : 0.0;
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    if (!magnify) { visibility = lit(ivec2(gl_FragCoord.xy)); return; }
    vec2 scale = vec2(textureSize(shadow_mask, 0)) / vec2(textureSize(gbuffer_position, 0));
    vec2 t = gl_FragCoord.xy * scale - 0.5;
    ivec2 i = ivec2(floor(t));
    vec2 w = t - floor(t);
    visibility = mix(mix(lit(i), lit(i + ivec2(1, 0)), w.x),
                     mix(lit(i + ivec2(0, 1)), lit(i + ivec2(1, 1)), w.x), w.y);
}
