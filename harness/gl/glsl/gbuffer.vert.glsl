layout(location = 0) in vec3 position;
uniform mat4 view_proj;
out vec3 world_position;
#include "cutout_vertex.glsl"
void main() {
    world_position = position;
    gl_Position = view_proj * vec4(position, 1.0);
    pass_cutout();
}
