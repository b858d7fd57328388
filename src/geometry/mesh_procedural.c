/* Procedural meshes. Closed shapes share vertices along every edge (the
 * sphere and torus) or repeat them with bit-identical positions (the box, whose
 * flat normals need one vertex per face corner), so they are watertight, and
 * they wind counter-clockwise seen from outside (positive signed volume). */
#include <lucent/mesh.h>

#include <stdlib.h>
#include <string.h>

#define PI_D 3.14159265358979323846

/* ---- small helpers ------------------------------------------------------- */

static lu_result get_int(const lu_kvlist *params, const char *key, int def, int lo, int hi, int *out, const char *where,
                         lu_error *err) {
    double v;
    lu_result r = lu_kv_number(params, key, def, lo, hi, &v, where, err);
    if (r != LU_OK) return r;
    if (v != floor(v)) return lu_fail(err, LU_ERR_RANGE, "%s: \"%s\" = %g must be a whole number", where, key, v);
    *out = (int)v;
    return LU_OK;
}

static lu_result positive(const char *where, const char *key, const double *v, int n, lu_error *err) {
    for (int i = 0; i < n; i++)
        if (!(v[i] > 0.0 && v[i] <= 1e12))
            return lu_fail(err, LU_ERR_RANGE, "%s: \"%s\" components must be in (0, 1e12], got %g", where, key, v[i]);
    return LU_OK;
}

static void set_v(lu_mesh *m, uint32_t i, double x, double y, double z, double nx, double ny, double nz) {
    m->positions[i] = lu_v3((float)x, (float)y, (float)z);
    m->normals[i] = lu_v3((float)nx, (float)ny, (float)nz);
}

static void set_t(lu_mesh *m, uint32_t t, uint32_t a, uint32_t b, uint32_t c) {
    m->indices[3 * (size_t)t] = a;
    m->indices[3 * (size_t)t + 1] = b;
    m->indices[3 * (size_t)t + 2] = c;
}

/* ---- sphere: subdivided icosahedron ------------------------------------- */

typedef struct {
    uint64_t *keys; /* (lo << 32 | hi) + 1; 0 marks an empty slot */
    uint32_t *vals;
    size_t mask;
} edge_map;

static uint32_t midpoint(edge_map *em, double (*pos)[3], uint32_t *count, uint32_t a, uint32_t b) {
    uint32_t lo = a < b ? a : b, hi = a < b ? b : a;
    uint64_t key = ((uint64_t)lo << 32 | hi) + 1;
    size_t h = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 20) & em->mask;
    while (em->keys[h] && em->keys[h] != key) h = (h + 1) & em->mask;
    if (em->keys[h]) return em->vals[h];
    uint32_t v = (*count)++;
    double m[3], len = 0.0;
    for (int k = 0; k < 3; k++) {
        m[k] = 0.5 * (pos[a][k] + pos[b][k]);
        len += m[k] * m[k];
    }
    len = sqrt(len);
    for (int k = 0; k < 3; k++) pos[v][k] = m[k] / len;
    em->keys[h] = key;
    em->vals[h] = v;
    return v;
}

static lu_result make_sphere(const lu_kvlist *params, lu_mesh *mesh, const char *where, lu_error *err) {
    static const char *const known[] = {"radius", "subdivisions", NULL};
    double radius;
    int subdiv;
    lu_result r = lu_kv_check_known(params, known, where, err);
    if (r == LU_OK) r = lu_kv_number(params, "radius", 1.0, 1e-12, 1e12, &radius, where, err);
    /* Level 8 has 1.3 M triangles, far finer than any image needs; the cap
     * keeps the midpoint table small. */
    if (r == LU_OK) r = get_int(params, "subdivisions", 4, 0, 8, &subdiv, where, err);
    if (r != LU_OK) return r;
    uint32_t nt = 20u << (2 * subdiv), nv = 10u * (1u << (2 * subdiv)) + 2u;
    r = lu_mesh_alloc(mesh, nv, nt, err);
    if (r != LU_OK) return r;
    double(*pos)[3] = lu_malloc((size_t)nv * sizeof *pos);
    uint32_t *tri = lu_malloc((size_t)nt * 3 * sizeof *tri), *next = lu_malloc((size_t)nt * 3 * sizeof *next);
    size_t slots = 1;
    while (slots < (size_t)nt) slots <<= 1; /* the last level adds 1.5 nt / 4 midpoints */
    edge_map em = {lu_calloc(slots, sizeof(uint64_t)), lu_malloc(slots * sizeof(uint32_t)), slots - 1};
    if (!pos || !tri || !next || !em.keys || !em.vals) {
        lu_free(pos), lu_free(tri), lu_free(next), lu_free(em.keys), lu_free(em.vals);
        lu_mesh_destroy(mesh);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for an icosphere with %u triangles", where, nt);
    }
    const double t = (1.0 + sqrt(5.0)) / 2.0;
    const double base[12][3] = {{-1, t, 0}, {1, t, 0}, {-1, -t, 0}, {1, -t, 0}, {0, -1, t}, {0, 1, t},
                                {0, -1, -t}, {0, 1, -t}, {t, 0, -1}, {t, 0, 1}, {-t, 0, -1}, {-t, 0, 1}};
    static const uint32_t faces[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    double len = sqrt(1.0 + t * t);
    for (int i = 0; i < 12; i++)
        for (int k = 0; k < 3; k++) pos[i][k] = base[i][k] / len;
    for (int f = 0; f < 20; f++) {
        /* Orient each face outward from its own geometry rather than trusting the table. */
        const double *a = pos[faces[f][0]], *b = pos[faces[f][1]], *c = pos[faces[f][2]];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        bool flip = n[0] * a[0] + n[1] * a[1] + n[2] * a[2] < 0.0;
        tri[3 * f] = faces[f][0];
        tri[3 * f + 1] = faces[f][flip ? 2 : 1];
        tri[3 * f + 2] = faces[f][flip ? 1 : 2];
    }
    uint32_t count = 12, tcount = 20;
    for (int level = 0; level < subdiv; level++) {
        memset(em.keys, 0, slots * sizeof(uint64_t));
        for (uint32_t f = 0; f < tcount; f++) {
            uint32_t a = tri[3 * f], b = tri[3 * f + 1], c = tri[3 * f + 2];
            uint32_t ab = midpoint(&em, pos, &count, a, b), bc = midpoint(&em, pos, &count, b, c),
                     ca = midpoint(&em, pos, &count, c, a);
            const uint32_t out[4][3] = {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}};
            memcpy(next + 12 * (size_t)f, out, sizeof out);
        }
        uint32_t *swap = tri;
        tri = next;
        next = swap;
        tcount *= 4;
    }
    for (uint32_t i = 0; i < nv; i++)
        set_v(mesh, i, radius * pos[i][0], radius * pos[i][1], radius * pos[i][2], pos[i][0], pos[i][1], pos[i][2]);
    memcpy(mesh->indices, tri, (size_t)nt * 3 * sizeof *tri);
    lu_free(pos), lu_free(tri), lu_free(next), lu_free(em.keys), lu_free(em.vals);
    return LU_OK;
}

/* ---- box, plane, room: axis-aligned rectangles -------------------------- */

/* Rectangle in the plane coordinate[a] = offset, spanning [u0,u1] along axis
 * (a+1)%3 and [v0,v1] along (a+2)%3, facing +a when sign > 0, else -a. */
static void rect(lu_mesh *m, uint32_t *nv, uint32_t *nt, int a, double offset, double u0, double u1, double v0,
                 double v1, int sign) {
    int bu = (a + 1) % 3, bv = (a + 2) % 3;
    const double uv[4][2] = {{u0, v0}, {u1, v0}, {u1, v1}, {u0, v1}};
    uint32_t base = *nv;
    for (int i = 0; i < 4; i++) {
        double p[3], n[3] = {0, 0, 0};
        p[a] = offset;
        p[bu] = uv[i][0];
        p[bv] = uv[i][1];
        n[a] = sign;
        set_v(m, base + i, p[0], p[1], p[2], n[0], n[1], n[2]);
    }
    /* Corners 0,1,2,3 run counter-clockwise around e_bu x e_bv = e_a. */
    if (sign > 0) {
        set_t(m, (*nt)++, base, base + 1, base + 2);
        set_t(m, (*nt)++, base, base + 2, base + 3);
    } else {
        set_t(m, (*nt)++, base, base + 2, base + 1);
        set_t(m, (*nt)++, base, base + 3, base + 2);
    }
    *nv += 4;
}

static lu_result make_box(const lu_kvlist *params, lu_mesh *mesh, const char *where, lu_error *err) {
    static const char *const known[] = {"size", NULL};
    const double def[3] = {2, 2, 2};
    double size[3];
    lu_result r = lu_kv_check_known(params, known, where, err);
    if (r == LU_OK) r = lu_kv_vec3(params, "size", def, size, where, err);
    if (r == LU_OK) r = positive(where, "size", size, 3, err);
    if (r == LU_OK) r = lu_mesh_alloc(mesh, 24, 12, err);
    if (r != LU_OK) return r;
    uint32_t nv = 0, nt = 0;
    for (int a = 0; a < 3; a++) {
        double h[3] = {size[0] / 2, size[1] / 2, size[2] / 2};
        int bu = (a + 1) % 3, bv = (a + 2) % 3;
        for (int s = -1; s <= 1; s += 2) rect(mesh, &nv, &nt, a, s * h[a], -h[bu], h[bu], -h[bv], h[bv], s);
    }
    return LU_OK;
}

static lu_result make_plane(const lu_kvlist *params, lu_mesh *mesh, const char *where, lu_error *err) {
    static const char *const known[] = {"size", NULL};
    double size[2] = {10, 10};
    lu_result r = lu_kv_check_known(params, known, where, err);
    if (r != LU_OK) return r;
    const lu_kv *kv = lu_kv_find(params, "size");
    if (kv) {
        if (kv->count != 1 && kv->count != 2)
            return lu_fail(err, LU_ERR_SCENE, "%s: \"size\" must be a number or 2 numbers [x, z]", where);
        size[0] = kv->v[0];
        size[1] = kv->count == 2 ? kv->v[1] : kv->v[0];
    }
    r = positive(where, "size", size, 2, err);
    if (r == LU_OK) r = lu_mesh_alloc(mesh, 4, 2, err);
    if (r != LU_OK) return r;
    uint32_t nv = 0, nt = 0;
    /* Axis 1 (Y): u runs along Z and v along X, and e_z x e_x = +Y. */
    rect(mesh, &nv, &nt, 1, 0.0, -size[1] / 2, size[1] / 2, -size[0] / 2, size[0] / 2, 1);
    return LU_OK;
}

static lu_result make_room(const lu_kvlist *params, lu_mesh *mesh, const char *where, lu_error *err) {
    static const char *const known[] = {"size", "window", NULL};
    const double def[3] = {6, 3, 6};
    double size[3];
    lu_result r = lu_kv_check_known(params, known, where, err);
    if (r == LU_OK) r = lu_kv_vec3(params, "size", def, size, where, err);
    if (r == LU_OK) r = positive(where, "size", size, 3, err);
    if (r != LU_OK) return r;
    double h[3] = {size[0] / 2, size[1] / 2, size[2] / 2};
    /* window = [z0, y0, z1, y1] on the +X wall, in room coordinates. */
    double w[4] = {-size[2] / 6, -size[1] / 4, size[2] / 6, size[1] / 4};
    const lu_kv *kv = lu_kv_find(params, "window");
    if (kv) {
        if (kv->count != 4)
            return lu_fail(err, LU_ERR_SCENE, "%s: \"window\" must be 4 numbers [z0, y0, z1, y1]", where);
        memcpy(w, kv->v, sizeof w);
        if (!(w[0] >= -h[2] && w[0] <= w[2] && w[2] <= h[2] && w[1] >= -h[1] && w[1] <= w[3] && w[3] <= h[1]))
            return lu_fail(err, LU_ERR_RANGE,
                           "%s: \"window\" [%g, %g, %g, %g] must satisfy %g <= z0 <= z1 <= %g and %g <= y0 <= y1 <= %g",
                           where, w[0], w[1], w[2], w[3], -h[2], h[2], -h[1], h[1]);
    }
    /* The +X wall is a 3 x 3 grid of cells (Y rows, Z columns) without the
     * centre one; empty cells (a window touching an edge) are left out. */
    const double ys[4] = {-h[1], w[1], w[3], h[1]}, zs[4] = {-h[2], w[0], w[2], h[2]};
    uint32_t cells = 0;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if ((i != 1 || j != 1) && ys[i + 1] > ys[i] && zs[j + 1] > zs[j]) cells++;
    /* With an empty window the centre cell has no extent and the other eight
     * cover the whole wall. */
    r = lu_mesh_alloc(mesh, 4 * (5 + cells), 2 * (5 + cells), err);
    if (r != LU_OK) return r;
    uint32_t nv = 0, nt = 0;
    for (int a = 0; a < 3; a++) {
        int bu = (a + 1) % 3, bv = (a + 2) % 3;
        for (int s = -1; s <= 1; s += 2) {
            if (a == 0 && s > 0) continue;
            /* Inward: the wall at +h faces -a, the one at -h faces +a. */
            rect(mesh, &nv, &nt, a, s * h[a], -h[bu], h[bu], -h[bv], h[bv], -s);
        }
    }
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) {
            if ((i != 1 || j != 1) && ys[i + 1] > ys[i] && zs[j + 1] > zs[j])
                rect(mesh, &nv, &nt, 0, h[0], ys[i], ys[i + 1], zs[j], zs[j + 1], -1);
        }
    return LU_OK;
}

/* ---- torus ---------------------------------------------------------------- */

static lu_result make_torus(const lu_kvlist *params, lu_mesh *mesh, const char *where, lu_error *err) {
    static const char *const known[] = {"major_radius", "minor_radius", "segments", "sides", NULL};
    double R, rr;
    int nseg, nside;
    lu_result r = lu_kv_check_known(params, known, where, err);
    if (r == LU_OK) r = lu_kv_number(params, "major_radius", 0.6, 1e-12, 1e12, &R, where, err);
    if (r == LU_OK) r = lu_kv_number(params, "minor_radius", 0.2, 1e-12, 1e12, &rr, where, err);
    if (r == LU_OK) r = get_int(params, "segments", 64, 3, 4096, &nseg, where, err);
    if (r == LU_OK) r = get_int(params, "sides", 32, 3, 4096, &nside, where, err);
    if (r != LU_OK) return r;
    if (!(rr < R))
        return lu_fail(err, LU_ERR_RANGE, "%s: minor_radius %g must be smaller than major_radius %g", where, rr, R);
    r = lu_mesh_alloc(mesh, (uint32_t)(nseg * nside), (uint32_t)(2 * nseg * nside), err);
    if (r != LU_OK) return r;
    for (int i = 0; i < nseg; i++) {
        double u = 2.0 * PI_D * i / nseg, cu = cos(u), su = sin(u);
        for (int j = 0; j < nside; j++) {
            double v = 2.0 * PI_D * j / nside, cv = cos(v), sv = sin(v), rho = R + rr * cv;
            set_v(mesh, (uint32_t)(i * nside + j), rho * cu, rr * sv, rho * su, cv * cu, sv, cv * su);
        }
    }
    uint32_t t = 0;
    for (int i = 0; i < nseg; i++)
        for (int j = 0; j < nside; j++) {
            uint32_t i1 = (uint32_t)((i + 1) % nseg), j1 = (uint32_t)((j + 1) % nside);
            uint32_t a = (uint32_t)(i * nside + j), b = (uint32_t)i * nside + j1, c = i1 * nside + j1,
                     d = i1 * nside + (uint32_t)j;
            /* dP/dv x dP/du points away from the tube centre, so a -> b (along v)
             * -> c (along u) is counter-clockwise seen from outside. */
            set_t(mesh, t++, a, b, c);
            set_t(mesh, t++, a, c, d);
        }
    return LU_OK;
}

lu_result lu_mesh_procedural(const char *name, const lu_kvlist *params, lu_mesh *mesh, const char *where,
                             lu_error *err) {
    memset(mesh, 0, sizeof *mesh);
    if (!where) where = "procedural mesh";
    if (!name) return lu_fail(err, LU_ERR_SCENE, "%s: no procedural mesh name", where);
    if (strcmp(name, "sphere") == 0) return make_sphere(params, mesh, where, err);
    if (strcmp(name, "box") == 0) return make_box(params, mesh, where, err);
    if (strcmp(name, "torus") == 0) return make_torus(params, mesh, where, err);
    if (strcmp(name, "plane") == 0) return make_plane(params, mesh, where, err);
    if (strcmp(name, "room") == 0) return make_room(params, mesh, where, err);
    return lu_fail(err, LU_ERR_SCENE, "%s: unknown procedural mesh \"%s\" (known: sphere, box, torus, plane, room)",
                   where, name);
}
