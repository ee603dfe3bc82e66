// One scene edge (EdgeMesh in silhouette_edges.py): is it a silhouette from the light, and
// where does it lie in the silhouette map? As EdgeAdjacency.silhouette and project_edges do
// on the CPU: an edge between a face toward the light and one away from it, or a boundary edge
// of an open mesh (one face), is kept; it is clipped to the light's near plane and projected to
// map texels. The edge's part's pose (a moving object's rigid motion) moves its endpoints and
// turns its faces' normals first. Defines from Python: EDGE_FACES_BINDING,
// FACE_NORMALS_BINDING, PART_POSES_BINDING.
layout(location = 0) in vec3 built_a;
layout(location = 1) in vec3 built_b;
layout(location = 2) in vec2 face_run;   // first entry in edge_faces, number of faces
layout(location = 3) in float part;

layout(std430, binding = EDGE_FACES_BINDING) readonly buffer EdgeFaces { uint edge_faces[]; };
layout(std430, binding = FACE_NORMALS_BINDING) readonly buffer FaceNormals { vec4 face_normals[]; };
layout(std430, binding = PART_POSES_BINDING) readonly buffer PartPoses { mat4 part_poses[]; };

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
        toward += int(dot(turn * face_normals[edge_faces[first + k]].xyz, to_light) > 0.0);
    }
    return faces == 1 || (toward > 0 && toward < faces);
}

vec2 to_texels(vec3 view) {
    vec4 clip = silhouette_proj * vec4(view, 1.0);
    return (clip.xy / clip.w * 0.5 + 0.5) * map_res;
}

void main() {
    mat4 pose = part_poses[int(part)];
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
