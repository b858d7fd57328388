/* Diffusion profile tables, splat radius and multi-layer stacking by FFT
 * (see bssrdf_profile.h). The Monte Carlo validator is profile_mc.c, photon
 * beam diffusion profile_pbd.c. Over 800 lines because every profile kind
 * fills the one table layout lu_bssrdf.h reads, and the stacking and
 * prefilter passes operate on that layout. */
#include "methods/bssrdf/bssrdf_profile.h"

#include <fftw3.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "core/quadrature.h"
#include "methods/bssrdf/lu_diffusion.h"
#include "methods/bssrdf/profile_pbd.h"
#include "kernels/lu_optics.h"

void lu_bssrdf_profile_desc_default(lu_bssrdf_profile_desc *d) {
    d->model = LU_BSSRDF_DIPOLE;
    d->table_size = 512;
    d->thickness_steps = 32;
    d->pairs = 10;
    d->epsilon = 0.01;
    d->d_min_mfp = 4.0;
    d->d_max_mfp = 64.0;
    d->fft_size = 256;
}

void lu_bssrdf_profile_destroy(lu_bssrdf_profile *p) {
    if (!p) return;
    lu_free(p->table);
    memset(p, 0, sizeof *p);
}

/* ---- radial functions of one channel ----------------------------------------- */

typedef struct radial_ctx {
    lu_bssrdf_model model;
    int ch;
    lu_k_diffusion k;
    float d;             /* multipole thickness */
    int pairs, transmit;
    float burley_a, burley_h;
    const lu_bssrdf_pbd_table *pbd;
} radial_ctx;

static double radial_eval(const void *vctx, double r) {
    const radial_ctx *c = vctx;
    float s = lu_v3_get(c->k.sigma_tr, c->ch), a = lu_v3_get(c->k.alpha_p, c->ch), l = lu_v3_get(c->k.l, c->ch);
    float zb0 = lu_v3_get(c->k.zb_top, c->ch), zbd = lu_v3_get(c->k.zb_bottom, c->ch);
    switch (c->model) {
    case LU_BSSRDF_DIPOLE: return lu_k_dipole1((float)r, s, a, l, zb0);
    case LU_BSSRDF_MULTIPOLE: return lu_k_multipole1((float)r, c->d, c->pairs, c->transmit, s, a, l, zb0, zbd);
    case LU_BSSRDF_BURLEY: return r > 0.0 ? lu_k_burley1((float)r, c->burley_a, c->burley_h) : 0.0;
    case LU_BSSRDF_PBD: return lu_bssrdf_pbd_eval(c->pbd, a, r / l) / ((double)l * l);
    }
    return 0.0;
}

/* One Simpson panel [2ih, 2ih + 2h] in t = ln r of 2 pi r^2 f(e^t). */
static double eps_panel(lu_bssrdf_radial_fn f, const void *ctx, double t0, double h, int i) {
    double ra = i ? exp(t0 + 2 * i * h) : exp(t0), rm = exp(t0 + (2 * i + 1) * h), rb = exp(t0 + (2 * i + 2) * h);
    double fa = 2.0 * M_PI * ra * ra * f(ctx, ra), fm = 2.0 * M_PI * rm * rm * f(ctx, rm);
    double fb = 2.0 * M_PI * rb * rb * f(ctx, rb);
    return h / 3.0 * (fa + 4.0 * fm + fb);
}

/* Simpson in t = ln r of 2 pi r^2 f(e^t); r_max is where what lies beyond
 * drops below eps times ref (ref <= 0: times the total). The crossing is
 * interpolated linearly within the Simpson panel. Two passes over the
 * panels (the total, then the crossing) rather than a stored running sum:
 * this runs inside prepare, where an allocation could fail. */
static double eps_radius_ref(lu_bssrdf_radial_fn f, const void *ctx, double r_lo, double r_hi, int n, double eps,
                             double ref, double *total) {
    if (n < 2) n = 2;
    if (n & 1) n++;
    double t0 = log(r_lo), t1 = log(r_hi), h = (t1 - t0) / n;
    double sum = 0.0;
    for (int i = 0; i < n / 2; i++) sum += eps_panel(f, ctx, t0, h, i);
    *total = sum;
    double target = sum - eps * (ref > 0.0 ? ref : sum);
    double cum = 0.0;
    for (int i = 0; i < n / 2; i++) {
        double next = cum + eps_panel(f, ctx, t0, h, i);
        if (next >= target) {
            double a = exp(t0 + 2 * i * h), b = exp(t0 + (2 * i + 2) * h);
            double w = next > cum ? (target - cum) / (next - cum) : 1.0;
            return a + (b - a) * fmin(fmax(w, 0.0), 1.0);
        }
        cum = next;
    }
    return r_hi;
}

double lu_bssrdf_eps_radius(lu_bssrdf_radial_fn f, const void *ctx, double r_lo, double r_hi, int n, double eps,
                            double *total) {
    return eps_radius_ref(f, ctx, r_lo, r_hi, n, eps, 0.0, total);
}

/* Integration range of a channel: from far inside the source depth to where
 * e^{-sigma_tr r} is negligible, or a power law has dropped by 1e-7. */
static void radial_range(float l, float s, double *r_lo, double *r_hi) {
    *r_lo = 1e-5 * l;
    double far_power = 1e7 * l;
    *r_hi = s > 0.0f ? fmin(far_power, 60.0 * l + 45.0 / s) : far_power;
}

/* ---- closed forms --------------------------------------------------------------- */

void lu_bssrdf_slab_totals(double sigma_sp, double sigma_a, double eta_top, double eta_bottom, double d, double *r_total,
                           double *t_total) {
    double st = sigma_sp + sigma_a, alpha = sigma_sp / st, l = 1.0 / st, D = l / 3.0;
    double s = sqrt(3.0 * sigma_a * st);
    double zb0 = 2.0 * lu_k_diffusion_a((float)eta_top) * D, zbd = 2.0 * lu_k_diffusion_a((float)eta_bottom) * D;
    if (!isfinite(d)) {
        *r_total = 0.5 * alpha * (exp(-s * l) + exp(-s * (l + 2.0 * zb0)));
        *t_total = 0.0;
        return;
    }
    /* The plane-integrated fluence solves Phi'' - s^2 Phi = -(alpha'/D) delta(z - l)
     * with Phi = 0 at the extrapolated faces; with x = z + zb0, L = d + zb0 + zbd,
     * x0 = l + zb0 the reflected flux D Phi'(zb0) and transmitted -D Phi'(zb0 + d)
     * are below (the multipole series is this Green's function by images). */
    double L = d + zb0 + zbd, x0 = l + zb0;
    if (s * L < 1e-6) { /* sigma_a -> 0: the linear Green's function */
        *r_total = alpha * (L - x0) / L;
        *t_total = alpha * x0 / L;
        return;
    }
    /* Ratios of sinh written with exponentials so large s L cannot overflow. */
    double e2L = exp(-2.0 * s * L);
    double rr = cosh(s * zb0) * exp(-s * x0) * (1.0 - exp(-2.0 * s * (L - x0))) / (1.0 - e2L);
    double tt = cosh(s * zbd) * exp(-s * (L - x0)) * (1.0 - exp(-2.0 * s * x0)) / (1.0 - e2L);
    *r_total = alpha * rr;
    *t_total = alpha * tt;
}

double lu_bssrdf_invert_albedo(double albedo, double eta) {
    double lo = 0.0, hi = 1.0;
    for (int i = 0; i < 64; i++) {
        double mid = 0.5 * (lo + hi), r, t;
        lu_bssrdf_slab_totals(mid, 1.0 - mid, eta, eta, INFINITY, &r, &t);
        if (r < albedo) lo = mid;
        else hi = mid;
    }
    return 0.5 * (lo + hi);
}

/* ---- table helpers ------------------------------------------------------------------ */

/* Entry i of an n-entry table sits at r = r_max (i / (n - 1))^2: the
 * square-root spacing puts most entries where the profile is steep (its
 * peak is about one mean free path wide, r_max often hundreds). */
static double table_r(int i, int n, double r_max) {
    double x = (double)i / (n - 1);
    return r_max * x * x;
}

/* Integral of 2 pi r f(r) over [0, r_max] for f linear in the table
 * coordinate between entries (how the renderer interpolates): Gauss-Legendre
 * with 3 nodes per segment, exact for the degree-5 integrand. */
static double table_total(const float *t, int n, double r_max, int ch) {
    static const double gx[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
    static const double gw[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
    double sum = 0.0, hx = 1.0 / (n - 1);
    for (int i = 0; i + 1 < n; i++) {
        for (int q = 0; q < 3; q++) {
            double w = 0.5 * (1.0 + gx[q]);        /* position within the segment */
            double x = (i + w) * hx;               /* table coordinate in [0, 1] */
            double r = r_max * x * x, drdx = 2.0 * r_max * x;
            double f = t[3 * i + ch] * (1.0 - w) + t[3 * (i + 1) + ch] * w;
            sum += 0.5 * hx * gw[q] * r * f * drdx;
        }
    }
    return 2.0 * M_PI * sum;
}

static float table_lerp(const float *t, int n, float r_max, float r, int ch) {
    if (!(r < r_max) || r < 0.0f) return 0.0f;
    float x = sqrtf(r / r_max) * (float)(n - 1);
    int i = (int)x;
    if (i >= n - 1) return t[3 * (n - 1) + ch];
    float w = x - (float)i;
    return t[3 * i + ch] * (1.0f - w) + t[3 * (i + 1) + ch] * w;
}

lu_vec3 lu_bssrdf_profile_eval(const lu_bssrdf_profile *p, float r, float d, int transmit) {
    float out[3];
    if (p->kind == 0) {
        for (int c = 0; c < 3; c++) out[c] = transmit ? 0.0f : table_lerp(p->table, p->nr, p->r_max, r, c);
        return lu_v3(out[0], out[1], out[2]);
    }
    float y = p->nd > 1 ? logf(fmaxf(d, p->d_lo) / p->d_lo) / logf(p->d_hi / p->d_lo) * (float)(p->nd - 1) : 0.0f;
    y = fminf(fmaxf(y, 0.0f), (float)(p->nd - 1));
    int j = (int)y;
    if (j >= p->nd - 1) j = p->nd > 1 ? p->nd - 2 : 0;
    float w = p->nd > 1 ? y - (float)j : 0.0f;
    const float *block = p->table + (size_t)(transmit ? 3 * p->nr * p->nd : 0);
    float rm = transmit ? p->r_max_t : p->r_max;
    if (transmit && d > p->d_t_cut) return lu_v3s(0.0f);
    for (int c = 0; c < 3; c++) {
        float a = table_lerp(block + (size_t)3 * p->nr * j, p->nr, rm, r, c);
        float b = p->nd > 1 ? table_lerp(block + (size_t)3 * p->nr * (j + 1), p->nr, rm, r, c) : a;
        out[c] = a * (1.0f - w) + b * w;
        if (transmit) out[c] *= expf(-fminf(p->t_decay[c] * d, LU_BSSRDF_DECAY_CAP));
    }
    return lu_v3(out[0], out[1], out[2]);
}

static float row_thickness(const lu_bssrdf_profile *p, int j) {
    return p->nd > 1 ? p->d_lo * powf(p->d_hi / p->d_lo, (float)j / (float)(p->nd - 1)) : p->d_lo;
}

/* ---- single layer --------------------------------------------------------------------- */

static lu_k_diffusion layer_diffusion(const lu_bssrdf_layer *layers, int count, int i) {
    float above = i == 0 ? 1.0f : layers[i - 1].eta, below = i + 1 < count ? layers[i + 1].eta : 1.0f;
    return lu_k_diffusion_make(layers[i].sigma_sp, layers[i].sigma_a, layers[i].eta / above, layers[i].eta / below);
}

static lu_result build_1d(const lu_bssrdf_layer *layer, const lu_bssrdf_profile_desc *desc, lu_bssrdf_profile *p,
                          lu_error *err) {
    radial_ctx ctx = {0};
    ctx.model = desc->model;
    ctx.k = layer_diffusion(layer, 1, 0);
    if (desc->model == LU_BSSRDF_PBD) {
        lu_result r = lu_bssrdf_pbd_table_get(layer->eta, &ctx.pbd, err);
        if (r != LU_OK) return r;
    }
    double r_max = 0.0;
    float burley_h[3], burley_a[3];
    for (int c = 0; c < 3; c++) {
        float s = lu_v3_get(ctx.k.sigma_tr, c), l = lu_v3_get(ctx.k.l, c);
        float a = lu_v3_get(ctx.k.alpha_p, c), zb = lu_v3_get(ctx.k.zb_top, c);
        double r_lo, r_hi;
        radial_range(l, s, &r_lo, &r_hi);
        ctx.ch = c;
        if (desc->model == LU_BSSRDF_BURLEY) {
            /* Matched to the dipole's total (the same albedo, and so the same
             * inversion of authored albedos, for every profile). */
            burley_a[c] = lu_k_dipole_total1(s, a, l, zb);
            burley_h[c] = lu_k_burley_h(burley_a[c], l);
            ctx.burley_a = burley_a[c];
            ctx.burley_h = burley_h[c];
            r_hi = 60.0 * burley_h[c];
            p->total_closed[c] = burley_a[c];
        } else if (desc->model == LU_BSSRDF_PBD) {
            p->total_closed[c] = lu_bssrdf_pbd_total(ctx.pbd, a);  /* the table's own integral */
            r_hi = fmin(r_hi, lu_bssrdf_pbd_r_end(ctx.pbd) * l);
        } else {
            p->total_closed[c] = lu_k_dipole_total1(s, a, l, zb);
        }
        double total;
        double rc = lu_bssrdf_eps_radius(radial_eval, &ctx, r_lo, r_hi, 4096, desc->epsilon, &total);
        p->total_numeric[c] = total;
        if (rc > r_max) r_max = rc;
    }
    p->kind = 0;
    p->nr = desc->table_size;
    p->nd = 1;
    p->r_max = (float)r_max;
    p->table = lu_malloc((size_t)3 * p->nr * sizeof *p->table);
    if (!p->table) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the profile table");
    for (int i = 0; i < p->nr; i++) {
        for (int c = 0; c < 3; c++) {
            ctx.ch = c;
            ctx.burley_a = desc->model == LU_BSSRDF_BURLEY ? burley_a[c] : 0.0f;
            ctx.burley_h = desc->model == LU_BSSRDF_BURLEY ? burley_h[c] : 1.0f;
            /* Burley and pbd are singular at 0: the first entry holds the value
             * at a third of the first step (where 2 pi r f matches its segment mean). */
            bool singular = desc->model == LU_BSSRDF_BURLEY || desc->model == LU_BSSRDF_PBD;
            double r = i == 0 && singular ? table_r(1, p->nr, r_max) / 3.0 : table_r(i, p->nr, r_max);
            p->table[3 * i + c] = (float)radial_eval(&ctx, r);
        }
    }
    for (int c = 0; c < 3; c++) p->total_table[c] = table_total(p->table, p->nr, r_max, c);
    return LU_OK;
}

static lu_result build_multipole(const lu_bssrdf_layer *layer, const lu_bssrdf_profile_desc *desc,
                                 lu_bssrdf_profile *p, lu_error *err) {
    radial_ctx ctx = {0};
    ctx.model = LU_BSSRDF_MULTIPOLE;
    ctx.k = layer_diffusion(layer, 1, 0);
    ctx.pairs = desc->pairs;
    p->kind = 1;
    p->nr = desc->table_size;
    p->nd = desc->thickness_steps;
    for (int c = 0; c < 3; c++) p->t_decay[c] = lu_v3_get(ctx.k.sigma_tr, c);
    p->d_lo = (float)(desc->d_min_mfp * p->mfp);
    p->d_hi = (float)(desc->d_max_mfp * p->mfp);
    /* R and T get their own radius: R's covers 1 - eps of each row's
     * reflected power, T's 1 - eps of each row's transmitted power wherever
     * that is at least LU_BSSRDF_T_FLOOR of the reflected (a back-lit pixel
     * sees nothing else), and T is dropped beyond the thickest such row. */
    double r_max = 0.0, r_max_t = 0.0;
    p->d_t_cut = 0.0f;
    for (int j = 0; j < p->nd; j++) {
        ctx.d = row_thickness(p, j);
        for (int c = 0; c < 3; c++) {
            ctx.ch = c;
            float s = lu_v3_get(ctx.k.sigma_tr, c), l = lu_v3_get(ctx.k.l, c);
            double r_lo, r_hi, rt, tt, rc, tc;
            radial_range(l, s, &r_lo, &r_hi);
            lu_bssrdf_slab_totals(lu_v3_get(layer->sigma_sp, c), lu_v3_get(layer->sigma_a, c), layer->eta, layer->eta,
                                  ctx.d, &rc, &tc);
            ctx.transmit = 0;
            r_max = fmax(r_max, eps_radius_ref(radial_eval, &ctx, r_lo, r_hi, 1024, desc->epsilon, 0.0, &rt));
            if (tc >= LU_BSSRDF_T_FLOOR * rc) {
                ctx.transmit = 1;
                r_max_t = fmax(r_max_t, eps_radius_ref(radial_eval, &ctx, r_lo, r_hi, 1024, desc->epsilon, 0.0, &tt));
                p->d_t_cut = fmaxf(p->d_t_cut, ctx.d);
            }
            if (j == p->nd - 1) {
                p->total_numeric[c] = rt;
                p->total_closed[c] = rc;
            }
        }
    }
    p->r_max = (float)r_max;
    p->r_max_t = (float)(r_max_t > 0.0 ? r_max_t : r_max);
    p->table = lu_malloc((size_t)6 * p->nr * p->nd * sizeof *p->table);
    if (!p->table) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the profile tables");
    for (int t = 0; t < 2; t++) {
        ctx.transmit = t;
        for (int j = 0; j < p->nd; j++) {
            ctx.d = row_thickness(p, j);
            float *row = p->table + (size_t)3 * p->nr * (t * p->nd + j);
            float f[3] = {1.0f, 1.0f, 1.0f};
            for (int c = 0; t && c < 3; c++) f[c] = expf(fminf(p->t_decay[c] * ctx.d, LU_BSSRDF_DECAY_CAP));
            for (int i = 0; i < p->nr; i++) {
                vec3 v = lu_k_multipole(ctx.k, (float)table_r(i, p->nr, t ? p->r_max_t : r_max), ctx.d, ctx.pairs, t);
                row[3 * i] = v.x * f[0];
                row[3 * i + 1] = v.y * f[1];
                row[3 * i + 2] = v.z * f[2];
            }
        }
    }
    const float *thick_row = p->table + (size_t)3 * p->nr * (p->nd - 1);
    for (int c = 0; c < 3; c++) p->total_table[c] = table_total(thick_row, p->nr, r_max, c);
    return LU_OK;
}

/* ---- frequency-domain stacking ----------------------------------------------------------- */

struct lu_bssrdf_spectra {
    int g;
    double h;
    /* reflectance from above and from below, transmittance downwards and
     * upwards: the diffusion model is not reciprocal when the two faces
     * have different boundary conditions. g x (g/2 + 1) each. */
    fftwf_complex *c[4];
};
enum { S_RTOP, S_RBOTTOM, S_TDOWN, S_TUP };

void lu_bssrdf_spectra_destroy(lu_bssrdf_spectra *s) {
    if (!s) return;
    for (int i = 0; i < 4; i++) fftwf_free(s->c[i]);
    lu_free(s);
}

static lu_result spectra_alloc(int g, double h, lu_bssrdf_spectra **out, lu_error *err) {
    *out = NULL;
    if (g < 8 || g > 8192 || (g & 1)) return lu_fail(err, LU_ERR_RANGE, "bssrdf: FFT size %d must be even, in [8, 8192]", g);
    lu_bssrdf_spectra *s = lu_calloc(1, sizeof *s);
    if (!s) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    s->g = g;
    s->h = h;
    size_t n = (size_t)g * (size_t)(g / 2 + 1);
    bool ok = true;
    for (int i = 0; i < 4; i++) ok = (s->c[i] = fftwf_malloc(n * sizeof(fftwf_complex))) != NULL && ok;
    if (!ok) {
        lu_bssrdf_spectra_destroy(s);
        return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for %dx%d spectra", g, g);
    }
    *out = s;
    return LU_OK;
}

/* The integral of f(|x|) over the square [-a, a]^2 from radial samples
 * r_k = k dr: Simpson over r of 2 pi r f(r) times the fraction of the circle
 * of radius r inside the square (1 up to a, 1 - (4/pi) acos(a/r) beyond). */
static double square_integral(const float *f, int n, double dr, double a) {
    double sum = 0.0;
    int m = n - 1;
    if (m & 1) m--;
    for (int i = 0; i <= m; i++) {
        double r = i * dr, w = (i == 0 || i == m) ? 1.0 : ((i & 1) ? 4.0 : 2.0);
        double frac = r <= a ? 1.0 : (r >= a * M_SQRT2 ? 0.0 : 1.0 - 4.0 / M_PI * acos(a / r));
        sum += w * 2.0 * M_PI * r * f[i] * frac;
    }
    return sum * dr / 3.0;
}

static float radial_lerp(const float *f, int n, double dr, double r) {
    double x = r / dr;
    int i = (int)x;
    if (i >= n - 1) return 0.0f;
    double w = x - i;
    return (float)(f[i] * (1.0 - w) + f[i + 1] * w);
}

/* h^2 DFT of the radially symmetric field f(|x|) on the grid (origin at
 * texel 0, wrapping). Each texel holds f averaged over its cell (8 x 8
 * points near the origin, where the profile's peak is about as wide as a
 * cell, 4 x 4 a little further, the centre beyond), so the sum times h^2 is
 * the integral and the peak's power is not smeared over the whole field; a
 * last rescale to the Simpson integral over the square removes what is left. */
static lu_result radial_spectrum(const float *f, int n, double dr, int g, double h, float *work, fftwf_complex *out,
                                 lu_error *err) {
    double sum = 0.0;
    for (int j = 0; j < g; j++) {
        double y = (j <= g / 2 ? j : j - g) * h;
        for (int i = 0; i < g; i++) {
            double x = (i <= g / 2 ? i : i - g) * h;
            double rho = sqrt(x * x + y * y);
            int ss = rho < 3.0 * h ? 8 : (rho < 8.0 * h ? 4 : 1);
            double acc = 0.0;
            for (int b = 0; b < ss; b++)
                for (int a = 0; a < ss; a++) {
                    double px = x + h * ((a + 0.5) / ss - 0.5), py = y + h * ((b + 0.5) / ss - 0.5);
                    acc += radial_lerp(f, n, dr, sqrt(px * px + py * py));
                }
            float v = (float)(acc / (ss * ss));
            work[(size_t)j * g + i] = v;
            sum += v;
        }
    }
    double exact = square_integral(f, n, dr, 0.5 * g * h);
    double scale = sum > 0.0 ? exact / sum : h * h;
    for (size_t k = 0; k < (size_t)g * g; k++) work[k] = (float)(work[k] * scale);
    fftwf_plan plan = fftwf_plan_dft_r2c_2d(g, g, work, out, FFTW_ESTIMATE);
    if (!plan) return lu_fail(err, LU_ERR_BACKEND, "bssrdf: FFTW could not plan a %dx%d transform", g, g);
    fftwf_execute(plan);
    fftwf_destroy_plan(plan);
    return LU_OK;
}

lu_result lu_bssrdf_spectra_from_radial(const float *r_top, const float *r_bottom, const float *t_down,
                                        const float *t_up, int n, double dr, int fft_size, double h,
                                        lu_bssrdf_spectra **out, lu_error *err) {
    lu_result r = spectra_alloc(fft_size, h, out, err);
    if (r != LU_OK) return r;
    lu_bssrdf_spectra *s = *out;
    float *work = fftwf_malloc((size_t)fft_size * fft_size * sizeof(float));
    if (!work) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    const float *src[4] = {r_top, r_bottom, t_down, t_up};
    size_t nc = (size_t)fft_size * (size_t)(fft_size / 2 + 1);
    for (int i = 0; i < 4 && r == LU_OK; i++) {
        if (src[i]) r = radial_spectrum(src[i], n, dr, fft_size, h, work, s->c[i], err);
        else memset(s->c[i], 0, nc * sizeof(fftwf_complex)); /* not needed (a bottom layer's upward terms) */
    }
    fftwf_free(work);
    if (r != LU_OK) {
        lu_bssrdf_spectra_destroy(s);
        *out = NULL;
    }
    return r;
}

lu_result lu_bssrdf_spectra_identity(int fft_size, double h, lu_bssrdf_spectra **out, lu_error *err) {
    lu_result r = spectra_alloc(fft_size, h, out, err);
    if (r != LU_OK) return r;
    size_t n = (size_t)fft_size * (size_t)(fft_size / 2 + 1);
    for (int i = 0; i < 4; i++)
        for (size_t k = 0; k < n; k++) {
            (*out)->c[i][k][0] = i >= S_TDOWN ? 1.0f : 0.0f;
            (*out)->c[i][k][1] = 0.0f;
        }
    return LU_OK;
}

typedef struct cplx {
    double re, im;
} cplx;
static cplx cx(const fftwf_complex v) { return (cplx){v[0], v[1]}; }
static cplx cmul(cplx a, cplx b) { return (cplx){a.re * b.re - a.im * b.im, a.re * b.im + a.im * b.re}; }
static cplx cadd(cplx a, cplx b) { return (cplx){a.re + b.re, a.im + b.im}; }
/* 1 / (1 - a b): the geometric series of inter-reflections between two faces */
static cplx cseries(cplx a, cplx b) {
    cplx p = cmul(a, b);
    double re = 1.0 - p.re, im = -p.im, den = re * re + im * im;
    return (cplx){re / den, -im / den};
}
static void cstore(fftwf_complex out, cplx v) {
    out[0] = (float)v.re;
    out[1] = (float)v.im;
}

lu_result lu_bssrdf_spectra_stack(const lu_bssrdf_spectra *top, const lu_bssrdf_spectra *bottom,
                                  lu_bssrdf_spectra **out, lu_error *err) {
    if (top->g != bottom->g || top->h != bottom->h)
        return lu_fail(err, LU_ERR_INVALID_ARG, "bssrdf: stacking spectra of different grids");
    lu_result r = spectra_alloc(top->g, top->h, out, err);
    if (r != LU_OK) return r;
    size_t n = (size_t)top->g * (size_t)(top->g / 2 + 1);
    for (size_t k = 0; k < n; k++) {
        cplx r1t = cx(top->c[S_RTOP][k]), r1b = cx(top->c[S_RBOTTOM][k]);
        cplx t1d = cx(top->c[S_TDOWN][k]), t1u = cx(top->c[S_TUP][k]);
        cplx r2t = cx(bottom->c[S_RTOP][k]), r2b = cx(bottom->c[S_RBOTTOM][k]);
        cplx t2d = cx(bottom->c[S_TDOWN][k]), t2u = cx(bottom->c[S_TUP][k]);
        cplx q = cseries(r2t, r1b);   /* bounces between the layers' facing sides */
        /* Thesis Eq. 3.10 and 3.12 with each face's own terms:
         * T12 = T1 T2 q, R12 = R1 + T1 R2 T1' q (and the mirrored pair). */
        cstore((*out)->c[S_TDOWN][k], cmul(cmul(t1d, t2d), q));
        cstore((*out)->c[S_RTOP][k], cadd(r1t, cmul(cmul(cmul(t1d, r2t), t1u), q)));
        cstore((*out)->c[S_TUP][k], cmul(cmul(t2u, t1u), q));
        cstore((*out)->c[S_RBOTTOM][k], cadd(r2b, cmul(cmul(cmul(t2u, r1b), t2d), q)));
    }
    return LU_OK;
}

static lu_result inverse_line(const fftwf_complex *spec, int g, double h, float *line, int n, lu_error *err) {
    size_t nc = (size_t)g * (size_t)(g / 2 + 1);
    fftwf_complex *copy = fftwf_malloc(nc * sizeof *copy);
    float *space = fftwf_malloc((size_t)g * g * sizeof *space);
    lu_result r = LU_OK;
    if (!copy || !space) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");
    if (r == LU_OK) {
        memcpy(copy, spec, nc * sizeof *copy);
        fftwf_plan plan = fftwf_plan_dft_c2r_2d(g, g, copy, space, FFTW_ESTIMATE);
        if (!plan) {
            r = lu_fail(err, LU_ERR_BACKEND, "bssrdf: FFTW could not plan a %dx%d transform", g, g);
        } else {
            fftwf_execute(plan);
            fftwf_destroy_plan(plan);
            double norm = 1.0 / ((double)g * g * h * h);
            for (int k = 0; k < n; k++) line[k] = (float)(space[k] * norm);
        }
    }
    fftwf_free(copy);
    fftwf_free(space);
    return r;
}

lu_result lu_bssrdf_spectra_radial(const lu_bssrdf_spectra *s, float *r_top, float *t, int n, lu_error *err) {
    if (n > s->g / 2 + 1) return lu_fail(err, LU_ERR_RANGE, "bssrdf: %d radial samples exceed half the FFT grid", n);
    lu_result r = LU_OK;
    if (r_top) r = inverse_line(s->c[S_RTOP], s->g, s->h, r_top, n, err);
    if (r == LU_OK && t) r = inverse_line(s->c[S_TDOWN], s->g, s->h, t, n, err);
    return r;
}

double lu_bssrdf_spectra_dc(const lu_bssrdf_spectra *s, int transmit) {
    return s->c[transmit ? S_TDOWN : S_RTOP][0][0];
}

/* ---- multi-layer tables ---------------------------------------------------------------------- */

/* Radial multipole profile of layer `i` of the stack, one channel, at r_k = k dr. */
static void sample_radial(lu_k_diffusion k, int ch, float d, int pairs, int transmit, int n, double dr, float *out) {
    radial_ctx ctx = {0};
    ctx.model = LU_BSSRDF_MULTIPOLE;
    ctx.k = k;
    ctx.ch = ch;
    ctx.d = d;
    ctx.pairs = pairs;
    ctx.transmit = transmit;
    for (int i = 0; i < n; i++) out[i] = (float)radial_eval(&ctx, i * dr);
}

/* The same layer seen from below: its faces swapped. */
static lu_k_diffusion flipped(lu_k_diffusion k) {
    vec3 t = k.zb_top;
    k.zb_top = k.zb_bottom;
    k.zb_bottom = t;
    return k;
}

static lu_result build_layers(const lu_bssrdf_layer *layers, int count, const lu_bssrdf_profile_desc *desc,
                              lu_bssrdf_profile *p, lu_error *err) {
    int base = count - 1;
    double coat = 0.0;
    for (int i = 0; i < base; i++) coat += layers[i].thickness;
    p->kind = 1;
    p->nr = desc->table_size;
    p->nd = desc->thickness_steps;
    p->d_lo = (float)(coat + desc->d_min_mfp * p->mfp);
    p->d_hi = (float)(coat + desc->d_max_mfp * p->mfp);
    lu_k_diffusion kd[LU_MAX_COATINGS + 1];
    for (int i = 0; i < count; i++) kd[i] = layer_diffusion(layers, count, i);
    for (int c = 0; c < 3; c++) p->t_decay[c] = lu_v3_get(kd[base].sigma_tr, c);

    /* The grid must hold every layer's reach and then the spread of their
     * inter-reflections: twice the widest single-layer radius, so the
     * circular convolution's wrap-around lands where the profiles are ~0. */
    double reach = 0.0;
    for (int i = 0; i < count; i++) {
        for (int c = 0; c < 3; c++) {
            radial_ctx ctx = {0};
            ctx.model = LU_BSSRDF_MULTIPOLE;
            ctx.k = kd[i];
            ctx.ch = c;
            ctx.pairs = desc->pairs;
            ctx.d = i == base ? p->d_hi - (float)coat : layers[i].thickness;
            double r_lo, r_hi, tot;
            radial_range(lu_v3_get(kd[i].l, c), lu_v3_get(kd[i].sigma_tr, c), &r_lo, &r_hi);
            reach = fmax(reach, eps_radius_ref(radial_eval, &ctx, r_lo, r_hi, 1024, desc->epsilon, 0.0, &tot));
        }
    }
    int g = desc->fft_size;
    double r_ext = 2.0 * reach, h = r_ext / (g / 2);
    int nrad = 2 * g;                   /* radial samples over [0, 1.5 r_ext] (grid corners are at sqrt 2 r_ext) */
    double drad = 1.5 * r_ext / (nrad - 1);
    int nline = g / 2 + 1;              /* extracted line: r_k = k h, k < nline */

    float *rad_r = lu_malloc((size_t)nrad * sizeof(float)), *rad_rb = lu_malloc((size_t)nrad * sizeof(float));
    float *rad_t = lu_malloc((size_t)nrad * sizeof(float)), *rad_tu = lu_malloc((size_t)nrad * sizeof(float));
    float *lines = lu_malloc((size_t)2 * 3 * p->nd * nline * sizeof(float)); /* [t][c][j][k] */
    double *dc = lu_malloc((size_t)2 * 3 * p->nd * sizeof(double));            /* [t][c][j]: exact totals */
    lu_bssrdf_spectra *coats[3][LU_MAX_COATINGS] = {{0}};
    lu_result r = LU_OK;
    if (!rad_r || !rad_rb || !rad_t || !rad_tu || !lines || !dc) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory");

    for (int c = 0; c < 3 && r == LU_OK; c++) {
        for (int i = 0; i < base && r == LU_OK; i++) {
            sample_radial(kd[i], c, layers[i].thickness, desc->pairs, 0, nrad, drad, rad_r);
            sample_radial(flipped(kd[i]), c, layers[i].thickness, desc->pairs, 0, nrad, drad, rad_rb);
            sample_radial(kd[i], c, layers[i].thickness, desc->pairs, 1, nrad, drad, rad_t);
            sample_radial(flipped(kd[i]), c, layers[i].thickness, desc->pairs, 1, nrad, drad, rad_tu);
            r = lu_bssrdf_spectra_from_radial(rad_r, rad_rb, rad_t, rad_tu, nrad, drad, g, h, &coats[c][i], err);
        }
    }
    for (int j = 0; j < p->nd && r == LU_OK; j++) {
        float d_base = row_thickness(p, j) - (float)coat;
        for (int c = 0; c < 3 && r == LU_OK; c++) {
            lu_bssrdf_spectra *acc = NULL;
            /* Nothing lies below the base: its upward terms never enter the stack's
             * R from above or T downwards. */
            sample_radial(kd[base], c, d_base, desc->pairs, 0, nrad, drad, rad_r);
            sample_radial(kd[base], c, d_base, desc->pairs, 1, nrad, drad, rad_t);
            r = lu_bssrdf_spectra_from_radial(rad_r, NULL, rad_t, NULL, nrad, drad, g, h, &acc, err);
            for (int i = base - 1; i >= 0 && r == LU_OK; i--) {
                lu_bssrdf_spectra *next = NULL;
                r = lu_bssrdf_spectra_stack(coats[c][i], acc, &next, err);
                lu_bssrdf_spectra_destroy(acc);
                acc = next;
            }
            if (r == LU_OK) {
                r = lu_bssrdf_spectra_radial(acc, lines + (size_t)((0 * 3 + c) * p->nd + j) * nline,
                                             lines + (size_t)((1 * 3 + c) * p->nd + j) * nline, nline, err);
                dc[(0 * 3 + c) * p->nd + j] = lu_bssrdf_spectra_dc(acc, 0);
                dc[(1 * 3 + c) * p->nd + j] = lu_bssrdf_spectra_dc(acc, 1);
            }
            lu_bssrdf_spectra_destroy(acc);
        }
    }
    for (int c = 0; c < 3; c++)
        for (int i = 0; i < base; i++) lu_bssrdf_spectra_destroy(coats[c][i]);

    if (r == LU_OK) {
        /* Radii from the stacked profiles as for one layer (2 pi r weighted,
         * trapezoid on the line): R per row, T per row where it matters. */
        double r_max = 0.0, r_max_t = 0.0;
        p->d_t_cut = 0.0f;
        for (int t = 0; t < 2; t++)
            for (int c = 0; c < 3; c++)
                for (int j = 0; j < p->nd; j++) {
                    const float *ln = lines + (size_t)((t * 3 + c) * p->nd + j) * nline;
                    const float *rl = lines + (size_t)((0 * 3 + c) * p->nd + j) * nline;
                    double tot = 0.0, ref = 0.0;
                    for (int k = 0; k + 1 < nline; k++) {
                        tot += 0.5 * h * 2.0 * M_PI * (k * h * fmax(ln[k], 0.0) + (k + 1) * h * fmax(ln[k + 1], 0.0));
                        ref += 0.5 * h * 2.0 * M_PI * (k * h * fmax(rl[k], 0.0) + (k + 1) * h * fmax(rl[k + 1], 0.0));
                    }
                    if (t == 0 && j == p->nd - 1) p->total_numeric[c] = tot;
                    if (tot <= 0.0 || (t == 1 && tot < LU_BSSRDF_T_FLOOR * ref)) continue;
                    double cum = 0.0;
                    for (int k = 0; k + 1 < nline; k++) {
                        cum += 0.5 * h * 2.0 * M_PI * (k * h * fmax(ln[k], 0.0) + (k + 1) * h * fmax(ln[k + 1], 0.0));
                        if (cum >= (1.0 - desc->epsilon) * tot) {
                            if (t) r_max_t = fmax(r_max_t, (k + 1) * h);
                            else r_max = fmax(r_max, (k + 1) * h);
                            break;
                        }
                    }
                    if (t) p->d_t_cut = fmaxf(p->d_t_cut, row_thickness(p, j));
                }
        if (r_max <= 0.0) r_max = reach;
        p->r_max = (float)r_max;
        p->r_max_t = (float)(r_max_t > 0.0 ? r_max_t : r_max);
        p->table = lu_malloc((size_t)6 * p->nr * p->nd * sizeof *p->table);
        if (!p->table) r = lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for the profile tables");
    }
    if (r == LU_OK) {
        for (int t = 0; t < 2; t++)
            for (int j = 0; j < p->nd; j++)
                for (int c = 0; c < 3; c++) {
                    const float *ln = lines + (size_t)((t * 3 + c) * p->nd + j) * nline;
                    float *row = p->table + (size_t)3 * p->nr * (t * p->nd + j);
                    float f = t ? expf(fminf(p->t_decay[c] * row_thickness(p, j), LU_BSSRDF_DECAY_CAP)) : 1.0f;
                    /* FFT round-off leaves tiny negative ripples where the profile is ~0. */
                    float rm = t ? p->r_max_t : p->r_max;
                    for (int i = 0; i < p->nr; i++)
                        row[3 * i + c] = fmaxf(radial_lerp(ln, nline, h, table_r(i, p->nr, rm)), 0.0f);
                    /* The grid resolves a coat's peak only to a cell; the spectrum's
                     * DC term is the stack's exact total, so the row (plus what
                     * lies beyond its radius) is scaled to carry exactly that. */
                    double tail = 0.0;
                    for (int k = 0; k + 1 < nline; k++) {
                        double r0 = k * h, r1 = (k + 1) * h;
                        if (r1 <= rm) continue;
                        r0 = fmax(r0, rm);
                        tail += (r1 - r0) * M_PI * (r0 * fmax(radial_lerp(ln, nline, h, r0), 0.0) +
                                                    r1 * fmax(radial_lerp(ln, nline, h, r1), 0.0));
                    }
                    double have = table_total(row, p->nr, rm, c) + tail, want = dc[(t * 3 + c) * p->nd + j];
                    float scale = have > 0.0 && want > 0.0 ? (float)(want / have) : 1.0f;
                    for (int i = 0; i < p->nr; i++) row[3 * i + c] *= scale * f;
                }
        const float *thick_row = p->table + (size_t)3 * p->nr * (p->nd - 1);
        for (int c = 0; c < 3; c++) {
            p->total_table[c] = table_total(thick_row, p->nr, p->r_max, c);
            p->total_closed[c] = NAN;  /* no closed form for a stack */
        }
    }
    lu_free(rad_r);
    lu_free(rad_rb);
    lu_free(rad_t);
    lu_free(rad_tu);
    lu_free(lines);
    lu_free(dc);
    return r;
}

size_t lu_bssrdf_profile_level_entries(const lu_bssrdf_profile *p) {
    return (size_t)p->nr * p->nd * (p->kind ? 2 : 1);
}

enum { PREFILTER_NG = 24 };

typedef struct prefilter_job {
    lu_bssrdf_profile *p;
    int levels;
    float rho0;
    size_t level_entries;
    double gx[PREFILTER_NG], gw[PREFILTER_NG];   /* Gauss-Legendre on [-1, 1] */
    atomic_bool nomem;                            /* a worker's scratch could not be allocated */
} prefilter_job;

/* One row (of nr entries) of every level; rows are independent. With the
 * entry point at the origin and the shaded point at distance r, the disc of
 * radius rho around the origin seen from the shaded point is, for each
 * distance t from it, an arc of angle 2 alpha(t):
 *   P_rho(r) = 1/(pi rho^2) int P(t) 2 t alpha(t) dt,
 *   alpha = pi for t <= rho - r (whole circles: the cumulative power C),
 *   alpha = acos((t^2 + r^2 - rho^2) / (2 t r)) for |rho - r| < t < rho + r. */
static void prefilter_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    enum { NG = PREFILTER_NG };
    prefilter_job *j = ctx;
    lu_bssrdf_profile *p = j->p;
    int rows_per_level = (int)(j->level_entries / p->nr);
    double *cum = lu_malloc((size_t)3 * p->nr * sizeof *cum);
    if (!cum) {
        atomic_store(&j->nomem, true);
        return;
    }
    for (int64_t row = begin; row < end; row++) {
        const float *src = p->table + (size_t)row * 3 * p->nr;
        bool transmit = p->kind && row >= p->nd;
        float rm = transmit ? p->r_max_t : p->r_max;
        /* C(r_i) = int_0^{r_i} 2 pi t P(t) dt, as table_total integrates. */
        double hx = 1.0 / (p->nr - 1);
        for (int c = 0; c < 3; c++) cum[c] = 0.0;
        for (int i = 0; i + 1 < p->nr; i++) {
            static const double g3x[3] = {-0.7745966692414834, 0.0, 0.7745966692414834};
            static const double g3w[3] = {5.0 / 9.0, 8.0 / 9.0, 5.0 / 9.0};
            for (int c = 0; c < 3; c++) {
                double add = 0.0;
                for (int q = 0; q < 3; q++) {
                    double w = 0.5 * (1.0 + g3x[q]), x = (i + w) * hx, r = rm * x * x;
                    double f = src[3 * i + c] * (1.0 - w) + src[3 * (i + 1) + c] * w;
                    add += 0.5 * hx * g3w[q] * r * f * 2.0 * rm * x;
                }
                cum[3 * (i + 1) + c] = cum[3 * i + c] + 2.0 * M_PI * add;
            }
        }
        for (int k = 1; k < j->levels; k++) {
            double rho = j->rho0 * pow(M_SQRT2, k - 1);
            float *dst = p->table + ((size_t)k * rows_per_level + (size_t)row) * 3 * p->nr;
            for (int i = 0; i < p->nr; i++) {
                double r = table_r(i, p->nr, rm), acc[3] = {0, 0, 0};
                if (r < rho) { /* whole circles out to rho - r */
                    double t = rho - r;
                    double x = t >= rm ? (double)(p->nr - 1) : sqrt(t / rm) * (p->nr - 1);
                    int a = (int)x;
                    if (a >= p->nr - 1) a = p->nr - 2;
                    double w = x - a;
                    for (int c = 0; c < 3; c++) acc[c] = cum[3 * a + c] * (1.0 - w) + cum[3 * (a + 1) + c] * w;
                }
                double t0 = fabs(rho - r), t1 = fmin(rho + r, (double)rm);
                if (r > 0.0 && t1 > t0) {
                    for (int q = 0; q < NG; q++) {
                        double t = 0.5 * (t0 + t1) + 0.5 * (t1 - t0) * j->gx[q];
                        double ca = (t * t + r * r - rho * rho) / (2.0 * t * r);
                        double alpha = acos(fmin(fmax(ca, -1.0), 1.0));
                        double wq = 0.5 * (t1 - t0) * j->gw[q] * 2.0 * t * alpha;
                        for (int c = 0; c < 3; c++) acc[c] += wq * table_lerp(src, p->nr, rm, (float)t, c);
                    }
                }
                for (int c = 0; c < 3; c++) dst[3 * i + c] = (float)(acc[c] / (M_PI * rho * rho));
            }
        }
    }
    lu_free(cum);
}

lu_result lu_bssrdf_profile_prefilter(lu_bssrdf_profile *p, int levels, float rho0, lu_error *err) {
    if (levels <= 1 || p->levels != 1) return LU_OK;
    if (!(rho0 > 0.0f)) return lu_fail(err, LU_ERR_RANGE, "bssrdf: prefilter radius must be > 0");
    size_t per = lu_bssrdf_profile_level_entries(p);
    float *t = lu_realloc(p->table, (size_t)levels * per * 3 * sizeof *t);
    if (!t) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory for %d profile levels", levels);
    p->table = t;
    p->levels = levels;
    p->rho0 = rho0;
    prefilter_job j = {p, levels, rho0, per, {0}, {0}, false};
    lu_gauss_legendre(PREFILTER_NG, j.gx, j.gw);
    lu_parallel_for((int64_t)(per / p->nr), 1, prefilter_rows, &j, NULL);
    if (atomic_load(&j.nomem)) return lu_fail(err, LU_ERR_NOMEM, "bssrdf: out of memory (profile prefilter)");
    return LU_OK;
}

lu_result lu_bssrdf_profile_build(const lu_bssrdf_layer *layers, int count, const lu_bssrdf_profile_desc *desc,
                                  lu_bssrdf_profile *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    if (count < 1 || count > LU_MAX_COATINGS + 1)
        return lu_fail(err, LU_ERR_RANGE, "bssrdf: %d layers (1 to %d supported)", count, LU_MAX_COATINGS + 1);
    if (desc->table_size < 4 || desc->thickness_steps < 2 || desc->epsilon <= 0.0 || desc->epsilon >= 1.0 ||
        !(desc->d_min_mfp > 0.0 && desc->d_max_mfp > desc->d_min_mfp))
        return lu_fail(err, LU_ERR_RANGE, "bssrdf: invalid profile settings");
    double mfp = 0.0;
    for (int i = 0; i < count; i++) {
        const lu_bssrdf_layer *L = &layers[i];
        for (int c = 0; c < 3; c++) {
            double sp = lu_v3_get(L->sigma_sp, c), sa = lu_v3_get(L->sigma_a, c);
            if (!(sp > 0.0) || !(sa >= 0.0) || !isfinite(sp) || !isfinite(sa))
                return lu_fail(err, LU_ERR_RANGE,
                               "bssrdf: layer %d needs sigma_s' > 0 and sigma_a >= 0 in every channel (got %g, %g)", i,
                               sp, sa);
            mfp = fmax(mfp, 1.0 / (sp + sa));
        }
        if (!(L->eta >= 1.0f && L->eta <= 4.0f)) return lu_fail(err, LU_ERR_RANGE, "bssrdf: layer %d eta %g", i, L->eta);
        if (i + 1 < count && !(L->thickness > 0.0f))
            return lu_fail(err, LU_ERR_RANGE, "bssrdf: coating %d needs a thickness > 0", i);
    }
    out->mfp = (float)mfp;
    out->levels = 1;
    lu_result r;
    if (count > 1) r = build_layers(layers, count, desc, out, err);
    else if (desc->model == LU_BSSRDF_MULTIPOLE) r = build_multipole(layers, desc, out, err);
    else r = build_1d(layers, desc, out, err);
    if (r != LU_OK) lu_bssrdf_profile_destroy(out);
    return r;
}

int lu_bssrdf_material_layers(const lu_material *m, lu_bssrdf_layer *layers, int max_layers) {
    int n = 0;
    for (int i = 0; i < m->coating_count && n < max_layers - 1; i++) {
        const lu_coating *c = &m->coatings[i];
        layers[n].sigma_sp = lu_v3_scale(c->sigma_s, 1.0f - c->g);
        layers[n].sigma_a = c->sigma_a;
        layers[n].eta = c->eta;
        layers[n].thickness = c->thickness;
        n++;
    }
    layers[n].sigma_sp = lu_v3_scale(m->sigma_s, 1.0f - m->g);
    layers[n].sigma_a = m->sigma_a;
    layers[n].eta = m->eta;
    layers[n].thickness = 0.0f;
    return n + 1;
}
