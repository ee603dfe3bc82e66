// The alpha-test rule of harness/scene/alpha.py (sample_alpha), written once for every GL
// side (fragment and compute shaders alike): bilinear at mip level 0, repeat wrap, texel
// (row i, column j) centred at ((j + 0.5) / W, (i + 0.5) / H), uv's (0, 0) the first texel
// row's left edge. The four texels are read explicitly (no hardware filtering), so every
// driver gives sample_alpha's value up to float32 rounding: in one fetch, each texel stored
// with its right, lower and lower-right neighbours (wrapped). harness/gl/alpha.py's
// AlphaTextures binds the two buffers.
uniform usamplerBuffer alpha_texels;  // every cut-out's texel quads, RGBA8UI, row by row
uniform usamplerBuffer alpha_table;   // per cut-out: (first texel, width, height, cutoff bits)

// The alpha at `uv`, in [0, 1], of the cut-out whose alpha_table texel is `entry`.
float sample_alpha_of(uvec4 entry, vec2 uv) {
    ivec2 size = ivec2(entry.yz);
    vec2 p = uv * vec2(size) - 0.5;
    vec2 low = floor(p), f = p - low;
    // repeat: low mod size, exact for integer-valued floats below 2^24
    ivec2 c0 = ivec2(low - vec2(size) * floor(low / vec2(size)));
    vec4 quad = vec4(texelFetch(alpha_texels, int(entry.x) + c0.y * size.x + c0.x)) / 255.0;
    return mix(mix(quad.x, quad.y, f.x), mix(quad.z, quad.w, f.x), f.y);
}

// The cut-out `mask`'s alpha at `uv`, in [0, 1].
float sample_alpha(int mask, vec2 uv) {
    return sample_alpha_of(texelFetch(alpha_table, mask), uv);
}

// Whether the surface is cut out at `uv` (alpha below the cutoff); mask < 0 is opaque.
bool cut_out(int mask, vec2 uv) {
    if (mask < 0) {
        return false;
    }
    uvec4 entry = texelFetch(alpha_table, mask);
    return sample_alpha_of(entry, uv) < uintBitsToFloat(entry.w);
}
