layout(location = 0) in vec3 position;
uniform mat4 view_proj;
out vec3 world_position;
#ifdef ALPHA_TEST
layout(location = 1) in vec3 cutout;  // u, v, the cut-out's index (-1: opaque)
out vec2 uv;
flat out int mask;
#endif
void main() {
    world_position = position;
    gl_Position = view_proj * vec4(position, 1.0);
#ifdef ALPHA_TEST
    uv = cutout.xy;
    mask = int(cutout.z);
#endif
}
