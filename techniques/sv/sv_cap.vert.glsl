// A closed mesh's caps, for z-fail: the faces turned toward the light stay where they are
// (the near cap), the others go to infinity (the far cap; for a directional light all three
// corners reach one point there, so that cap has no area).
#include "sv_extrude.glsl"

layout(location = 0) in vec3 position;
layout(location = 1) in vec4 face_plane;

void main() {
    gl_Position = to_clip(faces_light(face_plane) ? vec4(position, 1.0) : at_infinity(position));
}
