/* Internal: diffusion profile tables for the bssrdf method (Rohat 2011,
 * sections 3.4, 4.3, 5.1): dipole / normalised-diffusion 1D tables R(r),
 * multipole 2D tables R(r, d) and T(r, d), multi-layer stacks combined in
 * the frequency domain (Kubelka-Munk, thesis Eq. 3.10 and 3.12), the splat
 * radius r_max and closed-form totals (profile_mc.h measures the same
 * profiles without the diffusion approximation).
 *
 * The per-r formulas are the kernel src/methods/bssrdf/lu_diffusion.h; this file
 * integrates and tabulates them. Lengths are in whatever unit the
 * coefficients are per (scene units in the renderer, mm in `lucent profile`). */
#ifndef LU_METHODS_BSSRDF_PROFILE_H
#define LU_METHODS_BSSRDF_PROFILE_H

#include <lucent/lucent.h>

typedef enum lu_bssrdf_model {
    LU_BSSRDF_DIPOLE = 0,
    LU_BSSRDF_MULTIPOLE = 1,
    LU_BSSRDF_BURLEY = 2,
    LU_BSSRDF_PBD = 3     /* photon beam diffusion + single scattering (profile_pbd.h), 1D */
} lu_bssrdf_model;

/* One homogeneous layer. */
typedef struct lu_bssrdf_layer {
    lu_vec3 sigma_sp;    /* reduced scattering (1 - g) sigma_s */
    lu_vec3 sigma_a;
    float eta;           /* absolute index of refraction */
    float thickness;     /* coatings: their thickness; the base (last layer): ignored */
} lu_bssrdf_layer;

typedef struct lu_bssrdf_profile_desc {
    lu_bssrdf_model model;
    int table_size;        /* entries along r (256-512 in the thesis) */
    int thickness_steps;   /* rows along d of the 2D tables */
    int pairs;             /* multipole: dipole pairs i = -pairs .. pairs */
    double epsilon;        /* r_max: fraction of the total reflectance left outside */
    double d_min_mfp, d_max_mfp;  /* 2D tables: thickness range in mean free paths */
    int fft_size;          /* multi-layer: FFT grid side */
} lu_bssrdf_profile_desc;

/* Defaults: dipole, 512 entries, 32 rows, 10 pairs, eps 0.01, d in [4, 64] mfp, FFT 256. */
void lu_bssrdf_profile_desc_default(lu_bssrdf_profile_desc *d);

#define LU_BSSRDF_DECAY_CAP 40.0f
#define LU_BSSRDF_T_FLOOR 1e-4

typedef struct lu_bssrdf_profile {
    int kind;              /* 0: 1D table R(r); 1: 2D tables R(r, d), T(r, d) */
    int nr, nd;
    float r_max;           /* table r in [0, r_max], entry i at r = r_max (i / (nr - 1))^2; zero beyond */
    float r_max_t;         /* 2D: the same for the T block */
    float d_t_cut;         /* 2D: T is zero for thicker slabs (it carries < LU_BSSRDF_T_FLOOR of R there) */
    float d_lo, d_hi;      /* 2D: row j at d = d_lo (d_hi / d_lo)^(j / (nd - 1)) */
    float *table;          /* rgb triples: kind 0: nr; kind 1: R block nr*nd then T block (row-major by d);
                            * `levels` such tables one after the other (see lu_bssrdf_profile_prefilter) */
    int levels;            /* 1 until prefiltered */
    float rho0;            /* level k >= 1 is averaged over discs of radius rho0 sqrt(2)^(k - 1) */
    float mfp;             /* longest reduced mean free path of the stack (1 / min sigma_t') */
    /* 2D: the T block holds T(r, d) e^{min(k d, LU_BSSRDF_DECAY_CAP)} with k the
     * (base layer's) sigma_tr per channel, which makes it nearly flat along d
     * so that interpolating between rows stays accurate. */
    float t_decay[3];
    /* Energy bookkeeping (kind 0; kind 1: the thickest row's reflectance): */
    double total_closed[3];   /* closed form (dipole, Burley: the albedo; multipole: 1D Green's function;
                               * pbd: the (albedo, radius) table's own integral) */
    double total_numeric[3];  /* Simpson of 2 pi r R(r) over [0, infinity) in log r */
    double total_table[3];    /* 2 pi r times the table as interpolated, over [0, r_max] */
} lu_bssrdf_profile;

lu_result lu_bssrdf_profile_build(const lu_bssrdf_layer *layers, int layer_count, const lu_bssrdf_profile_desc *desc,
                                  lu_bssrdf_profile *out, lu_error *err);
void lu_bssrdf_profile_destroy(lu_bssrdf_profile *p);

/* Adds levels 1 .. levels-1: the profile averaged over a disc of radius
 * rho_k = rho0 sqrt(2)^(k-1) around the entry point,
 *   P_k(r) = 1/(pi rho_k^2) int_{|y| < rho_k} P(|x - y|) dy,  |x| = r,
 * so that a sample standing for a surface cell of that size adds the
 * profile integrated over its cell (a quadrature exact for irradiance
 * constant over the cell) instead of the profile at one point. Level 0
 * stays the point-sampled profile. */
lu_result lu_bssrdf_profile_prefilter(lu_bssrdf_profile *p, int levels, float rho0, lu_error *err);
/* Entries (rgb triples) in one level. */
size_t lu_bssrdf_profile_level_entries(const lu_bssrdf_profile *p);

/* Table lookups on the CPU (the renderer uses the kernel lu_bssrdf.h, which
 * reads the same layout). */
lu_vec3 lu_bssrdf_profile_eval(const lu_bssrdf_profile *p, float r, float d, int transmit);

/* The splat radius for one channel's profile f (thesis Eq. 4.3, weighted by
 * 2 pi r so that eps is the fraction of the reflected power outside r_max):
 * composite Simpson in t = ln r over [r_lo, r_hi], n even. Returns r_max and
 * the integral. */
typedef double (*lu_bssrdf_radial_fn)(const void *ctx, double r);
double lu_bssrdf_eps_radius(lu_bssrdf_radial_fn f, const void *ctx, double r_lo, double r_hi, int n, double eps,
                            double *total);

/* Total reflectance and transmittance of a slab by the 1D diffusion Green's
 * function (the multipole sum integrated over the plane, summed in closed
 * form): one channel; d = INFINITY gives the dipole total. */
void lu_bssrdf_slab_totals(double sigma_sp, double sigma_a, double eta_top, double eta_bottom, double d, double *r_total,
                           double *t_total);

/* The reduced albedo alpha' = sigma_s' / sigma_t' whose half-space total
 * diffuse reflectance (the dipole's closed form, which the dipole, the
 * thick-slab multipole and normalised diffusion all integrate to) is
 * `albedo` behind relative index eta: bisection, the total rising
 * monotonically in alpha'. albedo in (0, 1]. */
double lu_bssrdf_invert_albedo(double albedo, double eta);

/* ---- multi-layer combination (frequency domain) ------------------------------ */

/* A layer's spectra on a fft_size^2 grid of spacing h, origin at texel
 * (0, 0) with wrap-around: R from above and from below, T downwards and
 * upwards (diffusion with different boundary conditions on the two faces is
 * not reciprocal, so all four are kept). */
typedef struct lu_bssrdf_spectra lu_bssrdf_spectra;

/* From radial profiles sampled at r_k = k dr, k < n (values beyond: 0); a
 * NULL profile gives zero spectra (for terms a caller knows it never uses). The
 * 2D arrays are scaled so their sums times h^2 equal the Simpson integrals
 * of f over the grid's square (so the DC term carries the exact total). */
lu_result lu_bssrdf_spectra_from_radial(const float *r_top, const float *r_bottom, const float *t_down,
                                        const float *t_up, int n, double dr, int fft_size, double h,
                                        lu_bssrdf_spectra **out, lu_error *err);
/* The empty layer: R = 0, T = identity (a Dirac delta). */
lu_result lu_bssrdf_spectra_identity(int fft_size, double h, lu_bssrdf_spectra **out, lu_error *err);
/* top over bottom (thesis Eq. 3.10, 3.12: T12 = T1 T2 / (1 - R2 R1'),
 * R12 = R1 + T1 R2 T1' / (1 - R2 R1'), primes for the sides facing each
 * other); out may alias neither input. */
lu_result lu_bssrdf_spectra_stack(const lu_bssrdf_spectra *top, const lu_bssrdf_spectra *bottom,
                                  lu_bssrdf_spectra **out, lu_error *err);
/* Radial profiles of the stack back in space (R from above, T downwards):
 * values at r_k = k h, k < n (n <= fft_size / 2 + 1). */
lu_result lu_bssrdf_spectra_radial(const lu_bssrdf_spectra *s, float *r_top, float *t, int n, lu_error *err);
/* The DC term (the plane integral, i.e. the total) of R from above or T downwards. */
double lu_bssrdf_spectra_dc(const lu_bssrdf_spectra *s, int transmit);
void lu_bssrdf_spectra_destroy(lu_bssrdf_spectra *s);

/* Material coefficients of a scene material as a layer stack (coatings
 * first, the material itself last), reduced scattering (1 - g) sigma_s. */
int lu_bssrdf_material_layers(const lu_material *m, lu_bssrdf_layer *layers, int max_layers);

#endif
