/* Wavefront OBJ: v and f (v, v/vt, v//vn, v/vt/vn, negative = relative),
 * polygons as fans. File normals (vn) are per corner while lu_mesh keeps one
 * normal per vertex, so they are validated by index only and the normals are
 * recomputed (area-weighted). Texture coordinates, groups, smoothing groups,
 * materials and free-form statements are ignored. */
#include "mesh_internal.h"

#include <stdlib.h>
#include <string.h>

/* A positive index may name a vertex defined further down the file, so the
 * largest one seen is checked once the whole file is read. */
typedef struct {
    long long max;
    long line;
} forward_ref;

typedef struct {
    lu_stream s;
    lu_mesh_builder b;
    long long count[3]; /* v, vt, vn seen so far */
    forward_ref fwd[3];
} obj_state;

static const char *const k_kind[3] = {"vertex", "texture coordinate", "normal"};

static lu_result resolve(obj_state *o, int kind, long long idx, uint32_t *out, lu_error *err) {
    const char *path = o->s.path;
    long line = o->s.line;
    if (idx == 0)
        return lu_fail(err, LU_ERR_RANGE, "%s:%ld: %s index 0 (OBJ indices start at 1)", path, line, k_kind[kind]);
    long long r;
    if (idx < 0) {
        r = o->count[kind] + idx;
        if (r < 0)
            return lu_fail(err, LU_ERR_RANGE, "%s:%ld: relative %s index %lld reaches before the first %s (%lld defined)",
                           path, line, k_kind[kind], idx, k_kind[kind], o->count[kind]);
    } else {
        r = idx - 1;
        if (r >= (long long)LU_MAX_VERTICES)
            return lu_fail(err, LU_ERR_RANGE, "%s:%ld: %s index %lld out of range", path, line, k_kind[kind], idx);
        if (idx > o->count[kind] && idx > o->fwd[kind].max) {
            o->fwd[kind].max = idx;
            o->fwd[kind].line = line;
        }
    }
    *out = (uint32_t)r;
    return LU_OK;
}

static lu_result parse_vertex(obj_state *o, const char *p, lu_error *err) {
    const char *path = o->s.path;
    long line = o->s.line;
    double v[3];
    int n = 0;
    for (;;) {
        p = lu_skip_blank(p);
        if (*p == '\0' || *p == '#') break;
        double x;
        const char *e;
        if (!lu_parse_double(p, &e, &x) || !(*e == '\0' || lu_is_blank(*e) || *e == '#')) {
            int len = 0;
            while (p[len] && !lu_is_blank(p[len]) && len < 40) len++;
            return lu_fail(err, LU_ERR_FORMAT, "%s:%ld: bad number \"%.*s\" in vertex", path, line, len, p);
        }
        /* x y z are stored; w or per-vertex colours may follow and are ignored. */
        if (n < 3) {
            if (!isfinite((float)x))
                return lu_fail(err, LU_ERR_NONFINITE, "%s:%ld: non-finite vertex coordinate", path, line);
            v[n] = x;
        }
        n++;
        p = e;
    }
    if (n < 3) return lu_fail(err, LU_ERR_FORMAT, "%s:%ld: vertex has %d coordinates, expected 3", path, line, n);
    if (o->b.vcount >= LU_MAX_VERTICES)
        return lu_fail(err, LU_ERR_LIMIT, "%s:%ld: more than %u vertices", path, line, LU_MAX_VERTICES);
    lu_result r = lu_mb_reserve_vertices(&o->b, o->b.vcount + 1, false, path, err);
    if (r != LU_OK) return r;
    o->b.positions[o->b.vcount++] = lu_v3((float)v[0], (float)v[1], (float)v[2]);
    o->count[0]++;
    return LU_OK;
}

static lu_result parse_face(obj_state *o, const char *p, lu_error *err) {
    const char *path = o->s.path;
    long line = o->s.line;
    uint32_t first = 0, prev = 0;
    int corners = 0;
    for (;;) {
        p = lu_skip_blank(p);
        if (*p == '\0' || *p == '#') break;
        const char *tok = p;
        long long idx[3];
        bool has[3] = {false, false, false};
        const char *e;
        bool ok = lu_parse_int64(p, &e, &idx[0]);
        has[0] = ok;
        p = e;
        for (int k = 1; ok && k < 3 && *p == '/'; k++) {
            p++;
            if (*p == '/' || *p == '\0' || lu_is_blank(*p)) continue; /* empty slot: v//vn */
            ok = lu_parse_int64(p, &e, &idx[k]);
            has[k] = ok;
            p = e;
        }
        if (!ok || !(*p == '\0' || lu_is_blank(*p) || *p == '#')) {
            int len = 0;
            while (tok[len] && !lu_is_blank(tok[len]) && len < 40) len++;
            return lu_fail(err, LU_ERR_FORMAT, "%s:%ld: bad face vertex \"%.*s\"", path, line, len, tok);
        }
        uint32_t v = 0, unused;
        lu_result r = resolve(o, 0, idx[0], &v, err);
        for (int k = 1; r == LU_OK && k < 3; k++)
            if (has[k]) r = resolve(o, k, idx[k], &unused, err);
        if (r != LU_OK) return r;
        if (corners == 0) first = v;
        if (corners >= 2) {
            if (o->b.tcount >= LU_MAX_TRIANGLES)
                return lu_fail(err, LU_ERR_LIMIT, "%s:%ld: more than %u triangles", path, line, LU_MAX_TRIANGLES);
            r = lu_mb_triangle(&o->b, first, prev, v, path, err);
            if (r != LU_OK) return r;
        }
        prev = v;
        corners++;
    }
    if (corners < 3)
        return lu_fail(err, LU_ERR_FORMAT, "%s:%ld: face with %d vertices (at least 3 needed)", path, line, corners);
    return LU_OK;
}

static bool keyword_is(const char *p, size_t len, const char *kw) {
    return strlen(kw) == len && memcmp(p, kw, len) == 0;
}

lu_result lu_mesh_load_obj(const char *path, lu_mesh *mesh, lu_error *err) {
    memset(mesh, 0, sizeof *mesh);
    obj_state *o = lu_calloc(1, sizeof *o);
    if (!o) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
    lu_result r = lu_stream_open(&o->s, path, err);
    while (r == LU_OK) {
        char *line;
        r = lu_stream_line(&o->s, &line, err);
        if (r != LU_OK || !line) break;
        const char *p = lu_skip_blank(line);
        if (*p == '\0' || *p == '#') continue;
        size_t kl = 0;
        while (p[kl] && !lu_is_blank(p[kl])) kl++;
        const char *rest = p + kl;
        if (keyword_is(p, kl, "v")) r = parse_vertex(o, rest, err);
        else if (keyword_is(p, kl, "f")) r = parse_face(o, rest, err);
        else if (keyword_is(p, kl, "vt")) o->count[1]++;
        else if (keyword_is(p, kl, "vn")) o->count[2]++;
        else {
            /* Other statements (o, g, s, usemtl, mtllib, l, p, vp, free-form
             * geometry) are ignored, but a line that does not start with a
             * keyword means this is not an OBJ file. */
            bool word = (p[0] >= 'a' && p[0] <= 'z') || (p[0] >= 'A' && p[0] <= 'Z') || p[0] == '_';
            if (!word) {
                char shown[41];
                size_t n = kl < 40 ? kl : 40;
                for (size_t i = 0; i < n; i++) shown[i] = p[i] >= 0x20 && p[i] < 0x7f ? p[i] : '?';
                shown[n] = '\0';
                r = lu_fail(err, LU_ERR_FORMAT, "%s:%ld: unexpected \"%s\" at the start of a line (not an OBJ file?)",
                            path, o->s.line, shown);
            }
        }
    }
    for (int k = 0; r == LU_OK && k < 3; k++)
        if (o->fwd[k].max > o->count[k])
            r = lu_fail(err, LU_ERR_RANGE, "%s:%ld: %s index %lld out of range (the file defines %lld)", path,
                        o->fwd[k].line, k_kind[k], o->fwd[k].max, o->count[k]);
    lu_stream_close(&o->s);
    if (r == LU_OK) r = lu_mb_finish(&o->b, false, mesh, path, err);
    lu_mb_free(&o->b);
    lu_free(o);
    return r;
}
