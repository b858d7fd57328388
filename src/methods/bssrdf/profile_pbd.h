/* Internal: the photon beam diffusion profile (Habel, Christensen and Jarosz
 * 2013) plus single scattering, tabulated once per index of refraction over
 * (reduced albedo, optical radius), as pbrt-v3 builds its BSSRDF table.
 *
 * Everything here is in optical units (lengths times sigma_t', so sigma_t' =
 * 1) for one channel of a half-space with isotropic scattering of reduced
 * coefficients sigma_s' (the similarity relation) and a smooth dielectric
 * boundary of relative index eta. The quantity is the radiant exitance that
 * leaves the surface at distance r from a unit-power pencil beam entering at
 * normal incidence, already past the entry interface: the same R_d as the
 * dipole's (bssrdf_profile.h) and as profile_mc.h's walk tallies. A material
 * channel of sigma_t' reads R(r) = sigma_t'^2 R_opt(rho, r sigma_t').
 *
 * bssrdf_profile.c resamples this table into the renderer's per-material 1D
 * R(r) tables (LU_BSSRDF_PBD); those reach both backends as every other 1D
 * profile does (lu_bssrdf.h). See docs/bssrdf.md, "pbd". */
#ifndef LU_METHODS_BSSRDF_PROFILE_PBD_H
#define LU_METHODS_BSSRDF_PROFILE_PBD_H

#include <lucent/lucent.h>

typedef struct lu_bssrdf_pbd_table {
    double eta;
    int n_rho, n_r;
    double *rho;       /* n_rho reduced albedos in [0, 1], crowding towards 1 */
    double *r;         /* n_r optical radii: 0, then geometric */
    double *profile;   /* n_rho x n_r (row per albedo): 2 pi r (R_ss + R_ms) */
    double *ss;        /* the same for single scattering alone (tests, docs) */
    double *rho_eff;   /* per albedo: the row's integral over r, the total diffuse reflectance */
} lu_bssrdf_pbd_table;

/* The shared table for eta (built on first use, kept for the process). */
lu_result lu_bssrdf_pbd_table_get(double eta, const lu_bssrdf_pbd_table **out, lu_error *err);

/* The two terms at one optical radius, by quadrature (no table): exitance
 * per unit area, single scattering (events == 1) and multiple (events >= 2). */
double lu_bssrdf_pbd_ss(double rho, double eta, double r);
double lu_bssrdf_pbd_ms(double rho, double eta, double r);

/* Table look-ups (Catmull-Rom in albedo and radius, as pbrt): R_opt(rho, r)
 * per unit area (0 beyond the table's last radius; r = 0 is singular and
 * gives the value at the first non-zero node), and the total reflectance. */
double lu_bssrdf_pbd_eval(const lu_bssrdf_pbd_table *t, double rho, double r);
double lu_bssrdf_pbd_total(const lu_bssrdf_pbd_table *t, double rho);
/* The last tabulated optical radius. */
double lu_bssrdf_pbd_r_end(const lu_bssrdf_pbd_table *t);

/* Fresnel moments of the boundary seen from inside a medium of relative
 * index eta: int_0^1 F_r(mu) mu^k dmu with F_r = 1 under total internal
 * reflection (2 FM_1 is the internal diffuse reflectance). By quadrature of
 * the exact Fresnel reflectance. */
double lu_bssrdf_fresnel_moment_inside(double eta, int k);

#endif
