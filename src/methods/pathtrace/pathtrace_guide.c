/* Dwivedi sampling for subsurface random walks (Krivanek and d'Eon 2014,
 * "A Zero-variance-based Sampling Scheme for Monte Carlo Subsurface
 * Scattering"; Meng, Hanika and Dachsbacher 2016, "Improving the
 * Dwivedi Sampling Scheme"). In an isotropic half-space of albedo a the
 * asymptotic solution of the transport equation falls off as
 * exp(-z / v0) with depth z, where v0 solves
 *     (a v0 / 2) ln((v0 + 1) / (v0 - 1)) = 1,
 * and the zero-variance walk towards the surface samples the cosine mu0
 * between the new direction and the outward normal with density
 *     p(mu0) = 1 / (ln((v0 + 1) / (v0 - 1)) (v0 - mu0))  on [-1, 1],
 * and the step length with the stretched rate sigma_t (1 - mu0 / v0).
 * The path tracer mixes this with the classical walk (phase function and
 * sigma_t) and weights by the mixture density, so any v0 stays unbiased;
 * anisotropic media use the similarity-reduced albedo. */
#include "methods/pathtrace/pathtrace_internal.h"

#include <math.h>

double lu_pt_dwivedi_v0(double albedo) {
    if (!(albedo > 0.0)) return 1.0 + 1e-12;
    if (albedo > 1.0 - 1e-7) albedo = 1.0 - 1e-7;
    /* g(v) = (a v / 2) ln((v + 1) / (v - 1)) - 1 falls from +inf at v = 1+ to
     * a - 1 < 0 as v grows; bisection on x = ln(v - 1). */
    double lo = -40.0, hi = log(4.0 / sqrt(1.0 - albedo));
    for (int i = 0; i < 200; i++) {
        double x = 0.5 * (lo + hi), v = 1.0 + exp(x);
        double g = 0.5 * albedo * v * log1p(2.0 / (v - 1.0)) - 1.0;
        if (g > 0.0)
            lo = x;
        else
            hi = x;
    }
    return 1.0 + exp(0.5 * (lo + hi));
}

float lu_pt_dwivedi_log(float v0) { return log1pf(2.0f / (v0 - 1.0f)); }

float lu_pt_dwivedi_sample(float v0, float log_ratio, float u) {
    /* Inverse CDF: mu0 = v0 - (v0 + 1) ((v0 - 1) / (v0 + 1))^u, written with
     * expm1 so that v0 >> 1 (high albedo) keeps its precision. */
    float mu = -(v0 + 1.0f) * expm1f(-u * log_ratio) - 1.0f;
    return fminf(fmaxf(mu, -1.0f), 1.0f);
}

float lu_pt_dwivedi_pdf(float v0, float log_ratio, float mu0) {
    return 1.0f / (2.0f * LU_PI * log_ratio * (v0 - mu0)); /* per steradian */
}
