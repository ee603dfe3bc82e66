// A vertex shader's side of the cut-outs (ALPHA_TEST: a scene with alpha-tested surfaces):
// SceneMesh's attribute at location 1 (u, v, the cut-out's index, -1: opaque) passed on as uv
// and mask to the fragment shader's alpha_test.glsl. Without ALPHA_TEST nothing is read.
#ifdef ALPHA_TEST
layout(location = 1) in vec3 cutout;
out vec2 uv;
flat out int mask;
#endif

void pass_cutout() {
#ifdef ALPHA_TEST
    uv = cutout.xy;
    mask = int(cutout.z);
#endif
}
