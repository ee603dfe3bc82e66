// One any-hit shadow ray per mask texel, from the G-buffer point at the texel's centre pixel
// to the light, through a two-level BVH (rt_bvh.py): the top level over the parts' instances
// in world space, each leaf one instance whose bottom-level BVH is in the part's own space
// (the ray moved there by the instance's world-to-object transform). One stack serves both
// levels (Aila and Laine 2009's while-while loop, one level at a time). Early exit on the
// first hit. Writes V (0/1) to `mask`; with COUNT defined also nodes entered, triangle tests,
// whether it was occluded and its alpha tests, per ray, to `counts`. With ALPHA_TEST (a scene
// with alpha-tested casters) a hit on a cut-out texel (alpha_test.glsl's rule at the hit's
// texture coordinates) does not end the ray: any hit, not the first.
layout(local_size_x = 16, local_size_y = 16) in;

layout(r32f, binding = 0) writeonly uniform image2D mask;
#ifdef COUNT
layout(rgba32ui, binding = 1) writeonly uniform uimage2D counts;
#endif
uniform sampler2D gbuffer_position;
uniform sampler2D gbuffer_normal;
uniform samplerBuffer nodes;      // the top level's records, then all parts' bottom-level
                                  // ones (bvh.py's texels); a top-level leaf is one instance
uniform samplerBuffer triangles;  // 3 texels (vertices) per triangle, in leaf order
uniform int tlas_root;            // the top level's root entry
uniform samplerBuffer instances;  // 4 texels: rows of world-to-object 3x4, (root entry, ...)
uniform int divisor;              // image pixels per mask texel along each axis
uniform bool directional;
uniform vec3 light;               // directional: unit vector towards the light; else position
uniform vec3 camera_position;

#include "../common/ray_offset.glsl"
#include "../common/receives_light.glsl"
#include "rt_watertight.glsl"
#ifdef ALPHA_TEST
#include "alpha_test.glsl"
uniform samplerBuffer cutouts;  // 2 texels per triangle, in leaf order: (u0, v0, u1, v1),
                                // (u2, v2, its cut-out's index or -1, 0)

// Whether triangle i is cut out where the ray hit it (barycentric `weights`).
bool cut_out_hit(int i, vec3 weights) {
    vec4 a = texelFetch(cutouts, 2 * i), b = texelFetch(cutouts, 2 * i + 1);
    return cut_out(int(b.z), weights.x * a.xy + weights.y * a.zw + weights.z * b.xy);
}
#endif

uint bits(float f) { return floatBitsToUint(f); }

// Slab test with the far distance widened by 1 + 2 gamma(3) (Ize 2013, "Robust BVH ray
// traversal"), so rounding never rejects a box the ray touches: with the watertight triangle
// test it keeps a ray aimed at a shared edge from slipping between two boxes. The distance
// where the ray enters the box (>= 0), or -1 where it misses it.
float box_enter(vec3 lo, vec3 hi, vec3 origin, vec3 inv, float tmax) {
    vec3 t0 = (lo - origin) * inv, t1 = (hi - origin) * inv;
    vec3 near = min(t0, t1), far = max(t0, t1);
    float enter = max(max(near.x, near.y), max(near.z, 0.0));
    float leave = min(min(far.x, far.y), min(far.z, tmax)) * 1.0000004;
    return enter <= leave ? enter : -1.0;
}

vec3 safe_inverse(vec3 d) {
    const float tiny = 1e-30;  // a zero component: a huge inverse of its sign, never inf * 0
    vec3 s = vec3(greaterThanEqual(d, vec3(0.0))) * 2.0 - 1.0;
    return 1.0 / mix(d, s * tiny, lessThan(abs(d), vec3(tiny)));
}

// An entry names a node (bvh.py): a record (an internal node: both children's boxes and
// entries, four texels) by its index, or a leaf by its count (top 5 bits) and first primitive.
const uint COUNT_SHIFT = 27u;
const uint FIRST_MASK = (1u << COUNT_SHIFT) - 1u;

// true where the segment (origin, origin + t dir), 0 < t < tmax, meets a triangle. Each step
// enters one node: a record tests both children's boxes and goes on into the nearer child it
// hits, the other one pushed; a leaf tests its triangles (bottom level) or moves the ray into
// its instance's space and enters the part's root (top level). Aila and Laine's while-while
// loop: a ray steps through internal nodes until it holds a leaf, so the rays of one SIMD
// batch (llvmpipe runs 8 invocations as one) test their leaves together; on foliage,
// instancing and architecture at 10^6 triangles 1.4-1.6x faster than entering one node of
// either kind per step (same V).
bool occluded(vec3 world_origin, vec3 world_dir, float tmax, out uint visited, out uint tested,
              out uint alpha_tests) {
    const uint POP = 0xFFFFFFFFu;  // no leaf has 31 primitives: the entry "take the next one"
    uint stack[STACK_SIZE];
    int sp = 0, floor_sp = 0;
    bool bottom = false;
    uint entry = uint(tlas_root);
    vec3 origin = world_origin, dir = world_dir, inv = safe_inverse(dir);
    Watertight ray;
    visited = 0u;
    tested = 0u;
    alpha_tests = 0u;
    vec3 weights;
    while (true) {
        // internal nodes (and pops) until a leaf: the rays of a SIMD batch then test their
        // leaves together (Aila and Laine's while-while)
        while ((entry >> COUNT_SHIFT) == 0u || entry == POP) {
            if (entry == POP) {
                if (bottom && sp == floor_sp) {  // the instance is done: back to the top level
                    bottom = false;
                    origin = world_origin;
                    dir = world_dir;
                    inv = safe_inverse(dir);
                }
                if (sp == 0) {
                    return false;
                }
                entry = stack[--sp];
                continue;
            }
            visited++;
            int at = int(4u * entry);
            vec4 lo0 = texelFetch(nodes, at), hi0 = texelFetch(nodes, at + 1);
            vec4 lo1 = texelFetch(nodes, at + 2), hi1 = texelFetch(nodes, at + 3);
            float enter0 = box_enter(lo0.xyz, hi0.xyz, origin, inv, tmax);
            float enter1 = box_enter(lo1.xyz, hi1.xyz, origin, inv, tmax);
            bool hit0 = enter0 >= 0.0, hit1 = enter1 >= 0.0;
            bool first0 = hit0 && (!hit1 || enter0 <= enter1);  // the nearer child hit
            if (hit0 && hit1) {
                stack[sp++] = bits(first0 ? lo1.w : lo0.w);
            }
            entry = hit0 || hit1 ? bits(first0 ? lo0.w : lo1.w) : POP;
        }
        visited++;
        uint count = entry >> COUNT_SHIFT, first = entry & FIRST_MASK;
        if (bottom) {
            for (uint i = first; i < first + count; ++i) {
                tested++;
                int t = int(3u * i);
                if (watertight_hit(ray, texelFetch(triangles, t).xyz,
                                   texelFetch(triangles, t + 1).xyz,
                                   texelFetch(triangles, t + 2).xyz, tmax, weights)) {
#ifdef ALPHA_TEST
                    alpha_tests++;
                    if (cut_out_hit(int(i), weights)) {
                        continue;
                    }
#endif
                    return true;
                }
            }
            entry = POP;
        } else {  // an instance: into the part's space, down its bottom level
            int k = int(4u * first);
            mat4x3 to_object = transpose(mat3x4(texelFetch(instances, k),
                                                texelFetch(instances, k + 1),
                                                texelFetch(instances, k + 2)));
            origin = to_object * vec4(world_origin, 1.0);
            dir = to_object * vec4(world_dir, 0.0);
            inv = safe_inverse(dir);
            ray = watertight_setup(origin, dir);
            bottom = true;
            floor_sp = sp;
            entry = bits(texelFetch(instances, k + 3).x);
        }
    }
}

void main() {
    ivec2 texel = ivec2(gl_GlobalInvocationID.xy);
    if (any(greaterThanEqual(texel, imageSize(mask)))) {
        return;
    }
    ivec2 size = textureSize(gbuffer_position, 0);
    ivec2 pixel = min(texel * divisor + divisor / 2, size - 1);
    vec4 p = texelFetch(gbuffer_position, pixel, 0);
    float v = 1.0;
    uint visited = 0u, tested = 0u, alpha_tests = 0u;
    if (p.w > 0.5) {
        // the visible side facing away from the light receives no light: V = 0 and no ray,
        // as engines skip it
        vec3 n = visible_side(texelFetch(gbuffer_normal, pixel, 0).xyz, p.xyz, camera_position);
        v = 0.0;
        if (faces_light(p.xyz, n, vec4(light, directional ? 0.0 : 1.0))) {
            vec3 origin = offset_ray(p.xyz, n);
            vec3 dir = directional ? light : light - origin;
            float tmax = directional ? 3.0e38 : 1.0;
            v = occluded(origin, dir, tmax, visited, tested, alpha_tests) ? 0.0 : 1.0;
        }
    }
    imageStore(mask, texel, vec4(v));
#ifdef COUNT
    imageStore(counts, texel, uvec4(visited, tested, v == 0.0 ? 1u : 0u, alpha_tests));
#endif
}
