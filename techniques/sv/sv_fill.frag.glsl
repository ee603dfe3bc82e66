// A constant colour: the normalisation rectangles, the stencil-to-mask rectangle, the scene
// redrawn onto the screen-buffer mask.
uniform vec4 fill_colour;
layout(location = 0) out vec4 colour;
void main() {
    colour = fill_colour;
}
