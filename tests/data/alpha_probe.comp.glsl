// alpha_test.glsl's sample_alpha and cut_out at each probe's (mask, u, v): writes (alpha,
// cut out 1/0) per probe.
layout(local_size_x = 64) in;
#include "alpha_test.glsl"
uniform samplerBuffer probes;  // (u, v, mask, 0)
uniform int count;
layout(std430, binding = 0) writeonly buffer Result { vec2 result[]; };
void main() {
    int i = int(gl_GlobalInvocationID.x);
    if (i >= count) {
        return;
    }
    vec4 probe = texelFetch(probes, i);
    int mask = int(probe.z);
    result[i] = vec2(sample_alpha(mask, probe.xy), cut_out(mask, probe.xy) ? 1.0 : 0.0);
}
