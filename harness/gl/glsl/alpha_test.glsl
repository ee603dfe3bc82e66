// The alpha-test rule of harness/scene/alpha.py (sample_alpha), written once for every GL
// side (fragment and compute shaders alike): bilinear at mip level 0, repeat wrap, texel
// (row i, column j) centred at ((j + 0.5) / W, (i + 0.5) / H), uv's (0, 0) the first texel
// row's left edge. The four texels are read explicitly (no hardware filtering), so every
// driver gives sample_alpha's value up to float32 rounding. harness/gl/alpha.py's
// AlphaTextures binds the two buffers.
uniform usamplerBuffer alpha_texels;  // every cut-out's texels, R8UI, row by row
uniform usamplerBuffer alpha_table;   // per cut-out: (first texel, width, height, cutoff bits)

float alpha_texel(int first, int width, ivec2 texel) {
    return float(texelFetch(alpha_texels, first + texel.y * width + texel.x).r) / 255.0;
}

// The alpha at `uv`, in [0, 1], of the cut-out whose alpha_table texel is `entry`.
float sample_alpha_of(uvec4 entry, vec2 uv) {
    ivec2 size = ivec2(entry.yz);
    vec2 p = uv * vec2(size) - 0.5;
    vec2 low = floor(p), f = p - low;
    // repeat: low mod size, exact for integer-valued floats below 2^24
    ivec2 c0 = ivec2(low - vec2(size) * floor(low / vec2(size)));
    ivec2 c1 = ivec2(c0.x + 1 == size.x ? 0 : c0.x + 1, c0.y + 1 == size.y ? 0 : c0.y + 1);
    int first = int(entry.x), w = size.x;
    float top = mix(alpha_texel(first, w, c0), alpha_texel(first, w, ivec2(c1.x, c0.y)), f.x);
    float bottom = mix(alpha_texel(first, w, ivec2(c0.x, c1.y)), alpha_texel(first, w, c1), f.x);
    return mix(top, bottom, f.y);
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
