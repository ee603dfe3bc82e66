// Each triangle unchanged: draws the CPU-built volumes through llvmpipe's geometry-shader
// path, the path the GPU's per-triangle volumes take (tests/test_sv_gpu.py).
layout(triangles) in;
layout(triangle_strip, max_vertices = 3) out;
void main() {
    for (int i = 0; i < 3; ++i) {
        gl_Position = gl_in[i].gl_Position;
        EmitVertex();
    }
    EndPrimitive();
}
