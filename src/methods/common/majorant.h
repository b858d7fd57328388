/* Internal: the coarse majorant grid of a density grid (per-block maximum),
 * shared by the path tracer's null-collision tracking (lu_tracking.h) and
 * the view march's empty-space skipping (lu_view_march.h, lu_march.h). */
#ifndef LU_METHODS_MAJORANT_H
#define LU_METHODS_MAJORANT_H

#include <lucent/lucent.h>

/* Blocks of `block`^3 voxels; block k along an axis covers index coordinates
 * [k block - 1, (k + 1) block - 1] (block space q = (p_index + 1) / block),
 * and dmax holds the largest grid value among the voxels whose trilinear
 * support touches that region (voxels k block - 1 .. (k + 1) block, the
 * neighbours' border voxels included), which bounds the trilinear field
 * there. A block of dmax 0 has density exactly 0 at every point of index
 * coordinates [k block - 1, (k + 1) block) per axis. */
typedef struct lu_majorant {
    int block;
    int nx, ny, nz;
    float *dmax;      /* nx*ny*nz, x fastest */
} lu_majorant;

lu_result lu_majorant_build(const lu_grid *g, int block, lu_majorant *out, lu_error *err);
void lu_majorant_destroy(lu_majorant *m);

static inline float lu_majorant_at(const lu_majorant *m, int bx, int by, int bz) {
    if (bx < 0 || by < 0 || bz < 0 || bx >= m->nx || by >= m->ny || bz >= m->nz) return 0.0f;
    return m->dmax[((size_t)bz * m->ny + by) * m->nx + bx];
}

#endif
