// Lookup of a perspective-warped directional shadow map (psm, lispsm, gmnpr): k x k texel-grid
// PCF around the point, each sample with the constant bias plus the slope term of
// shadow_map.glsl for the texel it reads. That term is computed in the warped map's own texels
// (the receiver plane's Jacobian includes the warp), so it follows texels that are small near
// the viewer and large far away.
#include "gbuffer_read.glsl"
#include "../common/shadow_map.glsl"

uniform int grid_n;
uniform float bias;
layout(location = 0) out float visibility;

void main() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) { visibility = 1.0; return; }
    Receiver r = receiver(p, n);
    if (!r.in_front) { visibility = 1.0; return; }
    float lit = 0.0;
    for (int j = 0; j < grid_n; ++j) {
        for (int i = 0; i < grid_n; ++i) {
            vec2 offset = vec2(i, j) + 0.5 - 0.5 * float(grid_n);
            lit += receiver_test(r, r.texel + offset, bias);
        }
    }
    visibility = lit / float(grid_n * grid_n);
}
