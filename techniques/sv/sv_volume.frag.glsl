// The alpha/screen state machine (Roettger et al. 2002, section 4.2) with one blend function,
// (GL_DST_COLOR, GL_SRC_COLOR): dst' = 2 src dst, so src = 1 doubles and src = 1/4 halves.
// Which faces increment the count depends on the method (z-pass: front, z-fail: back).
uniform bool front_increments;
uniform vec4 increment_colour;
uniform vec4 decrement_colour;
layout(location = 0) out vec4 colour;
void main() {
    colour = gl_FrontFacing == front_increments ? increment_colour : decrement_colour;
}
