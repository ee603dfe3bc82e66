// What the warps need of the visible receivers (techniques/warp_receivers.py), reduced over the
// covered G-buffer pixels by covered_range.glsl. A pixel counts when it lies inside the spot
// light's frustum (spot_clip's unit cube) where there is a spot light, as view_setup's
// receivers do. Per pixel:
//   x: its view depth, -z of camera_view;
//   y: its depth along the camera's view direction in the spot light's clip space (from
//      space_eye along space_forward);
//   z: how far it lies outside test_clip's unit cube, beyond outside_unit_cube's tolerance
//      (> 0: outside);
//   w: -w of test_clip (>= 0: on or behind its eye plane).
uniform mat4 camera_view;
uniform bool spot;
uniform mat4 spot_clip;
uniform vec3 space_eye;
uniform vec3 space_forward;
uniform mat4 test_clip;

const float CUBE_TOLERANCE = 1e-5;  // warp_diagnostics.outside_unit_cube's, times |w|

float beyond_cube(vec4 c) {
    return max(max(abs(c.x), abs(c.y)), abs(c.z)) - c.w - CUBE_TOLERANCE * abs(c.w);
}

bool quantity(vec3 position, vec3 normal, out vec4 value) {
    vec4 s = spot_clip * vec4(position, 1.0);
    if (spot && (s.w <= 0.0 || beyond_cube(s) > 0.0)) {
        return false;
    }
    vec4 t = test_clip * vec4(position, 1.0);
    value = vec4(-(camera_view * vec4(position, 1.0)).z, dot(s.xyz / s.w - space_eye, space_forward),
                 beyond_cube(t), -t.w);
    return true;
}

#include "covered_range.glsl"
