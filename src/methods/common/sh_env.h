/* Internal: an environment light's radiance projected onto real SH (lu_sh.h),
 * L_k = int L(w) Y_k(w) dw, shared by ddod (its SH lighting) and bssrdf (the
 * irradiance of its environment term). */
#ifndef LU_METHODS_SH_ENV_H
#define LU_METHODS_SH_ENV_H

#include <lucent/lucent.h>

/* Radiance arriving from direction dir (unit, world space). */
typedef lu_vec3 (*lu_sh_env_radiance_fn)(const void *user, lu_vec3 dir);

/* How the cells' polar edges and solid angles are computed: in double with
 * pi in double, or from pi and the edge angles rounded to float (the way
 * ddod has always computed them; kept so its coefficients do not move). */
typedef enum lu_sh_env_angles { LU_SH_ENV_ANGLES_DOUBLE, LU_SH_ENV_ANGLES_FLOAT } lu_sh_env_angles;

/* The cell grid for a width x height lat-long map: cells_per_texel cells per
 * texel along each axis, at least 64 cells_per_texel in theta, and at least
 * twice as many cells in phi as in theta. */
void lu_sh_env_grid(int width, int height, int cells_per_texel, int *nt, int *np);

/* out[3 k + c] = sum over the nt x np cells (equal steps in theta, the polar
 * angle of lu_k_env_dir, and in phi) of L_c(d) Y_k(d) dw, d the direction at
 * the cell's centre (u, v) = ((i + 0.5) / np, (j + 0.5) / nt) and dw the
 * cell's exact solid angle, for k < bands^2 (bands in [1, LU_SH_MAX_BANDS]).
 * out is overwritten. */
void lu_sh_env_project(lu_sh_env_radiance_fn radiance, const void *user, int nt, int np, int bands,
                       lu_sh_env_angles angles, double *out);

#endif
