layout(location = 0) in vec3 position;
out vec3 world;
void main() {
    world = position;
}
