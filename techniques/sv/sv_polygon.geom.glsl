// One shadow volume per triangle (a mesh that is not closed, or a state machine that must not
// see a ray enter one volume twice): the triangle turned toward the light, its three sides
// extruded to infinity and, for z-fail, its near cap (the triangle) and, for a spot or point
// light, its far cap (the triangle at infinity). A triangle edge-on to the light casts none.
// With increments_first (the alpha and screen state machine, Roettger et al. section 4.2)
// the faces that increment the count come out before those that decrement it; faces leave
// in primitive order, so volume by volume.
#include "sv_extrude.glsl"
#ifdef CULL
// cull (Lloyd et al. 2004), directional light: a volume with no visible receiver beyond its
// triangle (by more than receiver_margin of light depth) in the cells of the triangle's
// light-space footprint is culled. With CLAMP (cull: cc) every other volume is clamped to the
// light depths from its triangle's nearest corner to the deepest receiver in those cells (each
// widened by the margin), per fragment (sv_volume.frag.glsl): its geometry stays, since a
// finite far edge rasterises otherwise than the edge to infinity and moved V at tie pixels
// (sv_cull.py).
#include "sv_receivers.glsl"
uniform bool cull_on;  // a directional light and a built grid
uniform float receiver_margin;
#endif
#ifdef CLAMP
flat out vec2 receiver_depths;  // the clamp: light depths a receiver of this volume lies between
#endif

layout(triangles) in;
layout(triangle_strip, max_vertices = 24) out;
in vec3 corner_position[];
in vec4 corner_plane[];
uniform bool caps;
uniform bool increments_first;
uniform bool front_increments;  // also the fragment shader's

// Counter-clockwise on screen (GL's front face): det [x y w] of the clip-space corners, valid
// for corners behind the eye too.
bool front_facing(vec4 a, vec4 b, vec4 c) {
    return determinant(mat3(a.xyw, b.xyw, c.xyw)) > 0.0;
}

void main() {
    vec4 plane = corner_plane[0];
    float facing = dot(plane, light);
    vec3 to_light = light.xyz - corner_position[0] * light.w;
    if (abs(facing) <= EDGE_ON * length(plane.xyz) * length(to_light)) return;
    bool away = facing < 0.0;
    vec3 p[3] = vec3[3](corner_position[0], corner_position[away ? 2 : 1],
                        corner_position[away ? 1 : 2]);
#ifdef CULL
    vec2 depths = vec2(-uintBitsToFloat(0x7f800000u), uintBitsToFloat(0x7f800000u));
    if (cull_on) {
        vec3 l[3];
        for (int k = 0; k < 3; ++k) l[k] = light_basis * (model * vec4(p[k], 1.0)).xyz;
        vec2 lo = min(min(l[0].xy, l[1].xy), l[2].xy), hi = max(max(l[0].xy, l[1].xy), l[2].xy);
        float nearest = min(min(l[0].z, l[1].z), l[2].z) - receiver_margin;
        float deepest = deepest_receiver(lo, hi);
        if (deepest < nearest) return;
        depths = vec2(nearest, deepest + receiver_margin);
    }
#endif
    vec4 near[3], far[3];
    for (int k = 0; k < 3; ++k) {
        near[k] = to_clip(vec4(p[k], 1.0));
        far[k] = to_clip(at_infinity(p[k]));
    }
    bool positional = light.w > 0.5;  // a directional light's far corners coincide
    vec4 faces[8][3];
    int count = 0;
    for (int k = 0; k < 3; ++k) {
        int a = k, b = (k + 1) % 3;
        faces[count++] = vec4[3](near[b], near[a], far[a]);
        if (positional) faces[count++] = vec4[3](near[b], far[a], far[b]);
    }
    if (caps) {
        faces[count++] = near;
        if (positional) faces[count++] = vec4[3](far[2], far[1], far[0]);
    }
    for (int round = 0; round < (increments_first ? 2 : 1); ++round) {
        for (int i = 0; i < count; ++i) {
            bool increments = front_facing(faces[i][0], faces[i][1], faces[i][2])
                == front_increments;
            if (increments_first && increments != (round == 0)) continue;
            for (int j = 0; j < 3; ++j) {
                gl_Position = faces[i][j];
#ifdef CLAMP
                receiver_depths = depths;  // outputs are undefined after each emit
#endif
                EmitVertex();
            }
            EndPrimitive();
        }
    }
}
