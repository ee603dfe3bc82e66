// cull: cc (Lloyd et al. 2004), step 1: the light-space bounds of the visible receivers. The
// quantity of covered_range.glsl is each covered pixel's position in the directional light's
// frame (light_basis rows: two axes across the light, then its direction): u, v, depth.
uniform mat3 light_basis;

bool quantity(vec3 position, vec3 normal, out vec4 value) {
    value = vec4(light_basis * position, 0.0);
    return true;
}

#include "covered_range.glsl"
