// One invocation per G-buffer pixel: its SAMPLES view samples, on the pixel's surface plane.
// Sample k sits at the pixel's film position plus offset k (a fixed pattern, or the
// reference's own positions per pixel); its world position is where the camera ray through
// that film position meets the plane through the G-buffer point with its normal (Wyman et
// al. 2015: one G-buffer sample, its tangent plane standing in for the pixel's surface). A
// sample at offset 0 is the G-buffer point itself, so one centred sample is rt's ray origin.
// Each sample is moved off its plane as rt moves its ray origin (ray_offset.glsl).
// With RASTER_SURFACE (`surface: raster`) a dispatch places one sample, `sample_index`, of
// every pixel instead, exactly on the surface its ray meets: the G-buffer read is then one
// rendered with the camera moved by that sample's offset (izb.py), whose pixel holds the
// sample's own point and normal; a sample whose ray meets nothing sets its bit in `missed`.
// Writes slot pixel * SAMPLES + k of `positions` (w = 1 for a sample to insert, 0 for none)
// and the pixel's initial mask: the bits of samples whose visible side faces away from the
// light (shadowed, as rt, never inserted). With FIT_VIEW, merges the light NDC of the samples
// inside the light frustum into the Bounds buffer.
layout(local_size_x = 16, local_size_y = 16) in;

uniform sampler2D gbuffer_position;
uniform sampler2D gbuffer_normal;
uniform vec3 camera_position;
uniform mat4 camera_inverse_view_proj;
uniform vec4 light;  // (position, 1) for a spot light, (unit vector towards it, 0) directional

layout(std430, binding = 0) writeonly buffer Positions { vec4 positions[]; };
layout(std430, binding = 2) buffer Masks { uint masks[]; };
#ifdef RASTER_SURFACE
layout(std430, binding = 6) buffer Missed { uint missed[]; };
uniform int sample_index;
#elif defined(REFERENCE_PATTERN)
layout(std430, binding = 4) readonly buffer Offsets { vec2 pixel_offsets[]; };
#else
uniform vec2 offsets[SAMPLES];  // from the pixel's centre, in pixels
#endif

#include "izb_grid.glsl"
#include "../common/ray_offset.glsl"
#include "../common/receives_light.glsl"

// The point of the plane (p, n) seen through film position `film` (window coordinates), or p
// where that ray runs along the plane or away from it. Found as p plus a step within the
// plane (its normal component removed), so the sample lies on the plane to the rounding of
// that sum, however far the camera is.
vec3 on_plane(vec3 p, vec3 n, vec2 film, vec2 size) {
    vec4 far_point = camera_inverse_view_proj * vec4(film / size * 2.0 - 1.0, 1.0, 1.0);
    vec3 dir = far_point.xyz / far_point.w - camera_position;
    float along = dot(n, dir);
    float t = dot(n, p - camera_position) / along;
    if (!(t > 0.0) || isinf(t)) {
        return p;
    }
    vec3 step = camera_position + t * dir - p;
    return p + (step - dot(step, n) * n);
}

void main() {
    ivec2 pixel = ivec2(gl_GlobalInvocationID.xy);
    ivec2 size = textureSize(gbuffer_position, 0);
    if (any(greaterThanEqual(pixel, size))) {
        return;
    }
    uint index = uint(pixel.y * size.x + pixel.x), first = index * uint(SAMPLES);
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    uint mask = 0u;
    vec2 low = vec2(3.0e38), high = vec2(-3.0e38);
    vec3 n = p.w > 0.5 ? normalize(visible_side(texelFetch(gbuffer_normal, pixel, 0).xyz,
                                                p.xyz, camera_position)) : vec3(0.0);
#ifdef RASTER_SURFACE
    int begin = sample_index, end = sample_index + 1;
#else
    int begin = 0, end = SAMPLES;
#endif
    for (int k = begin; k < end; ++k) {
        vec4 sample_at = vec4(0.0);
        if (p.w > 0.5) {
#ifdef RASTER_SURFACE
            vec2 offset = vec2(0.0);  // the G-buffer's own point
#elif defined(REFERENCE_PATTERN)
            vec2 offset = pixel_offsets[first + uint(k)];
#else
            vec2 offset = offsets[k];
#endif
            vec3 q = offset == vec2(0.0)
                ? p.xyz : on_plane(p.xyz, n, vec2(pixel) + 0.5 + offset, vec2(size));
            if (faces_light(q, n, light)) {
                sample_at = vec4(offset_ray(q, n), 1.0);
#ifdef FIT_VIEW
                vec2 ndc;
                if (light_ndc(sample_at.xyz, ndc)) {
                    low = min(low, ndc);
                    high = max(high, ndc);
                }
#endif
            } else {
                mask |= 1u << uint(k);
            }
        }
        positions[first + uint(k)] = sample_at;
    }
#ifdef RASTER_SURFACE
    // the first sample's dispatch starts the pixel's masks, the later ones add their bit
    uint bit = 1u << uint(sample_index);
    uint miss = p.w > 0.5 ? 0u : bit;
    masks[index] = sample_index == 0 ? mask : masks[index] | mask;
    missed[index] = sample_index == 0 ? miss : missed[index] | miss;
#else
    masks[index] = mask;
#endif
#ifdef FIT_VIEW
    if (low.x <= high.x) {
        atomicMin(bounds[0], ordered(low.x));
        atomicMin(bounds[1], ordered(low.y));
        atomicMax(bounds[2], ordered(high.x));
        atomicMax(bounds[3], ordered(high.y));
    }
#endif
}
