// The light's depth pass: only the depth buffer is written (light_depth.frag.glsl is empty).
layout(location = 0) in vec3 position;
uniform mat4 light_view;
uniform mat4 light_proj;
void main() {
    gl_Position = light_proj * light_view * vec4(position, 1.0);
}
