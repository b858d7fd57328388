/* The bssrdf method against numbers computed here, independently:
 *   - dipole: the tabulated profile against the test's own double-precision
 *     formula, and 2 pi r R_d integrated by Gauss-Legendre against the closed
 *     form (alpha'/2)(1 + e^{-4/3 A sqrt(3(1-a'))}) e^{-sqrt(3(1-a'))};
 *   - prefiltered levels keep the power and hold the disc's power at r = 0;
 *   - multipole: R and T integrated over the plane against the 1D diffusion
 *     Green's function of a slab with extrapolated boundaries (solved here in
 *     closed form), and R(r, d -> inf) against the dipole;
 *   - multi-layer: a layer stacked with the empty layer is the layer again,
 *     and a coated stack's totals follow Kubelka-Munk on the layers' totals;
 *   - SH9 irradiance of a constant and of a linear environment (exact in
 *     bands 0 and 1), and the Lambert/Fresnel convolution constants;
 *   - relaxation makes nearest-neighbour distances more uniform;
 *   - normalised diffusion against the random walk in the set-up its fit was
 *     made for (index-matched, pencil beam), per channel, for five presets;
 *   - white furnace: the exit term lets out what the profile carries, and a
 *     non-absorbing half-space returns everything that enters (the walk);
 *   - albedo + mean free path authoring: the rendered half-space albedo;
 *   - rendering: a flat slab under a point light equals the direct integral
 *     of profile x irradiance; slabs under directional light equal the
 *     multipole totals (R from above, T from below); CPU and GPU agree;
 *   - the dragon scene (npm data) loads, and its splat count lies between the
 *     grid cells whose sample lands on the dragon's light-facing part of its
 *     light-space map and those whose sample lands on the dragon at all, both
 *     counted here by casting the map's texel rays. */
#include <lucent/lucent.h>

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "lu_test.h"
#include "methods/bssrdf/bssrdf.h"
#include "methods/bssrdf/bssrdf_profile.h"
#include "methods/bssrdf/bssrdf_sampling.h"
#include "methods/bssrdf/lu_diffusion.h"
#include "methods/bssrdf/profile_mc.h"
#include "methods/common/lightview.h"

/* ---- independent formulas (double precision) ------------------------------------ */

static double fdr(double eta) { return -1.4399 / (eta * eta) + 0.7099 / eta + 0.6681 + 0.0636 * eta; }
static double bigA(double eta) { return (1.0 + fdr(eta)) / (1.0 - fdr(eta)); }

/* Jensen et al. 2001, Eq. 5 with z_v = z_r (1 + 4A/3). */
static double dipole(double sp, double sa, double eta, double r) {
    double st = sp + sa, a = sp / st, zr = 1.0 / st, zv = zr * (1.0 + 4.0 * bigA(eta) / 3.0);
    double s = sqrt(3.0 * sa * st), dr = sqrt(r * r + zr * zr), dv = sqrt(r * r + zv * zv);
    return a / (4.0 * M_PI) * (zr * (1.0 + s * dr) * exp(-s * dr) / (dr * dr * dr) +
                               zv * (1.0 + s * dv) * exp(-s * dv) / (dv * dv * dv));
}

static double dipole_total(double sp, double sa, double eta) {
    double a = sp / (sp + sa), q = sqrt(3.0 * (1.0 - a));
    return 0.5 * a * (1.0 + exp(-4.0 / 3.0 * bigA(eta) * q)) * exp(-q);
}

/* Slab totals by the 1D Green's function of Phi'' - s^2 Phi = -(a/D) delta(z - l)
 * with Phi = 0 at z = -zb and z = d + zb: R = D Phi'(0), T = -D Phi'(d). */
static void slab_totals2(double sp, double sa, double eta_top, double eta_bottom, double d, double *R, double *T) {
    double st = sp + sa, a = sp / st, l = 1.0 / st, D = l / 3.0, s = sqrt(3.0 * sa * st);
    double zb0 = 2.0 * bigA(eta_top) * D, zbd = 2.0 * bigA(eta_bottom) * D;
    double L = d + zb0 + zbd, x0 = l + zb0;
    *R = a * cosh(s * zb0) * sinh(s * (L - x0)) / sinh(s * L);
    *T = a * cosh(s * zbd) * sinh(s * x0) / sinh(s * L);
}
static void slab_totals(double sp, double sa, double eta, double d, double *R, double *T) {
    slab_totals2(sp, sa, eta, eta, d, R, T);
}

static double fresnel_r(double cos_i, double eta) {
    double c = fabs(cos_i), s2 = (1.0 - c * c) / (eta * eta);
    if (s2 >= 1.0) return 1.0;
    double ct = sqrt(1.0 - s2);
    double rs = (c - eta * ct) / (c + eta * ct), rp = (eta * c - ct) / (eta * c + ct);
    return 0.5 * (rs * rs + rp * rp);
}

/* What the exit term F_t(eta, w_o) / pi lets out over the hemisphere:
 * 2 int_0^1 F_t(mu) mu dmu = 1 - F_dr,ext (32-node Gauss-Legendre). */
static double exit_fraction(double eta) {
    double gx[32], gw[32], sum = 0.0;
    lu_test_gauss_legendre(32, gx, gw);
    for (int i = 0; i < 32; i++) {
        double mu = 0.5 * (1.0 + gx[i]);
        sum += 0.5 * gw[i] * 2.0 * (1.0 - fresnel_r(mu, eta)) * mu;
    }
    return sum;
}

/* int_a^b f(r) dr by composite 32-node Gauss-Legendre on `panels` pieces,
 * geometric between a > 0 and b (the profiles vary on the scale of r). */
typedef double (*rfn)(const void *ctx, double r);
static double integrate_r(rfn f, const void *ctx, double a, double b, int panels) {
    static double gx[32], gw[32];
    static int ready = 0;
    if (!ready) {
        lu_test_gauss_legendre(32, gx, gw);
        ready = 1;
    }
    double sum = 0.0;
    for (int p = 0; p < panels; p++) {
        double lo = a * pow(b / a, (double)p / panels), hi = a * pow(b / a, (double)(p + 1) / panels);
        for (int i = 0; i < 32; i++) sum += 0.5 * (hi - lo) * gw[i] * f(ctx, 0.5 * (hi + lo) + 0.5 * (hi - lo) * gx[i]);
    }
    /* [0, a]: the integrands below are 2 pi r f, ~ linear there. */
    for (int i = 0; i < 32; i++) sum += 0.5 * a * gw[i] * f(ctx, 0.5 * a * (1.0 + gx[i]));
    return sum;
}

/* ---- profiles ------------------------------------------------------------------------ */

typedef struct tab_ctx {
    const lu_bssrdf_profile *p;
    int ch, transmit;
    float d;
} tab_ctx;

static double tab_2pir(const void *vc, double r) {
    const tab_ctx *c = vc;
    return 2.0 * M_PI * r * lu_v3_get(lu_bssrdf_profile_eval(c->p, (float)r, c->d, c->transmit), c->ch);
}

static void test_dipole_profile_and_total(void) {
    static const char *const names[] = {"marble", "skin1", "ketchup", "wholemilk", "apple"};
    lu_bssrdf_profile_desc desc;
    lu_bssrdf_profile_desc_default(&desc);
    for (int k = 0; k < 5; k++) {
        const lu_material_preset *p = lu_material_preset_find(names[k]);
        CHECK(p != NULL);
        if (!p) continue;
        lu_bssrdf_layer layer = {lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]),
                                 lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]), p->eta, 0.0f};
        lu_bssrdf_profile prof;
        lu_error err;
        CHECK_OK(lu_bssrdf_profile_build(&layer, 1, &desc, &prof, &err), &err);
        for (int c = 0; c < 3; c++) {
            double sp = p->sigma_s_prime[c], sa = p->sigma_a[c];
            /* Table entries against the formula, where the profile is not ~0. */
            for (int i = 0; i < prof.nr; i += 37) {
                double x = (double)i / (prof.nr - 1), r = prof.r_max * x * x;
                CHECK_REL(prof.table[3 * i + c], dipole(sp, sa, p->eta, r), 2e-4);
            }
            /* The closed form is what Simpson over [0, inf) gives. */
            CHECK_REL(prof.total_closed[c], dipole_total(sp, sa, p->eta), 1e-5);
            CHECK_REL(prof.total_numeric[c], dipole_total(sp, sa, p->eta), 1e-5);
            /* The table, as the renderer interpolates it, holds the total less
             * what lies beyond r_max: at most eps, at least part of it. */
            tab_ctx tc = {&prof, c, 0, 0.0f};
            double t = integrate_r(tab_2pir, &tc, 1e-3 * prof.r_max, prof.r_max, 24);
            double closed = dipole_total(sp, sa, p->eta);
            CHECK_MSG(t <= closed * (1.0 + 2e-4) && t >= closed * (1.0 - desc.epsilon - 2e-4),
                      "%s ch %d: table total %.6f vs closed %.6f", names[k], c, t, closed);
            /* And the cut is where eps says: the exact tail beyond r_max. */
            double tail = 0.0;
            for (int i = 0; i < 4000; i++) {
                double r0 = prof.r_max * pow(1e4, i / 4000.0), r1 = prof.r_max * pow(1e4, (i + 1) / 4000.0);
                tail += (r1 - r0) * M_PI * (r0 * dipole(sp, sa, p->eta, r0) + r1 * dipole(sp, sa, p->eta, r1));
            }
            CHECK_MSG(tail <= desc.epsilon * closed * 1.01, "%s ch %d: tail %.3g beyond r_max", names[k], c, tail / closed);
        }
        lu_bssrdf_profile_destroy(&prof);
    }
}

static bool ok_(lu_result r, const lu_error *e) {
    CHECK_OK(r, e);
    return r == LU_OK;
}

/* Power of a 1D profile table in the annulus [r0, r1]: 2 pi r P(r) by
 * Gauss-Legendre in x = sqrt(r / r_max), the variable the table is linear in. */
static double table_annulus(const lu_bssrdf_profile *p, int ch, double r0, double r1) {
    static double gx[32], gw[32];
    static int ready = 0;
    if (!ready) {
        lu_test_gauss_legendre(32, gx, gw);
        ready = 1;
    }
    double x0 = sqrt(r0 / p->r_max), x1 = sqrt(fmin(r1, p->r_max) / p->r_max), sum = 0.0;
    for (int i = 0; i < 32 && x1 > x0; i++) {
        double x = 0.5 * (x0 + x1) + 0.5 * (x1 - x0) * gx[i], r = p->r_max * x * x;
        sum += 0.5 * (x1 - x0) * gw[i] * 2.0 * M_PI * r * lu_v3_get(lu_bssrdf_profile_eval(p, (float)r, 0.0f, 0), ch) *
               2.0 * p->r_max * x;
    }
    return sum;
}

/* Christensen-Burley's fit s = 1.85 - A + 7 |A - 0.8|^3 with the volume mean
 * free path (their perpendicular-illumination case, published mean relative
 * error 5.5 % against Monte Carlo) in the set-up it was fitted in: a pencil
 * beam entering an index-matched half-space with isotropic scattering,
 * everything that leaves counted (single scattering included). The measure is
 * the energy-weighted mean over radial bins of |model - walk| / walk, i.e.
 * E = sum |M_b - W_b| / sum W_b on bin powers over [0, r_max); its noise
 * sigma_E comes from the walk's per-bin standard errors, with
 * dE/dW_b = -(sgn(M_b - W_b) + E) / sum W.
 * On this measure even the best shape length h of the two-exponential form
 * (found here by search against the walk, same albedo) is 8-11 % off for
 * albedos near 0.9, so the fit is held to that best plus the published mean
 * error; the wrong pairing (h from 1/sigma_tr) is 7-16 times too wide and
 * far outside it. */
static double burley_bins_error(const double *W, double tot, int n, double dr, double a, double h) {
    double num = 0.0;
    for (int b = 0; b < n; b++) {
        double c0 = 1.0 - 0.25 * exp(-b * dr / h) - 0.75 * exp(-b * dr / (3.0 * h));
        double c1 = 1.0 - 0.25 * exp(-(b + 1) * dr / h) - 0.75 * exp(-(b + 1) * dr / (3.0 * h));
        num += fabs(a * (c1 - c0) - W[b]);
    }
    return num / tot;
}

static void test_burley_vs_walk(void) {
    static const char *const names[] = {"marble", "skin1", "ketchup", "apple", "wholemilk"};
    enum { BINS = 48 };
    lu_bssrdf_profile_desc desc;
    lu_bssrdf_profile_desc_default(&desc);
    desc.model = LU_BSSRDF_BURLEY;
    double worst = 0.0, sum_e = 0.0;
    int n_e = 0;
    for (int k = 0; k < 5; k++) {
        const lu_material_preset *p = lu_material_preset_find(names[k]);
        CHECK(p != NULL);
        if (!p) continue;
        lu_bssrdf_layer layer = {lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]),
                                 lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]), 1.0f, 0.0f};
        lu_bssrdf_profile prof;
        lu_error err;
        if (!ok_(lu_bssrdf_profile_build(&layer, 1, &desc, &prof, &err), &err)) continue;
        for (int c = 0; c < 3; c++) {
            /* Bins over this channel's own 99 % radius of the walk would need
             * the walk first; the profile's shared r_max is a superset. */
            double dr = prof.r_max / BINS;
            lu_bssrdf_mc_result mc;
            if (!ok_(lu_bssrdf_mc_slab(p->sigma_s_prime[c], p->sigma_a[c], 1.0, INFINITY, 60000, 7 + c, BINS + 1,
                                              dr, &mc, &err),
                            &err))
                continue;
            double M[BINS], W[BINS], S[BINS], tot = 0.0, num = 0.0;
            for (int b = 0; b < BINS; b++) {
                double area = M_PI * dr * dr * ((b + 1.0) * (b + 1.0) - (double)b * b);
                M[b] = table_annulus(&prof, c, b * dr, (b + 1) * dr);
                W[b] = mc.r_profile[b] * area;
                S[b] = mc.r_profile_stderr[b] * area;
                tot += W[b];
                num += fabs(M[b] - W[b]);
            }
            double e = num / tot, var = 0.0;
            for (int b = 0; b < BINS; b++) {
                double g = ((M[b] >= W[b] ? 1.0 : -1.0) + e) / tot;
                var += g * g * S[b] * S[b];
            }
            double l = 1.0 / (p->sigma_s_prime[c] + p->sigma_a[c]), best = INFINITY, h_best = l;
            for (int q = -300; q <= 300; q++) {
                double h = l * exp(0.01 * q), eq = burley_bins_error(W, tot, BINS, dr, prof.total_closed[c], h);
                if (eq < best) best = eq, h_best = h;
            }
            double bound = best + 0.055 + 3.0 * sqrt(var);
            /* For comparison, the other pairing: 1/sigma_tr with s = 3.5 + 100 (A - 0.33)^4. */
            double a = prof.total_closed[c], t4 = (a - 0.33) * (a - 0.33);
            double h_d = 1.0 / sqrt(3.0 * p->sigma_a[c] / l) / (3.5 + 100.0 * t4 * t4);
            fprintf(stderr,
                    "  burley %-9s ch %d: A %.3f, mean rel. error %.2f %% (sigma %.2f %%), best h %.2f %% at h/l %.2f "
                    "(fit %.2f); diffuse-mfp pairing %.2f %%\n",
                    names[k], c, a, 100 * e, 100 * sqrt(var), 100 * best, h_best / l, lu_k_burley_h((float)a, (float)l) / l,
                    100 * burley_bins_error(W, tot, BINS, dr, a, h_d));
            CHECK_MSG(e <= bound, "%s ch %d: %.4f > %.4f", names[k], c, e, bound);
            sum_e += e;
            n_e++;
            worst = fmax(worst, e);
            lu_bssrdf_mc_destroy(&mc);
        }
        lu_bssrdf_profile_destroy(&prof);
    }
    fprintf(stderr, "  burley: worst channel %.2f %%, mean over channels %.2f %%\n", 100 * worst, 100 * sum_e / n_e);
}

/* White furnace: a non-absorbing half-space behind a smooth dielectric lets
 * out everything that enters. The random walk with the same boundary
 * (Fresnel split at every internal hit) measures that fraction, 1 less the
 * weight of the walks it drops past 10^6 events (which it reports); the model
 * must return the same:
 * the dipole's total is alpha' = 1, and the exit term with the renderer's
 * normalisation (the material record's pi / k_0, k_0 = 2 pi int F_t mu dmu)
 * must integrate to 1 over the hemisphere (here by the test's own quadrature;
 * without it, 1 - F_dr,ext = 0.94 at eta 1.3). */
static void test_white_furnace(void) {
    static const double etas[3] = {1.0, 1.3, 1.5};
    for (int i = 0; i < 3; i++) {
        double k[3];
        lu_bssrdf_sh_kernel((float)etas[i], k);
        double norm = (float)(M_PI / k[0]);   /* as bssrdf.c stores it */
        double out = exit_fraction(etas[i]) * norm;
        fprintf(stderr, "  eta %.1f: exit term lets out %.6f unnormalised, %.6f normalised\n", etas[i],
                exit_fraction(etas[i]), out);
        CHECK_NEAR(out, 1.0, 1e-5);
    }
    lu_bssrdf_mc_result mc;
    lu_error err;
    if (!ok_(lu_bssrdf_mc_slab(1.0, 0.0, 1.3, INFINITY, 20000, 3, 4, 1.0, &mc, &err), &err)) return;
    fprintf(stderr, "  walk, non-absorbing, eta 1.3: %.5f +- %.1e leaves, %.1e dropped at the event cap\n", mc.r_total,
            mc.r_stderr, mc.dropped);
    CHECK(mc.r_total <= 1.0 + 3.0 * mc.r_stderr);
    CHECK(mc.r_total + mc.dropped >= 1.0 - 3.0 * mc.r_stderr);
    lu_bssrdf_mc_destroy(&mc);
    lu_bssrdf_layer layer = {lu_v3s(1.0f), lu_v3s(0.0f), 1.3f, 0.0f};
    lu_bssrdf_profile_desc desc;
    lu_bssrdf_profile_desc_default(&desc);
    lu_bssrdf_profile prof;
    if (!ok_(lu_bssrdf_profile_build(&layer, 1, &desc, &prof, &err), &err)) return;
    CHECK_NEAR(prof.total_closed[0], 1.0, 1e-6);
    lu_bssrdf_profile_destroy(&prof);
}

/* Prefiltered levels: each is the profile averaged over a disc, so it keeps
 * the power (up to what the disc spreads past r_max), and at r = 0 it is
 * the power inside the disc over its area. */
static void test_prefilter_levels(void) {
    const lu_material_preset *p = lu_material_preset_find("skin2");
    lu_bssrdf_layer layer = {lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]),
                             lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]), p->eta, 0.0f};
    lu_bssrdf_profile_desc desc;
    lu_bssrdf_profile_desc_default(&desc);
    desc.epsilon = 1e-4;
    lu_bssrdf_profile prof;
    lu_error err;
    CHECK_OK(lu_bssrdf_profile_build(&layer, 1, &desc, &prof, &err), &err);
    float rho0 = 0.25f * prof.mfp;
    CHECK_OK(lu_bssrdf_profile_prefilter(&prof, 9, rho0, &err), &err);
    CHECK(prof.levels == 9);
    size_t per = lu_bssrdf_profile_level_entries(&prof);
    for (int k = 1; k < prof.levels; k++) {
        double rho = rho0 * pow(M_SQRT2, k - 1);
        lu_bssrdf_profile lv = prof;   /* a view of level k */
        lv.table = prof.table + 3 * per * k;
        for (int c = 0; c < 3; c++) {
            double sp = p->sigma_s_prime[c], sa = p->sigma_a[c];
            tab_ctx t0 = {&prof, c, 0, 0.0f}, tk = {&lv, c, 0, 0.0f};
            double e0 = integrate_r(tab_2pir, &t0, 1e-3 * prof.r_max, prof.r_max, 24);
            double ek = integrate_r(tab_2pir, &tk, 1e-3 * prof.r_max, prof.r_max, 24);
            CHECK_MSG(fabs(ek - e0) <= 2e-3 * e0, "level %d ch %d: power %.5f vs %.5f", k, c, ek, e0);
            /* Power of the dipole inside rho, by the test's own quadrature. */
            double inside = 0.0;
            for (int i = 0; i < 2000; i++) {
                double r = (i + 0.5) * rho / 2000;
                inside += 2.0 * M_PI * r * dipole(sp, sa, p->eta, r) * rho / 2000;
            }
            CHECK_REL(lv.table[c], inside / (M_PI * rho * rho), 5e-3);
        }
    }
    lu_bssrdf_profile_destroy(&prof);
}

typedef struct mp_ctx {
    lu_k_diffusion k;
    int ch, transmit, pairs;
    float d;
} mp_ctx;

static double mp_2pir(const void *vc, double r) {
    const mp_ctx *c = vc;
    return 2.0 * M_PI * r *
           lu_k_multipole1((float)r, c->d, c->pairs, c->transmit, lu_v3_get(c->k.sigma_tr, c->ch),
                           lu_v3_get(c->k.alpha_p, c->ch), lu_v3_get(c->k.l, c->ch), lu_v3_get(c->k.zb_top, c->ch),
                           lu_v3_get(c->k.zb_bottom, c->ch));
}

static void test_multipole_totals(void) {
    /* marble and skin2, slabs from 2 to 60 mean free paths */
    static const char *const names[] = {"marble", "skin2"};
    static const double thick_mfp[] = {2.0, 4.0, 10.0, 60.0};
    for (int k = 0; k < 2; k++) {
        const lu_material_preset *p = lu_material_preset_find(names[k]);
        lu_vec3 sp = lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]);
        lu_vec3 sa = lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]);
        mp_ctx c = {lu_k_diffusion_make(sp, sa, p->eta, p->eta), 0, 0, 20, 0.0f};
        for (int ch = 0; ch < 3; ch++) {
            c.ch = ch;
            double l = 1.0 / (p->sigma_s_prime[ch] + p->sigma_a[ch]);
            for (int t = 0; t < 4; t++) {
                c.d = (float)(thick_mfp[t] * l);
                double R, T;
                slab_totals(p->sigma_s_prime[ch], p->sigma_a[ch], p->eta, c.d, &R, &T);
                double far = 60.0 * l + 60.0 / sqrt(3.0 * p->sigma_a[ch] / l);
                c.transmit = 0;
                double rn = integrate_r(mp_2pir, &c, 1e-3 * l, far, 48);
                c.transmit = 1;
                double tn = integrate_r(mp_2pir, &c, 1e-3 * l, far, 48);
                CHECK_MSG(fabs(rn - R) <= 2e-3 * R, "%s ch %d d=%g mfp: R %.6f vs Green %.6f", names[k], ch, thick_mfp[t],
                          rn, R);
                CHECK_MSG(fabs(tn - T) <= 2e-3 * R, "%s ch %d d=%g mfp: T %.6f vs Green %.6f", names[k], ch, thick_mfp[t],
                          tn, T);
            }
            /* A thick slab reflects like the half-space: R(r, d) -> dipole. */
            for (double r = 0.0; r < 20.0 * l; r += 2.5 * l) {
                double mp = lu_k_multipole1((float)r, (float)(400.0 * l), 10, 0, lu_v3_get(c.k.sigma_tr, ch),
                                            lu_v3_get(c.k.alpha_p, ch), lu_v3_get(c.k.l, ch), lu_v3_get(c.k.zb_top, ch),
                                            lu_v3_get(c.k.zb_bottom, ch));
                CHECK_REL(mp, dipole(p->sigma_s_prime[ch], p->sigma_a[ch], p->eta, r), 1e-4);
            }
        }
    }
    /* The library's own closed form agrees with this one (its A is computed
     * in float, hence the tolerance). */
    double R, T, R2, T2;
    slab_totals(2.19, 0.0021, 1.3, 3.0, &R, &T);
    lu_bssrdf_slab_totals(2.19, 0.0021, 1.3, 1.3, 3.0, &R2, &T2);
    CHECK_REL(R2, R, 1e-6);
    CHECK_REL(T2, T, 1e-6);
}

static void test_multilayer(void) {
    /* A multipole layer on a radial grid, stacked with the empty layer (R = 0,
     * T = delta) on either side, comes back unchanged. */
    const lu_material_preset *p = lu_material_preset_find("skin1");
    lu_vec3 sp = lu_v3(p->sigma_s_prime[0], p->sigma_s_prime[1], p->sigma_s_prime[2]);
    lu_vec3 sa = lu_v3(p->sigma_a[0], p->sigma_a[1], p->sigma_a[2]);
    lu_k_diffusion k = lu_k_diffusion_make(sp, sa, p->eta, p->eta);
    enum { G = 256, N = 2 * G };
    float d = 6.0f;   /* mm, ~5 mfp in red */
    double h = 0.1, dr = 1.5 * h * (G / 2) / (N - 1);
    static float rr[N], tt[N], line_r[G / 2 + 1], line_t[G / 2 + 1];
    for (int i = 0; i < N; i++) {
        rr[i] = lu_k_multipole1((float)(i * dr), d, 10, 0, k.sigma_tr.x, k.alpha_p.x, k.l.x, k.zb_top.x, k.zb_bottom.x);
        tt[i] = lu_k_multipole1((float)(i * dr), d, 10, 1, k.sigma_tr.x, k.alpha_p.x, k.l.x, k.zb_top.x, k.zb_bottom.x);
    }
    lu_error err;
    lu_bssrdf_spectra *layer = NULL, *empty = NULL, *a = NULL, *b = NULL;
    CHECK_OK(lu_bssrdf_spectra_from_radial(rr, rr, tt, tt, N, dr, G, h, &layer, &err), &err);
    CHECK_OK(lu_bssrdf_spectra_identity(G, h, &empty, &err), &err);
    CHECK_OK(lu_bssrdf_spectra_stack(empty, layer, &a, &err), &err);
    CHECK_OK(lu_bssrdf_spectra_stack(layer, empty, &b, &err), &err);
    lu_bssrdf_spectra *cases[3] = {layer, a, b};
    for (int c = 0; c < 3; c++) {
        if (!cases[c]) continue;
        CHECK_OK(lu_bssrdf_spectra_radial(cases[c], line_r, line_t, G / 2 + 1, &err), &err);
        double peak_r = rr[0], peak_t = tt[0];
        for (int i = 0; i <= G / 2; i += 3) {
            double x = i * h;
            int j = (int)(x / dr);
            double w = x / dr - j;
            double want_r = rr[j] * (1 - w) + rr[j + 1] * w, want_t = tt[j] * (1 - w) + tt[j + 1] * w;
            /* The 2D fields are rescaled so their sums match the radial
             * integrals; that and float FFTs move values by < 1 % of the peak. */
            CHECK_MSG(fabs(line_r[i] - want_r) <= 1e-2 * peak_r, "case %d r=%g: R %.4g vs %.4g", c, x, line_r[i], want_r);
            CHECK_MSG(fabs(line_t[i] - want_t) <= 1e-2 * peak_t, "case %d r=%g: T %.4g vs %.4g", c, x, line_t[i], want_t);
        }
    }
    lu_bssrdf_spectra_destroy(a);
    lu_bssrdf_spectra_destroy(b);
    lu_bssrdf_spectra_destroy(empty);
    lu_bssrdf_spectra_destroy(layer);

    /* A coating over a base: the stack's totals (its DC terms) must be the
     * Kubelka-Munk combination of the layers' closed-form totals, each face
     * with its own boundary (air above the coat, an index-matched interface
     * between the layers, air below the base):
     * R12 = R1 + T1 R2 T1' / (1 - R1' R2), T12 = T1 T2 / (1 - R1' R2),
     * primes for light travelling upwards (the faces swapped). */
    lu_bssrdf_layer layers[2] = {{lu_v3(3.0f, 3.0f, 3.0f), lu_v3(0.05f, 0.1f, 0.2f), 1.3f, 1.2f},
                                 {sp, sa, 1.3f, 0.0f}};
    lu_bssrdf_profile_desc desc;
    lu_bssrdf_profile_desc_default(&desc);
    desc.fft_size = 256;
    desc.thickness_steps = 4;
    desc.epsilon = 1e-4;
    lu_bssrdf_profile prof;
    CHECK_OK(lu_bssrdf_profile_build(layers, 2, &desc, &prof, &err), &err);
    if (prof.table) {
        for (int j = 0; j < prof.nd; j += prof.nd - 1) {
            float D = prof.d_lo * powf(prof.d_hi / prof.d_lo, (float)j / (float)(prof.nd - 1));
            for (int c = 0; c < 3; c++) {
                double R1, T1, R1u, T1u, R2, T2;
                double s1 = lu_v3_get(layers[0].sigma_sp, c), a1 = lu_v3_get(layers[0].sigma_a, c);
                slab_totals2(s1, a1, 1.3, 1.0, 1.2, &R1, &T1);
                slab_totals2(s1, a1, 1.0, 1.3, 1.2, &R1u, &T1u);
                slab_totals2(lu_v3_get(sp, c), lu_v3_get(sa, c), 1.0, 1.3, D - 1.2, &R2, &T2);
                double want_r = R1 + T1 * T1u * R2 / (1.0 - R1u * R2), want_t = T1 * T2 / (1.0 - R1u * R2);
                tab_ctx tr = {&prof, c, 0, D}, ttc = {&prof, c, 1, D};
                double got_r = integrate_r(tab_2pir, &tr, 1e-3 * prof.r_max, prof.r_max, 24);
                double got_t = integrate_r(tab_2pir, &ttc, 1e-3 * prof.r_max, prof.r_max, 24);
                CHECK_MSG(fabs(got_r - want_r) <= 0.01 * want_r, "coated D=%g ch %d: R %.5f vs KM %.5f", D, c, got_r, want_r);
                CHECK_MSG(fabs(got_t - want_t) <= 0.01 * want_r, "coated D=%g ch %d: T %.5f vs KM %.5f", D, c, got_t, want_t);
            }
        }
    }
    lu_bssrdf_profile_destroy(&prof);
}

/* ---- environment ------------------------------------------------------------------------ */

static void test_sh9_irradiance(void) {
    double a[3];
    lu_bssrdf_sh_kernel(0.0f, a);
    CHECK_REL(a[0], M_PI, 1e-9);
    CHECK_REL(a[1], 2.0 * M_PI / 3.0, 1e-9);
    CHECK_REL(a[2], M_PI / 4.0, 1e-9);
    /* With Fresnel: a[0] = pi (1 - F_dr,ext), here by a 2000-panel midpoint rule. */
    double af[3], ext = 0.0;
    lu_bssrdf_sh_kernel(1.3f, af);
    for (int i = 0; i < 2000; i++) {
        double mu = (i + 0.5) / 2000.0;
        ext += 2.0 * mu * fresnel_r(mu, 1.3) / 2000.0;
    }
    CHECK_REL(af[0], M_PI * (1.0 - ext), 1e-5);

    /* Constant environment L = (1, 2, 3): E = pi L for every normal. A linear
     * one L = 1 + 0.5 w_y (positive everywhere) has only bands 0 and 1:
     * E(n) = pi + (2 pi / 3) 0.5 n_y, exactly. */
    lu_light env;
    memset(&env, 0, sizeof env);
    env.type = LU_LIGHT_ENVIRONMENT;
    env.env_scale = 1.0f;
    lu_error err;
    CHECK_OK(lu_image_create(&env.env, 1, 1, &err), &err);
    env.env.rgb[0] = 1, env.env.rgb[1] = 2, env.env.rgb[2] = 3;
    double L[27];
    lu_bssrdf_env_project(&env, L);
    lu_vec3 dirs[5] = {lu_v3(0, 1, 0), lu_v3(0, -1, 0), lu_v3(1, 0, 0), lu_v3_norm(lu_v3(1, 2, -3)),
                       lu_v3_norm(lu_v3(-0.3f, 0.1f, 0.9f))};
    for (int i = 0; i < 5; i++) {
        lu_vec3 e = lu_bssrdf_sh_irradiance(L, a, dirs[i]);
        CHECK_REL(e.x, M_PI, 1e-4);
        CHECK_REL(e.y, 2 * M_PI, 1e-4);
        CHECK_REL(e.z, 3 * M_PI, 1e-4);
    }
    lu_image_destroy(&env.env);
    /* The linear map at 64 x 32 texels (texel centres at v = (j + 0.5) / 32). */
    CHECK_OK(lu_image_create(&env.env, 64, 32, &err), &err);
    for (int y = 0; y < 32; y++)
        for (int x = 0; x < 64; x++) {
            /* The bilinear lookup interpolates in v (polar angle), so the map
             * is exactly linear in w_y only between texel centres: keep the
             * error tiny by a fine map and a loose but meaningful tolerance. */
            float wy = cosf((float)M_PI * ((float)y + 0.5f) / 32.0f);
            float *px = lu_image_px(&env.env, x, y);
            px[0] = px[1] = px[2] = 1.0f + 0.5f * wy;
        }
    lu_bssrdf_env_project(&env, L);
    for (int i = 0; i < 5; i++) {
        lu_vec3 e = lu_bssrdf_sh_irradiance(L, a, dirs[i]);
        double want = M_PI + 2.0 * M_PI / 3.0 * 0.5 * dirs[i].y;
        CHECK_REL(e.x, want, 3e-3);
    }
    lu_image_destroy(&env.env);
}

static void test_relaxation(void) {
    lu_kvlist params = {0};
    double sub = 4;
    lu_error err;
    CHECK_OK(lu_kv_set_number(&params, "subdivisions", &sub, 1, &err), &err);
    lu_mesh sphere = {0};
    CHECK_OK(lu_mesh_procedural("sphere", &params, &sphere, "test", &err), &err);
    lu_kv_free(&params);
    lu_surface_points pts;
    int n = 600;
    CHECK_OK(lu_surface_sample(&sphere, n, 3, &pts, &err), &err);
    double area = lu_mesh_area(&sphere), radius = 2.0 * sqrt(area / n);
    double m0, cv0;
    lu_surface_nn_stats(&pts, 2.0 * radius, &m0, &cv0);
    lu_relax_stats rs;
    CHECK_OK(lu_surface_relax(&sphere, &pts, radius, 0.02, 200, 0.01, &rs, &err), &err);
    double m1, cv1;
    lu_surface_nn_stats(&pts, 2.0 * radius, &m1, &cv1);
    fprintf(stderr, "  relaxation: %d iterations, NN mean %.4f -> %.4f, CV %.3f -> %.3f\n", rs.iterations, m0, m1, cv0, cv1);
    CHECK(cv1 < 0.5 * cv0);      /* random placement: CV ~ 0.5; relaxed: well under half of it */
    CHECK(m1 > m0);              /* no clumps: the typical gap opens up */
    CHECK_NEAR(rs.nn_cv_before, cv0, 1e-9);
    /* Points stay on the surface (the icosphere lies within [0.99, 1] of the centre). */
    int off = 0;
    for (int i = 0; i < pts.count; i++) {
        float r = lu_v3_len(pts.position[i]);
        off += r < 0.985f || r > 1.0001f;
        off += fabsf(lu_v3_dot(pts.normal[i], lu_v3_norm(pts.position[i])) - 1.0f) > 0.01f;
    }
    CHECK(off == 0);
    lu_surface_points_destroy(&pts);
    lu_mesh_destroy(&sphere);
}

/* ---- rendering ----------------------------------------------------------------------------- */

/* A 50 x 10 x 50 mm slab (top face at y = 0), coefficients per mm. */
static const double k_sp[3] = {1.0, 1.2, 0.8}, k_sa[3] = {0.3, 0.4, 0.25};
#define K_ETA 1.3

static bool load(const char *json, lu_scene *s) {
    lu_error err;
    lu_result r = lu_scene_load_string(json, "test.json", s, &err);
    CHECK_OK(r, &err);
    return r == LU_OK;
}

static bool render(const lu_scene *s, const char *profile, lu_backend backend, int splats, lu_image *img) {
    if (lu_test_skip_gpu(backend)) return false;
    lu_kvlist set = {0};
    lu_error err;
    double n = splats, zero = 0, eps = 1e-3, res = 256;
    lu_kv_set_string(&set, "bssrdf.profile", profile, &err);
    lu_kv_set_number(&set, "bssrdf.splats", &n, 1, &err);
    lu_kv_set_number(&set, "bssrdf.jitter", &zero, 1, &err);
    lu_kv_set_number(&set, "bssrdf.epsilon", &eps, 1, &err);
    lu_kv_set_number(&set, "bssrdf.map_res", &res, 1, &err);
    lu_renderer *r = NULL;
    lu_result rc = lu_renderer_create("bssrdf", s, &set, backend, &r, &err);
    CHECK_OK(rc, &err);
    lu_kv_free(&set);
    if (rc != LU_OK) return false;
    memset(img, 0, sizeof *img);
    rc = lu_renderer_render(r, s, img, &err);
    CHECK_OK(rc, &err);
    lu_renderer_destroy(r);
    return rc == LU_OK;
}

static const char *slab_json(char *buf, size_t n, const char *light) {
    snprintf(buf, n,
             "{\"camera\": {\"position\": [0, 60, 0], \"look_at\": [0, 0, 0], \"up\": [0, 0, -1], \"fov_y_deg\": 8,"
             " \"width\": 20, \"height\": 20},"
             " \"lights\": [%s],"
             " \"objects\": [{\"mesh\": {\"procedural\": \"box\", \"size\": [50, 10, 50]},"
             " \"transform\": {\"translate\": [0, -5, 0]},"
             " \"material\": {\"type\": \"translucent\", \"sigma_s\": [%g, %g, %g], \"sigma_a\": [%g, %g, %g],"
             " \"eta\": %g, \"specular\": 0}}]}",
             light, k_sp[0], k_sp[1], k_sp[2], k_sa[0], k_sa[1], k_sa[2], K_ETA);
    return buf;
}

typedef struct conv_ctx {
    double xo, zo;   /* the shaded point on y = 0 */
    double ly;       /* light height above the face; at x = z = 0 */
    int ch;
    double phi;
} conv_ctx;

/* E(x) on the top face times the dipole at |x - x_o|, integrated over angle. */
static double ring(const void *vc, double r) {
    const conv_ctx *c = vc;
    enum { NP = 48 };
    double sum = 0.0;
    for (int k = 0; k < NP; k++) {
        double ph = 2.0 * M_PI * (k + 0.5) / NP;
        double x = c->xo + r * cos(ph), z = c->zo + r * sin(ph);
        if (fabs(x) > 25.0 || fabs(z) > 25.0) continue;
        double d2 = x * x + z * z + c->ly * c->ly, d = sqrt(d2), cos_i = c->ly / d;
        sum += 100.0 * (1.0 - fresnel_r(cos_i, K_ETA)) * cos_i / d2;
    }
    return 2.0 * M_PI * r * dipole(k_sp[c->ch], k_sa[c->ch], K_ETA, r) * sum / NP;
}

static void test_slab_point_light(void) {
    char json[2048];
    lu_scene s;
    if (!load(slab_json(json, sizeof json, "{\"type\": \"point\", \"position\": [0, 8, 0], \"intensity\": [100, 100, 100]}"), &s))
        return;
    lu_image img;
    if (render(&s, "dipole", LU_BACKEND_CPU, 30000, &img)) {
        double worst = 0.0, sum_got = 0.0, sum_want = 0.0;
        for (int py = 1; py < s.camera.height; py += 3)
            for (int px = 1; px < s.camera.width; px += 3) {
                lu_vec3 o, d;
                lu_camera_ray(&s.camera, (float)px + 0.5f, (float)py + 0.5f, &o, &d);
                double t = -o.y / d.y;
                conv_ctx c = {o.x + t * d.x, o.z + t * d.z, 8.0, 0, 0};
                double ft_o = (1.0 - fresnel_r(-d.y, K_ETA)) / exit_fraction(K_ETA);
                for (c.ch = 0; c.ch < 3; c.ch++) {
                    double l = 1.0 / (k_sp[c.ch] + k_sa[c.ch]);
                    double want = ft_o / M_PI * integrate_r(ring, &c, 1e-2 * l, 60.0 * l, 24);
                    double got = lu_image_px(&img, px, py)[c.ch];
                    worst = fmax(worst, fabs(got - want) / want);
                    sum_got += got;
                    sum_want += want;
                }
            }
        fprintf(stderr, "  point-lit slab: worst pixel %.2f %%, mean %.3f %%\n", 100 * worst,
                100 * (sum_got - sum_want) / sum_want);
        CHECK(worst < 0.03);
        CHECK(fabs(sum_got - sum_want) < 0.01 * sum_want);
        lu_image_destroy(&img);
    }
    lu_scene_destroy(&s);
}

static void test_slab_directional_multipole(void) {
    /* Uniform irradiance E0 at normal incidence: the splat sum is E0 F_t(0)
     * times the profile's plane integral, which the Green's function gives. */
    char json[2048];
    static const char *const lights[2] = {"{\"type\": \"directional\", \"direction\": [0, 1, 0], \"irradiance\": [2, 2, 2]}",
                                          "{\"type\": \"directional\", \"direction\": [0, -1, 0], \"irradiance\": [2, 2, 2]}"};
    for (int below = 0; below < 2; below++) {
        lu_scene s;
        if (!load(slab_json(json, sizeof json, lights[below]), &s)) continue;
        lu_image img;
        if (render(&s, "multipole", LU_BACKEND_CPU, 40000, &img)) {
            double worst = 0.0;
            double ft_in = 1.0 - fresnel_r(1.0, K_ETA);
            for (int py = 2; py < s.camera.height; py += 5)
                for (int px = 2; px < s.camera.width; px += 5) {
                    lu_vec3 o, d;
                    lu_camera_ray(&s.camera, (float)px + 0.5f, (float)py + 0.5f, &o, &d);
                    double ft_o = (1.0 - fresnel_r(-d.y, K_ETA)) / exit_fraction(K_ETA);
                    for (int c = 0; c < 3; c++) {
                        double R, T;
                        slab_totals(k_sp[c], k_sa[c], K_ETA, 10.0, &R, &T);
                        double want = ft_o / M_PI * 2.0 * ft_in * (below ? T : R);
                        double got = lu_image_px(&img, px, py)[c];
                        worst = fmax(worst, fabs(got - want) / want);
                    }
                }
            fprintf(stderr, "  slab lit from %s: worst pixel %.2f %% off the multipole %s total\n",
                    below ? "below" : "above", 100 * worst, below ? "T" : "R");
            CHECK(worst < 0.02);
            lu_image_destroy(&img);
        }
        lu_scene_destroy(&s);
    }
}

/* Authored albedo + mean free path: a 120 x 60 x 120 mm box (a half-space
 * for these lengths) under a directional light at normal incidence. Its
 * albedo as rendered, the exitance over what entered,
 *   L pi (1 - F_dr,ext) / (F_t(w_o) E F_t(0)),
 * must be the authored one within 0.01, for the 1D profiles. */
static void test_authored_albedo(void) {
    static const double alb[3] = {0.8, 0.5, 0.2};
    char json[2048];
    snprintf(json, sizeof json,
             "{\"camera\": {\"position\": [0, 60, 0], \"look_at\": [0, 0, 0], \"up\": [0, 0, -1], \"fov_y_deg\": 8,"
             " \"width\": 16, \"height\": 16},"
             " \"lights\": [{\"type\": \"directional\", \"direction\": [0, 1, 0], \"irradiance\": [2, 2, 2]}],"
             " \"objects\": [{\"mesh\": {\"procedural\": \"box\", \"size\": [120, 60, 120]},"
             " \"transform\": {\"translate\": [0, -30, 0]},"
             " \"material\": {\"type\": \"translucent\", \"subsurface_albedo\": [%g, %g, %g],"
             " \"mean_free_path_mm\": [1.0, 0.5, 0.25], \"eta\": %g, \"specular\": 0}}]}",
             alb[0], alb[1], alb[2], K_ETA);
    lu_scene s;
    if (!load(json, &s)) return;
    /* The inversion itself: the dipole total of the stored coefficients. */
    const lu_material *m = &s.objects[0].material;
    for (int c = 0; c < 3; c++) {
        CHECK_REL(dipole_total(lu_v3_get(m->sigma_s, c), lu_v3_get(m->sigma_a, c), K_ETA), alb[c], 1e-5);
        CHECK_REL(1.0 / (lu_v3_get(m->sigma_s, c) + lu_v3_get(m->sigma_a, c)), c == 0 ? 1.0 : (c == 1 ? 0.5 : 0.25),
                  1e-5);
    }
    static const char *const profiles[2] = {"dipole", "burley"};
    double ft_in = 1.0 - fresnel_r(1.0, K_ETA);
    for (int p = 0; p < 2; p++) {
        lu_image img;
        if (!render(&s, profiles[p], LU_BACKEND_CPU, 40000, &img)) continue;
        double got[3] = {0, 0, 0};
        int n = 0;
        for (int py = 0; py < s.camera.height; py++)
            for (int px = 0; px < s.camera.width; px++) {
                lu_vec3 o, d;
                lu_camera_ray(&s.camera, (float)px + 0.5f, (float)py + 0.5f, &o, &d);
                double conv = M_PI * exit_fraction(K_ETA) / ((1.0 - fresnel_r(-d.y, K_ETA)) * 2.0 * ft_in);
                for (int c = 0; c < 3; c++) got[c] += lu_image_px(&img, px, py)[c] * conv;
                n++;
            }
        for (int c = 0; c < 3; c++) {
            got[c] /= n;
            fprintf(stderr, "  %s: authored albedo %.3f, rendered %.4f\n", profiles[p], alb[c], got[c]);
            CHECK_NEAR(got[c], alb[c], 0.01);
        }
        lu_image_destroy(&img);
    }
    lu_scene_destroy(&s);
}

static void test_cpu_gpu_agree(void) {
    char json[2048];
    lu_scene s;
    if (!load(slab_json(json, sizeof json, "{\"type\": \"point\", \"position\": [3, 8, -2], \"intensity\": [100, 80, 60]}"), &s))
        return;
    static const char *const profiles[3] = {"dipole", "multipole", "burley"};
    for (int p = 0; p < 3; p++) {
        lu_image a, b;
        if (!render(&s, profiles[p], LU_BACKEND_CPU, 4000, &a)) continue;
        if (render(&s, profiles[p], LU_BACKEND_GPU, 4000, &b)) {
            lu_metrics m;
            lu_error err;
            CHECK_OK(lu_image_compare(&b, &a, &m, &err), &err);
            fprintf(stderr, "  %s: GPU vs CPU rel-L2 %.2e\n", profiles[p], m.rel_l2);
            CHECK(m.rel_l2 < 1e-4);
            lu_image_destroy(&b);
        }
        lu_image_destroy(&a);
    }
    lu_scene_destroy(&s);
}

static void test_scene_materials(void) {
    /* Rohat's Table 4.3: marble's imaginary indices give Jensen's sigma_a. */
    CHECK_REL(lu_sigma_a_from_ior_imag(1.16979e-7f, 700.0f), 0.0021, 1e-3);
    CHECK_REL(lu_sigma_a_from_ior_imag(1.79447e-7f, 550.0f), 0.0041, 1e-3);
    CHECK_REL(lu_sigma_a_from_ior_imag(2.40125e-7f, 425.0f), 0.0071, 1e-3);
    lu_scene s;
    const char *json =
        "{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0]},"
        " \"objects\": [{\"mesh\": {\"procedural\": \"sphere\", \"subdivisions\": 1},"
        " \"material\": {\"type\": \"translucent\", \"sigma_s\": [2.19, 2.62, 3.0],"
        " \"eta_imag\": [1.16979e-7, 1.79447e-7, 2.40125e-7], \"eta\": 1.5, \"mm_per_unit\": 10,"
        " \"coatings\": [{\"preset\": \"cream\", \"thickness_mm\": 2}]}}]}";
    if (load(json, &s)) {
        const lu_material *m = &s.objects[0].material;
        CHECK_REL(m->sigma_a.x, 0.021, 1e-3);   /* per scene unit: x mm_per_unit */
        CHECK_REL(m->sigma_s.z, 30.0, 1e-6);
        CHECK(m->coating_count == 1);
        CHECK_REL(m->coatings[0].thickness, 0.2, 1e-6);
        CHECK_REL(m->coatings[0].sigma_s.x, 73.8, 1e-5);
        lu_scene_destroy(&s);
    }
    lu_error err;
    CHECK(lu_scene_load_string("{\"camera\": {\"position\": [0, 0, 5], \"look_at\": [0, 0, 0]}, \"objects\": [{\"mesh\":"
                               " {\"procedural\": \"sphere\"}, \"material\": {\"type\": \"translucent\", \"sigma_s\": 1,"
                               " \"sigma_a\": 1, \"eta_imag\": 1e-7}}]}",
                               "bad.json", &s, &err) == LU_ERR_SCENE);
}

/* One texel of a light-space map as the method defines it: the ray through
 * the texel's centre hits object obj first, on a face turned to the light;
 * pos is the hit, nrm the interpolated normal (the geometric one where that
 * points the other way). */
typedef struct dtexel {
    bool on;
    lu_vec3 pos, nrm;
} dtexel;

typedef struct dmap {
    int r[4];      /* texels cast: [r0, r2) x [r1, r3) */
    dtexel *tex;
} dmap;

static const dtexel *dmap_at(const dmap *m, int x, int y) {
    if (x < m->r[0] || y < m->r[1] || x >= m->r[2] || y >= m->r[3]) return NULL;
    const dtexel *t = &m->tex[(size_t)(y - m->r[1]) * (m->r[2] - m->r[0]) + (x - m->r[0])];
    return t->on ? t : NULL;
}

/* Bounds on the splats of object obj under point light 0 with n_req
 * requested, from the geometry alone: the method lays an nx x ny grid over
 * the object's region of interest (the bounding rectangle of its texels) in
 * each view, nx ny ~ n_req w h / (sum of the views' w h), and makes a splat
 * where the cell's sample reads the object from the map and receives light.
 * A read succeeds exactly where the texel containing the sample is the
 * object's (the bilinear read falls back to that texel), so those cells are
 * *hi. A splat's light is nonzero iff its normal n faces the light L from its
 * position p: n . (L - p) > 0, where n and p are the texel's own or bilinear
 * blends of the 4 texels around the sample; the form is bilinear in (n, p),
 * so it holds for every blend when n_i . (L - p_j) > 0 for all object texels
 * i, j among the 4, and such cells (margin 1e-3 for rounding) are *lo. */
static void dragon_splat_bounds(const lu_scene *s, int obj, int n_req, int res, int *lo, int *hi) {
    lu_error err;
    lu_accel *acc = NULL;
    *lo = *hi = 0;
    CHECK_OK(lu_accel_create(&acc, &err), &err);
    if (!acc) return;
    lu_aabb box = lu_aabb_empty();
    for (int i = 0; i < s->object_count; i++) {
        uint32_t id;
        CHECK_OK(lu_accel_add_mesh(acc, &s->objects[i].mesh, &id, &err), &err);
        lu_aabb b = lu_mesh_bounds(&s->objects[i].mesh);
        lu_aabb_grow(&box, b.lo);
        lu_aabb_grow(&box, b.hi);
    }
    CHECK_OK(lu_accel_commit(acc, &err), &err);
    const lu_light *light = &s->lights[0];
    const lu_mesh *mesh = &s->objects[obj].mesh;
    lu_lightviews vs;
    lu_lightviews_for_light(light, box, &vs);
    lu_aabb db = lu_mesh_bounds(mesh);
    dmap maps[6];
    int roi[6][4];
    double area = 0.0;
    for (int f = 0; f < vs.count; f++) {
        const lu_k_lightview v = vs.view[f];
        /* The object's texels lie in its bounds' projection (the whole face
         * where the bounds reach behind the light). */
        float u0 = 1e30f, u1 = -1e30f, v0 = 1e30f, v1 = -1e30f;
        bool behind = false;
        for (int k = 0; k < 8; k++) {
            lu_vec3 c = lu_v3(k & 1 ? db.hi.x : db.lo.x, k & 2 ? db.hi.y : db.lo.y, k & 4 ? db.hi.z : db.lo.z);
            lu_vec3 uvd = lu_k_lightview_project(v, c);
            behind = behind || (!v.ortho && uvd.z <= 0.0f);
            u0 = fminf(u0, uvd.x), u1 = fmaxf(u1, uvd.x), v0 = fminf(v0, uvd.y), v1 = fmaxf(v1, uvd.y);
        }
        if (behind) u0 = v0 = 0.0f, u1 = v1 = 1.0f;
        dmap *m = &maps[f];
        m->r[0] = (int)fmaxf(0.0f, floorf(u0 * res) - 1), m->r[1] = (int)fmaxf(0.0f, floorf(v0 * res) - 1);
        m->r[2] = (int)fminf((float)res, ceilf(u1 * res) + 1), m->r[3] = (int)fminf((float)res, ceilf(v1 * res) + 1);
        if (m->r[2] < m->r[0]) m->r[2] = m->r[0];
        if (m->r[3] < m->r[1]) m->r[3] = m->r[1];
        m->tex = calloc((size_t)(m->r[2] - m->r[0]) * (m->r[3] - m->r[1]) + 1, sizeof *m->tex);
        roi[f][0] = roi[f][1] = res, roi[f][2] = roi[f][3] = 0;
        for (int y = m->r[1]; y < m->r[3]; y++)
            for (int x = m->r[0]; x < m->r[2]; x++) {
                lu_k_lightray ray = lu_k_lightview_ray(v, ((float)x + 0.5f) / (float)res, ((float)y + 0.5f) / (float)res);
                lu_hit h;
                if (!lu_accel_closest(acc, ray.origin, ray.dir, 0.0f, 1e30f, &h)) continue;
                if ((int)h.mesh_id != obj || lu_v3_dot(h.ng, ray.dir) > 0.0f) continue;
                dtexel *t = &m->tex[(size_t)(y - m->r[1]) * (m->r[2] - m->r[0]) + (x - m->r[0])];
                const uint32_t *tri = &mesh->indices[3u * h.prim_id];
                lu_vec3 n = lu_v3_add(lu_v3_add(lu_v3_scale(mesh->normals[tri[0]], 1.0f - h.u - h.v),
                                                lu_v3_scale(mesh->normals[tri[1]], h.u)),
                                      lu_v3_scale(mesh->normals[tri[2]], h.v));
                n = lu_v3_norm(n);
                t->on = true;
                t->pos = lu_v3_madd(ray.origin, ray.dir, h.t);
                t->nrm = lu_v3_dot(n, h.ng) < 0.0f ? h.ng : n;
                roi[f][0] = x < roi[f][0] ? x : roi[f][0], roi[f][1] = y < roi[f][1] ? y : roi[f][1];
                roi[f][2] = x + 1 > roi[f][2] ? x + 1 : roi[f][2], roi[f][3] = y + 1 > roi[f][3] ? y + 1 : roi[f][3];
            }
        if (roi[f][2] > roi[f][0]) area += (double)(roi[f][2] - roi[f][0]) * (roi[f][3] - roi[f][1]);
    }
    int cells = 0;
    for (int f = 0; f < vs.count; f++) {
        const dmap *m = &maps[f];
        if (roi[f][2] <= roi[f][0]) continue;
        double w = roi[f][2] - roi[f][0], h = roi[f][3] - roi[f][1];
        double n = n_req * w * h / area;
        int nx = (int)fmax(1.0, floor(sqrt(n * w / h) + 0.5)), ny = (int)fmax(1.0, floor(n / nx + 0.5));
        double du = w / ((double)res * nx), dv = h / ((double)res * ny);
        for (int j = 0; j < ny; j++)
            for (int i = 0; i < nx; i++) {
                cells++;
                float u = (float)(roi[f][0] / (double)res + (i + 0.5) * du);
                float vv = (float)(roi[f][1] / (double)res + (j + 0.5) * dv);
                if (!dmap_at(m, (int)floorf(u * (float)res), (int)floorf(vv * (float)res))) continue;
                (*hi)++;
                int x0 = (int)floorf(u * (float)res - 0.5f), y0 = (int)floorf(vv * (float)res - 0.5f);
                const dtexel *t[4] = {dmap_at(m, x0, y0), dmap_at(m, x0 + 1, y0), dmap_at(m, x0, y0 + 1),
                                      dmap_at(m, x0 + 1, y0 + 1)};
                bool lit = true;
                for (int a = 0; a < 4; a++)
                    for (int b = 0; b < 4; b++) {
                        if (!t[a] || !t[b]) continue;
                        lu_vec3 to = lu_v3_sub(light->position, t[b]->pos);
                        lit = lit && lu_v3_dot(t[a]->nrm, to) > 1e-3f * lu_v3_len(to);
                    }
                if (lit) (*lo)++;
            }
    }
    for (int f = 0; f < vs.count; f++) free(maps[f].tex);
    fprintf(stderr, "  dragon: %d views, %d grid cells, %d on the object (upper bound), %d of them surely lit (lower bound)\n",
            vs.count, cells, *hi, *lo);
    lu_accel_destroy(acc);
}

static void test_dragon_scene(void) {
    /* npm data: a missing dataset is a failure, not a skip. */
    lu_scene s;
    lu_error err;
    lu_result r = lu_scene_load(LU_SOURCE_DIR "/scenes/dragon_marble.json", &s, &err);
    CHECK_OK(r, &err);
    if (r != LU_OK) return;
    CHECK(s.objects[0].material.type == LU_MATERIAL_TRANSLUCENT && s.light_count == 1 &&
          s.lights[0].type == LU_LIGHT_POINT);
    s.camera.width = 48;
    s.camera.height = 48;
    lu_image img = {0};
    lu_kvlist set = {0};
    const int n_req = 1000, res = 512;
    double n = n_req, map_res = res, zero = 0;
    lu_kv_set_number(&set, "bssrdf.splats", &n, 1, &err);
    lu_kv_set_number(&set, "bssrdf.map_res", &map_res, 1, &err);
    lu_kv_set_number(&set, "bssrdf.jitter", &zero, 1, &err);
    lu_renderer *rd = NULL;
    CHECK_OK(lu_renderer_create("bssrdf", &s, &set, LU_BACKEND_CPU, &rd, &err), &err);
    lu_kv_free(&set);
    if (rd && lu_renderer_render(rd, &s, &img, &err) == LU_OK) {
        lu_bssrdf_frame_stats fs;
        CHECK(lu_bssrdf_last_stats(rd, &fs));
        int lo, hi;
        dragon_splat_bounds(&s, 0, n_req, res, &lo, &hi);
        fprintf(stderr, "  dragon: %d splats of %d requested\n", fs.splats, n_req);
        /* The dragon fills part of its region of interest: fewer valid samples than asked. */
        CHECK(fs.splats < n_req);
        CHECK(lo > 0 && fs.splats >= lo && fs.splats <= hi);
        CHECK(fs.env_splats == 0 && fs.map_texels > 0 && fs.list_entries >= fs.splats);
        /* The image itself is judged elsewhere: GPU against CPU in
         * test_cross_backend, and against pathtrace in docs/bssrdf.md. */
        lu_image_destroy(&img);
    }
    lu_renderer_destroy(rd);
    lu_scene_destroy(&s);
}

int main(void) {
    RUN_TEST(test_dipole_profile_and_total);
    RUN_TEST(test_prefilter_levels);
    RUN_TEST(test_multipole_totals);
    RUN_TEST(test_burley_vs_walk);
    RUN_TEST(test_white_furnace);
    RUN_TEST(test_multilayer);
    RUN_TEST(test_sh9_irradiance);
    RUN_TEST(test_relaxation);
    RUN_TEST(test_scene_materials);
    RUN_TEST(test_slab_point_light);
    RUN_TEST(test_slab_directional_multipole);
    RUN_TEST(test_authored_albedo);
    RUN_TEST(test_cpu_gpu_agree);
    RUN_TEST(test_dragon_scene);
    TEST_EXIT();
}
