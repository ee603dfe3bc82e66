// A triangle's corners, passed on to sv_polygon.geom.glsl, which builds its volume.
layout(location = 0) in vec3 position;
layout(location = 1) in vec4 face_plane;
out vec3 corner_position;
out vec4 corner_plane;

void main() {
    corner_position = position;
    corner_plane = face_plane;
}
