// Shadow-volume and scene vertices share this shader, so a near cap and the scene triangle it
// copies get bit-identical depths (a 3-component scene attribute arrives with w = 1).
// Volume vertices at infinity have w = 0; view_proj has an infinite far plane.
layout(location = 0) in vec4 position;
uniform mat4 view_proj;
void main() {
    gl_Position = view_proj * position;
}
