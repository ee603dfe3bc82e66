// Writes 1 and reads nothing: harness.gl.objects.drop_stale_bindings' pixel.
out vec4 colour;

void main() {
    colour = vec4(1.0);
}
