// The view samples: the G-buffer's position at one pixel per `divisor` x `divisor` block (the
// mask's resolution, mask_res), the block's pixel nearest its centre, relative to `origin`
// (ptsv_volume.glsl); w = 1 where covered.
uniform sampler2D gbuffer_position;
uniform int divisor;

vec4 sample_position(uvec2 s) {
    ivec2 pixel = min(ivec2(s) * divisor + divisor / 2, textureSize(gbuffer_position, 0) - 1);
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    return vec4(p.xyz - origin, p.w);
}

#ifdef SAMPLES
// Whether a covered sample receives the light (common/receives_light.glsl): one that does not
// the box pass marks shadowed and leaves out of the boxes, as rt casts no ray there.
#include "../common/receives_light.glsl"
uniform sampler2D gbuffer_normal;
uniform vec3 camera_position;  // world space, as the G-buffer's positions
uniform vec4 light_vector;  // (position, 1) for a spot or point light, (-direction, 0) directional

bool receives_light(uvec2 s) {
    ivec2 pixel = min(ivec2(s) * divisor + divisor / 2, textureSize(gbuffer_position, 0) - 1);
    vec3 p = texelFetch(gbuffer_position, pixel, 0).xyz;
    return faces_light(p, visible_side(texelFetch(gbuffer_normal, pixel, 0).xyz, p,
                                       camera_position), light_vector);
}
#endif

// Clusters (`slices` > 1): a covered sample's depth slice, its view depth quantised in log scale
// between the nearest and farthest view depths of the scene's bounds (slices at either end take
// what lies beyond); the box pass stores it per sample, which the traversal and V then read.
layout(std430, binding = 9) buffer Slices { uint sample_slices[]; };
uniform usamplerBuffer slice_texels;  // the same, read as a buffer texture by the traversal
uniform vec4 depth_plane;  // view depth of a position relative to `origin`: dot(xyz, p) + w
uniform vec2 slice_map;  // slice = floor(log(depth) * x + y), clamped to 0 .. slices - 1

uint slice_of_depth(float depth) {
    return uint(clamp(floor(log(max(depth, 1.0e-30)) * slice_map.x + slice_map.y), 0.0,
                      float(slices - 1u)));
}

uint depth_slice(vec3 p) {
    return slice_of_depth(dot(depth_plane.xyz, p) + depth_plane.w);
}
