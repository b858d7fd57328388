/* Surface sampling and repulsion relaxation (see bssrdf_sampling.h). */
#include "methods/bssrdf/bssrdf_sampling.h"

#include <stdlib.h>
#include <string.h>

#include "core/rng.h"
#include "methods/common/mesh_adjacency.h"

void lu_surface_points_destroy(lu_surface_points *p) {
    if (!p) return;
    lu_free(p->position);
    lu_free(p->normal);
    lu_free(p->triangle);
    memset(p, 0, sizeof *p);
}


static void tri_verts(const lu_mesh *m, uint32_t t, lu_vec3 *a, lu_vec3 *b, lu_vec3 *c) {
    const uint32_t *ix = &m->indices[3u * t];
    *a = m->positions[ix[0]];
    *b = m->positions[ix[1]];
    *c = m->positions[ix[2]];
}

/* Barycentric coordinates of p's projection onto triangle (a, b, c). */
static void barycentric(lu_vec3 a, lu_vec3 b, lu_vec3 c, lu_vec3 p, double l[3]) {
    lu_vec3 e0 = lu_v3_sub(b, a), e1 = lu_v3_sub(c, a), d = lu_v3_sub(p, a);
    double d00 = lu_v3_dot(e0, e0), d01 = lu_v3_dot(e0, e1), d11 = lu_v3_dot(e1, e1);
    double d20 = lu_v3_dot(d, e0), d21 = lu_v3_dot(d, e1);
    double den = d00 * d11 - d01 * d01;
    if (!(fabs(den) > 0.0)) {
        l[0] = 1.0;
        l[1] = l[2] = 0.0;
        return;
    }
    double v = (d11 * d20 - d01 * d21) / den, w = (d00 * d21 - d01 * d20) / den;
    l[0] = 1.0 - v - w;
    l[1] = v;
    l[2] = w;
}

static lu_vec3 interp_normal(const lu_mesh *m, uint32_t t, const double l[3]) {
    const uint32_t *ix = &m->indices[3u * t];
    lu_vec3 n = lu_v3_add(lu_v3_add(lu_v3_scale(m->normals[ix[0]], (float)l[0]), lu_v3_scale(m->normals[ix[1]], (float)l[1])),
                          lu_v3_scale(m->normals[ix[2]], (float)l[2]));
    return lu_v3_norm(n);
}

static lu_vec3 face_normal(const lu_mesh *m, uint32_t t) {
    lu_vec3 a, b, c;
    tri_verts(m, t, &a, &b, &c);
    return lu_v3_norm(lu_v3_cross(lu_v3_sub(b, a), lu_v3_sub(c, a)));
}

static lu_result points_alloc(lu_surface_points *p, int count, lu_error *err) {
    memset(p, 0, sizeof *p);
    p->position = lu_malloc((size_t)(count ? count : 1) * sizeof *p->position);
    p->normal = lu_malloc((size_t)(count ? count : 1) * sizeof *p->normal);
    p->triangle = lu_malloc((size_t)(count ? count : 1) * sizeof *p->triangle);
    if (!p->position || !p->normal || !p->triangle) {
        lu_surface_points_destroy(p);
        return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for %d surface points", count);
    }
    p->count = count;
    return LU_OK;
}

lu_result lu_surface_sample(const lu_mesh *mesh, int count, uint64_t seed, lu_surface_points *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    if (count < 1 || mesh->triangle_count == 0) return lu_fail(err, LU_ERR_RANGE, "bssrdf: nothing to sample");
    double *cdf = lu_malloc(mesh->triangle_count * sizeof *cdf);
    if (!cdf) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    double acc = 0.0;
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        lu_vec3 a, b, c;
        tri_verts(mesh, t, &a, &b, &c);
        acc += 0.5 * lu_v3_len(lu_v3_cross(lu_v3_sub(b, a), lu_v3_sub(c, a)));
        cdf[t] = acc;
    }
    if (!(acc > 0.0)) {
        lu_free(cdf);
        return lu_fail(err, LU_ERR_RANGE, "bssrdf: mesh has no area to sample");
    }
    lu_result r = points_alloc(out, count, err);
    if (r != LU_OK) {
        lu_free(cdf);
        return r;
    }
    uint64_t s = seed * 0x2545F4914F6CDD1Dull + 7;
    for (int i = 0; i < count; i++) {
        double x = lu_rng_unit(&s) * acc;
        uint32_t lo = 0, hi = mesh->triangle_count - 1;
        while (lo < hi) {
            uint32_t mid = (lo + hi) / 2;
            if (cdf[mid] > x) hi = mid;
            else lo = mid + 1;
        }
        double x1 = lu_rng_unit(&s), x2 = lu_rng_unit(&s), sq = sqrt(x1);
        double l[3] = {1.0 - sq, (1.0 - x2) * sq, x2 * sq};
        lu_vec3 a, b, c;
        tri_verts(mesh, lo, &a, &b, &c);
        out->position[i] = lu_v3_add(lu_v3_add(lu_v3_scale(a, (float)l[0]), lu_v3_scale(b, (float)l[1])),
                                     lu_v3_scale(c, (float)l[2]));
        out->normal[i] = interp_normal(mesh, lo, l);
        out->triangle[i] = lo;
    }
    lu_free(cdf);
    return LU_OK;
}

/* Moves a point from p on triangle *tri along the in-plane vector v over the
 * surface: where it leaves the triangle, the rest of v is unfolded about the
 * crossed edge into the next triangle's plane (thesis Fig. 5.20); a border
 * edge stops it. */
static lu_vec3 walk(const lu_mesh *m, const uint32_t *nb, uint32_t *tri, lu_vec3 p, lu_vec3 v, double bary[3]) {
    uint32_t t = *tri;
    uint32_t came_from = UINT32_MAX;
    for (int step = 0; step < 64; step++) {
        lu_vec3 a, b, c;
        tri_verts(m, t, &a, &b, &c);
        lu_vec3 corners[3] = {a, b, c};
        double lp[3], lq[3];
        barycentric(a, b, c, p, lp);
        lu_vec3 q = lu_v3_add(p, v);
        barycentric(a, b, c, q, lq);
        if (lq[0] >= 0.0 && lq[1] >= 0.0 && lq[2] >= 0.0) {
            memcpy(bary, lq, sizeof lq);
            *tri = t;
            return lu_v3_add(lu_v3_add(lu_v3_scale(a, (float)lq[0]), lu_v3_scale(b, (float)lq[1])),
                             lu_v3_scale(c, (float)lq[2]));
        }
        /* The first edge crossed: corner i's coordinate reaches 0 (edge i+1, i+2). */
        double tmin = 2.0;
        int ci = -1;
        for (int i = 0; i < 3; i++) {
            if (lq[i] >= 0.0) continue;
            double tt = lp[i] > 0.0 ? lp[i] / (lp[i] - lq[i]) : 0.0;
            int edge = (i + 1) % 3;
            if (nb[3u * t + edge] == came_from && came_from != UINT32_MAX && tt <= 1e-6) continue;
            if (tt < tmin) {
                tmin = tt;
                ci = i;
            }
        }
        if (ci < 0) { /* only the edge we came through: stay on it */
            for (int i = 0; i < 3; i++) lq[i] = fmax(lq[i], 0.0);
            double sum = lq[0] + lq[1] + lq[2];
            for (int i = 0; i < 3; i++) bary[i] = lq[i] / sum;
            *tri = t;
            return lu_v3_add(lu_v3_add(lu_v3_scale(a, (float)bary[0]), lu_v3_scale(b, (float)bary[1])),
                             lu_v3_scale(c, (float)bary[2]));
        }
        lu_vec3 x = lu_v3_add(p, lu_v3_scale(v, (float)tmin));
        lu_vec3 rest = lu_v3_scale(v, (float)(1.0 - tmin));
        int edge = (ci + 1) % 3;
        uint32_t next = nb[3u * t + edge];
        if (next == UINT32_MAX) { /* a border: stop where it was crossed */
            double lx[3];
            barycentric(a, b, c, x, lx);
            for (int i = 0; i < 3; i++) bary[i] = fmax(lx[i], 0.0);
            double sum = bary[0] + bary[1] + bary[2];
            for (int i = 0; i < 3; i++) bary[i] /= sum;
            *tri = t;
            return x;
        }
        lu_vec3 e0 = corners[edge], e1 = corners[(edge + 1) % 3];
        lu_vec3 ed = lu_v3_norm(lu_v3_sub(e1, e0));
        float along = lu_v3_dot(rest, ed);
        float across = lu_v3_len(lu_v3_sub(rest, lu_v3_scale(ed, along)));
        /* The next triangle's in-plane direction away from the shared edge. */
        lu_vec3 na, nbv, nc;
        tri_verts(m, next, &na, &nbv, &nc);
        lu_vec3 nn = lu_v3_norm(lu_v3_cross(lu_v3_sub(nbv, na), lu_v3_sub(nc, na)));
        lu_vec3 into = lu_v3_norm(lu_v3_cross(nn, ed));
        lu_vec3 centroid = lu_v3_scale(lu_v3_add(lu_v3_add(na, nbv), nc), 1.0f / 3.0f);
        if (lu_v3_dot(into, lu_v3_sub(centroid, e0)) < 0.0f) into = lu_v3_neg(into);
        v = lu_v3_add(lu_v3_scale(ed, along), lu_v3_scale(into, across));
        p = x;
        came_from = t;
        t = next;
    }
    double l[3];
    lu_vec3 a, b, c;
    tri_verts(m, t, &a, &b, &c);
    barycentric(a, b, c, p, l);
    for (int i = 0; i < 3; i++) bary[i] = fmax(l[i], 0.0);
    double sum = bary[0] + bary[1] + bary[2];
    for (int i = 0; i < 3; i++) bary[i] /= sum;
    *tri = t;
    return lu_v3_add(lu_v3_add(lu_v3_scale(a, (float)bary[0]), lu_v3_scale(b, (float)bary[1])), lu_v3_scale(c, (float)bary[2]));
}

/* ---- spatial grid ------------------------------------------------------------------ */

typedef struct pgrid {
    lu_vec3 lo;
    double cell;
    int nx, ny, nz;
    int *start;       /* nx*ny*nz + 1 */
    int *items;       /* point indices sorted by cell */
} pgrid;

static void pgrid_free(pgrid *g) {
    lu_free(g->start);
    lu_free(g->items);
    memset(g, 0, sizeof *g);
}

static int pgrid_cell(const pgrid *g, lu_vec3 p, int *ix, int *iy, int *iz) {
    *ix = (int)((p.x - g->lo.x) / g->cell);
    *iy = (int)((p.y - g->lo.y) / g->cell);
    *iz = (int)((p.z - g->lo.z) / g->cell);
    *ix = *ix < 0 ? 0 : (*ix >= g->nx ? g->nx - 1 : *ix);
    *iy = *iy < 0 ? 0 : (*iy >= g->ny ? g->ny - 1 : *iy);
    *iz = *iz < 0 ? 0 : (*iz >= g->nz ? g->nz - 1 : *iz);
    return (*iz * g->ny + *iy) * g->nx + *ix;
}

static lu_result pgrid_build(pgrid *g, const lu_surface_points *pts, double cell, lu_error *err) {
    memset(g, 0, sizeof *g);
    lu_aabb b = lu_aabb_empty();
    for (int i = 0; i < pts->count; i++) lu_aabb_grow(&b, pts->position[i]);
    lu_vec3 ext = lu_v3_sub(b.hi, b.lo);
    /* At most 128 cells a side; larger cells only cost extra distance tests. */
    double big = fmax(ext.x, fmax(ext.y, ext.z));
    g->cell = fmax(cell, big / 128.0);
    if (!(g->cell > 0.0)) g->cell = 1.0;
    g->lo = b.lo;
    g->nx = (int)(ext.x / g->cell) + 1;
    g->ny = (int)(ext.y / g->cell) + 1;
    g->nz = (int)(ext.z / g->cell) + 1;
    size_t ncell = (size_t)g->nx * g->ny * g->nz;
    g->start = lu_calloc(ncell + 1, sizeof *g->start);
    g->items = lu_malloc((size_t)(pts->count ? pts->count : 1) * sizeof *g->items);
    int *cellof = lu_malloc((size_t)(pts->count ? pts->count : 1) * sizeof *cellof);
    if (!g->start || !g->items || !cellof) {
        lu_free(cellof);
        pgrid_free(g);
        return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the point grid");
    }
    for (int i = 0; i < pts->count; i++) {
        int x, y, z;
        cellof[i] = pgrid_cell(g, pts->position[i], &x, &y, &z);
        g->start[cellof[i] + 1]++;
    }
    for (size_t c = 0; c < ncell; c++) g->start[c + 1] += g->start[c];
    int *fill = lu_malloc(ncell * sizeof *fill);
    if (!fill) {
        lu_free(cellof);
        pgrid_free(g);
        return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the point grid");
    }
    memcpy(fill, g->start, ncell * sizeof *fill);
    for (int i = 0; i < pts->count; i++) g->items[fill[cellof[i]]++] = i;
    lu_free(fill);
    lu_free(cellof);
    return LU_OK;
}

/* ---- relaxation -------------------------------------------------------------------- */

typedef struct relax_job {
    const lu_mesh *mesh;
    const uint32_t *nb;
    lu_surface_points *pts;
    const pgrid *grid;
    double radius, step;
    lu_vec3 *force;
    double *moved2;   /* per point squared move */
} relax_job;

static void forces(void *ctx, int64_t begin, int64_t end, int thread) {
    relax_job *j = ctx;
    const pgrid *g = j->grid;
    int reach = (int)ceil(j->radius / g->cell);
    double r2 = j->radius * j->radius;
    for (int64_t i = begin; i < end; i++) {
        lu_vec3 p = j->pts->position[i];
        lu_vec3 n = face_normal(j->mesh, j->pts->triangle[i]);
        int cx, cy, cz;
        pgrid_cell(g, p, &cx, &cy, &cz);
        lu_vec3 f = lu_v3s(0.0f);
        for (int z = cz - reach; z <= cz + reach; z++) {
            if (z < 0 || z >= g->nz) continue;
            for (int y = cy - reach; y <= cy + reach; y++) {
                if (y < 0 || y >= g->ny) continue;
                for (int x = cx - reach; x <= cx + reach; x++) {
                    if (x < 0 || x >= g->nx) continue;
                    int c = (z * g->ny + y) * g->nx + x;
                    for (int k = g->start[c]; k < g->start[c + 1]; k++) {
                        int o = g->items[k];
                        if (o == i) continue;
                        lu_vec3 d = lu_v3_sub(p, j->pts->position[o]);
                        double dd = lu_v3_dot(d, d);
                        if (dd >= r2) continue;
                        /* Into the pivot's plane (the thesis rotates the neighbour
                         * about the shared edge; for the small angles between nearby
                         * faces the projected direction is the same). */
                        lu_vec3 t = lu_v3_sub(d, lu_v3_scale(n, lu_v3_dot(d, n)));
                        float tl = lu_v3_len(t);
                        if (tl <= 1e-12f * (float)j->radius) continue;
                        f = lu_v3_madd(f, t, (float)((j->radius - sqrt(dd)) / tl));
                    }
                }
            }
        }
        j->force[i] = lu_v3_scale(f, (float)j->step);
    }
}

static void moves(void *ctx, int64_t begin, int64_t end, int thread) {
    relax_job *j = ctx;
    for (int64_t i = begin; i < end; i++) {
        lu_vec3 f = j->force[i];
        j->moved2[i] = lu_v3_dot(f, f);
        if (j->moved2[i] <= 0.0) continue;
        double bary[3];
        uint32_t t = j->pts->triangle[i];
        lu_vec3 q = walk(j->mesh, j->nb, &t, j->pts->position[i], f, bary);
        j->pts->position[i] = q;
        j->pts->triangle[i] = t;
        j->pts->normal[i] = interp_normal(j->mesh, t, bary);
    }
}

typedef struct nn_job {
    const lu_surface_points *pts;
    const pgrid *grid;
    double search;
    double *nn;
} nn_job;

static void nn_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    nn_job *j = ctx;
    const pgrid *g = j->grid;
    int reach = (int)ceil(j->search / g->cell);
    for (int64_t i = begin; i < end; i++) {
        lu_vec3 p = j->pts->position[i];
        int cx, cy, cz;
        pgrid_cell(g, p, &cx, &cy, &cz);
        double best = j->search * j->search;
        for (int z = cz - reach; z <= cz + reach; z++) {
            if (z < 0 || z >= g->nz) continue;
            for (int y = cy - reach; y <= cy + reach; y++) {
                if (y < 0 || y >= g->ny) continue;
                for (int x = cx - reach; x <= cx + reach; x++) {
                    if (x < 0 || x >= g->nx) continue;
                    int c = (z * g->ny + y) * g->nx + x;
                    for (int k = g->start[c]; k < g->start[c + 1]; k++) {
                        if (g->items[k] == i) continue;
                        lu_vec3 d = lu_v3_sub(p, j->pts->position[g->items[k]]);
                        best = fmin(best, (double)lu_v3_dot(d, d));
                    }
                }
            }
        }
        j->nn[i] = sqrt(best);
    }
}

void lu_surface_nn_stats(const lu_surface_points *pts, double search, double *mean, double *cv) {
    *mean = *cv = 0.0;
    if (pts->count < 2) return;
    pgrid g;
    double *nn = lu_malloc((size_t)pts->count * sizeof *nn);
    if (!nn || pgrid_build(&g, pts, search, NULL) != LU_OK) {
        lu_free(nn);
        return;
    }
    nn_job j = {pts, &g, search, nn};
    lu_parallel_for(pts->count, 256, nn_rows, &j, NULL);
    double s = 0.0, s2 = 0.0;
    for (int i = 0; i < pts->count; i++) {
        s += nn[i];
        s2 += nn[i] * nn[i];
    }
    *mean = s / pts->count;
    *cv = sqrt(fmax(0.0, s2 / pts->count - *mean * *mean)) / *mean;
    lu_free(nn);
    pgrid_free(&g);
}

lu_result lu_surface_relax(const lu_mesh *mesh, lu_surface_points *pts, double radius, double step, int max_iters,
                           double tol, lu_relax_stats *stats, lu_error *err) {
    memset(stats, 0, sizeof *stats);
    if (!(radius > 0.0) || !(step >= 0.0)) return lu_fail(err, LU_ERR_RANGE, "bssrdf: relaxation radius/step");
    double t0 = lu_time_seconds();
    lu_surface_nn_stats(pts, 2.0 * radius, &stats->nn_mean_before, &stats->nn_cv_before);
    uint32_t *nb = NULL;
    lu_result r = lu_mesh_edge_neighbours(mesh, &nb, err);
    if (r != LU_OK) return r;
    lu_vec3 *force = lu_malloc((size_t)pts->count * sizeof *force);
    double *moved2 = lu_malloc((size_t)pts->count * sizeof *moved2);
    if (!force || !moved2) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    /* "Until uniform" (thesis listing 5.11): the nearest-neighbour spread has
     * stopped improving (by less than tol, relative, over the last 5
     * iterations) and the points have settled (RMS move under 1 % of the
     * radius; a step too large keeps them jumping back and forth). */
    double cv_hist[5];
    for (int i = 0; i < 5; i++) cv_hist[i] = stats->nn_cv_before;
    for (int it = 0; it < max_iters && r == LU_OK; it++) {
        pgrid g;
        r = pgrid_build(&g, pts, radius, err);
        if (r != LU_OK) break;
        relax_job j = {mesh, nb, pts, &g, radius, step, force, moved2};
        lu_parallel_for(pts->count, 256, forces, &j, NULL);
        lu_parallel_for(pts->count, 256, moves, &j, NULL);
        pgrid_free(&g);
        double sum = 0.0;
        for (int i = 0; i < pts->count; i++) sum += moved2[i];
        stats->iterations = it + 1;
        stats->last_rms_move = sqrt(sum / pts->count) / radius;
        if (!isfinite(stats->last_rms_move)) break;
        double mean, cv;
        lu_surface_nn_stats(pts, 2.0 * radius, &mean, &cv);
        double gain = (cv_hist[it % 5] - cv) / fmax(cv_hist[it % 5], 1e-12);
        cv_hist[it % 5] = cv;
        if (it >= 4 && gain < tol && stats->last_rms_move < 0.01) {
            stats->converged = true;
            break;
        }
    }
    lu_free(force);
    lu_free(moved2);
    lu_free(nb);
    lu_surface_nn_stats(pts, 2.0 * radius, &stats->nn_mean_after, &stats->nn_cv_after);
    stats->seconds = lu_time_seconds() - t0;
    return r;
}
