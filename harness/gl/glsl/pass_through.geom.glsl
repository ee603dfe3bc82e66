// Each triangle passed on unchanged, reading nothing: harness.gl.objects.drop_stale_bindings'
// draw, and the tests' path of the CPU-built volumes through llvmpipe's geometry stage
// (tests/techniques/test_sv_gpu.py).
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;

void main() {
    for (int i = 0; i < 3; ++i) {
        gl_Position = gl_in[i].gl_Position;
        EmitVertex();
    }
    EndPrimitive();
}
