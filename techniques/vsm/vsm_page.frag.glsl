// The nearest linear light depth per pool texel (light_depth.frag.glsl's, kept by an atomic
// minimum: positive floats order as their bits do), so the pool needs no depth buffer.
layout(early_fragment_tests) in;
layout(r32ui, binding = 0) uniform coherent uimage2D pool;
in float light_depth;

void main() {
    imageAtomicMin(pool, ivec2(gl_FragCoord.xy), floatBitsToUint(light_depth));
}
