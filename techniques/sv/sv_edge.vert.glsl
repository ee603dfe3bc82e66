// One vertex of an edge's degenerate quad (McGuire et al. 2003): each edge of a closed mesh
// is a quad whose two far corners are pushed to infinity where the edge is a silhouette edge
// (one adjacent face lit, the other not) and which collapses to the edge, zero area, where
// it is not. The quad's corners hold both ends (position, other_end), so where the twin face
// is the lit one they swap ends: the quad then winds the other way, outward as before.
#include "sv_extrude.glsl"

layout(location = 0) in vec3 position;
layout(location = 1) in vec3 other_end;
layout(location = 2) in vec4 face_plane;  // the face that holds the edge position -> other_end
layout(location = 3) in vec4 twin_plane;  // the face that holds other_end -> position
layout(location = 4) in float far_corner;

void main() {
    bool lit = faces_light(face_plane);
    bool silhouette = lit != faces_light(twin_plane);
    vec3 p = lit ? position : other_end;
    gl_Position = to_clip(silhouette && far_corner > 0.5 ? at_infinity(p) : vec4(p, 1.0));
}
