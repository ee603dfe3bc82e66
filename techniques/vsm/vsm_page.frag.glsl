// The pool is a depth texture: the nearest caster's window depth per texel, kept by the depth
// test (vsm_shading.frag.glsl turns it back into light depth). Built with ALPHA_TEST (a scene
// with alpha-tested casters), a cut-out texel writes no depth, as in the shared depth pass;
// with COUNT_ALPHA_TESTS too, each alpha test is counted (pages.py, untimed).
#include "../common/cut_out_texel.glsl"
void main() {
    discard_cut_out();
}
