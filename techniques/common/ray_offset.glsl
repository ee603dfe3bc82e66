// The shadow ray's origin: the G-buffer point moved off its surface along the normal (turned
// to the light's side), by the rule of Waechter and Binder ("A fast and robust method for
// avoiding self-intersection", Ray Tracing Gems 2019, ch. 6): each coordinate moved by
// OFFSET_ULPS units in the last place of itself times the normal's component (an integer step
// on the float's bits), so the step follows the rounding error of the position wherever it
// lies; within ORIGIN of zero, where ulps vanish, by FLOAT_SCALE times the normal instead.
// The G-buffer position is the rasteriser's float32 interpolation of float32 vertices: its
// error is a few ulps of the coordinates; OFFSET_ULPS = 256 is the paper's margin over it.
#ifndef OFFSET_ULPS
#define OFFSET_ULPS 256.0
#endif
const float ORIGIN = 1.0 / 32.0;
const float FLOAT_SCALE = 1.0 / 65536.0;

vec3 offset_ray(vec3 p, vec3 n) {
    ivec3 step = ivec3(OFFSET_ULPS * n);
    ivec3 signed_step = ivec3(p.x < 0.0 ? -step.x : step.x, p.y < 0.0 ? -step.y : step.y,
                              p.z < 0.0 ? -step.z : step.z);
    vec3 moved = intBitsToFloat(floatBitsToInt(p) + signed_step);
    return mix(moved, p + FLOAT_SCALE * n, lessThan(abs(p), vec3(ORIGIN)));
}
