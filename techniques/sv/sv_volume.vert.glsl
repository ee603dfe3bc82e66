// Shadow-volume vertices: homogeneous world positions (w = 1 on the caster, w = 0 at infinity),
// transformed like the G-buffer's scene (gbuffer.vert.glsl), so a cap and the scene triangle it
// copies get the same depth. Where on_near_plane is 1 the vertex is a near-plane clip
// polygon's, given as normalised device x, y: computed in double precision, since in float32
// world coordinates far from the origin a polygon a near distance from the eye is lost.
layout(location = 0) in vec4 position;
layout(location = 1) in float on_near_plane;
uniform mat4 view_proj;
void main() {
    gl_Position = on_near_plane > 0.5 ? vec4(position.xy, -1.0, 1.0) : view_proj * position;
}
