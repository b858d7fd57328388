/* Image storage, format dispatch and the sRGB transfer curve. */
#include "image/image_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

lu_result lu_image_create(lu_image *img, int width, int height, lu_error *err) {
    memset(img, 0, sizeof *img);
    if (width <= 0 || height <= 0)
        return lu_fail(err, LU_ERR_INVALID_ARG, "image size %dx%d: both sides must be positive", width, height);
    if (width > LU_MAX_IMAGE_DIM || height > LU_MAX_IMAGE_DIM)
        return lu_fail(err, LU_ERR_LIMIT, "image size %dx%d exceeds the limit of %d per side", width, height,
                       LU_MAX_IMAGE_DIM);
    img->rgb = lu_calloc((size_t)width * (size_t)height * 3, sizeof(float));
    if (!img->rgb) return lu_fail(err, LU_ERR_NOMEM, "out of memory for a %dx%d image", width, height);
    img->width = width;
    img->height = height;
    return LU_OK;
}

void lu_image_destroy(lu_image *img) {
    if (!img) return;
    lu_free(img->rgb);
    memset(img, 0, sizeof *img);
}

lu_result lu_image_check_dims(const char *path, long long width, long long height, lu_error *err) {
    if (width <= 0 || height <= 0)
        return lu_fail(err, LU_ERR_FORMAT, "%s: invalid image size %lldx%lld", path, width, height);
    if (width > LU_MAX_IMAGE_DIM || height > LU_MAX_IMAGE_DIM)
        return lu_fail(err, LU_ERR_LIMIT, "%s: image size %lldx%lld exceeds the limit of %d per side", path, width,
                       height, LU_MAX_IMAGE_DIM);
    return LU_OK;
}

float lu_srgb_encode(float linear) {
    if (!(linear > 0.0f)) return 0.0f; /* also maps NaN to 0 */
    if (linear <= 0.0031308f) return 12.92f * linear;
    return 1.055f * powf(linear, 1.0f / 2.4f) - 0.055f;
}

float lu_srgb_decode(float encoded) {
    if (!(encoded > 0.0f)) return 0.0f;
    if (encoded <= 0.04045f) return encoded / 12.92f;
    return powf((encoded + 0.055f) / 1.055f, 2.4f);
}

lu_image_format lu_image_format_from_path(const char *path) {
    const char *ext = lu_path_ext(path);
    if (strcmp(ext, "png") == 0) return LU_IMAGE_PNG;
    if (strcmp(ext, "exr") == 0) return LU_IMAGE_EXR;
    if (strcmp(ext, "pfm") == 0) return LU_IMAGE_PFM;
    return LU_IMAGE_AUTO;
}

lu_result lu_image_save(const lu_image *img, const char *path, const lu_image_save_desc *desc, lu_error *err) {
    static const lu_image_save_desc defaults = {0};
    if (!desc) desc = &defaults;
    if (!img || !img->rgb || img->width <= 0 || img->height <= 0)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: nothing to save (empty image)", path);
    if (!isfinite(desc->exposure))
        return lu_fail(err, LU_ERR_NONFINITE, "%s: exposure is not finite", path);
    lu_image_format fmt = desc->format != LU_IMAGE_AUTO ? desc->format : lu_image_format_from_path(path);
    switch (fmt) {
    case LU_IMAGE_PNG: return lu_png_save(img, path, desc->exposure, err);
    case LU_IMAGE_EXR: return lu_exr_save(img, path, desc->exr_half, err);
    case LU_IMAGE_PFM: return lu_pfm_save(img, path, err);
    default:
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: unknown image format (use a .png, .exr or .pfm extension)",
                       path);
    }
}

/* Files with an unknown extension are recognised by their first bytes. */
static lu_image_format sniff_format(const char *path) {
    unsigned char m[4] = {0};
    FILE *fp = fopen(path, "rb");
    if (!fp) return LU_IMAGE_AUTO;
    size_t n = fread(m, 1, sizeof m, fp);
    fclose(fp);
    if (n >= 4 && m[0] == 0x89 && m[1] == 'P' && m[2] == 'N' && m[3] == 'G') return LU_IMAGE_PNG;
    if (n >= 4 && m[0] == 0x76 && m[1] == 0x2f && m[2] == 0x31 && m[3] == 0x01) return LU_IMAGE_EXR;
    if (n >= 2 && m[0] == 'P' && (m[1] == 'F' || m[1] == 'f')) return LU_IMAGE_PFM;
    return LU_IMAGE_AUTO;
}

lu_result lu_image_load(const char *path, lu_image *img, lu_error *err) {
    memset(img, 0, sizeof *img);
    lu_image_format fmt = lu_image_format_from_path(path);
    if (fmt == LU_IMAGE_AUTO) fmt = sniff_format(path);
    switch (fmt) {
    case LU_IMAGE_PNG: return lu_png_load(path, img, err);
    case LU_IMAGE_EXR: return lu_exr_load(path, img, err);
    case LU_IMAGE_PFM: return lu_pfm_load(path, img, err);
    default: {
        FILE *fp = fopen(path, "rb");
        if (!fp) return lu_fail(err, LU_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
        fclose(fp);
        return lu_fail(err, LU_ERR_FORMAT, "%s: byte 0: not a PNG, OpenEXR or PFM file", path);
    }
    }
}
