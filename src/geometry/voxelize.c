/* Voxelisation of closed meshes by scanline parity.
 *
 * Grid: h = (longest side of bounds) / resolution; n = ceil(extent / h) voxels
 * per axis (at least 1), so the grid starts at bounds.lo and may reach up to
 * one voxel past bounds.hi on the shorter axes; voxel i has its centre at
 * lo + (i + 0.5) h, which is index_to_world (a scale by h and a translation
 * by lo + h/2), the procedural generators' convention.
 *
 * Each voxel holds ss^3 sub-samples at lo + (i + (s + 0.5)/ss) h per axis.
 * For every (y, z) sub-sample row one ray goes along +x from before the
 * meshes' bounds to infinity; its sorted crossings (lu_accel_all_hits, which
 * merges edge/vertex double reports) delimit inside spans [c0,c1], [c2,c3]...,
 * and the samples in those spans are counted per voxel. A row with an odd
 * number of crossings (a ray grazing something the merge could not resolve,
 * or an open mesh) falls back to per-sample majority-vote inside tests.
 * Overlapping meshes follow parity too: a region inside two meshes counts as
 * outside. Work is split over voxel rows (y, z), so each task writes its own
 * grid row and the result does not depend on the thread count. */
#include "geometry_internal.h"

#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>

#define LU_VOXELIZE_MAX_SS 32
#define LU_VOXELIZE_MAX_RESOLUTION 16384

typedef struct vox_job {
    const lu_accel *a;
    lu_aabb mesh_bounds;
    double lo[3], h;
    int n[3], ss;
    float x0;            /* ray origin x, before every mesh and the grid */
    float *data;
    atomic_int failed;   /* out of memory in a worker */
} vox_job;

/* Adds the samples m in [m0, m1] (sample index along the row) to the
 * per-voxel counts: partial voxels directly, whole voxels through a
 * difference array so a long span costs O(1). */
static void add_span(int64_t m0, int64_t m1, int ss, int nx, int *partial, int *full_diff) {
    const int64_t last = (int64_t)nx * ss - 1;
    if (m0 < 0) m0 = 0;
    if (m1 > last) m1 = last;
    if (m0 > m1) return;
    int64_t v0 = m0 / ss, v1 = m1 / ss;
    if (v0 == v1) {
        partial[v0] += (int)(m1 - m0 + 1);
        return;
    }
    partial[v0] += (int)(ss - m0 % ss);
    partial[v1] += (int)(m1 % ss + 1);
    if (v1 > v0 + 1) {
        full_diff[v0 + 1] += ss;
        full_diff[v1] -= ss;
    }
}

static void vox_rows(void *ctx, int64_t begin, int64_t end, int thread_index) {
    vox_job *j = ctx;
    const int nx = j->n[0], ny = j->n[1], ss = j->ss;
    const double hs = j->h / ss;
    int cap = 64;
    lu_hit *hits = lu_malloc((size_t)cap * sizeof *hits);
    int *partial = lu_malloc((size_t)nx * sizeof *partial);
    int *full_diff = lu_malloc(((size_t)nx + 1) * sizeof *full_diff);
    if (!hits || !partial || !full_diff) {
        atomic_store(&j->failed, 1);
        goto done;
    }
    for (int64_t row = begin; row < end; row++) {
        const int iy = (int)(row % ny), iz = (int)(row / ny);
        memset(partial, 0, (size_t)nx * sizeof *partial);
        memset(full_diff, 0, ((size_t)nx + 1) * sizeof *full_diff);
        for (int sz = 0; sz < ss; sz++) {
            const float z = (float)(j->lo[2] + (iz + (sz + 0.5) / ss) * j->h);
            if (z < j->mesh_bounds.lo.z || z > j->mesh_bounds.hi.z) continue;
            for (int sy = 0; sy < ss; sy++) {
                const float y = (float)(j->lo[1] + (iy + (sy + 0.5) / ss) * j->h);
                if (y < j->mesh_bounds.lo.y || y > j->mesh_bounds.hi.y) continue;
                const lu_vec3 o = lu_v3(j->x0, y, z), d = lu_v3(1.0f, 0.0f, 0.0f);
                int n = lu_accel_all_hits(j->a, o, d, 0.0f, INFINITY, hits, cap);
                if (n > cap) {
                    lu_hit *more = lu_realloc(hits, (size_t)n * sizeof *hits);
                    if (!more) n = -1;
                    else {
                        hits = more;
                        cap = n;
                        n = lu_accel_all_hits(j->a, o, d, 0.0f, INFINITY, hits, cap);
                    }
                }
                if (n < 0 || n > cap) {
                    atomic_store(&j->failed, 1);
                    goto done;
                }
                if (n % 2 == 0) {
                    /* Sample m sits at x = lo + (m + 0.5) hs; a span (xa, xb)
                     * holds floor(qa - 0.5) + 1 <= m <= ceil(qb - 0.5) - 1 with
                     * q = (x - lo) / hs. */
                    for (int k = 0; k + 1 < n; k += 2) {
                        double qa = ((double)j->x0 + hits[k].t - j->lo[0]) / hs;
                        double qb = ((double)j->x0 + hits[k + 1].t - j->lo[0]) / hs;
                        int64_t m0 = (int64_t)floor(qa - 0.5) + 1, m1 = (int64_t)ceil(qb - 0.5) - 1;
                        add_span(m0, m1, ss, nx, partial, full_diff);
                    }
                } else {
                    for (int64_t m = 0; m < (int64_t)nx * ss; m++) {
                        float x = (float)(j->lo[0] + (m + 0.5) * hs);
                        if (x < j->mesh_bounds.lo.x || x > j->mesh_bounds.hi.x) continue;
                        if (lu_accel_inside(j->a, lu_v3(x, y, z))) partial[m / ss]++;
                    }
                }
            }
        }
        const float inv = 1.0f / (float)((double)ss * ss * ss);
        float *out = j->data + ((size_t)iz * ny + iy) * nx;
        int run = 0;
        for (int ix = 0; ix < nx; ix++) {
            run += full_diff[ix];
            out[ix] = (float)(partial[ix] + run) * inv;
        }
    }
done:
    lu_free(hits);
    lu_free(partial);
    lu_free(full_diff);
}

lu_result lu_voxelize(const lu_accel *a, lu_aabb bounds, int resolution, int ss, lu_grid *g, lu_error *err) {
    if (!a || !g) return lu_fail(err, LU_ERR_INVALID_ARG, "voxelize: NULL accel or grid");
    if (!lu_accel_is_committed(a))
        return lu_fail(err, LU_ERR_INVALID_ARG, "voxelize: the accel is not committed");
    if (!lu_v3_finite(bounds.lo) || !lu_v3_finite(bounds.hi))
        return lu_fail(err, LU_ERR_NONFINITE, "voxelize: bounds are not finite");
    if (!lu_aabb_valid(bounds))
        return lu_fail(err, LU_ERR_RANGE, "voxelize: bounds have lo > hi");
    if (resolution < 1 || resolution > LU_VOXELIZE_MAX_RESOLUTION)
        return lu_fail(err, LU_ERR_RANGE, "voxelize: resolution %d outside [1, %d]", resolution,
                       LU_VOXELIZE_MAX_RESOLUTION);
    if (ss < 1 || ss > LU_VOXELIZE_MAX_SS)
        return lu_fail(err, LU_ERR_RANGE, "voxelize: supersampling %d outside [1, %d]", ss, LU_VOXELIZE_MAX_SS);
    double ext[3], longest = 0.0;
    for (int i = 0; i < 3; i++) {
        ext[i] = (double)lu_v3_get(bounds.hi, i) - (double)lu_v3_get(bounds.lo, i);
        if (ext[i] > longest) longest = ext[i];
    }
    if (!(longest > 0.0)) return lu_fail(err, LU_ERR_RANGE, "voxelize: bounds are empty");

    vox_job j = {.a = a, .mesh_bounds = lu_accel_bounds(a), .h = longest / resolution, .ss = ss};
    uint64_t total = 1;
    for (int i = 0; i < 3; i++) {
        j.lo[i] = lu_v3_get(bounds.lo, i);
        /* The 1e-9 absorbs rounding in ext / h, which is exact in reals for
         * the longest side (= resolution). */
        double q = ceil(ext[i] / j.h - 1e-9);
        if (q < 1.0) q = 1.0;
        if (q > (double)LU_MAX_GRID_VOXELS)
            return lu_fail(err, LU_ERR_LIMIT, "voxelize: axis %d would need %.0f voxels", i, q);
        j.n[i] = (int)q;
        total *= (uint64_t)j.n[i];
    }
    if (total > LU_MAX_GRID_VOXELS)
        return lu_fail(err, LU_ERR_LIMIT, "voxelize: %dx%dx%d voxels exceed the limit %llu", j.n[0], j.n[1],
                       j.n[2], (unsigned long long)LU_MAX_GRID_VOXELS);
    j.data = lu_calloc((size_t)total, sizeof(float));
    if (!j.data) return lu_fail(err, LU_ERR_NOMEM, "voxelize: out of memory for %llu voxels",
                                (unsigned long long)total);
    atomic_init(&j.failed, 0);

    if (lu_aabb_valid(j.mesh_bounds)) {
        /* Start one voxel before both the grid and the meshes: the ray begins
         * outside every closed mesh, so crossing parity is inside-ness. */
        j.x0 = (float)(fmin(j.lo[0], j.mesh_bounds.lo.x) - j.h);
        lu_parallel_for((int64_t)j.n[1] * j.n[2], 0, vox_rows, &j, "voxelize");
        if (atomic_load(&j.failed)) {
            lu_free(j.data);
            return lu_fail(err, LU_ERR_NOMEM, "voxelize: out of memory for ray hits");
        }
    }

    memset(g, 0, sizeof *g);
    g->nx = j.n[0];
    g->ny = j.n[1];
    g->nz = j.n[2];
    g->data = j.data;
    g->index_to_world = lu_affine_identity();
    for (int i = 0; i < 3; i++) {
        g->index_to_world.m[i][i] = (float)j.h;
        g->index_to_world.m[i][3] = (float)(j.lo[i] + 0.5 * j.h);
    }
    g->min_value = INFINITY;
    g->max_value = -INFINITY;
    for (uint64_t i = 0; i < total; i++) {
        if (g->data[i] < g->min_value) g->min_value = g->data[i];
        if (g->data[i] > g->max_value) g->max_value = g->data[i];
    }
    snprintf(g->name, sizeof g->name, "density");
    return LU_OK;
}
