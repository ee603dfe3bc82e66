// The percentage-closer sample region (Reeves, Salesin, Cook 1987), shared by every technique
// that filters a shadow test over map samples. grid_n x grid_n samples per pixel in a region
// centred on the point:
// - footprint region (Reeves et al., section 3.2 and Figure 4): the bounding box in the map of
//   the pixel's footprint on its receiver plane, times res_factor, each side at least min_size
//   texels. Grid samples run evenly from one side of the region to the other (the region, not
//   grid_n, sets how far they reach); jittered samples move uniformly inside their grid_n x
//   grid_n sub-regions (stratified jitter, the paper's method c).
// - fixed region: grid_n x grid_n sub-regions of side `spacing` texels, sampled at their
//   centres or jittered inside them.
// A constant bias is drawn per sample from [bias_min, bias_max] (the paper's Figure 4), plus
// the slope term of shadow_map.glsl for the texel the sample reads (and, for depths a map texel
// holds chosen from a window, to the farthest texel of [window_low, window_high]); under
// bias_mode adaptive no constant, and the tangent plane's depth on each read's light ray
// instead of the slope term (shadow_map.glsl).
// The including shader defines sample_test(texel, depth, bias, window_bias): the per-sample
// outcome in [0, 1], 1 = lit; `bias` has the slope term of the texel read itself, `window_bias`
// that of the farthest texel of its window (equal where the window is (0, 0)).
#include "gbuffer_read.glsl"
#include "shadow_map.glsl"

uniform int grid_n;
uniform bool footprint_region;
uniform float res_factor;
uniform float min_size;
uniform float spacing;
uniform float bias_min;
uniform float bias_max;
uniform vec2 window_low;
uniform vec2 window_high;
uniform bool jitter;
uniform uint seed;
// the camera ray through window position (x, y): camera_ray + x camera_ray_dx + y camera_ray_dy
uniform vec3 camera_position;
uniform vec3 camera_ray;
uniform vec3 camera_ray_dx;
uniform vec3 camera_ray_dy;

// A pixel seeing a plane edge-on covers an unbounded strip of the map; its region stops here
// (a shader whose reads must stay within pages it marked defines a smaller one).
#ifndef MAX_FOOTPRINT
#define MAX_FOOTPRINT 64.0
#endif

float sample_test(vec2 texel, float depth, float bias, float window_bias);

uint pcg(uint v) {
    uint state = v * 747796405u + 2891336453u;
    uint word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}

float random01(uint pixel, uint sample_index, uint stream) {
    return float(pcg(pcg(pcg(pixel ^ seed) + sample_index) + stream)) / 4294967296.0;
}

// Map position of the receiver plane (point, normal) seen through window position `window`.
vec2 receiver_texel_at(vec2 window, vec3 point, vec3 normal) {
    vec3 ray = camera_ray + window.x * camera_ray_dx + window.y * camera_ray_dy;
    float t = dot(normal, point - camera_position) / dot(normal, ray);
    return to_light(camera_position + t * ray).texel;
}

// Side lengths, in texels, of the bounding box of this pixel's footprint in the map.
vec2 pixel_footprint(vec3 point, vec3 normal) {
    vec2 centre = gl_FragCoord.xy;
    vec2 across_x = receiver_texel_at(centre + vec2(0.5, 0.0), point, normal)
                    - receiver_texel_at(centre - vec2(0.5, 0.0), point, normal);
    vec2 across_y = receiver_texel_at(centre + vec2(0.0, 0.5), point, normal)
                    - receiver_texel_at(centre - vec2(0.0, 0.5), point, normal);
    vec2 extent = abs(across_x) + abs(across_y);
    // an edge-on plane gives inf or nan, which min() would not catch
    return all(lessThan(extent, vec2(MAX_FOOTPRINT))) ? extent : vec2(MAX_FOOTPRINT);
}

// V of this fragment's G-buffer pixel: the mean of sample_test over the region's samples.
float filtered_visibility() {
    vec3 p, n;
    if (!gbuffer_fetch(p, n)) return 1.0;
    Receiver r = receiver(p, n);
    if (!r.in_front) return 1.0;
    vec2 side = footprint_region ? max(res_factor * pixel_footprint(p, n), vec2(min_size))
                                 : vec2(float(grid_n) * spacing);
    // sample i of a row sits at (i + place) / grid_n of the side, place in [0, 1)
    float stretch = footprint_region && !jitter && grid_n > 1
                    ? float(grid_n) / float(grid_n - 1) : 1.0;
    uint pixel = uint(gl_FragCoord.y) * 65536u + uint(gl_FragCoord.x);
    float lit = 0.0;
    for (int j = 0; j < grid_n; ++j) {
        for (int i = 0; i < grid_n; ++i) {
            uint index = uint(j * grid_n + i);
            vec2 place = jitter ? vec2(random01(pixel, index, 0u), random01(pixel, index, 1u))
                                : vec2(0.5);
            vec2 offset = ((vec2(i, j) + place) / float(grid_n) - 0.5) * side * stretch;
            vec2 at = r.texel + offset;
            float constant = bias_mode == BIAS_ADAPTIVE
                             ? 0.0 : bias_min + (bias_max - bias_min) * random01(pixel, index, 2u);
            vec2 centre = floor(at) + 0.5;
            lit += sample_test(at, r.depth,
                               constant + receiver_bias(r, centre, vec2(0.0), vec2(0.0)),
                               constant + receiver_bias(r, centre, window_low, window_high));
        }
    }
    return lit / float(grid_n * grid_n);
}
