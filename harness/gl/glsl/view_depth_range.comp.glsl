// The visible view-depth range: the quantity of covered_range.glsl is each covered pixel's
// depth along the camera's view axis, -z of camera_view (all four components).
uniform mat4 camera_view;

bool quantity(vec3 position, vec3 normal, out vec4 value) {
    value = vec4(-(camera_view * vec4(position, 1.0)).z);
    return true;
}

#include "covered_range.glsl"
