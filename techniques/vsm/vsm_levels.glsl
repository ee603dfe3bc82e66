// The levels of a virtual shadow map and its page table (levels.py says what each level is;
// choose_levels there is the float64 form of choose_level here, the tests' oracle).
// Binding 0: the levels; binding 1: the page table, an Entry per page of every level (level
// k's from bases[k], pages[k]^2 of them, at the page's global coordinate modulo pages[k]).
struct Level {
    mat4 view;
    mat4 proj;
    ivec4 grid;  // x, y: global page coordinate of the window's first page; z: pages per
                 // side; w: where the level's entries begin in the table
    vec4 res;    // x: texels per side
};

layout(std430, binding = 0) readonly buffer Levels { Level levels[]; };

struct Entry {
    int slot;     // the pool tile holding the page, -1 for none
    int gx;       // the page it holds (global coordinates)
    int gy;
    uint valid;   // 1: its depths are those of the current light and geometry
};

layout(std430, binding = 1) buffer Table { Entry entries[]; };

uniform int level_count;
uniform int nested_levels;  // levels 0..nested_levels-1 cover a window about the camera
uniform int level_bias;     // coarsening under a full pool
uniform int page_size;
uniform float pixel_angle;  // a pixel's width over its distance from the camera
uniform vec3 eye_position;  // the camera's
uniform vec4 light_vector;  // (position, 1) for a spot light, (toward the light, 0) directional

vec4 level_clip(int k, vec3 world) {
    return levels[k].proj * (levels[k].view * vec4(world, 1.0));
}

vec2 level_texel(int k, vec3 world) {
    vec4 clip = level_clip(k, world);
    return (clip.xy / clip.w * 0.5 + 0.5) * levels[k].res.x;
}

// levels.SLANT_FLOORS and SLANT_CEILING: the receiver's slant moves a pixel's level finer by
// as much as slant_floor allows (the pool's first step back), three levels coarser at most
uniform float slant_floor;
const float SLANT_CEILING = 8.0;

// The world side of the square of level k's texel's area at `world` (a light frustum fitted
// to the scene may give its texels two sides).
float level_texel_world(int k, vec3 world) {
    mat4 p = levels[k].proj;
    return 2.0 * level_clip(k, world).w / (sqrt(p[0][0] * p[1][1]) * levels[k].res.x);
}

// The level whose texel is the largest not above the pixel's footprint, both taken on the
// receiver's plane (levels.natural_level), coarsened by level_bias, then coarser while the
// point lies within a page of a nested level's window edge (a filter's reads stay inside).
int choose_level(vec3 world, vec3 normal) {
    vec3 to_light = light_vector.w == 0.0 ? normalize(light_vector.xyz)
                                          : normalize(light_vector.xyz - world);
    float facing_eye = max(abs(dot(normal, normalize(eye_position - world))), 1e-6);
    float slant = clamp(sqrt(abs(dot(normal, to_light)) / facing_eye), slant_floor,
                        SLANT_CEILING);
    float footprint = distance(world, eye_position) * pixel_angle * slant;
    float ratio = log2(footprint / level_texel_world(0, world));
    int k = int(clamp(floor(ratio), 0.0, float(level_count - 1)));
    k = min(k + level_bias, level_count - 1);
    while (k < nested_levels) {
        vec2 t = level_texel(k, world);
        float res = levels[k].res.x;
        if (all(greaterThanEqual(t, vec2(page_size))) && all(lessThanEqual(t, vec2(res - page_size))))
            break;
        ++k;
    }
    return k;
}

int positive_mod(int a, int n) {
    int r = a % n;
    return r < 0 ? r + n : r;
}

// The table index of level k's page holding texel `cell` (window coordinates), and its global
// coordinates; false outside the level's window.
bool page_entry(int k, ivec2 cell, out int index, out ivec2 global) {
    int pages = levels[k].grid.z;
    ivec2 local = cell / page_size;
    if (any(lessThan(cell, ivec2(0))) || any(greaterThanEqual(local, ivec2(pages)))) return false;
    global = levels[k].grid.xy + local;
    index = levels[k].grid.w + positive_mod(global.x, pages) + positive_mod(global.y, pages) * pages;
    return true;
}

// A pool texel no caster reached (light_maps.EMPTY_DEPTH): lit.
const float EMPTY_DEPTH = 3.0e38;
