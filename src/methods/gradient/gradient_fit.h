/* Internal: a density grid as a sum of Gaussians plus a residual (Ren et
 * al. Eq. 3, the representation of Zhou et al. 2007):
 *   D(x) = sum_j w_j exp(-|x - c_j|^2 / r_j^2) + F(x),
 * fitted greedily in index space (voxel units): repeatedly take the voxel of
 * largest remaining residual as a centre, pick the radius from a ladder
 * (1 .. max_radius voxels, at most 16) whose least-squares weight (clamped to [0, peak]) removes
 * the most squared residual around it, subtract that Gaussian, repeat. The
 * residual F = D - sum is kept dense, so D is reconstructed exactly (to
 * float rounding); the fit error reported is |F| / |D| (the Gaussians alone). */
#ifndef LU_METHODS_GRADIENT_FIT_H
#define LU_METHODS_GRADIENT_FIT_H

#include <lucent/lucent.h>

typedef struct lu_gauss {
    lu_vec3 c;     /* centre, index space */
    float r;       /* radius, voxels */
    float w;       /* weight (density units) */
} lu_gauss;

typedef struct lu_gauss_fit {
    lu_gauss *g;
    int count;
    lu_grid residual;     /* D minus the Gaussians (same size and map as the grid) */
    double rel_l2;        /* |residual| / |D| */
    double ms;            /* fit wall time */
} lu_gauss_fit;

/* Fits at most max_count Gaussians to grid (stops early when the residual
 * peak falls under 1e-3 of the grid's maximum). */
lu_result lu_gauss_fit_grid(const lu_grid *grid, int max_count, float max_radius, lu_gauss_fit *out, lu_error *err);
/* Adds sum_j w_j G_j (cut at 3 r_j) into `out` (a grid of the fitted size). */
void lu_gauss_splat(const lu_gauss *g, int count, lu_grid *out);
/* Reconstructs D = Gaussians + residual into out (allocated here). */
lu_result lu_gauss_reconstruct(const lu_gauss_fit *fit, lu_grid *out, lu_error *err);
void lu_gauss_fit_free(lu_gauss_fit *fit);

#endif
