// The minimum and maximum over the covered pixels of a G-buffer of a per-pixel quantity, up to
// four numbers (harness/gl/reduction.py). The including shader defines, before the include,
//     bool quantity(vec3 position, vec3 normal, out vec4 value)
// returning false for a covered pixel that does not count. Each 16 x 16 work group reduces its
// pixels in shared memory; one invocation per group then merges into the result buffer with
// integer atomics on an order-preserving encoding of the floats (GL has no float atomic min).
layout(local_size_x = 16, local_size_y = 16) in;

uniform sampler2D gbuffer_position;  // w = 1 where covered
uniform sampler2D gbuffer_normal;

layout(std430, binding = 0) buffer Range {
    uint low[4];
    uint high[4];
};

shared vec4 group_low[256];
shared vec4 group_high[256];

// Unsigned integers in the order of the floats: the sign bit flipped for positive floats, every
// bit for negative ones.
uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}

void main() {
    const float INF = uintBitsToFloat(0x7f800000u);
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    vec4 lo = vec4(INF), hi = vec4(-INF);
    if (all(lessThan(pixel, textureSize(gbuffer_position, 0)))) {
        vec4 p = texelFetch(gbuffer_position, pixel, 0);
        vec4 value;
        if (p.w > 0.5 && quantity(p.xyz, texelFetch(gbuffer_normal, pixel, 0).xyz, value)) {
            lo = value;
            hi = value;
        }
    }
    uint i = gl_LocalInvocationIndex;
    group_low[i] = lo;
    group_high[i] = hi;
    barrier();
    for (uint half_size = 128u; half_size > 0u; half_size >>= 1) {
        if (i < half_size) {
            group_low[i] = min(group_low[i], group_low[i + half_size]);
            group_high[i] = max(group_high[i], group_high[i + half_size]);
        }
        barrier();
    }
    if (i == 0u) {
        for (int k = 0; k < 4; ++k) {
            atomicMin(low[k], ordered(group_low[0][k]));
            atomicMax(high[k], ordered(group_high[0][k]));
        }
    }
}
