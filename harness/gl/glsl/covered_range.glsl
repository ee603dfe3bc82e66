// The minimum and maximum over the covered pixels of a G-buffer of a per-pixel quantity, up to
// four numbers (harness/gl/reduction.py). The including shader defines, before the include,
//     bool quantity(vec3 position, vec3 normal, out vec4 value)
// returning false for a covered pixel that does not count. Defines from Python:
// ROWS_PER_INVOCATION. Each invocation merges a column of that many pixels in registers, then
// into the result buffer with integer atomics on an order-preserving encoding of the floats
// (GL has no float atomic min). No shared memory and no barrier: on llvmpipe a barrier switches
// every invocation of the group, and a 16 x 16 shared-memory tree took 7x the time of this.
layout(local_size_x = 16, local_size_y = 16) in;

uniform sampler2D gbuffer_position;  // w = 1 where covered
uniform sampler2D gbuffer_normal;

layout(std430, binding = 0) buffer Range {
    uint low[4];
    uint high[4];
};

// Unsigned integers in the order of the floats: the sign bit flipped for positive floats, every
// bit for negative ones.
uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}

void main() {
    const float INF = uintBitsToFloat(0x7f800000u);
    ivec2 size = textureSize(gbuffer_position, 0);
    vec4 lo = vec4(INF), hi = vec4(-INF);
    for (int row = 0; row < ROWS_PER_INVOCATION; ++row) {
        ivec2 pixel = ivec2(gl_GlobalInvocationID.x, gl_GlobalInvocationID.y * ROWS_PER_INVOCATION + row);
        if (all(lessThan(pixel, size))) {
            vec4 p = texelFetch(gbuffer_position, pixel, 0);
            vec4 value;
            if (p.w > 0.5 && quantity(p.xyz, texelFetch(gbuffer_normal, pixel, 0).xyz, value)) {
                lo = min(lo, value);
                hi = max(hi, value);
            }
        }
    }
    if (lo.x <= hi.x) {
        for (int k = 0; k < 4; ++k) {
            atomicMin(low[k], ordered(lo[k]));
            atomicMax(high[k], ordered(hi[k]));
        }
    }
}
