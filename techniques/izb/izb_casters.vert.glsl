layout(location = 0) in vec3 position;
out vec3 world;
#ifdef ALPHA_TEST
layout(location = 1) in vec3 cutout;  // u, v, the cut-out's index (-1: opaque)
out vec3 corner_cutout;
#endif
void main() {
    world = position;
#ifdef ALPHA_TEST
    corner_cutout = cutout;
#endif
}
