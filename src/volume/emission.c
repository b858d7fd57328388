/* Emission of media: blackbody colour and the per-point Le of a medium
 * (include/lucent/scene.h; docs/volumes.md "Emission"). */
#include <lucent/lucent.h>

#include <math.h>
#include <pthread.h>
#include <string.h>

#include "kernels/lu_scene_layout.h"
#include "volume/grid_internal.h"

/* CIE 1931 2-degree colour matching functions, the multi-lobe piecewise
 * Gaussian fit of Wyman, Sloan and Shirley 2013 ("Simple Analytic
 * Approximations to the CIE XYZ Color Matching Functions", Eq. 2-4). */
static double wyman_g(double x, double mu, double s1, double s2) {
    double t = (x - mu) / (x < mu ? s1 : s2);
    return exp(-0.5 * t * t);
}
static void cmf(double nm, double *x, double *y, double *z) {
    *x = 1.056 * wyman_g(nm, 599.8, 37.9, 31.0) + 0.362 * wyman_g(nm, 442.0, 16.0, 26.7) -
         0.065 * wyman_g(nm, 501.1, 20.4, 26.2);
    *y = 0.821 * wyman_g(nm, 568.8, 46.9, 40.5) + 0.286 * wyman_g(nm, 530.9, 16.3, 31.1);
    *z = 1.217 * wyman_g(nm, 437.0, 11.8, 36.0) + 0.681 * wyman_g(nm, 459.0, 26.0, 13.8);
}

/* Planck's spectral radiance at wavelength nm (arbitrary common factor). */
static double planck(double nm, double kelvin) {
    const double c = 299792458.0, h = 6.62606957e-34, kb = 1.3806488e-23;
    double l = nm * 1e-9;
    return (2.0 * h * c * c) / (pow(l, 5.0) * (exp((h * c) / (l * kb * kelvin)) - 1.0));
}

lu_vec3 lu_blackbody_rgb_exact(double kelvin) {
    if (!(kelvin > 100.0)) return lu_v3s(0.0f);
    /* Peak-normalised (Wien's displacement law), so the spectrum's largest
     * value is 1 whatever T: le_scale sets the brightness. */
    double norm = 1.0 / planck(2.8977721e-3 / kelvin * 1e9, kelvin);
    /* Composite Simpson over 360-830 nm in 0.5 nm steps: the integrand is
     * smooth (the fit's lobes have widths >= 11.8 nm). */
    const int n = 940;
    const double a = 360.0, b = 830.0, h = (b - a) / n;
    double X = 0, Y = 0, Z = 0, Yn = 0;
    for (int i = 0; i <= n; i++) {
        double nm = a + h * i, w = (i == 0 || i == n) ? 1.0 : (i % 2 ? 4.0 : 2.0);
        double x, y, z;
        cmf(nm, &x, &y, &z);
        double s = planck(nm, kelvin) * norm;
        X += w * s * x;
        Y += w * s * y;
        Z += w * s * z;
        Yn += w * y;
    }
    X /= Yn;
    Y /= Yn;
    Z /= Yn;
    /* XYZ -> linear sRGB (IEC 61966-2-1, D65). */
    double r = 3.2404542 * X - 1.5371385 * Y - 0.4985314 * Z;
    double g = -0.9692660 * X + 1.8760108 * Y + 0.0415560 * Z;
    double bl = 0.0556434 * X - 0.2040259 * Y + 1.0572252 * Z;
    return lu_v3((float)fmax(r, 0.0), (float)fmax(g, 0.0), (float)fmax(bl, 0.0));
}

/* Nodes uniform in log T from 100 K to 100000 K. Below ~3000 K the visible
 * part of the peak-normalised spectrum grows like exp(-c / (lambda T)), by
 * orders of magnitude across the range, so each channel is interpolated in
 * log value (near-linear there in log T): relative error below 1e-4
 * (tests/test_emission.c checks it against an independent quadrature). A
 * channel that is 0 at either node (clamped out of gamut, or below float
 * range) is interpolated linearly. */
#define BB_N LU_SCENE_BLACKBODY_N
#define BB_LO 100.0
#define BB_HI 100000.0
static float bb_val[BB_N][3], bb_log[BB_N][3];
static pthread_once_t bb_once = PTHREAD_ONCE_INIT;

static void bb_build(void) {
    for (int i = 0; i < BB_N; i++) {
        double t = BB_LO * pow(BB_HI / BB_LO, (double)i / (BB_N - 1));
        lu_vec3 c = lu_blackbody_rgb_exact(i == 0 ? BB_LO * (1.0 + 1e-9) : t);
        for (int ch = 0; ch < 3; ch++) {
            bb_val[i][ch] = lu_v3_get(c, ch);
            bb_log[i][ch] = bb_val[i][ch] > 0.0f ? logf(bb_val[i][ch]) : 0.0f;
        }
    }
}

lu_vec3 lu_blackbody_rgb(float kelvin) {
    if (!(kelvin > (float)BB_LO)) return lu_v3s(0.0f);
    pthread_once(&bb_once, bb_build);
    double u = log((double)kelvin / BB_LO) / log(BB_HI / BB_LO) * (BB_N - 1);
    if (u >= BB_N - 1) return lu_v3(bb_val[BB_N - 1][0], bb_val[BB_N - 1][1], bb_val[BB_N - 1][2]);
    int i = (int)u;
    float f = (float)(u - i), out[3];
    for (int ch = 0; ch < 3; ch++) {
        float a = bb_val[i][ch], b = bb_val[i + 1][ch];
        out[ch] = a > 0.0f && b > 0.0f ? expf(bb_log[i][ch] + f * (bb_log[i + 1][ch] - bb_log[i][ch]))
                                       : a + f * (b - a);
    }
    return lu_v3(out[0], out[1], out[2]);
}

void lu_blackbody_table(float *rgb) {
    pthread_once(&bb_once, bb_build);
    memcpy(rgb, bb_val, sizeof bb_val);
}

lu_vec3 lu_medium_emission(const lu_medium *m, lu_vec3 p) {
    lu_vec3 c = lu_v3_scale(m->le_color, m->le_scale);
    switch (m->emission) {
    case LU_EMISSION_CONSTANT: return c;
    case LU_EMISSION_GRID: return lu_v3_scale(c, lu_grid_sample(&m->emission_grid, p));
    case LU_EMISSION_BLACKBODY: {
        float t = (lu_grid_sample(&m->emission_grid, p) - m->temp_offset) * m->temp_scale;
        return lu_v3_mul(c, lu_blackbody_rgb(t));
    }
    default: return lu_v3s(0.0f);
    }
}

lu_vec3 lu_medium_emission_max(const lu_medium *m) {
    lu_vec3 c = lu_v3_scale(m->le_color, m->le_scale);
    switch (m->emission) {
    case LU_EMISSION_CONSTANT: return c;
    case LU_EMISSION_GRID: return lu_v3_scale(c, fmaxf(m->emission_grid.max_value, 0.0f));
    case LU_EMISSION_BLACKBODY: {
        /* Trilinear values lie in [min, max] of the grid; the mapped range
         * is scanned at the table's own nodes (B is piecewise linear there). */
        float a = (m->emission_grid.min_value - m->temp_offset) * m->temp_scale;
        float b = (m->emission_grid.max_value - m->temp_offset) * m->temp_scale;
        if (a > b) {
            float t = a;
            a = b;
            b = t;
        }
        lu_vec3 mx = lu_v3_max(lu_blackbody_rgb(a), lu_blackbody_rgb(b));
        for (int i = 0; i < BB_N; i++) {
            float t = (float)(BB_LO * pow(BB_HI / BB_LO, (double)i / (BB_N - 1)));
            if (t > a && t < b) mx = lu_v3_max(mx, lu_blackbody_rgb(t));
        }
        return lu_v3_mul(c, mx);
    }
    default: return lu_v3s(0.0f);
    }
}
