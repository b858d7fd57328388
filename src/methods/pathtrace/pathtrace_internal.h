/* Internal pieces of the path tracer that tests reach directly: the coarse
 * majorant grid (per-block maximum density) the tracking kernels walk. */
#ifndef LU_PATHTRACE_INTERNAL_H
#define LU_PATHTRACE_INTERNAL_H

#include <lucent/lucent.h>

/* Blocks of `block`^3 voxels; block k along an axis covers index coordinates
 * [k block - 1, (k + 1) block - 1] (lu_tracking.h), and dmax holds the largest
 * grid value among the voxels whose trilinear support touches that region,
 * which bounds the trilinear field there. */
typedef struct lu_pt_majorant {
    int block;
    int nx, ny, nz;
    float *dmax;      /* nx*ny*nz, x fastest */
} lu_pt_majorant;

lu_result lu_pt_majorant_build(const lu_grid *g, int block, lu_pt_majorant *out, lu_error *err);
void lu_pt_majorant_destroy(lu_pt_majorant *m);

static inline float lu_pt_majorant_at(const lu_pt_majorant *m, int bx, int by, int bz) {
    if (bx < 0 || by < 0 || bz < 0 || bx >= m->nx || by >= m->ny || bz >= m->nz) return 0.0f;
    return m->dmax[((size_t)bz * m->ny + by) * m->nx + bx];
}

#endif
