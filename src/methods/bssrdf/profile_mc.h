/* Internal: a Monte Carlo random walk in a slab, the independent check of the
 * diffusion profiles (bssrdf_profile.h). Only the CLI (`lucent profile`) and
 * the tests use it; the renderer never does. */
#ifndef LU_METHODS_BSSRDF_PROFILE_MC_H
#define LU_METHODS_BSSRDF_PROFILE_MC_H

#include <lucent/lucent.h>

/* Random walk in a slab (thickness INFINITY: semi-infinite) of one channel:
 * isotropic scattering with sigma_s' (similarity), absorption as weight,
 * smooth dielectric faces of relative index eta (Fresnel split at every
 * hit), a pencil beam entering at the origin straight down (already past the
 * entry interface: the BSSRDF's F_t(w_i) is outside the profile). Tallies
 * the exitance per unit area on the top (R) and bottom (T) faces in radial
 * bins of width dr (the last bin collects everything beyond), per unit
 * entering power. Deterministic for a given seed, whatever the thread count. */
typedef struct lu_bssrdf_mc_result {
    int bins;
    double dr;
    double *r_profile, *t_profile;   /* bins each; per area */
    double *r_multiple;              /* R of paths that scattered at least twice (what diffusion models) */
    double *r_profile_stderr;        /* standard error of each r_profile bin (batch means over the chunks) */
    double r_total, t_total;         /* all exiting power, per unit entering power */
    double r_multiple_total;
    /* R of paths that scattered at least twice with no face reflection
     * between their first two events: what a path tracer reaches that joins
     * a vertex to the light's first scattering point by one straight segment
     * (docs/bssrdf.md, "Where the error comes from"). */
    double r_multiple_unreflected_total;
    double r_stderr;                 /* standard error of r_total */
    double dropped;                  /* weight of walks cut at 10^6 events, per unit entering power */
} lu_bssrdf_mc_result;

lu_result lu_bssrdf_mc_slab(double sigma_sp, double sigma_a, double eta, double thickness, long long paths,
                            unsigned long long seed, int bins, double dr, lu_bssrdf_mc_result *out, lu_error *err);
void lu_bssrdf_mc_destroy(lu_bssrdf_mc_result *r);

#endif
