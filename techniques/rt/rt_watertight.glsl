// Watertight ray-triangle intersection (Woop, Benthin, Wald, JCGT 2(1) 2013): the ray's
// dominant axis becomes z, the vertices are sheared into the ray's space and the 2D edge
// functions U, V, W are computed there, falling back to double precision when one is exactly
// zero, so a ray through a shared edge or vertex hits at least one of the triangles around it.
// Both faces count (any hit). `weights`: the hit's barycentric weights of v0, v1, v2.
struct Watertight {
    vec3 origin;
    ivec3 k;      // kx, ky, kz
    vec3 shear;   // Sx, Sy, Sz
};

Watertight watertight_setup(vec3 origin, vec3 dir) {
    vec3 a = abs(dir);
    int kz = a.x > a.y ? (a.x > a.z ? 0 : 2) : (a.y > a.z ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    if (dir[kz] < 0.0) {  // keep the winding: swap kx and ky
        int swap = kx;
        kx = ky;
        ky = swap;
    }
    Watertight r;
    r.origin = origin;
    r.k = ivec3(kx, ky, kz);
    r.shear = vec3(dir[kx] / dir[kz], dir[ky] / dir[kz], 1.0 / dir[kz]);
    return r;
}

bool watertight_hit(Watertight r, vec3 v0, vec3 v1, vec3 v2, float tmax, out vec3 weights) {
    vec3 A = v0 - r.origin, B = v1 - r.origin, C = v2 - r.origin;
    int kx = r.k.x, ky = r.k.y, kz = r.k.z;
    float Ax = A[kx] - r.shear.x * A[kz], Ay = A[ky] - r.shear.y * A[kz];
    float Bx = B[kx] - r.shear.x * B[kz], By = B[ky] - r.shear.y * B[kz];
    float Cx = C[kx] - r.shear.x * C[kz], Cy = C[ky] - r.shear.y * C[kz];
    float U = Cx * By - Cy * Bx;
    float V = Ax * Cy - Ay * Cx;
    float W = Bx * Ay - By * Ax;
    if (U == 0.0 || V == 0.0 || W == 0.0) {
        U = float(double(Cx) * double(By) - double(Cy) * double(Bx));
        V = float(double(Ax) * double(Cy) - double(Ay) * double(Cx));
        W = float(double(Bx) * double(Ay) - double(By) * double(Ax));
    }
    if ((U < 0.0 || V < 0.0 || W < 0.0) && (U > 0.0 || V > 0.0 || W > 0.0)) {
        return false;
    }
    float det = U + V + W;
    if (det == 0.0) {
        return false;
    }
    float T = (U * A[kz] + V * B[kz] + W * C[kz]) * r.shear.z;
    float t = T / det;
    weights = vec3(U, V, W) / det;
    return t > 0.0 && t < tmax;
}
