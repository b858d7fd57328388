/* Geometry: Embree ray queries, all-hits parity, inside tests, voxelisation.
 *
 * Meshes are built here by hand (boxes with 8 and 24 vertices, a
 * tetrahedron, a UV sphere). Expected values come from closed forms (slab
 * intersection, face normals, half-space tests), from a brute-force
 * double-precision ray/triangle loop over every triangle, and from the
 * divergence theorem for the polyhedron's volume. */
#define _POSIX_C_SOURCE 200809L   /* setenv */
#include <lucent/lucent.h>

#include <float.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "lu_test.h"

#define PI_D 3.14159265358979323846

/* ---- helpers ------------------------------------------------------------ */

static uint64_t g_rng = 0x9E3779B97F4A7C15ull;
static double rnd(void) {   /* xorshift64*, uniform in [0, 1) */
    g_rng ^= g_rng >> 12;
    g_rng ^= g_rng << 25;
    g_rng ^= g_rng >> 27;
    return (double)((g_rng * 0x2545F4914F6CDD1Dull) >> 11) * (1.0 / 9007199254740992.0);
}
static double rnd_range(double a, double b) { return a + (b - a) * rnd(); }
static lu_vec3 rnd_unit(void) {
    for (;;) {
        double x = rnd_range(-1, 1), y = rnd_range(-1, 1), z = rnd_range(-1, 1), l = x * x + y * y + z * z;
        if (l > 1e-4 && l <= 1.0) {
            l = sqrt(l);
            return lu_v3((float)(x / l), (float)(y / l), (float)(z / l));
        }
    }
}

typedef struct dvec { double x, y, z; } dvec;
static dvec dv(lu_vec3 a) { dvec r = {a.x, a.y, a.z}; return r; }
static dvec dsub(dvec a, dvec b) { dvec r = {a.x - b.x, a.y - b.y, a.z - b.z}; return r; }
static double ddot(dvec a, dvec b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static dvec dcross(dvec a, dvec b) {
    dvec r = {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x};
    return r;
}
static double dlen(dvec a) { return sqrt(ddot(a, a)); }

static void mesh_free(lu_mesh *m) {
    free(m->positions);
    free(m->indices);
    free(m->normals);
    memset(m, 0, sizeof *m);
}

static void mesh_init(lu_mesh *m, uint32_t nv, uint32_t nt) {
    memset(m, 0, sizeof *m);
    m->vertex_count = nv;
    m->triangle_count = nt;
    m->positions = calloc(nv ? nv : 1, sizeof(lu_vec3));
    m->indices = calloc(nt ? 3 * nt : 1, sizeof(uint32_t));
}

/* Appends triangle (a, b, c), flipped if needed so it winds counter-clockwise
 * seen from outside a convex solid around `inner`. */
static void add_tri_outward(lu_mesh *m, uint32_t *t, uint32_t a, uint32_t b, uint32_t c, dvec inner) {
    dvec pa = dv(m->positions[a]), pb = dv(m->positions[b]), pc = dv(m->positions[c]);
    dvec n = dcross(dsub(pb, pa), dsub(pc, pa));
    if (ddot(n, dsub(pa, inner)) < 0) {
        uint32_t s = b;
        b = c;
        c = s;
    }
    m->indices[3 * *t + 0] = a;
    m->indices[3 * *t + 1] = b;
    m->indices[3 * *t + 2] = c;
    (*t)++;
}

/* Corner k of a box: bit 0 = x, bit 1 = y, bit 2 = z (0 = lo, 1 = hi). */
static lu_vec3 box_corner(lu_vec3 lo, lu_vec3 hi, int k) {
    return lu_v3(k & 1 ? hi.x : lo.x, k & 2 ? hi.y : lo.y, k & 4 ? hi.z : lo.z);
}
/* Faces as corner quads (in cyclic order). */
static const int k_box_faces[6][4] = {
    {0, 2, 6, 4}, {1, 3, 7, 5},   /* x lo, x hi */
    {0, 1, 5, 4}, {2, 3, 7, 6},   /* y lo, y hi */
    {0, 1, 3, 2}, {4, 5, 7, 6},   /* z lo, z hi */
};

/* 8 shared vertices, 12 triangles. */
static void make_box8(lu_mesh *m, lu_vec3 lo, lu_vec3 hi) {
    mesh_init(m, 8, 12);
    for (int k = 0; k < 8; k++) m->positions[k] = box_corner(lo, hi, k);
    dvec c = {0.5 * ((double)lo.x + hi.x), 0.5 * ((double)lo.y + hi.y), 0.5 * ((double)lo.z + hi.z)};
    uint32_t t = 0;
    for (int f = 0; f < 6; f++) {
        const int *q = k_box_faces[f];
        add_tri_outward(m, &t, q[0], q[1], q[2], c);
        add_tri_outward(m, &t, q[0], q[2], q[3], c);
    }
}

/* 24 vertices (4 per face, as flat-shaded files have), 12 triangles. */
static void make_box24(lu_mesh *m, lu_vec3 lo, lu_vec3 hi) {
    mesh_init(m, 24, 12);
    dvec c = {0.5 * ((double)lo.x + hi.x), 0.5 * ((double)lo.y + hi.y), 0.5 * ((double)lo.z + hi.z)};
    uint32_t t = 0;
    for (int f = 0; f < 6; f++) {
        for (int i = 0; i < 4; i++) m->positions[4 * f + i] = box_corner(lo, hi, k_box_faces[f][i]);
        add_tri_outward(m, &t, 4 * f, 4 * f + 1, 4 * f + 2, c);
        add_tri_outward(m, &t, 4 * f, 4 * f + 2, 4 * f + 3, c);
    }
}

static void make_tetra(lu_mesh *m, const lu_vec3 p[4]) {
    mesh_init(m, 4, 4);
    dvec c = {0, 0, 0};
    for (int i = 0; i < 4; i++) {
        m->positions[i] = p[i];
        c.x += p[i].x / 4.0;
        c.y += p[i].y / 4.0;
        c.z += p[i].z / 4.0;
    }
    uint32_t t = 0;
    add_tri_outward(m, &t, 0, 1, 2, c);
    add_tri_outward(m, &t, 0, 1, 3, c);
    add_tri_outward(m, &t, 0, 2, 3, c);
    add_tri_outward(m, &t, 1, 2, 3, c);
}

/* UV sphere: poles on z, nu segments in longitude, nv bands in latitude,
 * vertices on the sphere; wound CCW from outside by construction. */
static void make_uv_sphere(lu_mesh *m, lu_vec3 c, float r, int nu, int nv) {
    uint32_t nvert = 2 + (uint32_t)nu * (nv - 1), ntri = 2u * nu * (nv - 1);
    mesh_init(m, nvert, ntri);
    m->positions[0] = lu_v3(c.x, c.y, c.z + r);
    for (int i = 1; i < nv; i++)
        for (int j = 0; j < nu; j++) {
            double th = PI_D * i / nv, ph = 2 * PI_D * j / nu;
            m->positions[1 + (i - 1) * nu + j] = lu_v3((float)(c.x + r * sin(th) * cos(ph)),
                                                       (float)(c.y + r * sin(th) * sin(ph)),
                                                       (float)(c.z + r * cos(th)));
        }
    const uint32_t bottom = nvert - 1;
    m->positions[bottom] = lu_v3(c.x, c.y, c.z - r);
#define RING(i, j) (1u + (uint32_t)((i) - 1) * nu + (uint32_t)((j) % nu))
    uint32_t *ix = m->indices, t = 0;
    for (int j = 0; j < nu; j++) {
        uint32_t tri[3] = {0, RING(1, j), RING(1, j + 1)};
        memcpy(ix + 3 * t++, tri, sizeof tri);
    }
    for (int i = 1; i < nv - 1; i++)
        for (int j = 0; j < nu; j++) {
            uint32_t a = RING(i, j), b = RING(i + 1, j), cc = RING(i + 1, j + 1), d = RING(i, j + 1);
            uint32_t t1[3] = {a, b, cc}, t2[3] = {a, cc, d};
            memcpy(ix + 3 * t++, t1, sizeof t1);
            memcpy(ix + 3 * t++, t2, sizeof t2);
        }
    for (int j = 0; j < nu; j++) {
        uint32_t tri[3] = {RING(nv - 1, j), bottom, RING(nv - 1, j + 1)};
        memcpy(ix + 3 * t++, tri, sizeof tri);
    }
#undef RING
}

static lu_vec3 tri_vertex(const lu_mesh *m, uint32_t t, int k) { return m->positions[m->indices[3 * t + k]]; }

/* Signed volume by the divergence theorem: sum of p0 . (p1 x p2) / 6. */
static double mesh_volume(const lu_mesh *m) {
    double v = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++)
        v += ddot(dv(tri_vertex(m, t, 0)), dcross(dv(tri_vertex(m, t, 1)), dv(tri_vertex(m, t, 2))));
    return v / 6.0;
}
static double mesh_area(const lu_mesh *m) {
    double a = 0;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        dvec p0 = dv(tri_vertex(m, t, 0));
        a += 0.5 * dlen(dcross(dsub(dv(tri_vertex(m, t, 1)), p0), dsub(dv(tri_vertex(m, t, 2)), p0)));
    }
    return a;
}
/* Smallest distance from c to a triangle's plane: the polyhedron contains
 * the ball of that radius (it is convex, vertices on the sphere). */
static double sphere_mesh_inradius(const lu_mesh *m, dvec c) {
    double rmin = INFINITY;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        dvec p0 = dv(tri_vertex(m, t, 0));
        dvec n = dcross(dsub(dv(tri_vertex(m, t, 1)), p0), dsub(dv(tri_vertex(m, t, 2)), p0));
        double d = fabs(ddot(n, dsub(p0, c))) / dlen(n);
        if (d < rmin) rmin = d;
    }
    return rmin;
}

/* Brute-force Moeller-Trumbore in double. edge_margin reports how close the
 * hit is to the triangle's boundary (min barycentric). */
typedef struct bf_hit { double t, u, v, margin; uint32_t prim; dvec n; } bf_hit;
static bool bf_tri(const lu_mesh *m, uint32_t tri, dvec o, dvec d, bf_hit *h) {
    dvec p0 = dv(tri_vertex(m, tri, 0)), e1 = dsub(dv(tri_vertex(m, tri, 1)), p0),
         e2 = dsub(dv(tri_vertex(m, tri, 2)), p0);
    dvec pv = dcross(d, e2);
    double det = ddot(e1, pv);
    if (det == 0) return false;
    double inv = 1 / det;
    dvec tv = dsub(o, p0);
    double u = ddot(tv, pv) * inv;
    dvec qv = dcross(tv, e1);
    double v = ddot(d, qv) * inv;
    if (u < 0 || v < 0 || u + v > 1) return false;
    h->t = ddot(e2, qv) * inv;
    h->u = u;
    h->v = v;
    h->margin = fmin(fmin(u, v), 1 - u - v);
    h->prim = tri;
    dvec n = dcross(e1, e2);
    double l = dlen(n);
    h->n = (dvec){n.x / l, n.y / l, n.z / l};
    return true;
}
static bool bf_closest(const lu_mesh *m, dvec o, dvec d, double tmin, double tmax, bf_hit *best) {
    bool any = false;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        bf_hit h;
        if (bf_tri(m, t, o, d, &h) && h.t > tmin && h.t < tmax && (!any || h.t < best->t)) {
            *best = h;
            any = true;
        }
    }
    return any;
}

static lu_accel *accel_of(const lu_mesh *const *meshes, int n) {
    lu_accel *a = NULL;
    lu_error err = {0};
    CHECK_OK(lu_accel_create(&a, &err), &err);
    for (int i = 0; i < n; i++) {
        uint32_t id = 99;
        CHECK_OK(lu_accel_add_mesh(a, meshes[i], &id, &err), &err);
        CHECK(id == (uint32_t)i);
    }
    CHECK_OK(lu_accel_commit(a, &err), &err);
    return a;
}

/* Float rounding of a hit parameter: Embree works in float on coordinates of
 * magnitude up to |o| + t |d|; allow 16 ulps of that, in units of |d|. */
static double t_tol(lu_vec3 o, lu_vec3 d, double t) {
    double om = fmax(fabs(o.x), fmax(fabs(o.y), fabs(o.z)));
    double dm = fmax(fabs(d.x), fmax(fabs(d.y), fabs(d.z)));
    return 16.0 * FLT_EPSILON * (om + fabs(t) * dm) / dm;
}

/* Analytic slab test for a box: entry/exit parameters and entry axis. */
static bool slab(lu_vec3 lo, lu_vec3 hi, dvec o, dvec d, double *t0, double *t1, int *axis0, int *axis1) {
    double a = -INFINITY, b = INFINITY;
    const double oo[3] = {o.x, o.y, o.z}, dd[3] = {d.x, d.y, d.z};
    const double l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
    for (int i = 0; i < 3; i++) {
        double ta = (l[i] - oo[i]) / dd[i], tb = (h[i] - oo[i]) / dd[i];
        if (ta > tb) {
            double s = ta;
            ta = tb;
            tb = s;
        }
        if (ta > a) {
            a = ta;
            *axis0 = i;
        }
        if (tb < b) {
            b = tb;
            *axis1 = i;
        }
    }
    *t0 = a;
    *t1 = b;
    return a < b;
}

/* Distance from p on a box face to the face's border (in the face plane). */
static double face_border_margin(lu_vec3 lo, lu_vec3 hi, dvec p, int axis) {
    const double pp[3] = {p.x, p.y, p.z}, l[3] = {lo.x, lo.y, lo.z}, h[3] = {hi.x, hi.y, hi.z};
    double m = INFINITY;
    for (int i = 0; i < 3; i++)
        if (i != axis) m = fmin(m, fmin(pp[i] - l[i], h[i] - pp[i]));
    return m;
}

/* ---- closest / occluded ---------------------------------------------------- */

static void check_hit_on_triangle(const lu_mesh *m, const lu_hit *h, lu_vec3 o, lu_vec3 d, double tol) {
    /* u, v are the barycentrics of vertices 1 and 2: they rebuild the hit point. */
    dvec p0 = dv(tri_vertex(m, h->prim_id, 0)), p1 = dv(tri_vertex(m, h->prim_id, 1)),
         p2 = dv(tri_vertex(m, h->prim_id, 2));
    double w = 1.0 - h->u - h->v;
    dvec q = {w * p0.x + h->u * p1.x + h->v * p2.x, w * p0.y + h->u * p1.y + h->v * p2.y,
              w * p0.z + h->u * p1.z + h->v * p2.z};
    dvec p = {o.x + (double)h->t * d.x, o.y + (double)h->t * d.y, o.z + (double)h->t * d.z};
    CHECK_NEAR(dlen(dsub(p, q)), 0.0, tol);
}

static void test_box_closest(void) {
    const lu_vec3 lo = lu_v3(-0.7f, -1.1f, -0.4f), hi = lu_v3(1.3f, 0.9f, 1.6f);
    lu_mesh box;
    make_box8(&box, lo, hi);
    const lu_mesh *ms[1] = {&box};
    lu_accel *a = accel_of(ms, 1);
    lu_aabb b = lu_accel_bounds(a);
    CHECK(b.lo.x == lo.x && b.lo.y == lo.y && b.lo.z == lo.z && b.hi.x == hi.x && b.hi.y == hi.y &&
          b.hi.z == hi.z);
    int hits = 0, misses = 0, inside = 0, bad_t = 0, bad_n = 0;
    for (int k = 0; k < 4000; k++) {
        /* Origins outside (on a sphere of radius 4) and inside; directions
         * aimed near the box so most rays hit. */
        bool from_inside = k % 4 == 0;
        lu_vec3 o = from_inside ? lu_v3((float)rnd_range(lo.x, hi.x), (float)rnd_range(lo.y, hi.y),
                                        (float)rnd_range(lo.z, hi.z))
                                : lu_v3_add(lu_v3s(0.3f), lu_v3_scale(rnd_unit(), 4.0f));
        lu_vec3 target = lu_v3((float)rnd_range(-1.5, 2), (float)rnd_range(-2, 1.5), (float)rnd_range(-1, 2.2));
        lu_vec3 d = from_inside ? rnd_unit() : lu_v3_norm(lu_v3_sub(target, o));
        double t0, t1;
        int ax0 = 0, ax1 = 0;
        bool an = slab(lo, hi, dv(o), dv(d), &t0, &t1, &ax0, &ax1);
        double th = an ? (t0 > 0 ? t0 : t1) : 0;
        int axis = an && t0 > 0 ? ax0 : ax1;
        an = an && t1 > 0;
        lu_hit h;
        bool got = lu_accel_closest(a, o, d, 0.0f, INFINITY, &h);
        if (an) {
            dvec p = {o.x + th * d.x, o.y + th * d.y, o.z + th * d.z};
            /* Skip rays within float reach of an edge: either face is right. */
            if (face_border_margin(lo, hi, p, axis) < 1e-4) continue;
        } else if (t0 < t1 + 1e-4 && t1 > -1e-4) {
            continue;   /* near-grazing miss */
        }
        CHECK(got == an);
        if (!got || !an) {
            misses += !an;
            continue;
        }
        hits++;
        inside += from_inside;
        if (fabs(h.t - th) > t_tol(o, d, th)) bad_t++;
        CHECK_NEAR(h.t, th, t_tol(o, d, th));
        /* Outward unit normal of the face hit, exactly axis-aligned. */
        const double pp[3] = {o.x + th * d.x, o.y + th * d.y, o.z + th * d.z};
        const double mid[3] = {0.5 * (lo.x + hi.x), 0.5 * (lo.y + hi.y), 0.5 * (lo.z + hi.z)};
        float sign = pp[axis] > mid[axis] ? 1.0f : -1.0f;
        lu_vec3 want = lu_v3(axis == 0 ? sign : 0, axis == 1 ? sign : 0, axis == 2 ? sign : 0);
        if (lu_v3_len(lu_v3_sub(h.ng, want)) > 1e-6f) bad_n++;
        CHECK_NEAR(lu_v3_len(lu_v3_sub(h.ng, want)), 0.0, 1e-6);
        CHECK(h.mesh_id == 0 && h.prim_id < 12);
        check_hit_on_triangle(&box, &h, o, d, 4 * t_tol(o, d, th));
    }
    CHECK_MSG(hits > 2500 && misses > 100 && inside > 800, "hits %d misses %d inside %d", hits, misses, inside);
    CHECK_MSG(bad_t == 0 && bad_n == 0, "bad t %d bad normal %d", bad_t, bad_n);
    lu_accel_destroy(a);
    mesh_free(&box);
}

static void test_sphere_closest(void) {
    const lu_vec3 c = lu_v3(0.2f, -0.1f, 0.3f);
    const float r = 1.0f;
    lu_mesh s;
    make_uv_sphere(&s, c, r, 48, 24);
    const lu_mesh *ms[1] = {&s};
    lu_accel *a = accel_of(ms, 1);
    const double rin = sphere_mesh_inradius(&s, dv(c));
    CHECK(rin > 0.99 && rin < 1.0);
    int hits = 0;
    for (int k = 0; k < 1500; k++) {
        lu_vec3 o = lu_v3_add(c, lu_v3_scale(rnd_unit(), (float)rnd_range(1.5, 5)));
        lu_vec3 target = lu_v3_add(c, lu_v3_scale(rnd_unit(), (float)rnd_range(0, 1.2)));
        lu_vec3 d = lu_v3_scale(lu_v3_norm(lu_v3_sub(target, o)), (float)rnd_range(0.3, 3));   /* any length */
        bf_hit bh = {0};
        bool want = bf_closest(&s, dv(o), dv(d), 0, INFINITY, &bh);
        lu_hit h;
        bool got = lu_accel_closest(a, o, d, 0.0f, INFINITY, &h);
        /* Analytic sphere: the polyhedron lies between radius rin and r. */
        dvec oc = dsub(dv(o), dv(c)), dd = dv(d);
        double qa = ddot(dd, dd), qb = 2 * ddot(oc, dd);
        double disc_out = qb * qb - 4 * qa * (ddot(oc, oc) - (double)r * r);
        double disc_in = qb * qb - 4 * qa * (ddot(oc, oc) - rin * rin);
        if (disc_in > 1e-3) CHECK(want);    /* crosses the inscribed ball: must hit */
        if (disc_out < -1e-3) CHECK(!want); /* misses the circumscribed ball */
        if (want && bh.margin < 1e-5) continue;   /* edge: which triangle is float noise */
        if (!want) {
            /* A miss must be a clear miss: skip rays within float reach of the silhouette. */
            CHECK(!got || disc_out > -1e-3);
            continue;
        }
        CHECK(got);
        if (!got) continue;
        hits++;
        CHECK_NEAR(h.t, bh.t, t_tol(o, d, bh.t));
        CHECK(h.prim_id == bh.prim);
        CHECK(h.mesh_id == 0);
        CHECK_NEAR(h.ng.x, bh.n.x, 1e-5);
        CHECK_NEAR(h.ng.y, bh.n.y, 1e-5);
        CHECK_NEAR(h.ng.z, bh.n.z, 1e-5);
        /* Outward: the normal points away from the centre. */
        dvec p = {o.x + h.t * (double)d.x, o.y + h.t * (double)d.y, o.z + h.t * (double)d.z};
        CHECK(ddot(dv(h.ng), dsub(p, dv(c))) > 0.9);
        double rp = dlen(dsub(p, dv(c)));
        CHECK(rp >= rin - 1e-5 && rp <= r + 1e-5);
        /* The closed-form sphere entry, to within the tessellation gap:
         * entering the inscribed ball and the sphere bound the polyhedron's entry. */
        double t_out = (-qb - sqrt(fmax(disc_out, 0))) / (2 * qa);
        CHECK(h.t >= t_out - t_tol(o, d, t_out));
        if (disc_in > 0) {
            double t_in = (-qb - sqrt(disc_in)) / (2 * qa);
            CHECK(h.t <= t_in + t_tol(o, d, t_in));
        }
        check_hit_on_triangle(&s, &h, o, d, 4 * t_tol(o, d, bh.t) * lu_v3_len(d));
    }
    CHECK_MSG(hits > 1000, "hits %d", hits);
    lu_accel_destroy(a);
    mesh_free(&s);
}

static void test_tetra_closest_and_inside(void) {
    const lu_vec3 p[4] = {{0.1f, 0.0f, -0.2f}, {1.2f, 0.1f, 0.0f}, {0.3f, 1.1f, 0.2f}, {0.4f, 0.3f, 1.3f}};
    lu_mesh t;
    make_tetra(&t, p);
    const lu_mesh *ms[1] = {&t};
    lu_accel *a = accel_of(ms, 1);
    CHECK(mesh_volume(&t) > 0);
    dvec cen = {0, 0, 0};
    for (int i = 0; i < 4; i++) {
        cen.x += p[i].x / 4.0;
        cen.y += p[i].y / 4.0;
        cen.z += p[i].z / 4.0;
    }
    /* A ray from outside at each face's centroid, against the face's plane. */
    for (uint32_t f = 0; f < 4; f++) {
        dvec p0 = dv(tri_vertex(&t, f, 0)), p1 = dv(tri_vertex(&t, f, 1)), p2 = dv(tri_vertex(&t, f, 2));
        dvec n = dcross(dsub(p1, p0), dsub(p2, p0));
        double l = dlen(n);
        n = (dvec){n.x / l, n.y / l, n.z / l};
        dvec fc = {(p0.x + p1.x + p2.x) / 3, (p0.y + p1.y + p2.y) / 3, (p0.z + p1.z + p2.z) / 3};
        lu_vec3 o = lu_v3((float)(fc.x + 2 * n.x), (float)(fc.y + 2 * n.y), (float)(fc.z + 2 * n.z));
        lu_vec3 d = lu_v3((float)-n.x, (float)-n.y, (float)-n.z);
        lu_hit h;
        CHECK(lu_accel_closest(a, o, d, 0, INFINITY, &h));
        CHECK(h.prim_id == f);
        double tw = ddot(dsub(dv(o), p0), n);   /* distance to the plane, |d| = 1 */
        CHECK_NEAR(h.t, tw, t_tol(o, d, tw));
        CHECK_NEAR(h.ng.x, n.x, 1e-6);
        CHECK_NEAR(h.ng.y, n.y, 1e-6);
        CHECK_NEAR(h.ng.z, n.z, 1e-6);
        CHECK(ddot(n, dsub(fc, cen)) > 0);   /* CCW triangles: outward */
    }
    /* Inside: half-space test against every face, away from the surface. */
    int agree = 0, total = 0;
    for (int k = 0; k < 3000; k++) {
        lu_vec3 q = lu_v3((float)rnd_range(-0.2, 1.5), (float)rnd_range(-0.3, 1.4), (float)rnd_range(-0.5, 1.6));
        double dmin = INFINITY;
        bool in = true;
        for (uint32_t f = 0; f < 4; f++) {
            dvec p0 = dv(tri_vertex(&t, f, 0));
            dvec n = dcross(dsub(dv(tri_vertex(&t, f, 1)), p0), dsub(dv(tri_vertex(&t, f, 2)), p0));
            double s = ddot(n, dsub(dv(q), p0)) / dlen(n);
            if (s > 0) in = false;
            dmin = fmin(dmin, fabs(s));
        }
        if (dmin < 1e-5) continue;   /* float rounding of the surface itself */
        total++;
        agree += lu_accel_inside(a, q) == in;
    }
    CHECK_MSG(agree == total && total > 2500, "%d of %d agree", agree, total);
    lu_accel_destroy(a);
    mesh_free(&t);
}

static void test_occluded_matches_closest(void) {
    lu_mesh s, b;
    make_uv_sphere(&s, lu_v3(0, 0, 0), 0.8f, 32, 16);
    make_box8(&b, lu_v3(1.0f, -0.5f, -0.5f), lu_v3(2.0f, 0.5f, 0.5f));
    const lu_mesh *ms[2] = {&s, &b};
    lu_accel *a = accel_of(ms, 2);
    int n_occ = 0, n_free = 0, seen[2] = {0, 0};
    for (int k = 0; k < 3000; k++) {
        lu_vec3 o = lu_v3_scale(rnd_unit(), (float)rnd_range(0, 3.5));
        lu_vec3 d = rnd_unit();
        float tmin = (float)rnd_range(0, 0.5), tmax = (float)rnd_range(0.5, 6);
        lu_hit h;
        bool c = lu_accel_closest(a, o, d, tmin, INFINITY, &h);
        if (c) {
            seen[h.mesh_id < 2 ? h.mesh_id : 0]++;
            CHECK(h.t > tmin);
            if (fabs(h.t - tmax) < 1e-4 || fabs(h.t - tmin) < 1e-4) continue;
        }
        bool want = c && h.t < tmax;
        bool got = lu_accel_occluded(a, o, d, tmin, tmax);
        CHECK(got == want);
        /* The closest hit with the same finite interval agrees too. */
        lu_hit h2;
        CHECK(lu_accel_closest(a, o, d, tmin, tmax, &h2) == want);
        n_occ += want;
        n_free += !want;
    }
    CHECK_MSG(n_occ > 500 && n_free > 500 && seen[0] > 100 && seen[1] > 100, "occ %d free %d sphere %d box %d",
              n_occ, n_free, seen[0], seen[1]);
    lu_accel_destroy(a);
    mesh_free(&s);
    mesh_free(&b);
}

/* ---- all hits ---------------------------------------------------------------- */

static void test_all_hits_boxes(void) {
    lu_mesh outer, inner;
    make_box8(&outer, lu_v3(-1, -1, -1), lu_v3(1, 1, 1));
    make_box24(&inner, lu_v3(-0.5f, -0.25f, -0.5f), lu_v3(0.5f, 0.75f, 0.25f));
    const lu_mesh *ms[2] = {&outer, &inner};
    lu_accel *a = accel_of(ms, 2);
    lu_hit h[8];
    /* Along +x through both: analytic crossings at x = -1, -0.5, 0.5, 1. */
    lu_vec3 o = lu_v3(-3.0f, 0.1f, -0.2f), d = lu_v3(2.0f, 0.0f, 0.0f);
    int n = lu_accel_all_hits(a, o, d, 0, INFINITY, h, 8);
    CHECK(n == 4);
    const double want_t[4] = {1.0, 1.25, 1.75, 2.0};
    const uint32_t want_mesh[4] = {0, 1, 1, 0};
    for (int i = 0; i < 4 && i < n; i++) {
        CHECK_NEAR(h[i].t, want_t[i], t_tol(o, d, want_t[i]));
        CHECK(h[i].mesh_id == want_mesh[i]);
        CHECK_NEAR(h[i].ng.x, i < 2 ? -1.0 : 1.0, 1e-6);
    }
    /* Truncation: the total is returned, only max_hits written. */
    lu_hit one[2];
    one[1].t = -7.0f;
    CHECK(lu_accel_all_hits(a, o, d, 0, INFINITY, one, 1) == 4);
    CHECK_NEAR(one[0].t, 1.0, t_tol(o, d, 1.0));
    CHECK(one[1].t == -7.0f);
    CHECK(lu_accel_all_hits(a, o, d, 0, INFINITY, NULL, 0) == 4);
    /* The open interval (tmin, tmax) selects crossings. */
    CHECK(lu_accel_all_hits(a, o, d, 1.1f, 1.9f, h, 8) == 2);
    CHECK_NEAR(h[0].t, 1.25, t_tol(o, d, 1.25));
    /* Negative tmin: the ray reaches back behind its origin. */
    lu_vec3 oc = lu_v3(0.0f, 0.1f, -0.2f);
    CHECK(lu_accel_all_hits(a, oc, d, -INFINITY, INFINITY, h, 8) == 4);
    CHECK_NEAR(h[0].t, -0.5, 1e-6);
    CHECK_NEAR(h[3].t, 0.5, 1e-6);
    CHECK(lu_accel_all_hits(a, oc, d, -0.3f, INFINITY, h, 8) == 3);
    CHECK_NEAR(h[0].t, -0.25, 1e-6);

    /* Random rays from outside the outer box: 0, 2 or 4 crossings exactly as
     * the slab test says, away from edges. */
    int checked = 0, fours = 0;
    for (int k = 0; k < 2000; k++) {
        lu_vec3 ro = lu_v3_scale(rnd_unit(), 3.0f), rd = lu_v3_norm(lu_v3_sub(lu_v3_scale(rnd_unit(), 0.9f), ro));
        double t[4];
        int ax0 = 0, ax1 = 0, count = 0;
        bool skip = false;
        const lu_mesh *bx[2] = {&outer, &inner};
        double tt[2][2];
        for (int m = 0; m < 2; m++) {
            lu_vec3 blo = bx[m]->positions[0], bhi = bx[m]->positions[0];
            for (uint32_t v = 0; v < bx[m]->vertex_count; v++) {
                blo = lu_v3_min(blo, bx[m]->positions[v]);
                bhi = lu_v3_max(bhi, bx[m]->positions[v]);
            }
            double t0, t1;
            bool hit = slab(blo, bhi, dv(ro), dv(rd), &t0, &t1, &ax0, &ax1);
            if (fabs(t1 - t0) < 1e-4) skip = true;
            if (hit) {
                dvec p0 = {ro.x + t0 * rd.x, ro.y + t0 * rd.y, ro.z + t0 * rd.z};
                dvec p1 = {ro.x + t1 * rd.x, ro.y + t1 * rd.y, ro.z + t1 * rd.z};
                if (face_border_margin(blo, bhi, p0, ax0) < 1e-4 || face_border_margin(blo, bhi, p1, ax1) < 1e-4)
                    skip = true;
                tt[m][0] = t0;
                tt[m][1] = t1;
            }
            if (hit) count += 2;
            else tt[m][0] = tt[m][1] = NAN;
        }
        if (skip) continue;
        int nn = lu_accel_all_hits(a, ro, rd, 0, INFINITY, h, 8);
        CHECK(nn == count);
        if (nn != count) continue;
        checked++;
        if (count == 4) {
            fours++;
            t[0] = tt[0][0], t[1] = tt[1][0], t[2] = tt[1][1], t[3] = tt[0][1];
        } else if (count == 2) {
            t[0] = tt[0][0], t[1] = tt[0][1];
        }
        for (int i = 0; i < count; i++) CHECK_NEAR(h[i].t, t[i], t_tol(ro, rd, t[i]));
        for (int i = 1; i < nn; i++) CHECK(h[i].t >= h[i - 1].t);
    }
    CHECK_MSG(checked > 1500 && fours > 300, "checked %d, through both %d", checked, fours);
    lu_accel_destroy(a);
    mesh_free(&outer);
    mesh_free(&inner);
}

/* Rays exactly through a box's edges, vertices and face diagonals: the
 * watertight test reports every triangle there; they must count once. Done
 * for the 8-vertex box (shared indices) and the 24-vertex box (shared
 * positions only). */
static void test_all_hits_edges_and_vertices(void) {
    for (int variant = 0; variant < 2; variant++) {
        lu_mesh b;
        if (variant == 0) make_box8(&b, lu_v3(-1, -1, -1), lu_v3(1, 1, 1));
        else make_box24(&b, lu_v3(-1, -1, -1), lu_v3(1, 1, 1));
        const lu_mesh *ms[1] = {&b};
        lu_accel *a = accel_of(ms, 1);
        lu_hit h[8];
        /* Through the edge x = y = 1 and out through x = y = -1, at z = 0.25. */
        lu_vec3 o = lu_v3(3.0f, 3.0f, 0.25f), d = lu_v3(-1.0f, -1.0f, 0.0f);
        int n = lu_accel_all_hits(a, o, d, 0, INFINITY, h, 8);
        CHECK_MSG(n == 2, "variant %d: edge ray gives %d crossings", variant, n);
        if (n == 2) {
            CHECK_NEAR(h[0].t, 2.0, t_tol(o, d, 2));
            CHECK_NEAR(h[1].t, 4.0, t_tol(o, d, 4));
        }
        /* Through corner (1,1,1) and out through (-1,-1,-1): 3 faces meet there. */
        o = lu_v3(2.0f, 2.0f, 2.0f);
        d = lu_v3(-1.0f, -1.0f, -1.0f);
        n = lu_accel_all_hits(a, o, d, 0, INFINITY, h, 8);
        CHECK_MSG(n == 2, "variant %d: vertex ray gives %d crossings", variant, n);
        if (n == 2) {
            CHECK_NEAR(h[0].t, 1.0, t_tol(o, d, 1));
            CHECK_NEAR(h[1].t, 3.0, t_tol(o, d, 3));
        }
        /* Through a corner on the other diagonal, and along the face
         * diagonals of every face (the edge between a face's two triangles). */
        o = lu_v3(-2.0f, 2.0f, -2.0f);
        d = lu_v3(1.0f, -1.0f, 1.0f);
        CHECK(lu_accel_all_hits(a, o, d, 0, INFINITY, h, 8) == 2);
        for (int f = 0; f < 6; f++) {
            /* The diagonal shared by the face's two triangles runs from
             * corner q[0] to q[2]; aim at a point a quarter along it. */
            lu_vec3 c0 = box_corner(lu_v3(-1, -1, -1), lu_v3(1, 1, 1), k_box_faces[f][0]);
            lu_vec3 c2 = box_corner(lu_v3(-1, -1, -1), lu_v3(1, 1, 1), k_box_faces[f][2]);
            lu_vec3 p = lu_v3_add(c0, lu_v3_scale(lu_v3_sub(c2, c0), 0.25f));
            int axis = f / 2;
            lu_vec3 nrm = lu_v3(axis == 0, axis == 1, axis == 2);
            if (f % 2 == 0) nrm = lu_v3_neg(nrm);
            o = lu_v3_add(p, lu_v3_scale(nrm, 3.0f));
            d = lu_v3_neg(nrm);
            n = lu_accel_all_hits(a, o, d, 0, INFINITY, h, 8);
            CHECK_MSG(n == 2, "variant %d face %d diagonal gives %d crossings", variant, f, n);
            if (n == 2) {
                CHECK_NEAR(h[0].t, 3.0, t_tol(o, d, 3));
                CHECK_NEAR(h[1].t, 5.0, t_tol(o, d, 5));
            }
        }
        /* Grazing: touching the box only along the edge x = y = 1 gives an
         * in and an out crossing at the same t (or none): an even count. */
        o = lu_v3(2.0f, 0.0f, 0.25f);
        d = lu_v3(-1.0f, 1.0f, 0.0f);
        n = lu_accel_all_hits(a, o, d, 0, INFINITY, h, 8);
        CHECK_MSG(n % 2 == 0, "variant %d grazing edge gives %d crossings", variant, n);
        /* Inside with the origin exactly on edge- and vertex-aligned lines. */
        CHECK(lu_accel_inside(a, lu_v3(0, 0, 0)));
        CHECK(lu_accel_inside(a, lu_v3(0.5f, 0.5f, 0.5f)));
        CHECK(!lu_accel_inside(a, lu_v3(1.5f, 1.5f, 0.25f)));
        lu_accel_destroy(a);
        mesh_free(&b);
    }
}

/* ---- inside ------------------------------------------------------------------ */

static void test_inside_box_and_sphere(void) {
    const lu_vec3 lo = lu_v3(-0.6f, -0.3f, -0.9f), hi = lu_v3(0.7f, 1.1f, 0.4f);
    lu_mesh b, s;
    make_box24(&b, lo, hi);
    const lu_vec3 c = lu_v3(3.0f, 0.2f, -0.1f);
    const float r = 0.9f;
    make_uv_sphere(&s, c, r, 40, 20);
    const lu_mesh *ms[2] = {&b, &s};
    lu_accel *a = accel_of(ms, 2);
    const double rin = sphere_mesh_inradius(&s, dv(c));
    /* Box: the tessellation is exact, so only float rounding of the faces
     * (1e-5 here) may disagree. */
    int total = 0, agree = 0, n_in = 0;
    for (int k = 0; k < 4000; k++) {
        lu_vec3 q = lu_v3((float)rnd_range(-1, 1.1), (float)rnd_range(-0.7, 1.5), (float)rnd_range(-1.3, 0.8));
        double m = fmin(fmin(fabs(q.x - lo.x), fabs(q.x - hi.x)),
                        fmin(fmin(fabs(q.y - lo.y), fabs(q.y - hi.y)), fmin(fabs(q.z - lo.z), fabs(q.z - hi.z))));
        bool in = q.x > lo.x && q.x < hi.x && q.y > lo.y && q.y < hi.y && q.z > lo.z && q.z < hi.z;
        if (m < 1e-5) continue;
        total++;
        n_in += in;
        agree += lu_accel_inside(a, q) == in;
    }
    CHECK_MSG(agree == total && n_in > 800 && total - n_in > 1000, "box: %d of %d agree (%d inside)", agree,
              total, n_in);
    /* Sphere: the polyhedron lies between the inscribed radius rin and r;
     * points outside that shell (widened by 1e-5 for float) must agree
     * with the analytic ball. */
    total = agree = n_in = 0;
    int shell = 0;
    for (int k = 0; k < 4000; k++) {
        lu_vec3 q = lu_v3_add(c, lu_v3_scale(rnd_unit(), (float)rnd_range(0, 1.3 * r)));
        double rq = dlen(dsub(dv(q), dv(c)));
        if (rq > rin - 1e-5 && rq < r + 1e-5) {
            shell++;
            continue;
        }
        bool in = rq < rin;
        total++;
        n_in += in;
        agree += lu_accel_inside(a, q) == in;
    }
    CHECK_MSG(agree == total && n_in > 2000 && total - n_in > 500 && shell < 200,
              "sphere: %d of %d agree (%d inside, %d in the shell)", agree, total, n_in, shell);
    lu_accel_destroy(a);
    mesh_free(&b);
    mesh_free(&s);
}

/* ---- voxelisation ------------------------------------------------------------ */

/* Expected fraction of a voxel covered by an axis-aligned box, per axis
 * overlap in double (exact for the dyadic values used here). */
static double box_voxel_overlap(const double vlo[3], double h, const double blo[3], const double bhi[3]) {
    double ov = 1;
    for (int i = 0; i < 3; i++) {
        double l = fmax(vlo[i], blo[i]), u = fmin(vlo[i] + h, bhi[i]);
        ov *= u > l ? (u - l) / h : 0;
    }
    return ov;
}

static void test_voxelize_box_exact(void) {
    lu_error err = {0};
    for (int variant = 0; variant < 2; variant++) {
        /* Grid over [0,1]^3 at 8 voxels: h = 1/8. The box covers voxels 2..5
         * in y and z and 2..4 in x, plus half of layer x = 5 (its face passes
         * through the layer's centres at 0.6875). With ss = 4 the sub-samples
         * sit at odd multiples of 1/64 and never on a face. Rows with y = z
         * run exactly through the diagonal edges of both x faces. */
        lu_mesh b;
        const double blo[3] = {0.25, 0.25, 0.25}, bhi[3] = {0.6875, 0.75, 0.75};
        lu_vec3 lo = lu_v3(0.25f, 0.25f, 0.25f), hi = lu_v3(0.6875f, 0.75f, 0.75f);
        if (variant == 0) make_box8(&b, lo, hi);
        else make_box24(&b, lo, hi);
        const lu_mesh *ms[1] = {&b};
        lu_accel *a = accel_of(ms, 1);
        lu_grid g;
        lu_aabb bounds = {{0, 0, 0}, {1, 1, 1}};
        CHECK_OK(lu_voxelize(a, bounds, 8, 4, &g, &err), &err);
        CHECK(g.nx == 8 && g.ny == 8 && g.nz == 8);
        int wrong = 0;
        double sum = 0;
        for (int z = 0; z < 8; z++)
            for (int y = 0; y < 8; y++)
                for (int x = 0; x < 8; x++) {
                    bool yz = y >= 2 && y <= 5 && z >= 2 && z <= 5;
                    float want = yz && x >= 2 && x <= 4 ? 1.0f : (yz && x == 5 ? 0.5f : 0.0f);
                    const double vlo[3] = {x / 8.0, y / 8.0, z / 8.0};
                    CHECK(want == box_voxel_overlap(vlo, 0.125, blo, bhi));
                    float got = g.data[((size_t)z * 8 + y) * 8 + x];
                    wrong += got != want;
                    sum += got;
                }
        CHECK_MSG(wrong == 0, "variant %d: %d voxels differ", variant, wrong);
        CHECK(sum == 4 * 4 * 3 + 4 * 4 * 0.5);
        CHECK(g.min_value == 0.0f && g.max_value == 1.0f);
        /* index_to_world: voxel centres at lo + (i + 0.5) h. */
        lu_vec3 c0 = lu_affine_point(&g.index_to_world, lu_v3(0, 0, 0));
        lu_vec3 c7 = lu_affine_point(&g.index_to_world, lu_v3(7, 2, 5));
        CHECK(c0.x == 0.0625f && c0.y == 0.0625f && c0.z == 0.0625f);
        CHECK(c7.x == 0.9375f && c7.y == 0.3125f && c7.z == 0.6875f);
        lu_free(g.data);

        /* Non-cubic bounds cutting through the box, ss = 2: extents 1.25 x
         * 0.5 x 0.375 at resolution 10 give h = 1/8 and 10 x 4 x 3 voxels.
         * The grid starts at x = -1/16, so x = 0.25 is a voxel centre:
         * voxel 2 is half covered in x, 3..5 fully (0.6875 is a voxel face
         * now); y voxels 2..3 and z voxel 2 are covered up to the grid's end. */
        lu_aabb nb = {{-0.0625f, 0.0f, 0.0f}, {1.1875f, 0.5f, 0.375f}};
        CHECK_OK(lu_voxelize(a, nb, 10, 2, &g, &err), &err);
        CHECK(g.nx == 10 && g.ny == 4 && g.nz == 3);
        int nonzero = 0, halves = 0;
        wrong = 0;
        for (int z = 0; z < g.nz; z++)
            for (int y = 0; y < g.ny; y++)
                for (int x = 0; x < g.nx; x++) {
                    const double vlo[3] = {-0.0625 + 0.125 * x, 0.125 * y, 0.125 * z};
                    double want = box_voxel_overlap(vlo, 0.125, blo, bhi);
                    float got = g.data[((size_t)z * g.ny + y) * g.nx + x];
                    wrong += got != want;
                    nonzero += got > 0;
                    halves += got == 0.5f;
                }
        CHECK_MSG(wrong == 0 && nonzero == 8 && halves == 2, "variant %d non-cubic: %d voxels differ, %d nonzero",
                  variant, wrong, nonzero);
        lu_free(g.data);
        lu_accel_destroy(a);
        mesh_free(&b);
    }
}

/* A row with an odd crossing count (here: a tiny open flap, a lone triangle
 * before the box, crossed by one +x sample row) must fall back to per-sample
 * majority-vote inside tests instead of filling (flap, box) and (box, inf)
 * as "inside". The flap is 0.003 across and at least 0.006 from the
 * nearest samples in x, so no inside-test ray from a grid sample meets it
 * (each direction moves y or z by more than 0.003 over that gap); it adds
 * no volume, so the grid must equal the box's exactly. */
static void test_voxelize_odd_row_fallback(void) {
    lu_error err = {0};
    lu_mesh b, flap;
    make_box8(&b, lu_v3(0.25f, 0.25f, 0.25f), lu_v3(0.6875f, 0.75f, 0.75f));
    mesh_init(&flap, 3, 1);
    const float fy = 25.0f / 64, fz = 29.0f / 64;   /* a sample row at ss = 4, h = 1/8 */
    flap.positions[0] = lu_v3(0.1f, fy - 0.001f, fz - 0.001f);
    flap.positions[1] = lu_v3(0.1f, fy + 0.002f, fz - 0.001f);
    flap.positions[2] = lu_v3(0.1f, fy - 0.001f, fz + 0.002f);
    flap.indices[0] = 0, flap.indices[1] = 1, flap.indices[2] = 2;
    const lu_mesh *ms[2] = {&b, &flap};
    lu_accel *a = accel_of(ms, 2);
    /* The flap does make some rows odd. */
    CHECK(lu_accel_all_hits(a, lu_v3(-1, fy, fz), lu_v3(1, 0, 0), 0, INFINITY, NULL, 0) == 3);
    lu_grid g;
    CHECK_OK(lu_voxelize(a, (lu_aabb){{0, 0, 0}, {1, 1, 1}}, 8, 4, &g, &err), &err);
    const double blo[3] = {0.25, 0.25, 0.25}, bhi[3] = {0.6875, 0.75, 0.75};
    int wrong = 0;
    for (int z = 0; z < 8; z++)
        for (int y = 0; y < 8; y++)
            for (int x = 0; x < 8; x++) {
                const double vlo[3] = {x / 8.0, y / 8.0, z / 8.0};
                wrong += g.data[((size_t)z * 8 + y) * 8 + x] != box_voxel_overlap(vlo, 0.125, blo, bhi);
            }
    CHECK_MSG(wrong == 0, "%d voxels differ", wrong);
    lu_free(g.data);
    lu_accel_destroy(a);
    mesh_free(&b);
    mesh_free(&flap);
}

/* Brute-force double-precision crossings of the row y, z along +x. */
static int bf_row_crossings(const lu_mesh *m, double y, double z, double *xs, int cap, double *margin) {
    int n = 0;
    dvec o = {-10, y, z}, d = {1, 0, 0};
    *margin = INFINITY;
    for (uint32_t t = 0; t < m->triangle_count; t++) {
        bf_hit h;
        if (bf_tri(m, t, o, d, &h)) {
            if (n < cap) xs[n] = -10 + h.t;
            n++;
            *margin = fmin(*margin, h.margin);
        }
    }
    for (int i = 1; i < n && i < cap; i++)
        for (int j = i; j > 0 && xs[j] < xs[j - 1]; j--) {
            double s = xs[j];
            xs[j] = xs[j - 1];
            xs[j - 1] = s;
        }
    return n;
}

static void test_voxelize_sphere(void) {
    lu_error err = {0};
    const lu_vec3 c = lu_v3(0.03f, -0.02f, 0.05f);
    const float r = 0.8f;
    lu_mesh s;
    make_uv_sphere(&s, c, r, 48, 24);
    const lu_mesh *ms[1] = {&s};
    lu_accel *a = accel_of(ms, 1);
    const int res = 32, ss = 2;
    lu_aabb bounds = {{-1, -1, -1}, {1, 1, 1}};
    lu_grid g;
    CHECK_OK(lu_voxelize(a, bounds, res, ss, &g, &err), &err);
    CHECK(g.nx == res && g.ny == res && g.nz == res);
    const double h = 2.0 / res, hs = h / ss;

    /* (1) Every sub-sample row against brute-force double-precision
     * crossings: the per-voxel counts must match exactly, except for samples
     * within 1e-5 of a crossing or rows within 1e-6 of a triangle edge. */
    int *count = calloc((size_t)res * res * res, sizeof *count);
    unsigned char *fuzzy = calloc((size_t)res * res * res, 1);
    double xs[64];
    int odd_rows = 0;
    for (int iz = 0; iz < res * ss; iz++)
        for (int iy = 0; iy < res * ss; iy++) {
            double y = (float)(-1 + (iy + 0.5) * hs), z = (float)(-1 + (iz + 0.5) * hs), margin;
            int n = bf_row_crossings(&s, y, z, xs, 64, &margin);
            if (n % 2) {
                odd_rows++;
                continue;
            }
            for (int ix = 0; ix < res * ss; ix++) {
                double x = (float)(-1 + (ix + 0.5) * hs);
                int before = 0;
                double near = INFINITY;
                for (int k = 0; k < n; k++) {
                    before += xs[k] < x;
                    near = fmin(near, fabs(xs[k] - x));
                }
                size_t v = ((size_t)(iz / ss) * res + iy / ss) * res + ix / ss;
                count[v] += before & 1;
                if (near < 1e-5 || margin < 1e-6) fuzzy[v] = 1;
            }
        }
    int mismatch = 0, compared = 0;
    for (size_t v = 0; v < (size_t)res * res * res; v++) {
        if (fuzzy[v]) continue;
        compared++;
        mismatch += g.data[v] != (float)count[v] / (ss * ss * ss);
    }
    CHECK_MSG(mismatch == 0 && odd_rows == 0 && compared > res * res * res * 9 / 10,
              "%d of %d voxels differ from brute force (%d odd rows)", mismatch, compared, odd_rows);
    free(count);
    free(fuzzy);

    /* (2) Volume: sum(fraction) h^3 against the polyhedron's exact volume
     * (divergence theorem), on a finer grid (res 64, ss 4). Each sample
     * stands for a cube of side hs centred on it, and only cubes the surface
     * cuts are in error, all within rho = hs sqrt(3)/2 of the surface. So the
     * estimate lies between the volumes of the inner and outer parallel
     * bodies at distance rho; for a convex body Steiner's formula bounds both
     * gaps by A rho + M rho^2 + 4/3 pi rho^3, with M <= 4 pi r for a body
     * inside a ball of radius r (A = the polyhedron's area). */
    lu_free(g.data);
    const int res2 = 64, ss2 = 4;
    CHECK_OK(lu_voxelize(a, bounds, res2, ss2, &g, &err), &err);
    double sum = 0;
    for (size_t v = 0; v < (size_t)res2 * res2 * res2; v++) sum += g.data[v];
    const double h2 = 2.0 / res2, vol = mesh_volume(&s), area = mesh_area(&s);
    const double rho = h2 / ss2 * sqrt(3.0) / 2;
    const double tol = area * rho + 4 * PI_D * r * rho * rho + 4.0 / 3.0 * PI_D * rho * rho * rho;
    CHECK(vol > 0 && vol < 4.0 / 3.0 * PI_D * r * r * r);
    CHECK_NEAR(sum * h2 * h2 * h2, vol, tol);
    lu_free(g.data);
    CHECK_OK(lu_voxelize(a, bounds, res, ss, &g, &err), &err);
    /* Voxels wholly inside the inscribed ball are 1, wholly outside the
     * circumscribed ball 0. */
    const double rin = sphere_mesh_inradius(&s, dv(c));
    int bad = 0;
    for (int z = 0; z < res; z++)
        for (int y = 0; y < res; y++)
            for (int x = 0; x < res; x++) {
                lu_vec3 p = lu_affine_point(&g.index_to_world, lu_v3((float)x, (float)y, (float)z));
                double dc = dlen(dsub(dv(p), dv(c))), half_diag = h * sqrt(3.0) / 2;
                float f = g.data[((size_t)z * res + y) * res + x];
                if (dc + half_diag < rin && f != 1.0f) bad++;
                if (dc - half_diag > r && f != 0.0f) bad++;
            }
    CHECK_MSG(bad == 0, "%d voxels wrong far from the surface", bad);
    lu_free(g.data);
    lu_accel_destroy(a);
    mesh_free(&s);
}

/* ---- concurrency ---------------------------------------------------------------- */

typedef struct conc_ctx {
    const lu_accel *a;
    const lu_vec3 *o, *d;
    lu_hit *hits;
    int *found, *counts;
} conc_ctx;

static void conc_range(void *p, int64_t begin, int64_t end, int thread_index) {
    conc_ctx *c = p;
    for (int64_t i = begin; i < end; i++) {
        c->found[i] = lu_accel_closest(c->a, c->o[i], c->d[i], 0, INFINITY, &c->hits[i]);
        c->counts[i] = lu_accel_all_hits(c->a, c->o[i], c->d[i], 0, INFINITY, NULL, 0);
    }
}

static void test_concurrent_queries(void) {
    lu_mesh s, b;
    make_uv_sphere(&s, lu_v3(0, 0, 0), 1.0f, 64, 32);
    make_box24(&b, lu_v3(-0.3f, -0.3f, -0.3f), lu_v3(0.3f, 0.3f, 0.3f));
    const lu_mesh *ms[2] = {&s, &b};
    lu_accel *a = accel_of(ms, 2);
    enum { N = 20000 };
    lu_vec3 *o = malloc(N * sizeof *o), *d = malloc(N * sizeof *d);
    lu_hit *h1 = calloc(N, sizeof *h1), *h2 = calloc(N, sizeof *h2);
    int *f1 = calloc(N, sizeof(int)), *f2 = calloc(N, sizeof(int)), *c1 = calloc(N, sizeof(int)),
        *c2 = calloc(N, sizeof(int));
    for (int i = 0; i < N; i++) {
        o[i] = lu_v3_scale(rnd_unit(), (float)rnd_range(0, 2));
        d[i] = rnd_unit();
    }
    conc_ctx single = {a, o, d, h1, f1, c1};
    conc_range(&single, 0, N, 0);
    /* Four workers even on a two-core machine, small chunks to interleave. */
    lu_set_thread_count(4, NULL);
    conc_ctx multi = {a, o, d, h2, f2, c2};
    lu_parallel_for(N, 64, conc_range, &multi, NULL);
    lu_set_thread_count(0, NULL);
    int diff = 0, found = 0, deep = 0;
    for (int i = 0; i < N; i++) {
        found += f1[i];
        deep += c1[i] >= 3;
        if (f1[i] != f2[i] || c1[i] != c2[i]) diff++;
        else if (f1[i] && memcmp(&h1[i], &h2[i], sizeof h1[i]) != 0) diff++;
    }
    CHECK_MSG(diff == 0 && found > N / 2 && deep > 1000, "%d differ, %d found, %d with >= 3 crossings", diff, found,
              deep);
    free(o);
    free(d);
    free(h1);
    free(h2);
    free(f1);
    free(f2);
    free(c1);
    free(c2);
    lu_accel_destroy(a);
    mesh_free(&s);
    mesh_free(&b);
}

/* ---- errors and edge cases ---------------------------------------------------- */

static void test_errors(void) {
    lu_error err = {0};
    lu_accel *a = NULL;
    CHECK_OK(lu_accel_create(&a, &err), &err);
    lu_mesh m;
    make_box8(&m, lu_v3(0, 0, 0), lu_v3(1, 1, 1));
    /* Queries before commit find nothing. */
    CHECK(!lu_accel_closest(a, lu_v3(-1, 0.5f, 0.5f), lu_v3(1, 0, 0), 0, INFINITY, NULL));
    lu_grid g;
    CHECK(lu_voxelize(a, (lu_aabb){{0, 0, 0}, {1, 1, 1}}, 4, 1, &g, &err) == LU_ERR_INVALID_ARG);

    m.indices[7] = 8;   /* one past the last vertex */
    CHECK(lu_accel_add_mesh(a, &m, NULL, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "triangle 2") && strstr(err.message, "vertex 8"), "%s", err.message);
    m.indices[7] = 1;
    m.positions[5].y = NAN;
    CHECK(lu_accel_add_mesh(a, &m, NULL, &err) == LU_ERR_NONFINITE);
    CHECK_MSG(strstr(err.message, "vertex 5") != NULL, "%s", err.message);
    m.positions[5].y = 0.0f;
    CHECK(lu_accel_add_mesh(a, NULL, NULL, &err) == LU_ERR_INVALID_ARG);
    lu_mesh big = {.vertex_count = 3, .triangle_count = LU_MAX_TRIANGLES + 1, .positions = m.positions,
                   .indices = m.indices};
    CHECK(lu_accel_add_mesh(a, &big, NULL, &err) == LU_ERR_LIMIT);

    /* An empty mesh still takes an id; the box after it is mesh 1. */
    lu_mesh empty = {0};
    uint32_t id = 99;
    CHECK_OK(lu_accel_add_mesh(a, &empty, &id, &err), &err);
    CHECK(id == 0);
    CHECK_OK(lu_accel_add_mesh(a, &m, &id, &err), &err);
    CHECK(id == 1);
    CHECK_OK(lu_accel_commit(a, &err), &err);
    lu_hit h;
    CHECK(lu_accel_closest(a, lu_v3(-1, 0.5f, 0.25f), lu_v3(1, 0, 0), 0, INFINITY, &h));
    CHECK(h.mesh_id == 1);
    /* Degenerate rays are refused, not traced. */
    CHECK(!lu_accel_closest(a, lu_v3(-1, 0.5f, 0.25f), lu_v3(0, 0, 0), 0, INFINITY, &h));
    CHECK(!lu_accel_closest(a, lu_v3(NAN, 0.5f, 0.25f), lu_v3(1, 0, 0), 0, INFINITY, &h));
    CHECK(lu_accel_all_hits(a, lu_v3(-1, 0.5f, 0.25f), lu_v3(1, 0, 0), 2, 1, NULL, 0) == 0);
    CHECK(!lu_accel_inside(a, lu_v3(NAN, 0.5f, 0.5f)));

    /* Voxelize arguments. */
    lu_aabb bx = {{0, 0, 0}, {1, 1, 1}};
    CHECK(lu_voxelize(a, bx, 4, 0, &g, &err) == LU_ERR_RANGE);
    CHECK(lu_voxelize(a, bx, 4, 33, &g, &err) == LU_ERR_RANGE);
    CHECK(lu_voxelize(a, bx, 0, 1, &g, &err) == LU_ERR_RANGE);
    CHECK(lu_voxelize(a, bx, 1024, 1, &g, &err) == LU_ERR_LIMIT);   /* 1024^3 > 512^3 */
    CHECK(lu_voxelize(a, (lu_aabb){{0, 0, 0}, {INFINITY, 1, 1}}, 4, 1, &g, &err) == LU_ERR_NONFINITE);
    CHECK(lu_voxelize(a, (lu_aabb){{0, 0, 0}, {0, 0, 0}}, 4, 1, &g, &err) == LU_ERR_RANGE);
    CHECK(lu_voxelize(a, (lu_aabb){{1, 0, 0}, {0, 1, 1}}, 4, 1, &g, &err) == LU_ERR_RANGE);
    /* A flat box still gets one voxel layer. */
    CHECK_OK(lu_voxelize(a, (lu_aabb){{0, 0, 0.5f}, {1, 1, 0.5f}}, 4, 2, &g, &err), &err);
    CHECK(g.nx == 4 && g.ny == 4 && g.nz == 1);
    lu_free(g.data);
    lu_accel_destroy(a);

    /* A committed accel with no meshes: nothing is hit, the grid is empty. */
    CHECK_OK(lu_accel_create(&a, &err), &err);
    CHECK_OK(lu_accel_commit(a, &err), &err);
    CHECK(!lu_accel_closest(a, lu_v3(0, 0, 0), lu_v3(1, 0, 0), 0, INFINITY, &h));
    CHECK(!lu_accel_occluded(a, lu_v3(0, 0, 0), lu_v3(1, 0, 0), 0, INFINITY));
    CHECK(lu_accel_all_hits(a, lu_v3(0, 0, 0), lu_v3(1, 0, 0), 0, INFINITY, NULL, 0) == 0);
    CHECK(!lu_accel_inside(a, lu_v3(0, 0, 0)));
    CHECK(!lu_aabb_valid(lu_accel_bounds(a)));
    CHECK_OK(lu_voxelize(a, bx, 4, 2, &g, &err), &err);
    CHECK(g.nx == 4 && g.max_value == 0.0f);
    lu_free(g.data);
    lu_accel_destroy(a);
    lu_accel_destroy(NULL);
    mesh_free(&m);
}

int main(void) {
    RUN_TEST(test_box_closest);
    RUN_TEST(test_sphere_closest);
    RUN_TEST(test_tetra_closest_and_inside);
    RUN_TEST(test_occluded_matches_closest);
    RUN_TEST(test_all_hits_boxes);
    RUN_TEST(test_all_hits_edges_and_vertices);
    RUN_TEST(test_inside_box_and_sphere);
    RUN_TEST(test_voxelize_box_exact);
    RUN_TEST(test_voxelize_odd_row_fallback);
    RUN_TEST(test_voxelize_sphere);
    RUN_TEST(test_concurrent_queries);
    RUN_TEST(test_errors);
    TEST_EXIT();
}
