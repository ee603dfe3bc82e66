// Whether a G-buffer sample receives the light: its visible side (the normal turned toward the
// camera) faces the light. One that does not receives no direct light whatever shadows it, so
// the exact techniques (rt, ptsv) give it V = 0 and test nothing there; harness.truth.metrics'
// receives_light leaves such pixels out of every comparison (a spot's cone is not asked here).

vec3 visible_side(vec3 n, vec3 p, vec3 camera_position) {
    return dot(n, camera_position - p) >= 0.0 ? n : -n;
}

// `light`: (position, 1) for a spot or point light, (unit vector toward it, 0) directional;
// `n` the visible side's normal
bool faces_light(vec3 p, vec3 n, vec4 light) {
    return dot(n, light.xyz - p * light.w) > 0.0;
}
