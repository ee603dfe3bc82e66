// V from the ray mask (0 shadow, 1 lit per mask texel). A mask smaller than the image is
// magnified bilinearly, as sv's (Roettger et al. section 4.5), which gives fractional V near
// shadow edges; at full size each pixel reads its own ray.
#include "gbuffer_read.glsl"

uniform sampler2D ray_mask;
uniform bool magnify;
layout(location = 0) out float visibility;

float lit(ivec2 texel) {
    return texelFetch(ray_mask, clamp(texel, ivec2(0), textureSize(ray_mask, 0) - 1), 0).r;
}

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    if (!magnify) { visibility = lit(ivec2(gl_FragCoord.xy)); return; }
    vec2 scale = vec2(textureSize(ray_mask, 0)) / vec2(textureSize(gbuffer_position, 0));
    vec2 t = gl_FragCoord.xy * scale - 0.5;
    ivec2 i = ivec2(floor(t));
    vec2 w = t - floor(t);
    visibility = mix(mix(lit(i), lit(i + ivec2(1, 0)), w.x),
                     mix(lit(i + ivec2(0, 1)), lit(i + ivec2(1, 1)), w.x), w.y);
}
