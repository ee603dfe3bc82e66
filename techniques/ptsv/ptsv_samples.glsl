// The view samples: the G-buffer's position at one pixel per `divisor` x `divisor` block (the
// mask's resolution, mask_res), the block's pixel nearest its centre, relative to `origin`
// (ptsv_volume.glsl); w = 1 where covered.
uniform sampler2D gbuffer_position;
uniform int divisor;

vec4 sample_position(uvec2 s) {
    ivec2 pixel = min(ivec2(s) * divisor + divisor / 2, textureSize(gbuffer_position, 0) - 1);
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    return vec4(p.xyz - origin, p.w);
}
