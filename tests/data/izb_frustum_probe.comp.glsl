// izb's sample-in-frustum test on cases from a test: per case, the sample, the triangle's
// three vertices and the light (xyz, w), five vec4s; the answer (1 in the frustum) per case.
layout(local_size_x = 64) in;
layout(std430, binding = 0) readonly buffer Cases { vec4 cases[]; };
layout(std430, binding = 1) writeonly buffer Answers { uint answers[]; };
uniform uint count;

#include "../../techniques/izb/izb_frustum.glsl"

void main() {
    uint i = gl_GlobalInvocationID.x;
    if (i >= count) {
        return;
    }
    uint k = 5u * i;
    answers[i] = in_shadow_frustum(cases[k].xyz, cases[k + 1u].xyz, cases[k + 2u].xyz,
                                   cases[k + 3u].xyz, cases[k + 4u]) ? 1u : 0u;
}
