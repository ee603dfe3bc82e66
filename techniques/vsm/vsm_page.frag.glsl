// The pool is a depth texture: the nearest caster's window depth per texel, kept by the depth
// test (vsm_shading.frag.glsl turns it back into light depth).
void main() {
}
