/* ddod's weighted Poisson-disk sampling (ddod_poisson.h). */
#include "methods/ddod/ddod_poisson.h"
#include "core/rng.h"

#include <stdlib.h>
#include <string.h>

void lu_ddod_darts_free(lu_ddod_darts *d) {
    lu_free(d->p);
    lu_free(d->r);
    lu_free(d->valid);
    memset(d, 0, sizeof *d);
}

typedef struct dart_key {
    double u;
    int i;
} dart_key;

static int cmp_dart_key(const void *a, const void *b) {
    const dart_key *x = a, *y = b;
    if (x->u != y->u) return x->u < y->u ? -1 : 1;
    return (x->i > y->i) - (x->i < y->i);
}

/* Draws `candidates` darts. Each dart takes four numbers from the stream
 * (the CDF position, then the offset in the voxel); the voxels are found by
 * one walk of the CDF over the sorted positions instead of a binary search
 * per dart (the CDF is larger than the caches). */
lu_result lu_ddod_darts_draw(const lu_ddod_field *f, int candidates, uint32_t seed, lu_ddod_darts *d, lu_error *err) {
    memset(d, 0, sizeof *d);
    size_t nv = (size_t)f->n[0] * f->n[1] * f->n[2];
    double *cdf = lu_malloc((nv + 1) * sizeof *cdf);
    if (!cdf) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for sampling");
    cdf[0] = 0.0;
    for (size_t v = 0; v < nv; v++) {
        float r = f->radius[v];
        cdf[v + 1] = cdf[v] + (r > 0.0f ? 1.0 / ((double)r * r * r) : 0.0);
        d->rmax = r > d->rmax ? r : d->rmax;
    }
    if (!(cdf[nv] > 0.0) || candidates <= 0) {
        lu_free(cdf);
        return LU_OK;
    }
    dart_key *key = lu_malloc((size_t)candidates * sizeof *key);
    float *off = lu_malloc((size_t)candidates * 3 * sizeof *off);
    d->p = lu_malloc((size_t)candidates * 3 * sizeof *d->p);
    d->r = lu_malloc((size_t)candidates * sizeof *d->r);
    d->valid = lu_calloc((size_t)candidates, sizeof *d->valid);
    if (!key || !off || !d->p || !d->r || !d->valid) {
        lu_free(cdf), lu_free(key), lu_free(off);
        lu_ddod_darts_free(d);
        return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for %d sampling candidates", candidates);
    }
    uint64_t rs = 0x5eedull ^ ((uint64_t)seed << 32);
    for (int i = 0; i < candidates; i++) {
        key[i].u = lu_rng_unit(&rs) * cdf[nv];
        key[i].i = i;
        for (int a = 0; a < 3; a++) off[3 * i + a] = (float)lu_rng_unit(&rs);
    }
    qsort(key, (size_t)candidates, sizeof *key, cmp_dart_key);
    size_t v = 0; /* first v with cdf[v + 1] > u, for increasing u */
    int n = 0;
    for (int k = 0; k < candidates; k++) {
        while (v + 1 < nv && !(cdf[v + 1] > key[k].u)) v++;
        int i = key[k].i;
        int vx = (int)(v % f->n[0]), vy = (int)((v / f->n[0]) % f->n[1]), vz = (int)(v / ((size_t)f->n[0] * f->n[1]));
        d->p[3 * i] = f->lo.x + ((float)vx + off[3 * i]) * f->h;
        d->p[3 * i + 1] = f->lo.y + ((float)vy + off[3 * i + 1]) * f->h;
        d->p[3 * i + 2] = f->lo.z + ((float)vz + off[3 * i + 2]) * f->h;
        d->r[i] = f->radius[v];
        n++;
    }
    d->n = n;
    lu_free(cdf);
    lu_free(key);
    lu_free(off);
    return LU_OK;
}

/* Dart throwing at radius scale `scale`: a dart is kept when no kept point q
 * has |p - q| < max(r_p, r_q) and `valid` accepts it. */
lu_result lu_ddod_darts_throw(const lu_ddod_field *f, lu_ddod_darts *d, float scale, const lu_ddod_valid *valid,
                              float **points_out, float **radii_out, int *count_out, lu_error *err) {
    *points_out = NULL;
    *radii_out = NULL;
    *count_out = 0;
    if (d->n == 0) return LU_OK;
    float rmax = d->rmax * scale;
    /* Spatial hash grid with cells of the largest radius: every conflict of
     * a point lies in its 27 neighbouring cells. */
    lu_vec3 ext = lu_v3((float)f->n[0] * f->h, (float)f->n[1] * f->h, (float)f->n[2] * f->h);
    int cn[3];
    for (int a = 0; a < 3; a++) {
        cn[a] = (int)(lu_v3_get(ext, a) / rmax) + 1;
        if (cn[a] > 1024) cn[a] = 1024;
    }
    float cell[3] = {ext.x / (float)cn[0], ext.y / (float)cn[1], ext.z / (float)cn[2]};
    size_t ncell = (size_t)cn[0] * cn[1] * cn[2];
    int *head = lu_malloc(ncell * sizeof *head);
    int cap = 4096;
    float *pts = lu_malloc((size_t)cap * 3 * sizeof *pts);
    float *rad = lu_malloc((size_t)cap * sizeof *rad);
    int *next = lu_malloc((size_t)cap * sizeof *next);
    if (!head || !pts || !rad || !next) {
        lu_free(head), lu_free(pts), lu_free(rad), lu_free(next);
        return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for sampling");
    }
    for (size_t i = 0; i < ncell; i++) head[i] = -1;
    /* the dart's own cell first: most conflicts are there */
    int order[27][3], no = 0;
    for (int dz = -1; dz <= 1; dz++)
        for (int dy = -1; dy <= 1; dy++)
            for (int dx = -1; dx <= 1; dx++) {
                int k = dx == 0 && dy == 0 && dz == 0 ? 0 : ++no;
                order[k][0] = dx, order[k][1] = dy, order[k][2] = dz;
            }
    int count = 0;
    for (int it = 0; it < d->n; it++) {
        if (!(d->r[it] > 0.0f)) continue;
        lu_vec3 p = lu_v3(d->p[3 * it], d->p[3 * it + 1], d->p[3 * it + 2]);
        float rp = scale * d->r[it];
        int c[3];
        float pv[3] = {p.x - f->lo.x, p.y - f->lo.y, p.z - f->lo.z};
        for (int a = 0; a < 3; a++) {
            c[a] = (int)(pv[a] / cell[a]);
            c[a] = c[a] < 0 ? 0 : (c[a] >= cn[a] ? cn[a] - 1 : c[a]);
        }
        bool ok = true;
        for (int k = 0; k < 27 && ok; k++) {
            int x = c[0] + order[k][0], y = c[1] + order[k][1], z = c[2] + order[k][2];
            if (x < 0 || y < 0 || z < 0 || x >= cn[0] || y >= cn[1] || z >= cn[2]) continue;
            for (int q = head[((size_t)z * cn[1] + y) * cn[0] + x]; q >= 0; q = next[q]) {
                float ddx = pts[3 * q] - p.x, ddy = pts[3 * q + 1] - p.y, ddz = pts[3 * q + 2] - p.z;
                float m = rad[q] > rp ? rad[q] : rp;
                if (ddx * ddx + ddy * ddy + ddz * ddz < m * m) {
                    ok = false;
                    break;
                }
            }
        }
        if (!ok) continue;
        if (valid) {
            if (d->valid[it] == 0) d->valid[it] = valid->fn(valid->user, p) ? 1 : -1;
            if (d->valid[it] < 0) continue;
        }
        if (count == cap) {
            cap *= 2;
            float *np = lu_realloc(pts, (size_t)cap * 3 * sizeof *np);
            if (np) pts = np;
            float *nr = np ? lu_realloc(rad, (size_t)cap * sizeof *nr) : NULL;
            if (nr) rad = nr;
            int *nn = nr ? lu_realloc(next, (size_t)cap * sizeof *nn) : NULL;
            if (!nn) {
                lu_free(head), lu_free(pts), lu_free(rad), lu_free(next);
                return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for %d samples", cap);
            }
            next = nn;
        }
        pts[3 * count] = p.x;
        pts[3 * count + 1] = p.y;
        pts[3 * count + 2] = p.z;
        rad[count] = rp;
        size_t ci = ((size_t)c[2] * cn[1] + c[1]) * cn[0] + c[0];
        next[count] = head[ci];
        head[ci] = count;
        count++;
    }
    lu_free(head);
    lu_free(next);
    *points_out = pts;
    *radii_out = rad;
    *count_out = count;
    return LU_OK;
}

lu_result lu_ddod_poisson(const lu_ddod_field *f, float scale, int candidates, uint32_t seed, float **points,
                          float **radii, int *count, lu_error *err) {
    *points = NULL;
    *radii = NULL;
    *count = 0;
    lu_ddod_darts d;
    lu_result r = lu_ddod_darts_draw(f, candidates, seed, &d, err);
    if (r == LU_OK) r = lu_ddod_darts_throw(f, &d, scale, NULL, points, radii, count, err);
    lu_ddod_darts_free(&d);
    return r;
}
