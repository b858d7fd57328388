/* Greedy Gaussian fit of a density grid (see gradient_fit.h). */
#include "methods/gradient/gradient_fit.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define BLOCK 8

typedef struct fit_state {
    lu_grid *res;          /* residual being reduced */
    int bx, by, bz;        /* block counts */
    float *bmax;           /* per block: the largest residual */
} fit_state;

static void block_update(fit_state *fs, int bi, int bj, int bk) {
    const lu_grid *g = fs->res;
    float m = -INFINITY;
    for (int z = bk * BLOCK; z < (bk + 1) * BLOCK && z < g->nz; z++)
        for (int y = bj * BLOCK; y < (bj + 1) * BLOCK && y < g->ny; y++) {
            const float *row = g->data + ((size_t)z * g->ny + y) * g->nx;
            for (int x = bi * BLOCK; x < (bi + 1) * BLOCK && x < g->nx; x++) m = fmaxf(m, row[x]);
        }
    fs->bmax[((size_t)bk * fs->by + bj) * fs->bx + bi] = m;
}

/* Sums of R G and G G over the box |x - c| <= 2r (stride s, scaled back). */
static void lsq_sums(const lu_grid *g, const int c[3], float r, double *rg, double *gg) {
    int h = (int)ceilf(2.0f * r);
    int s = r > 4.0f ? (int)(r / 4.0f) : 1;
    double a = 0.0, b = 0.0;
    float inv = 1.0f / (r * r);
    for (int z = -h; z <= h; z += s) {
        int zz = c[2] + z;
        if (zz < 0 || zz >= g->nz) continue;
        for (int y = -h; y <= h; y += s) {
            int yy = c[1] + y;
            if (yy < 0 || yy >= g->ny) continue;
            const float *row = g->data + ((size_t)zz * g->ny + yy) * g->nx;
            for (int x = -h; x <= h; x += s) {
                int xx = c[0] + x;
                if (xx < 0 || xx >= g->nx) continue;
                float gv = expf(-(float)(x * x + y * y + z * z) * inv);
                a += (double)row[xx] * gv;
                b += (double)gv * gv;
            }
        }
    }
    double k = (double)s * s * s;
    *rg = a * k;
    *gg = b * k;
}

static void splat_one(const lu_gauss *q, float sign, lu_grid *g, fit_state *fs) {
    int h = (int)ceilf(3.0f * q->r);
    int lo[3], hi[3];
    float cc[3] = {q->c.x, q->c.y, q->c.z};
    int n[3] = {g->nx, g->ny, g->nz};
    for (int i = 0; i < 3; i++) {
        lo[i] = (int)floorf(cc[i]) - h;
        hi[i] = (int)ceilf(cc[i]) + h;
        if (lo[i] < 0) lo[i] = 0;
        if (hi[i] > n[i] - 1) hi[i] = n[i] - 1;
    }
    float inv = 1.0f / (q->r * q->r), cut = 9.0f * q->r * q->r;
    for (int z = lo[2]; z <= hi[2]; z++)
        for (int y = lo[1]; y <= hi[1]; y++) {
            float *row = g->data + ((size_t)z * g->ny + y) * g->nx;
            for (int x = lo[0]; x <= hi[0]; x++) {
                float dx = (float)x - cc[0], dy = (float)y - cc[1], dz = (float)z - cc[2];
                float d2 = dx * dx + dy * dy + dz * dz;
                if (d2 > cut) continue;
                row[x] += sign * q->w * expf(-d2 * inv);
            }
        }
    if (!fs) return;
    for (int bk = lo[2] / BLOCK; bk <= hi[2] / BLOCK; bk++)
        for (int bj = lo[1] / BLOCK; bj <= hi[1] / BLOCK; bj++)
            for (int bi = lo[0] / BLOCK; bi <= hi[0] / BLOCK; bi++) block_update(fs, bi, bj, bk);
}

void lu_gauss_splat(const lu_gauss *g, int count, lu_grid *out) {
    for (int j = 0; j < count; j++) splat_one(&g[j], 1.0f, out, NULL);
}

lu_result lu_gauss_fit_grid(const lu_grid *grid, int max_count, float max_radius, lu_gauss_fit *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    double t0 = lu_time_seconds();
    /* The fit works on a dense residual, so a sparse grid is expanded here
     * (docs/volumes.md: the gradient family's memory is per voxel of the box). */
    lu_result r = lu_grid_densify(grid, &out->residual, err);
    if (r != LU_OK) return r;
    size_t nv = (size_t)grid->nx * grid->ny * grid->nz;
    const float *values = out->residual.data;
    out->g = lu_malloc((max_count > 0 ? (size_t)max_count : 1u) * sizeof *out->g);
    fit_state fs = {&out->residual, (grid->nx + BLOCK - 1) / BLOCK, (grid->ny + BLOCK - 1) / BLOCK,
                    (grid->nz + BLOCK - 1) / BLOCK, NULL};
    fs.bmax = lu_malloc((size_t)fs.bx * fs.by * fs.bz * sizeof(float));
    if (!out->g || !fs.bmax) {
        lu_free(fs.bmax);
        lu_gauss_fit_free(out);
        return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory fitting Gaussians");
    }
    for (int k = 0; k < fs.bz; k++)
        for (int j = 0; j < fs.by; j++)
            for (int i = 0; i < fs.bx; i++) block_update(&fs, i, j, k);
    double norm2 = 0.0;
    float dmax = 0.0f;
    for (size_t i = 0; i < nv; i++) {
        norm2 += (double)values[i] * values[i];
        dmax = fmaxf(dmax, values[i]);
    }
    static const float ladder[] = {1.0f, 1.5f, 2.0f, 3.0f, 4.0f, 6.0f, 8.0f, 12.0f, 16.0f};
    int maxdim = grid->nx > grid->ny ? grid->nx : grid->ny;
    if (grid->nz > maxdim) maxdim = grid->nz;
    while (out->count < max_count && dmax > 0.0f) {
        size_t nb = (size_t)fs.bx * fs.by * fs.bz, best = 0;
        for (size_t b = 1; b < nb; b++)
            if (fs.bmax[b] > fs.bmax[best]) best = b;
        float peak = fs.bmax[best];
        if (!(peak > 1e-3f * dmax)) break;
        int bi = (int)(best % fs.bx), bj = (int)((best / fs.bx) % fs.by), bk = (int)(best / ((size_t)fs.bx * fs.by));
        int c[3] = {0, 0, 0};
        for (int z = bk * BLOCK; z < (bk + 1) * BLOCK && z < grid->nz; z++)
            for (int y = bj * BLOCK; y < (bj + 1) * BLOCK && y < grid->ny; y++)
                for (int x = bi * BLOCK; x < (bi + 1) * BLOCK && x < grid->nx; x++)
                    if (lu_grid_at(&out->residual, x, y, z) == peak) c[0] = x, c[1] = y, c[2] = z;
        lu_gauss q = {lu_v3((float)c[0], (float)c[1], (float)c[2]), 1.0f, peak};
        double best_gain = -1.0;
        for (size_t i = 0; i < sizeof ladder / sizeof ladder[0]; i++) {
            float rad = ladder[i];
            if ((rad > 0.25f * (float)maxdim || rad > max_radius) && i > 0) break;
            double rg, gg;
            lsq_sums(&out->residual, c, rad, &rg, &gg);
            double w = gg > 0.0 ? rg / gg : 0.0;
            if (w > peak) w = peak;
            if (w < 0.0) w = 0.0;
            double gain = 2.0 * w * rg - w * w * gg;
            if (gain > best_gain) {
                best_gain = gain;
                q.r = rad;
                q.w = (float)w;
            }
        }
        if (!(q.w > 0.0f)) q.w = peak, q.r = 1.0f;
        splat_one(&q, -1.0f, &out->residual, &fs);
        out->g[out->count++] = q;
    }
    lu_free(fs.bmax);
    double res2 = 0.0;
    for (size_t i = 0; i < nv; i++) res2 += (double)out->residual.data[i] * out->residual.data[i];
    out->rel_l2 = norm2 > 0.0 ? sqrt(res2 / norm2) : 0.0;
    out->ms = 1e3 * (lu_time_seconds() - t0);
    return LU_OK;
}

lu_result lu_gauss_reconstruct(const lu_gauss_fit *fit, lu_grid *out, lu_error *err) {
    const lu_grid *rg = &fit->residual;
    lu_result r = lu_grid_alloc(out, rg->nx, rg->ny, rg->nz, err);
    if (r != LU_OK) return r;
    memcpy(out->data, rg->data, (size_t)rg->nx * rg->ny * rg->nz * sizeof(float));
    out->index_to_world = rg->index_to_world;
    lu_gauss_splat(fit->g, fit->count, out);
    lu_grid_update_range(out);
    return LU_OK;
}

void lu_gauss_fit_free(lu_gauss_fit *fit) {
    lu_free(fit->g);
    lu_grid_destroy(&fit->residual);
    memset(fit, 0, sizeof *fit);
}
