/* Affine maps and boxes. */
#include <lucent/math.h>

lu_affine lu_affine_identity(void) {
    lu_affine a = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, 1, 0}}};
    return a;
}

lu_affine lu_affine_translate(lu_vec3 t) {
    lu_affine a = lu_affine_identity();
    a.m[0][3] = t.x;
    a.m[1][3] = t.y;
    a.m[2][3] = t.z;
    return a;
}

lu_affine lu_affine_scale(lu_vec3 s) {
    lu_affine a = lu_affine_identity();
    a.m[0][0] = s.x;
    a.m[1][1] = s.y;
    a.m[2][2] = s.z;
    return a;
}

static lu_affine rot_axis(int axis, float deg) {
    float r = deg * (LU_PI / 180.0f), c = cosf(r), s = sinf(r);
    lu_affine a = lu_affine_identity();
    int i = (axis + 1) % 3, j = (axis + 2) % 3;
    a.m[i][i] = c;
    a.m[i][j] = -s;
    a.m[j][i] = s;
    a.m[j][j] = c;
    return a;
}

lu_affine lu_affine_rotate_xyz_deg(lu_vec3 deg) {
    lu_affine rx = rot_axis(0, deg.x), ry = rot_axis(1, deg.y), rz = rot_axis(2, deg.z);
    lu_affine yx = lu_affine_mul(&ry, &rx);
    return lu_affine_mul(&rz, &yx);
}

lu_affine lu_affine_mul(const lu_affine *a, const lu_affine *b) {
    lu_affine r;
    for (int i = 0; i < 3; i++) {
        for (int j = 0; j < 4; j++) {
            float s = j == 3 ? a->m[i][3] : 0.0f;
            for (int k = 0; k < 3; k++) s += a->m[i][k] * b->m[k][j];
            r.m[i][j] = s;
        }
    }
    return r;
}

bool lu_affine_invert(const lu_affine *a, lu_affine *inv) {
    const float(*m)[4] = a->m;
    double c00 = (double)m[1][1] * m[2][2] - (double)m[1][2] * m[2][1];
    double c01 = (double)m[1][2] * m[2][0] - (double)m[1][0] * m[2][2];
    double c02 = (double)m[1][0] * m[2][1] - (double)m[1][1] * m[2][0];
    double det = m[0][0] * c00 + m[0][1] * c01 + m[0][2] * c02;
    if (!(fabs(det) > 1e-30) || !isfinite(det)) return false;
    double id = 1.0 / det;
    double r[3][3];
    r[0][0] = c00 * id;
    r[0][1] = ((double)m[0][2] * m[2][1] - (double)m[0][1] * m[2][2]) * id;
    r[0][2] = ((double)m[0][1] * m[1][2] - (double)m[0][2] * m[1][1]) * id;
    r[1][0] = c01 * id;
    r[1][1] = ((double)m[0][0] * m[2][2] - (double)m[0][2] * m[2][0]) * id;
    r[1][2] = ((double)m[0][2] * m[1][0] - (double)m[0][0] * m[1][2]) * id;
    r[2][0] = c02 * id;
    r[2][1] = ((double)m[0][1] * m[2][0] - (double)m[0][0] * m[2][1]) * id;
    r[2][2] = ((double)m[0][0] * m[1][1] - (double)m[0][1] * m[1][0]) * id;
    for (int i = 0; i < 3; i++) {
        double t = 0.0;
        for (int k = 0; k < 3; k++) {
            inv->m[i][k] = (float)r[i][k];
            t -= r[i][k] * m[k][3];
        }
        inv->m[i][3] = (float)t;
    }
    return true;
}

lu_vec3 lu_affine_point(const lu_affine *a, lu_vec3 p) {
    const float(*m)[4] = a->m;
    return lu_v3(m[0][0] * p.x + m[0][1] * p.y + m[0][2] * p.z + m[0][3],
                 m[1][0] * p.x + m[1][1] * p.y + m[1][2] * p.z + m[1][3],
                 m[2][0] * p.x + m[2][1] * p.y + m[2][2] * p.z + m[2][3]);
}

lu_vec3 lu_affine_vector(const lu_affine *a, lu_vec3 v) {
    const float(*m)[4] = a->m;
    return lu_v3(m[0][0] * v.x + m[0][1] * v.y + m[0][2] * v.z, m[1][0] * v.x + m[1][1] * v.y + m[1][2] * v.z,
                 m[2][0] * v.x + m[2][1] * v.y + m[2][2] * v.z);
}

lu_vec3 lu_affine_normal(const lu_affine *a, lu_vec3 n) {
    /* Cofactor matrix = det * inverse-transpose; the scale drops out after normalising. */
    const float(*m)[4] = a->m;
    lu_vec3 c0 = lu_v3_cross(lu_v3(m[0][1], m[1][1], m[2][1]), lu_v3(m[0][2], m[1][2], m[2][2]));
    lu_vec3 c1 = lu_v3_cross(lu_v3(m[0][2], m[1][2], m[2][2]), lu_v3(m[0][0], m[1][0], m[2][0]));
    lu_vec3 c2 = lu_v3_cross(lu_v3(m[0][0], m[1][0], m[2][0]), lu_v3(m[0][1], m[1][1], m[2][1]));
    lu_vec3 r = lu_v3_add(lu_v3_add(lu_v3_scale(c0, n.x), lu_v3_scale(c1, n.y)), lu_v3_scale(c2, n.z));
    float det = lu_v3_dot(lu_v3(m[0][0], m[1][0], m[2][0]), c0);
    return det < 0.0f ? lu_v3_neg(r) : r;
}

lu_aabb lu_aabb_transform(const lu_affine *a, lu_aabb b) {
    lu_aabb r = lu_aabb_empty();
    for (int i = 0; i < 8; i++) {
        lu_vec3 c = lu_v3(i & 1 ? b.hi.x : b.lo.x, i & 2 ? b.hi.y : b.lo.y, i & 4 ? b.hi.z : b.lo.z);
        lu_aabb_grow(&r, lu_affine_point(a, c));
    }
    return r;
}

bool lu_aabb_ray(lu_aabb b, lu_vec3 o, lu_vec3 d, float tmin, float tmax, float *t0, float *t1) {
    float lo = tmin, hi = tmax;
    for (int i = 0; i < 3; i++) {
        float oi = lu_v3_get(o, i), di = lu_v3_get(d, i);
        float bl = lu_v3_get(b.lo, i), bh = lu_v3_get(b.hi, i);
        if (di == 0.0f) {
            if (oi < bl || oi > bh) return false;
            continue;
        }
        float inv = 1.0f / di;
        float ta = (bl - oi) * inv, tb = (bh - oi) * inv;
        if (ta > tb) {
            float t = ta;
            ta = tb;
            tb = t;
        }
        if (ta > lo) lo = ta;
        if (tb < hi) hi = tb;
        if (lo > hi) return false;
    }
    *t0 = lo;
    *t1 = hi;
    return true;
}
