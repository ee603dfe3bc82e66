// Tight cascade bounds (Lauritzen et al.'s sample distribution): the quantity of
// covered_range.glsl is the light-space position (light_rotation: world -> the light's rigid
// basis) of the pixels in one cascade's slice, chosen as csm_shading.frag.glsl chooses: view
// depth in (slice_near, slice_far].
uniform mat4 camera_view;
uniform mat4 light_rotation;
uniform float slice_near;
uniform float slice_far;

bool quantity(vec3 position, vec3 normal, out vec4 value) {
    float depth = -(camera_view * vec4(position, 1.0)).z;
    value = light_rotation * vec4(position, 1.0);
    return depth > slice_near && depth <= slice_far;
}

#include "covered_range.glsl"
