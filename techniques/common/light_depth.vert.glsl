layout(location = 0) in vec3 position;
uniform mat4 light_view;
uniform mat4 light_proj;
out float light_depth;
#include "cutout_vertex.glsl"
void main() {
    vec4 v = light_view * vec4(position, 1.0);
    light_depth = -v.z;
    gl_Position = light_proj * v;
    pass_cutout();
}
