/* Error metrics between a test image and a reference, and the false-colour
 * difference image. */
#include "image/image_internal.h"

#include <stdlib.h>
#include <string.h>

static lu_result check_pair(const lu_image *a, const lu_image *b, lu_error *err) {
    if (!a || !b || !a->rgb || !b->rgb)
        return lu_fail(err, LU_ERR_INVALID_ARG, "image comparison: an image is empty");
    if (a->width != b->width || a->height != b->height)
        return lu_fail(err, LU_ERR_INVALID_ARG, "image comparison: sizes differ (%dx%d vs %dx%d)", a->width,
                       a->height, b->width, b->height);
    const lu_image *imgs[2] = {a, b};
    const size_t n = (size_t)a->width * a->height * 3;
    for (int k = 0; k < 2; k++)
        for (size_t i = 0; i < n; i++)
            if (!isfinite(imgs[k]->rgb[i]))
                return lu_fail(err, LU_ERR_NONFINITE, "image comparison: image %c pixel (%d, %d) channel %d is %s",
                               "ab"[k], (int)(i / 3 % a->width), (int)(i / 3 / a->width), (int)(i % 3),
                               isnan(imgs[k]->rgb[i]) ? "NaN" : "infinite");
    return LU_OK;
}

static double ratio_of_sums(double a, double b) {
    if (b != 0) return a / b;
    return a == 0 ? 1.0 : INFINITY;
}

lu_result lu_image_compare(const lu_image *a, const lu_image *b, lu_metrics *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    lu_result res = check_pair(a, b, err);
    if (res != LU_OK) return res;
    const size_t n = (size_t)a->width * a->height * 3;
    double d2 = 0, b2 = 0, d1 = 0, b1 = 0, max_abs = 0, peak = -INFINITY, sa[3] = {0}, sb[3] = {0};
    for (size_t i = 0; i < n; i++) {
        double bv = b->rgb[i], d = (double)a->rgb[i] - bv;
        sa[i % 3] += a->rgb[i];
        sb[i % 3] += bv;
        d2 += d * d;
        b2 += bv * bv;
        d1 += fabs(d);
        b1 += fabs(bv);
        if (fabs(d) > max_abs) max_abs = fabs(d);
        if (bv > peak) peak = bv;
    }
    /* A zero reference gives 0 for a perfect match and +inf otherwise. */
    out->rel_l2 = b2 > 0 ? sqrt(d2) / sqrt(b2) : (d2 > 0 ? INFINITY : 0.0);
    out->rel_l1 = b1 > 0 ? d1 / b1 : (d1 > 0 ? INFINITY : 0.0);
    const double mse = d2 / (double)n;
    out->rmse = sqrt(mse);
    if (peak <= 0) peak = 1;
    out->psnr = mse > 0 ? 10.0 * log10(peak * peak / mse) : INFINITY;
    out->max_abs = max_abs;
    for (int c = 0; c < 3; c++) out->mean_ratio_rgb[c] = ratio_of_sums(sa[c], sb[c]);
    out->mean_ratio = ratio_of_sums(sa[0] + sa[1] + sa[2], sb[0] + sb[1] + sb[2]);
    return LU_OK;
}

lu_result lu_image_block_average(const lu_image *in, int k, lu_image *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    if (!in || !in->rgb) return lu_fail(err, LU_ERR_INVALID_ARG, "block average: the image is empty");
    if (k < 1 || k > in->width || k > in->height)
        return lu_fail(err, LU_ERR_INVALID_ARG, "block average: block size %d not in [1, %d] for a %dx%d image", k,
                       in->width < in->height ? in->width : in->height, in->width, in->height);
    lu_result res = lu_image_create(out, in->width / k, in->height / k, err);
    if (res != LU_OK) return res;
    const double w = 1.0 / ((double)k * k);
    for (int by = 0; by < out->height; by++)
        for (int bx = 0; bx < out->width; bx++) {
            double s[3] = {0};
            for (int y = by * k; y < (by + 1) * k; y++)
                for (int x = bx * k; x < (bx + 1) * k; x++) {
                    const float *p = lu_image_px(in, x, y);
                    for (int c = 0; c < 3; c++) s[c] += p[c];
                }
            float *o = lu_image_px(out, bx, by);
            for (int c = 0; c < 3; c++) o[c] = (float)(s[c] * w);
        }
    return LU_OK;
}

/* ---- the ramp ----------------------------------------------------------
 * Built in CIE LCh(ab): lightness L* = 100 t exactly, hue turning from purple
 * through red and orange to yellow, chroma as large as the sRGB gamut allows
 * up to a target that vanishes at both ends (black and white). */

static float lab_finv(float f) {
    const float d = 6.0f / 29.0f;
    return f > d ? f * f * f : 3.0f * d * d * (f - 4.0f / 29.0f);
}

static void lch_to_linear_srgb(float L, float C, float h_deg, float rgb[3]) {
    float h = h_deg * (LU_PI / 180.0f);
    float fy = (L + 16.0f) / 116.0f, fx = fy + C * cosf(h) / 500.0f, fz = fy - C * sinf(h) / 200.0f;
    float X = 0.95047f * lab_finv(fx), Y = lab_finv(fy), Z = 1.08883f * lab_finv(fz); /* D65 white */
    rgb[0] = 3.2404542f * X - 1.5371385f * Y - 0.4985314f * Z;
    rgb[1] = -0.9692660f * X + 1.8760108f * Y + 0.0415560f * Z;
    rgb[2] = 0.0556434f * X - 0.2040259f * Y + 1.0572252f * Z;
}

static bool in_gamut(const float rgb[3]) {
    const float eps = 1e-6f;
    for (int c = 0; c < 3; c++)
        if (rgb[c] < -eps || rgb[c] > 1.0f + eps) return false;
    return true;
}

void lu_false_colour_ramp(float t, float rgb[3]) {
    t = t > 0.0f ? (t < 1.0f ? t : 1.0f) : 0.0f; /* NaN -> 0 */
    const float L = 100.0f * t, h = 300.0f + 170.0f * t, target = 260.0f * t * (1.0f - t);
    float lo = 0.0f, hi = target; /* bisect the largest in-gamut chroma <= target */
    lch_to_linear_srgb(L, hi, h, rgb);
    if (!in_gamut(rgb)) {
        for (int i = 0; i < 24; i++) {
            float mid = 0.5f * (lo + hi);
            lch_to_linear_srgb(L, mid, h, rgb);
            if (in_gamut(rgb)) lo = mid;
            else hi = mid;
        }
        lch_to_linear_srgb(L, lo, h, rgb);
    }
    for (int c = 0; c < 3; c++) rgb[c] = rgb[c] < 0.0f ? 0.0f : (rgb[c] > 1.0f ? 1.0f : rgb[c]);
}

/* k-th smallest of v[0..n) by quickselect with a three-way partition, which
 * stays fast when most values are equal (difference images are mostly 0). */
static float select_kth(float *v, size_t n, size_t k) {
    size_t lo = 0, hi = n; /* the answer lies in v[lo, hi) */
    while (hi - lo > 1) {
        float x = v[lo], y = v[lo + (hi - lo) / 2], z = v[hi - 1];
        float pivot = fmaxf(fminf(x, y), fminf(fmaxf(x, y), z)); /* median of three */
        size_t lt = lo, i = lo, gt = hi;
        while (i < gt) {
            float t = v[i];
            if (t < pivot) v[i++] = v[lt], v[lt++] = t;
            else if (t > pivot) v[i] = v[--gt], v[gt] = t;
            else i++;
        }
        if (k < lt) hi = lt;
        else if (k >= gt) lo = gt;
        else return pivot;
    }
    return v[lo];
}

lu_result lu_image_diff_false_colour(const lu_image *a, const lu_image *b, float scale, lu_image *out,
                                     lu_error *err) {
    memset(out, 0, sizeof *out);
    lu_result res = check_pair(a, b, err);
    if (res != LU_OK) return res;
    if (!isfinite(scale) || scale < 0)
        return lu_fail(err, LU_ERR_RANGE, "false-colour scale %g must be finite and >= 0 (0 = automatic)", scale);
    const size_t n = (size_t)a->width * a->height;
    float *d = lu_malloc(n * sizeof *d);
    if (!d) return lu_fail(err, LU_ERR_NOMEM, "false-colour difference: out of memory");
    float dmax = 0;
    for (size_t i = 0; i < n; i++) {
        const float *p = a->rgb + 3 * i, *q = b->rgb + 3 * i;
        d[i] = 0.2126f * fabsf(p[0] - q[0]) + 0.7152f * fabsf(p[1] - q[1]) + 0.0722f * fabsf(p[2] - q[2]);
        if (d[i] > dmax) dmax = d[i];
    }
    if (scale == 0) {
        float *tmp = lu_malloc(n * sizeof *tmp);
        if (!tmp) {
            lu_free(d);
            return lu_fail(err, LU_ERR_NOMEM, "false-colour difference: out of memory");
        }
        memcpy(tmp, d, n * sizeof *tmp);
        scale = select_kth(tmp, n, (size_t)(0.99 * (double)(n - 1)));
        lu_free(tmp);
        if (scale <= 0) scale = dmax; /* mostly-equal images: show the few differences */
    }
    if ((res = lu_image_create(out, a->width, a->height, err)) == LU_OK) {
        enum { LUT = 1024 };
        float lut[LUT + 1][3];
        for (int i = 0; i <= LUT; i++) lu_false_colour_ramp((float)i / LUT, lut[i]);
        for (size_t i = 0; i < n; i++) {
            float t = scale > 0 ? d[i] / scale : 0.0f;
            t = (t < 1.0f ? t : 1.0f) * LUT;
            int k = (int)t;
            float f = t - (float)k;
            const float *c0 = lut[k], *c1 = lut[k < LUT ? k + 1 : LUT];
            for (int c = 0; c < 3; c++) out->rgb[3 * i + c] = c0[c] + f * (c1[c] - c0[c]);
        }
    }
    lu_free(d);
    return res;
}
