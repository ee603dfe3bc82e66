// The flat normal and albedo are per face (harness/gl/geometry.py SceneMesh): the face is the
// primitive this fragment belongs to, its index in the draw. Built with ALPHA_TEST (a scene
// with alpha-tested surfaces), the camera sees through a cut-out texel as the light does.
in vec3 world_position;
uniform samplerBuffer face_attributes;  // xyz: flat normal, w: albedo
layout(location = 0) out vec4 out_position;  // w = 1 where covered
layout(location = 1) out vec4 out_normal;    // w = albedo
#ifdef ALPHA_TEST
#include "alpha_test.glsl"
in vec2 uv;
flat in int mask;
#endif
void main() {
#ifdef ALPHA_TEST
    if (cut_out(mask, uv)) {
        discard;
    }
#endif
    out_position = vec4(world_position, 1.0);
    out_normal = texelFetch(face_attributes, gl_PrimitiveID);
}
