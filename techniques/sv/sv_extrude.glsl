// Shared by the GPU-extruded shadow volumes. Vertices and face planes are in the part's model
// space; the light comes in the same space, as a homogeneous point: (position, 1) for a spot or
// point light (volumes never look at a spot's cone: a point light is a spot without one),
// (-direction, 0) for a directional light. So one plane test serves every light, and a
// rigid per-part transform (model) needs no change to the vertex data.
uniform vec4 light;
uniform mat4 model;
uniform mat4 view_proj;

// A face plane (n, d) with n . x + d = 0 faces the light where the light lies on its front.
bool faces_light(vec4 plane) {
    return dot(plane, light) > 0.0;
}

// p pushed away from the light to infinity (w = 0; Everitt and Kilgard 2002): along the
// light's direction for a directional light, along p - position for a spot or point light.
vec4 at_infinity(vec3 p) {
    return vec4(p * light.w - light.xyz, 0.0);
}

vec4 to_clip(vec4 p) {
    return view_proj * (model * p);
}
