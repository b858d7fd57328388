/* The coarse majorant grid (majorant.h). */
#include "methods/common/majorant.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "volume/grid_internal.h"

/* A sparse grid's majorants come from its nodes, not its voxels: each leaf's
 * largest value (over all 512, inactive ones too, since the field reads
 * them) and each tile's value go to every block whose region the node's
 * voxels touch. Empty space (no node) costs nothing, so the build is
 * linear in the tree, not in the bounding box; the bound is a leaf's, at
 * most 3 leaves wide per block axis, instead of a block's. */
typedef struct tree_maj {
    const lu_grid *g;
    lu_majorant *out;
} tree_maj;

static void maj_node(void *p, const int64_t o[3], int dim, const float *leaf, float tile) {
    tree_maj *c = p;
    int lo[3], hi[3];
    /* A node's voxels outside the index box are never read (lu_grid_tree.h). */
    if (!lu_grid_tree_clip(c->g, o, dim, lo, hi)) return;
    float m = tile;
    if (leaf) {
        m = 0.0f;
        for (int i = 0; i < 512; i++) m = fmaxf(m, leaf[i]);
    }
    if (!(m > 0.0f)) return;
    lu_majorant *out = c->out;
    const int B = out->block, nb[3] = {out->nx, out->ny, out->nz};
    int b0[3], b1[3];
    for (int a = 0; a < 3; a++) {
        /* Voxel i is read by blocks k with k B - 1 <= i <= (k + 1) B. */
        b0[a] = lo[a] > 0 ? (lo[a] - 1) / B : 0;
        b1[a] = hi[a] / B;
        if (b1[a] > nb[a] - 1) b1[a] = nb[a] - 1;
    }
    for (int bz = b0[2]; bz <= b1[2]; bz++)
        for (int by = b0[1]; by <= b1[1]; by++)
            for (int bx = b0[0]; bx <= b1[0]; bx++) {
                float *d = &out->dmax[((size_t)bz * out->ny + by) * out->nx + bx];
                *d = fmaxf(*d, m);
            }
}


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
    if (lu_grid_is_sparse(g)) {
        tree_maj c = {g, out};
        lu_grid_tree_visit(g, maj_node, &c);
        size_t n = (size_t)out->nx * out->ny * out->nz;
        for (size_t i = 0; i < n; i++) out->dmax[i] *= 1.0f + 4e-7f;
        return LU_OK;
    }
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
