// Whether a view sample lies in a caster triangle's shadow frustum: the segment from the
// sample towards the light meets the triangle. `light`: (position, 1) for a spot light, (unit
// vector towards the light, 0) for a directional one. With w the direction from the sample
// towards the light (L - s, or the light's vector), the frustum is bounded by the three
// planes through the light and an edge, and by the triangle's plane:
//   edge ab: G_ab = det(a - s, b - s, w), and likewise bc, ca: all three >= 0 or all <= 0
//            (a sample on an edge plane is inside, as the watertight ray test counts a ray
//            through an edge as a hit), not all three 0;
//   plane:   P(s) = det(b - a, c - a, s - a) and the light's side P(L) (a spot light), or
//            n . w (directional, n = (b - a) x (c - a)), of strictly opposite signs: the
//            sample behind the triangle as the light sees it; a sample on the plane is lit.
// Each determinant is first evaluated in float; one whose magnitude is within its rounding
// bound (RELATIVE_BOUND times the product of its three vectors' lengths) of 0 has its sign
// decided again in double precision from the same float inputs, so a sample near a plane gets
// the sign of its exact position, not of a rounding error.
const float RELATIVE_BOUND = 1e-5;

float det3(vec3 x, vec3 y, vec3 z) {
    return dot(cross(x, y), z);
}

// the sign of det(x1 - x0, y1 - y0, z1 - z0): in float where it is clear, else in double
float safe_sign(vec3 x1, vec3 x0, vec3 y1, vec3 y0, vec3 z1, vec3 z0) {
    vec3 x = x1 - x0, y = y1 - y0, z = z1 - z0;
    float d = det3(x, y, z);
    if (abs(d) > RELATIVE_BOUND * length(x) * length(y) * length(z)) {
        return sign(d);
    }
    dvec3 dx = dvec3(x1) - dvec3(x0), dy = dvec3(y1) - dvec3(y0), dz = dvec3(z1) - dvec3(z0);
    double e = dot(cross(dx, dy), dz);
    return e > 0.0lf ? 1.0 : (e < 0.0lf ? -1.0 : 0.0);
}

bool in_shadow_frustum(vec3 s, vec3 a, vec3 b, vec3 c, vec4 light) {
    // w = light.xyz - from: the light's position less the sample's, or its vector less 0
    vec3 from = s * light.w;
    float gab = safe_sign(a, s, b, s, light.xyz, from);
    float gbc = safe_sign(b, s, c, s, light.xyz, from);
    float gca = safe_sign(c, s, a, s, light.xyz, from);
    bool inside = (gab >= 0.0 && gbc >= 0.0 && gca >= 0.0)
               || (gab <= 0.0 && gbc <= 0.0 && gca <= 0.0);
    if (!inside || (gab == 0.0 && gbc == 0.0 && gca == 0.0)) {
        return false;
    }
    float behind = safe_sign(b, a, c, a, s, a);
    float light_side = safe_sign(b, a, c, a, light.xyz, a * light.w);
    return behind * light_side < 0.0;
}

// Where the ray from `s` towards the light meets the triangle's plane, as the weights of a, b
// and c (barycentrics, summing to 1): each corner's weight is the edge determinant of the
// opposite edge (G_bc for a), so the weights of a sample in the frustum are all >= 0. Their
// sum is det(b - a, c - a, w), not 0 there: in_shadow_frustum has found w off the plane.
vec3 frustum_weights(vec3 s, vec3 a, vec3 b, vec3 c, vec4 light) {
    vec3 w = light.xyz - s * light.w;
    vec3 g = vec3(det3(b - s, c - s, w), det3(c - s, a - s, w), det3(a - s, b - s, w));
    return g / (g.x + g.y + g.z);
}
