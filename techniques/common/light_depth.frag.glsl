// Linear light depth (view-space distance along the light axis, scene units): a bias in scene
// units then means the same thing for orthographic and perspective maps.
in float light_depth;
layout(location = 0) out float out_depth;
void main() {
    out_depth = light_depth;
}
