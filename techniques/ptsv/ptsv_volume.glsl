// The buffers every ptsv kernel shares and the tests of a caster's shadow volume (Sintorn et
// al. 2011's per-triangle volume; a caster is a triangle or a planar convex quad of two,
// casters.py): the caster's plane, turned so the light lies on its positive side, and the
// planes through its three or four edges and the light, turned so the caster lies on their
// negative side (a triangle's fifth row is a plane every point is inside of). Positions are
// taken relative to `origin` (the scene's centre, a float32 value: the subtraction is exact near
// it), so that planes keep their precision far from the world's origin. A point is inside the
// volume where it is behind the caster's plane by more than `tie` (the receiver's own triangle
// is no caster) and on the negative side of every edge plane. Planes are (unit normal, d):
// signed distance n . x + d, in scene units.
layout(std430, binding = 2) buffer Volumes { vec4 planes[]; };  // VOLUME_ROWS per queued caster
layout(std430, binding = 3) buffer Boxes { vec4 boxes[]; };  // per node: min, max (xyz)
// The same volumes, boxes, marks and queues as buffer textures (hierarchy.py's TEXELS), through
// which the traversal reads them: llvmpipe loads a storage buffer's vector lane by lane, a
// texel in one fetch. A mark read so can miss one set in the same dispatch: it only saves work.
uniform samplerBuffer plane_texels;
uniform samplerBuffer box_texels;
uniform usamplerBuffer mark_texels;
uniform usamplerBuffer item_texels;
layout(std430, binding = 4) buffer Marks { uint marks[]; };  // samples, then nodes per level
layout(std430, binding = 5) buffer Queues { uvec2 items[]; };  // (volume, node), 2 regions
// COUNT_* entries, then per level the items queued for it (each level's queue region holds at
// most `capacity` of them)
layout(std430, binding = 6) buffer Counters { uint counters[]; };

#define COUNT_VOLUMES 0u       // casters whose volume is queued (rows of `planes`)
#define COUNT_CULLED 1u        // triangles culled before traversal (edge-on, or miss the root; a quad two)
#define COUNT_NODE_TESTS 2u    // node-volume tests (the root's included)
#define COUNT_ACCEPTS 3u       // nodes found inside a volume and marked whole
#define COUNT_ROOT_ACCEPTS 4u  // of those, at the root
#define COUNT_SAMPLE_TESTS 5u  // sample-volume tests at the leaves
#define COUNT_SEEDED 6u        // volumes whose traversal starts below the top level
#define COUNT_LEVELS 8u        // counters[COUNT_LEVELS + k]: items queued for level k
// counters[COUNT_SEEDS + k]: (volume, slice) seeds starting at level k; counters[SEED_FIRST +
// k]: where their run starts (ptsv_seed.comp.glsl). LEVELS: the levels of nodes.
#define COUNT_SEEDS (COUNT_LEVELS + LEVELS + 1u)
#define SEED_FIRST (COUNT_SEEDS + LEVELS + 1u)

uniform vec3 origin;
// A volume's cross-section lies within its caster's bounds on two unit axes across the
// light's (the volume's last row, set up in ptsv_setup.comp.glsl): a point x's coordinates are
// (u . x, v . x) across a directional light's direction; with POSITIONAL_LIGHT (a spot or
// point light, compiled apart: llvmpipe runs both sides of a branch)
// (u . d, v . d) / (axis . d), d = x - light_point, its central projection from the light onto
// the plane one unit along the axis (the spot's direction, a point light's toward the scene),
// taken only for a caster wholly in front of the light along the axis (any other has no
// bounds: min > max).
uniform vec3 light_u;
uniform vec3 light_v;
#ifdef POSITIONAL_LIGHT
uniform vec3 light_axis;
uniform vec3 light_point;  // relative to `origin`
#endif
#define VOLUME_ROWS 6  // vec4 per volume: its five planes, then (u min, u max, v min, v max)
#define BOUNDS_ROW 5
#define NO_CORNER 0xFFFFFFFFu  // a triangle caster's fourth corner (casters.py)
uniform float tie;  // how far behind its own plane a point must be to be shadowed
uniform uint capacity;  // items per queue region
uniform uint volume_capacity;  // rows of 4 planes in `planes`
uniform uint sample_count;  // marks before the nodes': node i's mark is sample_count + i
// Depth slices per screen tile: 1 for `hierarchy: tiles`; for `clusters`, each level's nodes are
// (tile, slice) pairs, numbered slice-major (a level's first node, then slice * its tiles), a
// node holding only the samples of its depth slice, and one root over the top level's slices.
uniform uint slices;

#ifdef COUNT
#define TALLY(what) atomicAdd(counters[what], 1u)
#define TALLY_TRIANGLES(what, n) atomicAdd(counters[what], n)
#else
#define TALLY(what)
#define TALLY_TRIANGLES(what, n)
#endif

// A point exactly on an edge plane is inside for one of the two triangles sharing the edge: as
// if moved a little along +x (then +y, +z). Both compute that plane from the same ordered
// ends (ptsv_setup.comp.glsl), so their distances are exact negatives and no ray slips between.
bool inside_edge(vec4 plane, vec3 p) {
    float d = dot(plane.xyz, p) + plane.w;
    if (d != 0.0) return d < 0.0;
    vec3 n = plane.xyz;
    return n.x != 0.0 ? n.x < 0.0 : (n.y != 0.0 ? n.y < 0.0 : n.z < 0.0);
}

#ifdef POSITIONAL_LIGHT
// Whether the box (centre c, half extent e) lies wholly beyond the bound `limit` of the
// coordinate along `across`, on the side `sign` (1: above): n . (x - light_point) > 0 for
// every x in the box, n = sign * (across - limit * axis), by more than the float rounding of
// evaluating it (2^-19 of the sum of its terms' magnitudes).
bool beyond(vec3 c, vec3 e, vec3 across, float limit, float sign) {
    vec3 n = sign * (across - limit * light_axis);
    vec3 d = c - light_point;
    return dot(n, d) - dot(abs(n), e) > dot(abs(n), abs(d) + e) * (1.0 / 524288.0);
}

bool outside_bounds(vec4 bounds, vec3 c, vec3 e) {
    return bounds.x <= bounds.y && (beyond(c, e, light_u, bounds.y, 1.0)
                                    || beyond(c, e, light_u, bounds.x, -1.0)
                                    || beyond(c, e, light_v, bounds.w, 1.0)
                                    || beyond(c, e, light_v, bounds.z, -1.0));
}
#else
// (the bounds widened by `tie` for rounding when set up)
bool outside_bounds(vec4 bounds, vec3 c, vec3 e) {
    float cu = dot(c, light_u), eu = dot(e, abs(light_u));
    float cv = dot(c, light_v), ev = dot(e, abs(light_v));
    return cu - eu > bounds.y || cu + eu < bounds.x || cv - ev > bounds.w || cv + ev < bounds.z;
}
#endif

// -1: the box [lo, hi] lies outside the volume (wholly behind the tie for the triangle's plane,
// wholly on the positive side of an edge plane); 1: wholly inside; 0: partly (a corner on an
// edge plane counts as partly, so the samples there meet the tie-break above).
int classify(vec4 volume[VOLUME_ROWS], vec3 lo, vec3 hi) {
    // outside the triangle's bounds across the light: a box the edge planes do not separate,
    // e.g. beyond a corner of the triangle
    vec3 c = 0.5 * (lo + hi), e = 0.5 * (hi - lo);
    if (outside_bounds(volume[BOUNDS_ROW], c, e)) return -1;
    bool inside = true;
    for (int k = 0; k < BOUNDS_ROW; ++k) {
        vec4 plane = volume[k];
        vec3 a = plane.xyz * lo, b = plane.xyz * hi;
        vec3 near = min(a, b), far = max(a, b);
        float nearest = plane.w + near.x + near.y + near.z;
        float furthest = plane.w + far.x + far.y + far.z;
        if (k == 0 ? nearest >= -tie : nearest > 0.0) return -1;
        if (k == 0 ? furthest >= -tie : furthest >= 0.0) inside = false;
    }
    return inside ? 1 : 0;
}

bool inside_volume(vec4 volume[VOLUME_ROWS], vec3 p) {
    return dot(volume[0].xyz, p) + volume[0].w < -tie && inside_edge(volume[1], p)
        && inside_edge(volume[2], p) && inside_edge(volume[3], p) && inside_edge(volume[4], p);
}

vec4[VOLUME_ROWS] volume_planes(uint volume) {
    int base = VOLUME_ROWS * int(volume);
    return vec4[VOLUME_ROWS](texelFetch(plane_texels, base), texelFetch(plane_texels, base + 1),
                             texelFetch(plane_texels, base + 2), texelFetch(plane_texels, base + 3),
                             texelFetch(plane_texels, base + 4), texelFetch(plane_texels, base + 5));
}

// A node's box; empty (lo > hi) where none of its samples is covered.
void node_box(uint node, out vec3 lo, out vec3 hi) {
    lo = texelFetch(box_texels, 2 * int(node)).xyz;
    hi = texelFetch(box_texels, 2 * int(node) + 1).xyz;
}

bool box_empty(vec3 lo, vec3 hi) {
    return any(greaterThan(lo, hi));
}

// Which of a node's TILE x TILE children are not empty, a bit each (y * TILE + x; at level 1
// its samples), kept in its box's fourth lane (ptsv_boxes.comp.glsl).
uint node_children(uint node) {
    return floatBitsToUint(texelFetch(box_texels, 2 * int(node)).w);
}

void mark_node(uint node) {
    marks[sample_count + node] = 1u;
}

// Node `node` against a volume: -2 where it is skipped (marked shadowed whole already, or
// empty), else classify's answer, the node marked where it lies inside (counted).
int test_node(vec4 volume[VOLUME_ROWS], uint node) {
    if (texelFetch(mark_texels, int(sample_count + node)).x != 0u) return -2;
    vec3 lo, hi;
    node_box(node, lo, hi);
    if (box_empty(lo, hi)) return -2;
    TALLY(COUNT_NODE_TESTS);
    int test = classify(volume, lo, hi);
    if (test > 0) {
        mark_node(node);
        TALLY(COUNT_ACCEPTS);
    }
    return test;
}

// Queue (volume, node) for level `level` (region level & 1); counted even past the capacity,
// so the caller sees an overflow and runs the traversal again with room for it.
void push(uint level, uint volume, uint node) {
    uint slot = atomicAdd(counters[COUNT_LEVELS + level], 1u);
    if (slot < capacity) items[(level & 1u) * capacity + slot] = uvec2(volume, node);
}
