// The alpha/screen state machine (Roettger et al. 2002, section 4.2) with one blend function,
// (GL_DST_COLOR, GL_SRC_COLOR): dst' = 2 src dst, so src = 1 doubles and src = 1/4 halves.
// Which faces increment the count depends on the method (z-pass: front, z-fail: back).
uniform bool front_increments;
uniform vec4 increment_colour;
uniform vec4 decrement_colour;
layout(location = 0) out vec4 colour;
#ifdef CLAMP
// cull: cc's clamp (sv_polygon.geom.glsl), where the mask is the G-buffer's resolution: a
// fragment whose receiver (the G-buffer's sample at this pixel; its light depth stored by
// sv_receivers_grid.comp.glsl, +inf where none) lies outside the volume's light depths is
// dropped. Such a receiver is outside the volume, whose fragments there add up to
// nothing; all others stay, so V is the same. It clamps what reaches the count, not what is
// rasterised (as a depth-bounds test does, in light depth).
flat in vec2 receiver_depths;
uniform sampler2D receiver_depth;
#endif
void main() {
#ifdef CLAMP
    float depth = texelFetch(receiver_depth, ivec2(gl_FragCoord.xy), 0).x;
    if (depth < receiver_depths.x || depth > receiver_depths.y) discard;
#endif
    colour = gl_FrontFacing == front_increments ? increment_colour : decrement_colour;
}
