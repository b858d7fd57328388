/* The coarse majorant grid (majorant.h). */
#include "methods/common/majorant.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

lu_result lu_majorant_build(const lu_grid *g, int block, lu_majorant *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    if (block < 1 || !g || g->nx < 1 || g->ny < 1 || g->nz < 1)
        return lu_fail(err, LU_ERR_INVALID_ARG, "majorant grid needs a grid and a block size >= 1");
    out->block = block;
    /* Support [-1, n] is n + 1 long: ceil((n + 1) / block) blocks. */
    out->nx = (g->nx + 1 + block - 1) / block;
    out->ny = (g->ny + 1 + block - 1) / block;
    out->nz = (g->nz + 1 + block - 1) / block;
    out->dmax = lu_calloc((size_t)out->nx * out->ny * out->nz, sizeof *out->dmax);
    if (!out->dmax) return lu_fail(err, LU_ERR_NOMEM, "out of memory for the majorant grid");
    for (int bz = 0; bz < out->nz; bz++)
        for (int by = 0; by < out->ny; by++)
            for (int bx = 0; bx < out->nx; bx++) {
                /* Region [k B - 1, (k+1) B - 1]: trilinear there reads voxels k B - 1 .. (k+1) B. */
                float m = 0.0f;
                for (int z = bz * block - 1; z <= (bz + 1) * block; z++)
                    for (int y = by * block - 1; y <= (by + 1) * block; y++)
                        for (int x = bx * block - 1; x <= (bx + 1) * block; x++) m = fmaxf(m, lu_grid_at(g, x, y, z));
                /* Trilinear weights sum to one only up to rounding: a relative
                 * ulp of headroom keeps sigma_n >= 0 without measurable cost. */
                out->dmax[((size_t)bz * out->ny + by) * out->nx + bx] = m * (1.0f + 4e-7f);
            }
    return LU_OK;
}

void lu_majorant_destroy(lu_majorant *m) {
    if (!m) return;
    lu_free(m->dmax);
    memset(m, 0, sizeof *m);
}
