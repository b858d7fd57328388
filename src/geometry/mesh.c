/* Indexed triangle meshes: allocation, transforms, normals, measures, loading
 * by extension, and the helpers the loaders share. */
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

void lu_mesh_destroy(lu_mesh *mesh) {
    if (!mesh) return;
    lu_free(mesh->positions);
    lu_free(mesh->normals);
    lu_free(mesh->indices);
    memset(mesh, 0, sizeof *mesh);
}

lu_result lu_mesh_alloc(lu_mesh *mesh, uint32_t vertex_count, uint32_t triangle_count, lu_error *err) {
    memset(mesh, 0, sizeof *mesh);
    if (vertex_count > LU_MAX_VERTICES)
        return lu_fail(err, LU_ERR_LIMIT, "mesh: %u vertices exceeds the limit of %u", vertex_count, LU_MAX_VERTICES);
    if (triangle_count > LU_MAX_TRIANGLES)
        return lu_fail(err, LU_ERR_LIMIT, "mesh: %u triangles exceeds the limit of %u", triangle_count,
                       LU_MAX_TRIANGLES);
    /* At least one element each, so a NULL pointer always means failure. */
    size_t nv = vertex_count ? vertex_count : 1, nt = triangle_count ? triangle_count : 1;
    mesh->positions = lu_calloc(nv, sizeof *mesh->positions);
    mesh->normals = lu_calloc(nv, sizeof *mesh->normals);
    mesh->indices = lu_calloc(3 * nt, sizeof *mesh->indices);
    if (!mesh->positions || !mesh->normals || !mesh->indices) {
        lu_mesh_destroy(mesh);
        return lu_fail(err, LU_ERR_NOMEM, "mesh: out of memory for %u vertices and %u triangles", vertex_count,
                       triangle_count);
    }
    mesh->vertex_count = vertex_count;
    mesh->triangle_count = triangle_count;
    return LU_OK;
}

void lu_mesh_transform(lu_mesh *mesh, const lu_affine *xf) {
    for (uint32_t i = 0; i < mesh->vertex_count; i++) mesh->positions[i] = lu_affine_point(xf, mesh->positions[i]);
    if (mesh->normals)
        for (uint32_t i = 0; i < mesh->vertex_count; i++)
            mesh->normals[i] = lu_v3_norm(lu_affine_normal(xf, mesh->normals[i]));
    /* A mirroring map reverses the handedness of every triangle; swapping two
     * corners keeps "counter-clockwise = outward" true (and the volume positive). */
    const float(*m)[4] = xf->m;
    double det = (double)m[0][0] * ((double)m[1][1] * m[2][2] - (double)m[1][2] * m[2][1]) -
                 (double)m[0][1] * ((double)m[1][0] * m[2][2] - (double)m[1][2] * m[2][0]) +
                 (double)m[0][2] * ((double)m[1][0] * m[2][1] - (double)m[1][1] * m[2][0]);
    if (det < 0.0) {
        for (uint32_t t = 0; t < mesh->triangle_count; t++) {
            uint32_t *tri = mesh->indices + 3 * (size_t)t, k = tri[1];
            tri[1] = tri[2];
            tri[2] = k;
        }
    }
}

void lu_mesh_compute_normals(lu_mesh *mesh) {
    if (!mesh->normals) return;
    memset(mesh->normals, 0, (size_t)mesh->vertex_count * sizeof *mesh->normals);
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        const uint32_t *tri = mesh->indices + 3 * (size_t)t;
        lu_vec3 a = mesh->positions[tri[0]], b = mesh->positions[tri[1]], c = mesh->positions[tri[2]];
        /* The unnormalised cross product is twice the area times the unit normal. */
        lu_vec3 n = lu_v3_cross(lu_v3_sub(b, a), lu_v3_sub(c, a));
        for (int k = 0; k < 3; k++) mesh->normals[tri[k]] = lu_v3_add(mesh->normals[tri[k]], n);
    }
    for (uint32_t i = 0; i < mesh->vertex_count; i++) {
        lu_vec3 n = mesh->normals[i];
        float len = lu_v3_len(n);
        /* Unreferenced or fully degenerate vertices still need a unit normal. */
        mesh->normals[i] = len > 0.0f && isfinite(len) ? lu_v3_scale(n, 1.0f / len) : lu_v3(0.0f, 1.0f, 0.0f);
    }
}

lu_aabb lu_mesh_bounds(const lu_mesh *mesh) {
    lu_aabb b = lu_aabb_empty();
    for (uint32_t i = 0; i < mesh->vertex_count; i++) lu_aabb_grow(&b, mesh->positions[i]);
    return b;
}

static void tri_d(const lu_mesh *mesh, uint32_t t, double p[3][3]) {
    const uint32_t *tri = mesh->indices + 3 * (size_t)t;
    for (int k = 0; k < 3; k++) {
        lu_vec3 v = mesh->positions[tri[k]];
        p[k][0] = v.x;
        p[k][1] = v.y;
        p[k][2] = v.z;
    }
}

double lu_mesh_area(const lu_mesh *mesh) {
    double sum = 0.0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        double p[3][3], e1[3], e2[3];
        tri_d(mesh, t, p);
        for (int k = 0; k < 3; k++) {
            e1[k] = p[1][k] - p[0][k];
            e2[k] = p[2][k] - p[0][k];
        }
        double cx = e1[1] * e2[2] - e1[2] * e2[1], cy = e1[2] * e2[0] - e1[0] * e2[2],
               cz = e1[0] * e2[1] - e1[1] * e2[0];
        sum += 0.5 * sqrt(cx * cx + cy * cy + cz * cz);
    }
    return sum;
}

double lu_mesh_volume(const lu_mesh *mesh) {
    /* Divergence theorem with F = x/3: each triangle adds the signed volume of
     * the tetrahedron it spans with the origin. */
    double sum = 0.0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        double p[3][3];
        tri_d(mesh, t, p);
        sum += p[0][0] * (p[1][1] * p[2][2] - p[1][2] * p[2][1]) - p[0][1] * (p[1][0] * p[2][2] - p[1][2] * p[2][0]) +
               p[0][2] * (p[1][0] * p[2][1] - p[1][1] * p[2][0]);
    }
    return sum / 6.0;
}

lu_result lu_mesh_append(lu_mesh *dst, const lu_mesh *src, lu_error *err) {
    uint32_t nv = src->vertex_count, nt = src->triangle_count, v0 = dst->vertex_count, t0 = dst->triangle_count;
    if ((uint64_t)v0 + nv > LU_MAX_VERTICES)
        return lu_fail(err, LU_ERR_LIMIT, "mesh append: %llu vertices exceeds the limit of %u",
                       (unsigned long long)v0 + nv, LU_MAX_VERTICES);
    if ((uint64_t)t0 + nt > LU_MAX_TRIANGLES)
        return lu_fail(err, LU_ERR_LIMIT, "mesh append: %llu triangles exceeds the limit of %u",
                       (unsigned long long)t0 + nt, LU_MAX_TRIANGLES);
    bool self = dst == src;
    size_t vbytes = ((size_t)v0 + nv + 1) * sizeof(lu_vec3);
    lu_vec3 *p = lu_realloc(dst->positions, vbytes);
    if (p) dst->positions = p;
    lu_vec3 *n = p ? lu_realloc(dst->normals, vbytes) : NULL;
    if (n) dst->normals = n;
    uint32_t *ix = n ? lu_realloc(dst->indices, ((size_t)t0 + nt + 1) * 3 * sizeof(uint32_t)) : NULL;
    if (ix) dst->indices = ix;
    if (!ix) return lu_fail(err, LU_ERR_NOMEM, "mesh append: out of memory");
    /* When appending a mesh to itself the source arrays moved with the realloc. */
    const lu_vec3 *sp = self ? dst->positions : src->positions;
    const lu_vec3 *sn = self ? dst->normals : src->normals;
    const uint32_t *si = self ? dst->indices : src->indices;
    memcpy(dst->positions + v0, sp, (size_t)nv * sizeof(lu_vec3));
    if (sn) memcpy(dst->normals + v0, sn, (size_t)nv * sizeof(lu_vec3));
    else
        for (uint32_t i = 0; i < nv; i++) dst->normals[v0 + i] = lu_v3(0.0f, 1.0f, 0.0f);
    for (size_t i = 0; i < 3 * (size_t)nt; i++) dst->indices[3 * (size_t)t0 + i] = si[i] + v0;
    dst->vertex_count = v0 + nv;
    dst->triangle_count = t0 + nt;
    return LU_OK;
}

lu_result lu_mesh_load(const char *path, lu_mesh *mesh, lu_error *err) {
    memset(mesh, 0, sizeof *mesh);
    if (lu_path_has_suffix(path, ".obj") || lu_path_has_suffix(path, ".obj.gz")) return lu_mesh_load_obj(path, mesh, err);
    if (lu_path_has_suffix(path, ".ply") || lu_path_has_suffix(path, ".gz")) return lu_mesh_load_ply(path, mesh, err);
    return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: unknown mesh format (expected .obj, .ply or .ply.gz)", path);
}

/* ---- number parsing ------------------------------------------------------ */

static bool word_ci(const char *p, const char *w, const char **end) {
    size_t i = 0;
    for (; w[i]; i++) {
        char c = p[i];
        if (c >= 'A' && c <= 'Z') c = (char)(c - 'A' + 'a');
        if (c != w[i]) return false;
    }
    *end = p + i;
    return true;
}

bool lu_parse_double(const char *p, const char **end, double *out) {
    static const double p10[23] = {1e0,  1e1,  1e2,  1e3,  1e4,  1e5,  1e6,  1e7,  1e8,  1e9,  1e10, 1e11,
                                   1e12, 1e13, 1e14, 1e15, 1e16, 1e17, 1e18, 1e19, 1e20, 1e21, 1e22};
    const char *s = p;
    bool neg = false;
    if (*s == '+' || *s == '-') neg = *s++ == '-';
    const char *w;
    if (word_ci(s, "nan", &w)) {
        *out = NAN;
        *end = w;
        return true;
    }
    if (word_ci(s, "inf", &w)) {
        const char *w2;
        if (word_ci(w, "inity", &w2)) w = w2;
        *out = neg ? -INFINITY : INFINITY;
        *end = w;
        return true;
    }
    uint64_t mant = 0;
    int digits = 0, exp10 = 0;
    bool any = false;
    for (; *s >= '0' && *s <= '9'; s++) {
        any = true;
        if (digits < 19) {
            mant = mant * 10 + (uint64_t)(*s - '0');
            if (mant) digits++;
        } else {
            exp10++;
        }
    }
    if (*s == '.') {
        s++;
        for (; *s >= '0' && *s <= '9'; s++) {
            any = true;
            if (digits < 19) {
                mant = mant * 10 + (uint64_t)(*s - '0');
                if (mant) digits++;
                exp10--;
            }
        }
    }
    if (!any) return false;
    if (*s == 'e' || *s == 'E') {
        const char *e = s + 1;
        bool eneg = false;
        if (*e == '+' || *e == '-') eneg = *e++ == '-';
        if (*e < '0' || *e > '9') return false;
        int ev = 0;
        for (; *e >= '0' && *e <= '9'; e++)
            if (ev < 100000) ev = ev * 10 + (*e - '0');
        exp10 += eneg ? -ev : ev;
        s = e;
    }
    double v = (double)mant;
    if (mant == 0) v = 0.0;
    else if (exp10 >= 0 && exp10 <= 22) v *= p10[exp10];
    else if (exp10 < 0 && exp10 >= -22) v /= p10[-exp10];
    else if (exp10 > 0) v *= pow(10.0, exp10);
    else v = (v / 1e22) * pow(10.0, exp10 + 22); /* two steps keep small values out of the subnormals longer */
    *out = neg ? -v : v;
    *end = s;
    return true;
}

bool lu_parse_int64(const char *p, const char **end, long long *out) {
    const char *s = p;
    bool neg = false;
    if (*s == '+' || *s == '-') neg = *s++ == '-';
    if (*s < '0' || *s > '9') return false;
    unsigned long long v = 0;
    for (; *s >= '0' && *s <= '9'; s++) {
        unsigned d = (unsigned)(*s - '0');
        if (v > (9223372036854775807ull - d) / 10) return false;
        v = v * 10 + d;
    }
    *out = neg ? -(long long)v : (long long)v;
    *end = s;
    return true;
}

/* ---- mesh builder -------------------------------------------------------- */

static lu_result grow(void **ptr, size_t *cap, size_t need, size_t elem, size_t max, const char *path, lu_error *err) {
    if (need <= *cap) return LU_OK;
    size_t nc = *cap ? *cap * 2 : 4096;
    if (nc < need) nc = need;
    if (nc > max) nc = max;
    void *q = lu_realloc(*ptr, nc * elem);
    if (!q) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory growing mesh arrays to %zu entries", path, nc);
    *ptr = q;
    *cap = nc;
    return LU_OK;
}

lu_result lu_mb_reserve_vertices(lu_mesh_builder *b, size_t n, bool with_normals, const char *path, lu_error *err) {
    if (n > LU_MAX_VERTICES) return lu_fail(err, LU_ERR_LIMIT, "%s: more than %u vertices", path, LU_MAX_VERTICES);
    void *p = b->positions;
    lu_result r = grow(&p, &b->vcap, n, sizeof(lu_vec3), LU_MAX_VERTICES, path, err);
    b->positions = p;
    if (r == LU_OK && with_normals) {
        p = b->normals;
        r = grow(&p, &b->ncap, n, sizeof(lu_vec3), LU_MAX_VERTICES, path, err);
        b->normals = p;
    }
    return r;
}

lu_result lu_mb_reserve_triangles(lu_mesh_builder *b, size_t n, const char *path, lu_error *err) {
    if (n > LU_MAX_TRIANGLES)
        return lu_fail(err, LU_ERR_LIMIT, "%s: more than %u triangles", path, LU_MAX_TRIANGLES);
    size_t cap = b->tcap;
    void *p = b->indices;
    lu_result r = grow(&p, &cap, n, 3 * sizeof(uint32_t), LU_MAX_TRIANGLES, path, err);
    b->indices = p;
    b->tcap = cap;
    return r;
}

void lu_mb_free(lu_mesh_builder *b) {
    lu_free(b->positions);
    lu_free(b->normals);
    lu_free(b->indices);
    memset(b, 0, sizeof *b);
}

lu_result lu_mb_finish(lu_mesh_builder *b, bool have_normals, lu_mesh *mesh, const char *path, lu_error *err) {
    memset(mesh, 0, sizeof *mesh);
    if (b->tcount == 0) {
        lu_mb_free(b);
        return lu_fail(err, LU_ERR_FORMAT, "%s: the mesh has no triangles", path);
    }
    size_t nv = b->vcount ? b->vcount : 1;
    lu_vec3 *p = lu_realloc(b->positions, nv * sizeof *p);
    if (p) b->positions = p;
    uint32_t *ix = lu_realloc(b->indices, b->tcount * 3 * sizeof *ix);
    if (ix) b->indices = ix;
    lu_vec3 *n;
    if (have_normals) {
        n = lu_realloc(b->normals, nv * sizeof *n);
        if (n) b->normals = n;
    } else {
        lu_free(b->normals);
        b->normals = n = lu_malloc(nv * sizeof *n);
    }
    if (!p || !ix || !n) {
        lu_mb_free(b);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
    }
    mesh->positions = b->positions;
    mesh->normals = n;
    mesh->indices = b->indices;
    mesh->vertex_count = (uint32_t)b->vcount;
    mesh->triangle_count = (uint32_t)b->tcount;
    memset(b, 0, sizeof *b);
    bool recompute = !have_normals;
    for (uint32_t i = 0; i < mesh->vertex_count && !recompute; i++) {
        float len = lu_v3_len(n[i]);
        if (!(len > 0.0f) || !isfinite(len)) recompute = true;
        else n[i] = lu_v3_scale(n[i], 1.0f / len);
    }
    if (recompute) lu_mesh_compute_normals(mesh);
    return LU_OK;
}
