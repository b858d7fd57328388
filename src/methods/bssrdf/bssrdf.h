/* Internal: pieces of the bssrdf method that tests and tools call directly. */
#ifndef LU_METHODS_BSSRDF_H
#define LU_METHODS_BSSRDF_H

#include <lucent/lucent.h>

/* Projects environment light l (its map as the renderer looks it up:
 * bilinear, times its scale) onto the 9 real SH of lu_sh.h: L[3 i + c] =
 * int L_c(w) Y_i(w) dw, by a midpoint rule in theta and phi fine enough for
 * the map (at least 128 x 256 nodes). */
void lu_bssrdf_env_project(const lu_light *l, double L[27]);

/* Zonal coefficients 2 pi int_0^1 w(mu) mu P_l(mu) dmu, l = 0, 1, 2, of the
 * clamped cosine (eta = 0: A_l of Ramamoorthi-Hanrahan, pi, 2 pi/3, pi/4) or
 * of the cosine times the Fresnel transmittance into index eta (light
 * entering a translucent surface). */
void lu_bssrdf_sh_kernel(float eta, double a[3]);

/* Irradiance-like sum_lm k_l L_lm Y_lm(n) (k from lu_bssrdf_sh_kernel). */
lu_vec3 lu_bssrdf_sh_irradiance(const double L[27], const double k[3], lu_vec3 n);

/* Frame statistics of the last render (for benches and tests). */
typedef struct lu_bssrdf_frame_stats {
    int splats;              /* splats drawn (light samples + environment samples) */
    int env_splats;
    long long list_entries;  /* splat-tile pairs after binning */
    long long map_texels;    /* light-space texels ray cast */
    double ms_maps, ms_samples, ms_gbuffer, ms_binning, ms_splat;  /* ms_splat: gather + deferred shading */
    double cpu_ms;           /* processor time of the process during the frame (all threads) */
} lu_bssrdf_frame_stats;

/* Stats of the renderer's last frame; false if `state` is not a bssrdf state. */
bool lu_bssrdf_last_stats(const lu_renderer *r, lu_bssrdf_frame_stats *out);

#endif
