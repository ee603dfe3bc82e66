in vec3 world_position;
flat in vec3 world_normal;
flat in float surface_albedo;
layout(location = 0) out vec4 out_position;  // w = 1 where covered
layout(location = 1) out vec4 out_normal;    // w = albedo
void main() {
    out_position = vec4(world_position, 1.0);
    out_normal = vec4(world_normal, surface_albedo);
}
