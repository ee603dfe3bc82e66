// The G-buffer pass as it was before indexed meshes (3 unshared vertices per triangle, the
// flat normal and albedo as vertex attributes): the oracle of tests/test_indexed_mesh.py.
layout(location = 0) in vec3 position;
layout(location = 1) in vec3 normal;
layout(location = 2) in float albedo;
uniform mat4 view_proj;
out vec3 world_position;
flat out vec3 world_normal;
flat out float surface_albedo;
void main() {
    world_position = position;
    world_normal = normal;
    surface_albedo = albedo;
    gl_Position = view_proj * vec4(position, 1.0);
}
