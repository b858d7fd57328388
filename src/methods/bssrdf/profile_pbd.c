/* Photon beam diffusion with single scattering, tabulated (profile_pbd.h).
 *
 * The terms follow Habel et al. 2013 as pbrt-v3 states them: single
 * scattering integrated along the refracted beam from the depth below which
 * the exit direction would be totally reflected, and the multiple-scattering
 * term as a line of dipoles along the beam (Grosjean's diffusion coefficient,
 * d'Eon's boundary condition with Fresnel moments, Habel's kappa correction
 * for sources near the surface, the source density times rho'^2). The depth
 * integrals use composite Simpson in log depth instead of pbrt's 100 midpoint
 * samples so that radii far below a mean free path are resolved too. */
#include "methods/bssrdf/profile_pbd.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>

#include "core/memory.h"
#include "kernels/lu_optics.h"

/* ---- the two terms by quadrature ------------------------------------------------ */

double lu_bssrdf_fresnel_moment_inside(double eta, int k) {
    /* Below the critical cosine the reflectance is 1 (exact part); above it,
     * Simpson in u = sqrt(mu - mu_c), which removes the square-root onset of
     * transmission there. */
    double mu_c = eta > 1.0 ? sqrt(1.0 - 1.0 / (eta * eta)) : 0.0;
    double sum = pow(mu_c, k + 1) / (k + 1), umax = sqrt(1.0 - mu_c);
    enum { N = 512 };
    double h = umax / N, acc = 0.0;
    for (int i = 0; i <= N; i++) {
        double u = i * h, mu = mu_c + u * u, w = (i == 0 || i == N) ? 1.0 : (i & 1 ? 4.0 : 2.0);
        acc += w * (double)lu_k_fresnel_reflectance((float)mu, (float)(1.0 / eta)) * pow(mu, k) * 2.0 * u;
    }
    return sum + acc * h / 3.0;
}

/* Composite Simpson of g(w) w over y = ln w in [ln w_lo, ln w_hi] (about 12
 * panels per e-fold, enough for integrands smooth on that scale). */
typedef double (*log_fn)(const void *ctx, double w);
static double simpson_log(log_fn g, const void *ctx, double w_lo, double w_hi) {
    double y0 = log(w_lo), y1 = log(w_hi);
    int n = 2 * (int)ceil((y1 - y0) * 6.0);
    if (n < 2) n = 2;
    double h = (y1 - y0) / n, acc = 0.0;
    for (int i = 0; i <= n; i++) {
        double w = exp(y0 + i * h), c = (i == 0 || i == n) ? 1.0 : (i & 1 ? 4.0 : 2.0);
        acc += c * g(ctx, w) * w;
    }
    return acc * h / 3.0;
}

typedef struct term_ctx {
    double rho, eta, r;
    double t_crit;                 /* single scattering: shallowest depth that can leave */
    double D, s_tr, ze, c_phi, c_e; /* multiple scattering */
} term_ctx;

/* Single scattering at depth t_crit + w: the beam reaches it with e^{-t},
 * scatters isotropically (rho / 4 pi), and the segment of length d to the
 * exit point is attenuated by e^{-d}, spread over d^2, projected by cos and
 * transmitted by 1 - F. */
static double ss_integrand(const void *vc, double w) {
    const term_ctx *c = vc;
    double t = c->t_crit + w, d = sqrt(c->r * c->r + t * t), mu = t / d;
    double tr = 1.0 - (double)lu_k_fresnel_reflectance((float)mu, (float)(1.0 / c->eta));
    return c->rho * (1.0 / (4.0 * M_PI)) * exp(-t - d) * tr * mu / (d * d);
}

double lu_bssrdf_pbd_ss(double rho, double eta, double r) {
    term_ctx c = {rho, eta, r, r * sqrt(fmax(eta * eta - 1.0, 0.0)), 0, 0, 0, 0, 0};
    if (!(rho > 0.0) || !(r > 0.0)) return 0.0;
    return simpson_log(ss_integrand, &c, 1e-4 * fmin(r, 1.0), 40.0);
}

/* Exitance of the dipole for a source at depth z, weighted by the beam's
 * source density e^{-z} rho'^2 and Habel's kappa. */
static double ms_integrand(const void *vc, double z) {
    const term_ctx *c = vc;
    double zv = -z + 2.0 * c->ze;
    double dr = sqrt(c->r * c->r + z * z), dv = sqrt(c->r * c->r + zv * zv);
    double er = exp(-c->s_tr * dr), ev = exp(-c->s_tr * dv);
    double phi = (er / dr - ev / dv) / (4.0 * M_PI * c->D);
    double edn = (z * (1.0 + c->s_tr * dr) * er / (dr * dr * dr) - zv * (1.0 + c->s_tr * dv) * ev / (dv * dv * dv)) /
                 (4.0 * M_PI);
    double kappa = 1.0 - exp(-2.0 * (dr + z));
    return exp(-z) * kappa * c->rho * c->rho * (c->c_phi * phi + c->c_e * edn);
}

static void ms_setup(term_ctx *c, double rho, double eta, double fm1, double fm2) {
    c->rho = rho;
    c->eta = eta;
    c->D = (2.0 * (1.0 - rho) + rho) / 3.0;         /* Grosjean, sigma_t' = 1 */
    c->s_tr = sqrt((1.0 - rho) / c->D);
    c->ze = -2.0 * c->D * (1.0 + 3.0 * fm2) / (1.0 - 2.0 * fm1);
    c->c_phi = 0.25 * (1.0 - 2.0 * fm1);
    c->c_e = 0.5 * (1.0 - 3.0 * fm2);
}

static double ms_at(term_ctx *c, double r) {
    c->r = r;
    return simpson_log(ms_integrand, c, 1e-5 * fmin(r, 1.0), 40.0);
}

double lu_bssrdf_pbd_ms(double rho, double eta, double r) {
    if (!(rho > 0.0) || !(r > 0.0)) return 0.0;
    term_ctx c;
    ms_setup(&c, rho, eta, lu_bssrdf_fresnel_moment_inside(eta, 1), lu_bssrdf_fresnel_moment_inside(eta, 2));
    return ms_at(&c, r);
}

/* ---- the table ---------------------------------------------------------------------- */

/* 100 albedos as pbrt spaces them; radii 0, then 1e-3 growing by 10 % per
 * node to about 1.2e4 mean free paths (a non-absorbing medium's power-law
 * tail leaves under 1e-3 of its power beyond). */
enum { PBD_N_RHO = 100, PBD_N_R = 172 };
#define PBD_R1 1e-3
#define PBD_R_GROWTH 1.1

typedef struct build_job {
    lu_bssrdf_pbd_table *t;
    double fm1, fm2;
} build_job;

static void build_rows(void *vctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    build_job *j = vctx;
    lu_bssrdf_pbd_table *t = j->t;
    for (int64_t i = begin; i < end; i++) {
        double rho = t->rho[i];
        term_ctx c;
        ms_setup(&c, rho, t->eta, j->fm1, j->fm2);
        double *row = t->profile + (size_t)i * t->n_r, *ss = t->ss + (size_t)i * t->n_r;
        /* r -> 0: 2 pi r R_ss tends to rho (1/2 - FM_1) / 2 (the depth integral
         * becomes int T(mu) mu dmu over the escape cone), 2 pi r R_ms to 0. */
        ss[0] = row[0] = 0.5 * rho * (0.5 - j->fm1);
        for (int k = 1; k < t->n_r; k++) {
            double r = t->r[k], s = lu_bssrdf_pbd_ss(rho, t->eta, r);
            double m = rho > 0.0 ? ms_at(&c, r) : 0.0;
            ss[k] = 2.0 * M_PI * r * s;
            row[k] = 2.0 * M_PI * r * (s + m);
        }
    }
}

/* Catmull-Rom weights over non-uniform nodes x[0..n-1] at v (pbrt's
 * scheme: central-difference slopes, one-sided at the ends). Returns the
 * first node index the 4 weights apply to (-1 in the first segment, whose
 * weight 0 is unused), or -2 outside [x0, x_{n-1}]. */
static int cr_weights(const double *x, int n, double v, double w[4]) {
    if (!(v >= x[0] && v <= x[n - 1])) return -2;
    int lo = 0, hi = n - 1;
    while (hi - lo > 1) {
        int mid = (lo + hi) / 2;
        if (x[mid] <= v) lo = mid;
        else hi = mid;
    }
    int i = lo < n - 1 ? lo : n - 2;
    double x0 = x[i], x1 = x[i + 1], h = x1 - x0, s = (v - x0) / h, s2 = s * s, s3 = s2 * s;
    w[1] = 2 * s3 - 3 * s2 + 1;
    w[2] = -2 * s3 + 3 * s2;
    double a = s3 - 2 * s2 + s, b = s3 - s2; /* times the slopes at x0, x1 (in units of h) */
    if (i > 0) {
        double f = a * h / (x1 - x[i - 1]);
        w[0] = -f;
        w[2] += f;
    } else {
        w[0] = 0.0;
        w[1] -= a;
        w[2] += a;
    }
    if (i + 2 < n) {
        double f = b * h / (x[i + 2] - x0);
        w[1] -= f;
        w[3] = f;
    } else {
        w[3] = 0.0;
        w[1] -= b;
        w[2] += b;
    }
    return i - 1;
}

/* Integral of the Catmull-Rom spline through (x, f) over [x0, x_{n-1}]:
 * per segment h (f0 + f1) / 2 + h^2 (m0 - m1) / 12 with the spline's slopes m. */
static double cr_integral(const double *x, const double *f, int n) {
    double sum = 0.0;
    for (int i = 0; i + 1 < n; i++) {
        double h = x[i + 1] - x[i];
        double m0 = i > 0 ? (f[i + 1] - f[i - 1]) / (x[i + 1] - x[i - 1]) : (f[i + 1] - f[i]) / h;
        double m1 = i + 2 < n ? (f[i + 2] - f[i]) / (x[i + 2] - x[i]) : (f[i + 1] - f[i]) / h;
        sum += h * 0.5 * (f[i] + f[i + 1]) + h * h * (m0 - m1) / 12.0;
    }
    return sum;
}

static void table_free(lu_bssrdf_pbd_table *t) {
    lu_free(t->rho);
    lu_free(t->r);
    lu_free(t->profile);
    lu_free(t->ss);
    lu_free(t->rho_eff);
    lu_free(t);
}

static lu_result table_build(double eta, lu_bssrdf_pbd_table **out, lu_error *err) {
    lu_bssrdf_pbd_table *t = lu_calloc(1, sizeof *t);
    if (!t) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the pbd table");
    t->eta = eta;
    t->n_rho = PBD_N_RHO;
    t->n_r = PBD_N_R;
    t->rho = lu_malloc(PBD_N_RHO * sizeof *t->rho);
    t->r = lu_malloc(PBD_N_R * sizeof *t->r);
    t->profile = lu_malloc((size_t)PBD_N_RHO * PBD_N_R * sizeof *t->profile);
    t->ss = lu_malloc((size_t)PBD_N_RHO * PBD_N_R * sizeof *t->ss);
    t->rho_eff = lu_malloc(PBD_N_RHO * sizeof *t->rho_eff);
    if (!t->rho || !t->r || !t->profile || !t->ss || !t->rho_eff) {
        table_free(t);
        return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the pbd table");
    }
    for (int i = 0; i < PBD_N_RHO; i++)
        t->rho[i] = (1.0 - exp(-8.0 * i / (PBD_N_RHO - 1))) / (1.0 - exp(-8.0));
    t->rho[PBD_N_RHO - 1] = 1.0;
    t->r[0] = 0.0;
    t->r[1] = PBD_R1;
    for (int k = 2; k < PBD_N_R; k++) t->r[k] = t->r[k - 1] * PBD_R_GROWTH;
    build_job j = {t, lu_bssrdf_fresnel_moment_inside(eta, 1), lu_bssrdf_fresnel_moment_inside(eta, 2)};
    lu_parallel_for(PBD_N_RHO, 1, build_rows, &j, NULL);
    for (int i = 0; i < PBD_N_RHO; i++) t->rho_eff[i] = cr_integral(t->r, t->profile + (size_t)i * t->n_r, t->n_r);
    *out = t;
    return LU_OK;
}

/* Tables per eta, built once and kept for the process (a handful of
 * indices in any scene; each is 0.3 MB). */
enum { PBD_CACHE = 16 };
static pthread_mutex_t g_pbd_mu = PTHREAD_MUTEX_INITIALIZER;
static lu_bssrdf_pbd_table *g_pbd[PBD_CACHE];

lu_result lu_bssrdf_pbd_table_get(double eta, const lu_bssrdf_pbd_table **out, lu_error *err) {
    *out = NULL;
    if (!(eta >= 1.0 && eta <= 4.0)) return lu_fail(err, LU_ERR_RANGE, "bssrdf: pbd needs eta in [1, 4] (got %g)", eta);
    eta = (double)(float)eta; /* materials carry float indices: one table per float value */
    pthread_mutex_lock(&g_pbd_mu);
    lu_result r = LU_OK;
    int slot = -1;
    for (int i = 0; i < PBD_CACHE && slot < 0; i++)
        if (!g_pbd[i] || g_pbd[i]->eta == eta) slot = i;
    if (slot < 0) {
        r = lu_fail(err, LU_ERR_LIMIT, "bssrdf: pbd tables for more than %d indices of refraction", PBD_CACHE);
    } else {
        if (!g_pbd[slot]) {
            /* the process's table, not the renderer's that asked first */
            lu_mem_account *renderer = lu_mem_account_use(NULL);
            r = table_build(eta, &g_pbd[slot], err);
            lu_mem_account_use(renderer);
        }
        *out = g_pbd[slot];
    }
    pthread_mutex_unlock(&g_pbd_mu);
    return r;
}

double lu_bssrdf_pbd_r_end(const lu_bssrdf_pbd_table *t) { return t->r[t->n_r - 1]; }

double lu_bssrdf_pbd_eval(const lu_bssrdf_pbd_table *t, double rho, double r) {
    double wa[4], wb[4];
    if (r < t->r[1]) r = t->r[1];
    int a = cr_weights(t->rho, t->n_rho, fmin(fmax(rho, 0.0), 1.0), wa);
    int b = cr_weights(t->r, t->n_r, r, wb);
    if (a < -1 || b < -1) return 0.0;
    double sum = 0.0;
    for (int i = 0; i < 4; i++) {
        int ri = a + i;
        if (ri < 0 || ri >= t->n_rho || wa[i] == 0.0) continue;
        for (int k = 0; k < 4; k++) {
            int ck = b + k;
            if (ck < 0 || ck >= t->n_r || wb[k] == 0.0) continue;
            sum += wa[i] * wb[k] * t->profile[(size_t)ri * t->n_r + ck];
        }
    }
    return fmax(sum, 0.0) / (2.0 * M_PI * r);
}

double lu_bssrdf_pbd_total(const lu_bssrdf_pbd_table *t, double rho) {
    double w[4], sum = 0.0;
    int a = cr_weights(t->rho, t->n_rho, fmin(fmax(rho, 0.0), 1.0), w);
    if (a < -1) return 0.0;
    for (int i = 0; i < 4; i++)
        if (a + i >= 0 && a + i < t->n_rho) sum += w[i] * t->rho_eff[a + i];
    return sum;
}
