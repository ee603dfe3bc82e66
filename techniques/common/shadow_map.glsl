// Lookups into a linear-depth shadow map made by light_depth.*.glsl, and the depth bias every
// map technique uses. A depth read at map position c for a point at map position u stands for
// the receiver at c: on the receiver's plane its light depth is depth + g . (c - u), g being
// the plane's depth change per texel (the receiver plane of Isidoro 2006, "Shadow mapping:
// GPU-based tips and techniques", GDC, and Schueler 2006, "Eliminating surface acne with
// gradient shadow mapping", ShaderX4). A read needs that much bias or the plane shadows
// itself (acne), so each read gets
//     bias + slope_bias * |g| * |c - u|
// with c the centre of the texel actually read (for a depth chosen from a window of texels,
// the farthest texel of the window). |g| is the slope-scaled bias of a shadow map
// (texel size x tan of the light's incidence, for an orthographic map), here taken per read
// and times the read's distance in texels of the technique's own map, so one slope_bias serves
// every scene size, map size and sampling pattern; slope_bias 1 covers a planar receiver in
// every direction. The bound |g| |c - u| rather than the signed g . (c - u) also keeps a
// receiver lit where a read lands on a surface meeting it in a concave contact (a floor at a
// wall's foot), which the plane alone does not describe: with the signed term castle's wall
// feet kept 0.17 % of the pixels in acne at map 4096 (256 x 256 image), 0.07 % with this one.
// The plane comes from the G-buffer's flat normal, not from screen-space derivatives, so it
// is exact where a pixel quad straddles two surfaces. `bias` stays in scene units (depth
// precision, the papers' constant Bias); every test also adds `depth_precision`, the float32
// rounding of coordinates as large as the scene's (techniques/shadowmap.py), which only
// matters far from the origin. That is bias_mode slope, every technique's default;
// receiver_plane and adaptive form the read's receiver depth otherwise (at receiver_bias).
// The plane is a guess where the receiver is not planar within the reach of its reads (curved
// or creased surfaces, a footprint region widened at grazing angles). There the point itself
// can move before any read: by normal_offset x w x sin(theta), w the texel's world size at the
// point (its local one in a warped map; in a cascade, that cascade's; for a point light's cube,
// the face texel at the point's distance along the face's axis, 2 d / res), theta the angle
// between normal and light ray, along the normal's side facing the light (the side the
// reference's shadow ray leaves from). A moved point takes its own cube face (it may cross a
// face's edge); csm keeps the cascade of the unmoved point. On a plane that clears
// normal_offset texels of reach at any angle: the point comes normal_offset x w x tan(theta)
// nearer the light along its ray, as much as the plane rises over that reach; the offset
// stays within a texel where the slope term grows as the tangent.
// Its default is 0. Measured with every other parameter at its default (512 x 512 views; maps
// 256, 1024, 4096; the ten shipped scenes and architecture at 10^5 triangles: 99 pcf, mdsm and
// silhouette runs), the acne/leak bar of tests/test_fair_bias.py holds on 69 runs at 0, 0.25
// and 0.5 (at 0.5 pins' mdsm at map 1024 and terrain_long's silhouette at 256 gain, castle's
// and architecture's pcf at 1024 lose) and on 66 at 1, while each technique's median mae grows
// by up to 0.6 %, 5 % and 16 %. The plane term already clears every planar read; the offset
// moves whole shadows by its rise, pushes points into the neighbour at a concave contact
// (crowd: sm's acne 0 -> 0.08 % at 1) and lifts ground points out of short shadows
// (terrain_long: sm's leak 0.10 -> 0.37 %). Where it helps, terrain_long's texels of 17-270
// pixels, no value reaches the bar (pcf's acne 9.5 -> 6.8 % at 1).
//
// A shader that picks one of several maps per pixel (csm's cascades) defines MAP_PER_PIXEL
// before the include and declares light_view, light_proj and map_res as globals it sets before
// calling receiver(), and map_depth(cell), the depth of the chosen map. A point light's cube
// (CUBE_FACES: cube_faces.glsl) is such a shader's part: there receiver() picks the face.
#ifdef CUBE_FACES
#define MAP_PER_PIXEL 1
#include "cube_faces.glsl"
#else
void choose_face(vec3 world) {}  // light_view is already the point's
#endif
#ifndef MAP_PER_PIXEL
uniform sampler2D shadow_map;
uniform mat4 light_view;
uniform mat4 light_proj;
uniform float map_res;
float map_depth(ivec2 cell) { return texelFetch(shadow_map, cell, 0).r; }
#endif
uniform bool light_is_ortho;
uniform float slope_bias;
uniform float depth_precision;  // float32 rounding of depths this far from the origin
uniform float normal_offset;  // texels of the map at the point
uniform int bias_mode;  // BIAS_SLOPE, BIAS_RECEIVER_PLANE or BIAS_ADAPTIVE
const int BIAS_SLOPE = 0;
const int BIAS_RECEIVER_PLANE = 1;
const int BIAS_ADAPTIVE = 2;

// Receiver planes closer to edge-on than this (tan of the angle between normal and light,
// measured per map texel) take this slope: the bias stays finite.
const float MAX_TAN = 100.0;

struct LightSample {
    vec2 texel;      // continuous map coordinates, in texels
    float depth;     // light view-space distance
    bool in_front;   // false behind a perspective light
};

// A shaded point with its receiver plane.
struct Receiver {
    vec2 texel;
    float depth;
    bool in_front;
    vec2 depth_slope;  // d depth / d texel on the receiver plane
    // what bias_mode adaptive needs: the plane's normal, the map's rows at the (moved) point
    vec3 normal;
    vec3 row_x;        // rows x, y and w of light_proj x light_view (world -> clip)
    vec3 row_y;
    vec3 row_w;
    float clip_w;      // clip w of the point
    vec3 depth_w;      // the direction light depth grows along
    float texel_world; // the texel's larger world side at the point
};

LightSample to_light(vec3 world) {
    vec4 v = light_view * vec4(world, 1.0);
    vec4 clip = light_proj * v;
    LightSample s;
    s.depth = -v.z;
    s.in_front = clip.w > 0.0;
    s.texel = (clip.xy / clip.w * 0.5 + 0.5) * map_res;
    return s;
}

// d texel / d world (two rows) and the direction light depth grows along, at a point of the
// current map (for a cube, of the face chosen last).
struct MapJacobian {
    vec3 texel_x;
    vec3 texel_y;
    vec3 depth_w;
};

MapJacobian map_jacobian(vec3 world) {
    mat4 m = light_proj * light_view;
    vec4 c = m * vec4(world, 1.0);
    vec3 row_x = vec3(m[0].x, m[1].x, m[2].x);
    vec3 row_y = vec3(m[0].y, m[1].y, m[2].y);
    vec3 row_w = vec3(m[0].w, m[1].w, m[2].w);
    MapJacobian j;
    j.texel_x = (row_x - c.x / c.w * row_w) * (0.5 * map_res / c.w);
    j.texel_y = (row_y - c.y / c.w * row_w) * (0.5 * map_res / c.w);
    j.depth_w = -vec3(light_view[0].z, light_view[1].z, light_view[2].z);
    return j;
}

// The smaller singular value of d texel / d world: 1 / the texel's larger world side there
// (a cube face's texel at the point's distance, a cascade's own texel, a warped map's local one).
float texels_per_world(MapJacobian j) {
    float a_sq = dot(j.texel_x, j.texel_x), b_sq = dot(j.texel_y, j.texel_y);
    float ab = dot(j.texel_x, j.texel_y);
    return sqrt(0.5 * (a_sq + b_sq)
                - sqrt(max(0.25 * (a_sq - b_sq) * (a_sq - b_sq) + ab * ab, 0.0)));
}

// The lookup point of normal_offset (see the header): the point moved along its normal's
// light-facing side by normal_offset x the texel's world size there x sin(light angle).
vec3 normal_offset_point(vec3 world, vec3 n, MapJacobian j) {
    // the light ray through the point (the map position does not move along it), to the light
    vec3 to_light_ray = normalize(cross(j.texel_x, j.texel_y));
    if (dot(to_light_ray, j.depth_w) > 0.0) to_light_ray = -to_light_ray;
    float cos_light = dot(n, to_light_ray);
    float sin_light = sqrt(max(1.0 - cos_light * cos_light, 0.0));
    vec3 lit_side = cos_light < 0.0 ? -n : n;
    return world + lit_side * (normal_offset * sin_light / texels_per_world(j));
}

// The point in light space with its receiver plane's depth slope per texel: the Jacobian of
// (texel, depth) along two tangents of the plane, inverted. Valid for any projective map
// (orthographic, perspective, warped): depth is affine in world space, the map position
// projective. With normal_offset the point is first moved (normal_offset_point) and the plane,
// parallel to the receiver's, is taken there; a point light's moved point takes its own face,
// so a point by a face's edge moved past it still reads real depths rather than falling off
// the face (which counts as lit).
Receiver receiver(vec3 world, vec3 normal) {
    vec3 n = normalize(normal);
    choose_face(world);  // the point's face serves every read of its receiver plane
    MapJacobian j = map_jacobian(world);
    if (normal_offset > 0.0) {
        world = normal_offset_point(world, n, j);
        choose_face(world);
        j = map_jacobian(world);
    }
    LightSample s = to_light(world);
    Receiver r;
    r.texel = s.texel;
    r.depth = s.depth;
    r.in_front = s.in_front;
    vec3 t1 = normalize(cross(n, abs(n.x) < 0.9 ? vec3(1.0, 0.0, 0.0) : vec3(0.0, 1.0, 0.0)));
    vec3 t2 = cross(n, t1);
    // columns: d texel / d t1, d texel / d t2
    mat2 a = mat2(dot(j.texel_x, t1), dot(j.texel_y, t1), dot(j.texel_x, t2), dot(j.texel_y, t2));
    vec2 b = vec2(dot(j.depth_w, t1), dot(j.depth_w, t2));
    float det = determinant(a);
    // g = b A^-1 = (b adj A) / det; |det| floored so |g| <= MAX_TAN x the texel's world size
    vec2 scaled = b * mat2(a[1].y, -a[0].y, -a[1].x, a[0].x);
    float floor_det = length(scaled) * texels_per_world(j) / MAX_TAN;
    r.depth_slope = scaled / ((det < 0.0 ? -1.0 : 1.0) * max(abs(det), max(floor_det, 1e-30)));
    if (bias_mode == BIAS_ADAPTIVE) {
        mat4 m = light_proj * light_view;
        r.normal = n;
        r.row_x = vec3(m[0].x, m[1].x, m[2].x);
        r.row_y = vec3(m[0].y, m[1].y, m[2].y);
        r.row_w = vec3(m[0].w, m[1].w, m[2].w);
        r.clip_w = (m * vec4(world, 1.0)).w;
        r.depth_w = j.depth_w;
        r.texel_world = 1.0 / texels_per_world(j);
    }
    return r;
}

// The slope term of a depth read at texel centre `centre` that may come from any texel centre
// within [centre + reach_low, centre + reach_high] (0, 0: the texel itself; mdsm: its
// selection window), by bias_mode (a technique's knob):
// - slope: slope_bias x |g| x the distance from the point to the farthest of them (header).
// - receiver_plane: Isidoro's and Schueler's receiver-plane depth bias: the read is compared
//   with the plane's own depth there, depth + g . (c - u), so the term is
//   slope_bias x -g . (c - u), at its largest over the window (g . d is linear, so its extreme
//   over a box is at a corner, per axis): negative where the plane falls away from the light,
//   which the bound |g| |c - u| over-biases (light leaking under casters near their
//   receivers), exact on a plane in an orthographic map, and with no margin at a concave
//   contact (header).
// - adaptive (Dou, Yan, Kerzner, Dai, Wyman 2014, "Adaptive depth bias for shadow maps",
//   JCGT 3(4)): the read is compared with the depth at which the light ray through the texel's
//   centre meets the receiver's tangent plane (plane_offset), the most lenient of the window's
//   corners (the depth along a line of texels is a ratio of linear functions: its extremes
//   over a box are at corners), less an epsilon for rounding alone: ADAPTIVE_SNAP of the
//   plane's depth change across one texel (the 8 subpixel bits GL rasterizers snap the map's
//   vertices to) and ADAPTIVE_ROUNDING of the offset (float32), beside depth_precision; the
//   constant bias and slope_bias are not read (receiver_test, pcf_samples.glsl). In an
//   orthographic map this is receiver_plane without its constant; in a perspective one (spot
//   lights, a point light's faces, the warps) the plane's depth is projective in the texel and
//   only this one is exact (tests/techniques/test_adaptive_bias.py). Like receiver_plane it has
//   no margin at a concave crease.
// slope stays the default: on 93 runs at the defaults (sm, pcf, mdsm, csm, lispsm on the 16
// hard cases, the four real scenes and architecture at 10^5) acne above 0.1 % on 2 runs with
// slope, 12 with receiver_plane, 26 with adaptive, leaks above 0.1 % on 8, 5 and 4
// (docs/techniques.md, "The bias modes").
const float ADAPTIVE_SNAP = 1.0 / 256.0;
const float ADAPTIVE_ROUNDING = 1.0 / 1048576.0;

// bias_mode adaptive: the light depth, less the point's, at which the light ray through map
// position c meets the receiver's tangent plane: the displacement d from the point with
// (row_x - ndc.x row_w) . d = (ndc.x - ndc_u.x) w_u (and y), n . d = 0 (Cramer's rule), so
// coordinates far from the origin lose nothing. Clamped to MAX_TAN texels' world size per texel
// of reach, as |g| is; a ray meeting the plane behind the light (or never) gives the far end.
float plane_offset(Receiver r, vec2 c) {
    vec2 ndc = c * (2.0 / map_res) - 1.0;
    vec2 rhs = (c - r.texel) * (2.0 / map_res) * r.clip_w;
    vec3 a = r.row_x - ndc.x * r.row_w;
    vec3 b = r.row_y - ndc.y * r.row_w;
    vec3 bn = cross(b, r.normal), na = cross(r.normal, a);
    vec3 delta = (rhs.x * bn + rhs.y * na) / dot(a, bn);
    float offset = dot(r.depth_w, delta);
    float limit = MAX_TAN * r.texel_world * length(c - r.texel);
    if (!(r.clip_w + dot(r.row_w, delta) > 0.0) || isnan(offset)) return limit;
    return clamp(offset, -limit, limit);
}

float receiver_bias(Receiver r, vec2 centre, vec2 reach_low, vec2 reach_high) {
    vec2 low = centre - r.texel + reach_low, high = centre - r.texel + reach_high;
    if (bias_mode == BIAS_ADAPTIVE) {
        float nearest = plane_offset(r, centre + reach_low);
        if (reach_low != reach_high) {
            nearest = min(nearest, plane_offset(r, centre + reach_high));
            nearest = min(nearest, plane_offset(r, centre + vec2(reach_low.x, reach_high.y)));
            nearest = min(nearest, plane_offset(r, centre + vec2(reach_high.x, reach_low.y)));
        }
        return ADAPTIVE_SNAP * length(r.depth_slope) + ADAPTIVE_ROUNDING * abs(nearest) - nearest;
    }
    if (bias_mode == BIAS_RECEIVER_PLANE) {
        vec2 down = -r.depth_slope;
        return slope_bias * (max(down.x * low.x, down.x * high.x)
                             + max(down.y * low.y, down.y * high.y));
    }
    vec2 farthest = max(abs(low), abs(high));
    return slope_bias * length(r.depth_slope) * length(farthest);
}

// The map cell holding continuous map coordinates; false outside the map, where samples count
// as lit (Reeves et al.'s convention).
bool map_cell(vec2 texel, out ivec2 cell) {
    cell = ivec2(floor(texel));
    return all(greaterThanEqual(cell, ivec2(0))) && all(lessThan(cell, ivec2(int(map_res))));
}

// 1 = lit.
float depth_test(vec2 texel, float depth, float bias) {
    ivec2 t;
    if (!map_cell(texel, t)) return 1.0;
    return depth - bias - depth_precision > map_depth(t) ? 0.0 : 1.0;
}

// Williams' test of the receiver against the texel holding map position `at`, with the
// constant bias and the slope term of that texel's centre. 1 = lit.
float receiver_test(Receiver r, vec2 at, float constant_bias) {
    vec2 centre = floor(at) + 0.5;
    float constant = bias_mode == BIAS_ADAPTIVE ? 0.0 : constant_bias;
    return depth_test(at, r.depth, constant + receiver_bias(r, centre, vec2(0.0), vec2(0.0)));
}
