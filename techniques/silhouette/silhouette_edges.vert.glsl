// One scene edge (EdgeMesh in silhouette_edges.py): is it a silhouette from the light, and
// where does it lie in the silhouette map? As EdgeAdjacency.silhouette and project_edges do
// on the CPU: an edge between a face toward the light and one away from it, or a boundary edge
// of an open mesh (one face), is kept; it is clipped to the light's near plane and projected to
// map texels. The edge's part's pose (a moving object's rigid motion) moves its endpoints and
// turns its faces' normals first. The face list, normals and poses are buffer textures, not
// storage buffers: llvmpipe's storage-buffer load is the slower (EdgeMesh).
layout(location = 0) in vec3 built_a;
layout(location = 1) in vec3 built_b;
layout(location = 2) in vec2 face_run;   // first entry in edge_faces, number of faces
layout(location = 3) in float part;

uniform usamplerBuffer edge_faces;   // R32UI: the faces of each edge, edge after edge
uniform samplerBuffer face_normals;  // RGBA32F: xyz each face's normal
uniform samplerBuffer part_poses;    // RGBA32F: each part's pose, four texels (columns)

// The edge mesh's frame (EdgeMesh.uniforms): positions relative to its origin, so float32 never
// holds a coordinate as large as the scene's distance from the world origin.
uniform mat4 light_view_model;  // the silhouette map's light view (without the depth map's
uniform mat4 silhouette_proj;   // half-texel offset) after the mesh's model transform
uniform vec4 light_in_model;    // (toward the light, 0) directional, (position, 1) spot
uniform float near;
uniform float map_res;

out EdgeData {
    flat int kept;
    vec2 a;        // map texels
    vec2 b;
    vec2 depths;   // light view distance of a and b
} edge;

bool is_silhouette(vec3 a, mat3 turn) {
    // a lies in the plane of every face around the edge, so it stands for their centroids
    vec3 to_light = light_in_model.xyz - light_in_model.w * a;
    int first = int(face_run.x), faces = int(face_run.y);
    int toward = 0;
    for (int k = 0; k < faces; ++k) {
        vec3 normal = texelFetch(face_normals, int(texelFetch(edge_faces, first + k).r)).xyz;
        toward += int(dot(turn * normal, to_light) > 0.0);
    }
    return faces == 1 || (toward > 0 && toward < faces);
}

vec2 to_texels(vec3 view) {
    vec4 clip = silhouette_proj * vec4(view, 1.0);
    return (clip.xy / clip.w * 0.5 + 0.5) * map_res;
}

void main() {
    int column = 4 * int(part);
    mat4 pose = mat4(texelFetch(part_poses, column), texelFetch(part_poses, column + 1),
                     texelFetch(part_poses, column + 2), texelFetch(part_poses, column + 3));
    vec3 endpoint_a = (pose * vec4(built_a, 1.0)).xyz;
    vec3 endpoint_b = (pose * vec4(built_b, 1.0)).xyz;
    vec3 view_a = (light_view_model * vec4(endpoint_a, 1.0)).xyz;
    vec3 view_b = (light_view_model * vec4(endpoint_b, 1.0)).xyz;
    float depth_a = -view_a.z, depth_b = -view_b.z;
    edge.kept = int(is_silhouette(endpoint_a, mat3(pose))
                    && (depth_a >= near || depth_b >= near));
    if (depth_a < near) {
        view_a += (near - depth_a) / (depth_b - depth_a) * (view_b - view_a);
        depth_a = near;
    } else if (depth_b < near) {
        view_b += (near - depth_b) / (depth_a - depth_b) * (view_a - view_b);
        depth_b = near;
    }
    edge.a = to_texels(view_a);
    edge.b = to_texels(view_b);
    edge.depths = vec2(depth_a, depth_b);
    gl_Position = vec4(0.0);
}
