layout(location = 0) in vec3 position;
uniform mat4 light_view;
uniform mat4 light_proj;
out float light_depth;
#ifdef ALPHA_TEST
layout(location = 1) in vec3 cutout;  // u, v, the cut-out's index (-1: opaque)
out vec2 uv;
flat out int mask;
#endif
void main() {
    vec4 v = light_view * vec4(position, 1.0);
    light_depth = -v.z;
    gl_Position = light_proj * v;
#ifdef ALPHA_TEST
    uv = cutout.xy;
    mask = int(cutout.z);
#endif
}
