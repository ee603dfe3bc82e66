// One fragment per grid texel a caster triangle touches: the samples of the texel's list are
// each tested against the triangle's shadow frustum (izb_frustum.glsl); an occluded sample
// sets its bit in its pixel's mask. The texel is dropped first where one of the triangle's
// edges separates it from the triangle (the edge's half-plane, grown by half a texel and
// MARGIN along its normal's L1 norm, holds no corner of the texel): with the quad's box this
// is the separating-axis test of the texel square against the triangle. A triangle nearly
// edge-on to the light (its projection's area within rounding of 0) keeps its box alone.
// With ALPHA_TEST (a scene with alpha-tested casters), an occluded sample is tested once more
// at the point where its ray to the light meets the triangle (frustum_weights), by
// alpha_test.glsl's rule at the texture coordinates there: a cut-out texel does not shadow it.
// With COUNT, fragments, sample tests and alpha tests are counted; with TEXEL_FRAGMENTS,
// fragments per texel.
flat in vec3 a, b, c;
flat in vec2 ga, gb, gc;
flat in int edge_test;
#ifdef ALPHA_TEST
#include "alpha_test.glsl"
flat in vec2 ta, tb, tc;
flat in int mask;
#endif

layout(std430, binding = 0) readonly buffer Positions { vec4 positions[]; };
layout(std430, binding = 1) readonly buffer Next { uint next[]; };
layout(std430, binding = 2) buffer Masks { uint masks[]; };
uniform usampler2D heads;
#ifdef COUNT
layout(std430, binding = 5) buffer Counts { uint fragments; uint tests; uint alpha_tests; };
#endif
#ifdef TEXEL_FRAGMENTS
layout(r32ui, binding = 1) uniform uimage2D texel_fragments;  // a test's: fragments per texel
#endif
uniform vec4 light;

// A link is a slot + 1; 0 ends a list. So a lane llvmpipe runs on after its own walk ended
// (its loops stop only when every lane of the group has) reads link 0's successor out of the
// buffer's bounds, which reads as 0: END again. With END = ~0 such lanes cycled through slot 0
// up to the driver's loop limit (65535 steps), 3000x the time of the walks themselves.
const uint END = 0u;
#include "izb_grid.glsl"
#include "izb_frustum.glsl"

// whether edge (p, q), oriented by the triangle's winding `turn`, leaves the texel centred
// at `centre` wholly outside
bool separates(vec2 p, vec2 q, float turn, vec2 centre) {
    vec2 normal = turn * vec2(q.y - p.y, p.x - q.x);  // outward
    float reach = (0.5 + MARGIN) * (abs(normal.x) + abs(normal.y));
    return dot(normal, centre - p) > reach;
}

void main() {
    ivec2 texel = ivec2(gl_FragCoord.xy);
    vec2 centre = vec2(texel) + 0.5;
    vec2 e1 = gb - ga, e2 = gc - ga;
    float area = e1.x * e2.y - e1.y * e2.x;
    if (edge_test == 1 && abs(area) > 1e-4 * length(e1) * length(e2)) {
        float turn = area > 0.0 ? 1.0 : -1.0;
        if (separates(ga, gb, turn, centre) || separates(gb, gc, turn, centre)
                || separates(gc, ga, turn, centre)) {
            discard;
        }
    }
#ifdef COUNT
    atomicAdd(fragments, 1u);
    uint tested = 0u;
#endif
#if defined(COUNT) && defined(ALPHA_TEST)
    uint alpha_tested = 0u;
#endif
#ifdef TEXEL_FRAGMENTS
    imageAtomicAdd(texel_fragments, texel, 1u);
#endif
    for (uint link = texelFetch(heads, texel, 0).x; link != END; link = next[link - 1u]) {
        uint slot = link - 1u;
#ifdef COUNT
        tested++;
#endif
        vec3 s = positions[slot].xyz;
        if (!in_shadow_frustum(s, a, b, c, light)) {
            continue;
        }
#ifdef ALPHA_TEST
        if (mask >= 0) {
#ifdef COUNT
            alpha_tested++;
#endif
            vec3 weights = frustum_weights(s, a, b, c, light);
            if (cut_out(mask, weights.x * ta + weights.y * tb + weights.z * tc)) {
                continue;
            }
        }
#endif
        atomicOr(masks[slot / uint(SAMPLES)], 1u << (slot % uint(SAMPLES)));
    }
#ifdef COUNT
    atomicAdd(tests, tested);
#endif
#if defined(COUNT) && defined(ALPHA_TEST)
    atomicAdd(alpha_tests, alpha_tested);
#endif
}
