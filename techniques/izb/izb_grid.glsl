// The irregular grid: `grid_res` x `grid_res` texels over a rectangle of the light's
// normalised device coordinates (the light frustum of harness.scene.transforms.fit_light).
// `fit: plain` takes the whole frustum, [-1, 1]^2; `fit: view` the rectangle the view's
// samples span, which izb_samples.comp.glsl merges into the Bounds buffer by integer atomics
// on an order-preserving encoding of the floats (as harness/gl/glsl/covered_range.glsl) and
// every later pass reads back on the GPU, with no read-back to the CPU.
uniform mat4 light_view_proj;
uniform float min_w;     // a spot light's near plane (clip w): nearer points are not gridded
uniform int grid_res;

// How far past half a texel conservative rasterisation reaches, in texels: the projections of
// a sample and of a triangle are rounded apart (a few units in the last place of coordinates
// up to 8192 texels, more where a spot light's w is small), and a sample on the triangle's
// shadow boundary must still find its texel rasterised.
const float MARGIN = 1.0 / 32.0;

layout(std430, binding = 3) buffer Bounds {
    uint bounds[4];  // ordered floats: low x, low y, high x, high y
};

uint ordered(float f) {
    uint u = floatBitsToUint(f);
    return (u & 0x80000000u) != 0u ? ~u : u | 0x80000000u;
}

float unordered(uint u) {
    return uintBitsToFloat((u & 0x80000000u) != 0u ? u & 0x7FFFFFFFu : ~u);
}

// The light's NDC of a world point, false where it lies behind the near plane or outside the
// frustum's square.
bool light_ndc(vec3 world, out vec2 ndc) {
    vec4 clip = light_view_proj * vec4(world, 1.0);
    if (!(clip.w > min_w)) {
        return false;
    }
    ndc = clip.xy / clip.w;
    return all(lessThanEqual(abs(ndc), vec2(1.0)));
}

// The grid's rectangle in NDC: its low corner and its texels per NDC unit. An empty one (no
// sample counted) gets a tiny rectangle: nothing is inserted in it, nothing rasterised.
void grid_rectangle(out vec2 low, out vec2 scale) {
    low = vec2(unordered(bounds[0]), unordered(bounds[1]));
    vec2 high = vec2(unordered(bounds[2]), unordered(bounds[3]));
    vec2 span = max(high - low, vec2(1e-6));
    scale = float(grid_res) / span;
}

// Grid coordinates (texels, real) of an NDC point.
vec2 grid_position(vec2 ndc) {
    vec2 low, scale;
    grid_rectangle(low, scale);
    return (ndc - low) * scale;
}
