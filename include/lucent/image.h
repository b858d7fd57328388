/* lucent/image.h — linear RGB float images, PNG/EXR/PFM I/O, error metrics.
 *
 * Pixels are linear radiance, 3 floats each, row 0 at the top. PNG output
 * applies exposure and the sRGB transfer curve; EXR and PFM store the floats
 * as they are (PFM rows are flipped on disk as the format requires). */
#ifndef LUCENT_IMAGE_H
#define LUCENT_IMAGE_H

#include "core.h"
#include "math.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct lu_image {
    int width, height;
    float *rgb;            /* width * height * 3, row-major, top row first */
} lu_image;

lu_result lu_image_create(lu_image *img, int width, int height, lu_error *err); /* zero-filled */
void lu_image_destroy(lu_image *img);
static inline float *lu_image_px(const lu_image *img, int x, int y) { return img->rgb + 3 * ((size_t)y * img->width + x); }

typedef enum lu_image_format { LU_IMAGE_AUTO = 0, LU_IMAGE_PNG, LU_IMAGE_EXR, LU_IMAGE_PFM } lu_image_format;

/* Format from the extension (.png .exr .pfm), LU_IMAGE_AUTO if unknown. */
lu_image_format lu_image_format_from_path(const char *path);

typedef struct lu_image_save_desc {
    lu_image_format format;  /* 0: from the path's extension */
    float exposure;          /* PNG only: multiply by 2^exposure before sRGB; 0 = none */
    bool exr_half;           /* EXR only: store half floats (default: 32-bit float) */
} lu_image_save_desc;

/* Writes atomically (temporary name, then rename). desc may be NULL. */
lu_result lu_image_save(const lu_image *img, const char *path, const lu_image_save_desc *desc, lu_error *err);
/* Loads PNG (sRGB decoded to linear), EXR (R,G,B channels; Y as grey) or PFM
 * (colour "PF" or grey "Pf"). Rejects non-finite values and sizes over
 * LU_MAX_IMAGE_DIM with the file name and reason. */
lu_result lu_image_load(const char *path, lu_image *img, lu_error *err);

/* The exact piecewise sRGB transfer function (IEC 61966-2-1), not gamma 2.2.
 * Inputs <= 0 (and NaN) map to 0; encode does not clamp above 1. */
float lu_srgb_encode(float linear);
float lu_srgb_decode(float encoded);

/* ---- metrics ---------------------------------------------------------- */

typedef struct lu_metrics {
    double rel_l2;   /* ||a - b||_2 / ||b||_2 over all channels (b is the reference) */
    double rel_l1;   /* sum |a - b| / sum |b| */
    double rmse;     /* sqrt(mean (a - b)^2) */
    double psnr;     /* 10 log10(peak^2 / mse), peak = max value of b (1 if b <= 0); +inf if equal */
    double max_abs;  /* largest |a - b| */
    double mean_ratio;       /* sum a / sum b over all channels (+inf if sum b is 0 and sum a is not, 1 if both are) */
    double mean_ratio_rgb[3]; /* the same per channel */
} lu_metrics;

/* Sizes must match. */
lu_result lu_image_compare(const lu_image *a, const lu_image *b, lu_metrics *out, lu_error *err);
/* *out = in averaged over k x k pixel blocks: (width / k) x (height / k), a
 * partial block at the right or bottom edge dropped. Comparing block averages
 * removes most of a Monte Carlo image's per-pixel noise (its variance falls by
 * k^2) while keeping structure coarser than k. k >= 1, at most the smaller
 * side. *out is created here and the caller destroys it. */
lu_result lu_image_block_average(const lu_image *in, int k, lu_image *out, lu_error *err);
/* False-colour |a - b| per pixel (luminance of the difference), mapped through
 * a perceptual colour ramp; scale 0 picks the 99th percentile as full scale.
 * *out is created here (linear RGB; save it as PNG with exposure 0 to see the
 * ramp's display colours) and the caller destroys it. */
lu_result lu_image_diff_false_colour(const lu_image *a, const lu_image *b, float scale, lu_image *out,
                                     lu_error *err);
/* The ramp itself, t in [0, 1] (clamped) to linear RGB: CIE L* rises linearly
 * from 0 (black) to 100 (white) through purple, red, orange and yellow, so
 * lightness alone orders the values. */
void lu_false_colour_ramp(float t, float rgb[3]);

#ifdef __cplusplus
}
#endif
#endif
