/* Per-format entry points behind lu_image_save / lu_image_load. Each loader
 * leaves *img zeroed on failure, so lu_image_destroy is always safe. */
#ifndef LU_IMAGE_INTERNAL_H
#define LU_IMAGE_INTERNAL_H

#include <lucent/image.h>

lu_result lu_png_save(const lu_image *img, const char *path, float exposure, lu_error *err);
lu_result lu_png_load(const char *path, lu_image *img, lu_error *err);
lu_result lu_exr_save(const lu_image *img, const char *path, bool half, lu_error *err);
lu_result lu_exr_load(const char *path, lu_image *img, lu_error *err);
lu_result lu_pfm_save(const lu_image *img, const char *path, lu_error *err);
lu_result lu_pfm_load(const char *path, lu_image *img, lu_error *err);

/* Width/height check shared by every loader: LU_ERR_FORMAT for <= 0,
 * LU_ERR_LIMIT above LU_MAX_IMAGE_DIM. Call before allocating. */
lu_result lu_image_check_dims(const char *path, long long width, long long height, lu_error *err);

#endif
