/* PNG through libpng. libpng reports errors by longjmp; the callbacks below
 * turn them into an lu_error naming the file and the byte offset reached, and
 * keep libpng from printing anything itself. */
#include "image/image_internal.h"

#include <errno.h>
#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

typedef struct png_io {
    FILE *fp;
    const char *path;
    unsigned long long offset; /* bytes read so far (reading only) */
    char message[256];
} png_io;

static void on_error(png_structp png, png_const_charp msg) {
    png_io *io = png_get_error_ptr(png);
    snprintf(io->message, sizeof io->message, "%s", msg);
    png_longjmp(png, 1);
}

static void on_warning(png_structp png, png_const_charp msg) { (void)png, (void)msg; }

/* Our own reader, so a truncated file reports where it ended. */
static void read_bytes(png_structp png, png_bytep out, size_t n) {
    png_io *io = png_get_io_ptr(png);
    size_t got = fread(out, 1, n, io->fp);
    io->offset += got;
    if (got != n) png_error(png, ferror(io->fp) ? "read error" : "unexpected end of file");
}

/* Everything between setjmp and the last libpng call lives here, with all
 * locals set before setjmp, so nothing is clobbered by the longjmp. */
static lu_result encode_png(png_io *io, int w, int h, png_bytep *rows, lu_error *err) {
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, io, on_error, on_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!info) {
        png_destroy_write_struct(&png, NULL);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory creating the PNG writer", io->path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_write_struct(&png, &info);
        return lu_fail(err, LU_ERR_IO, "%s: PNG write error: %s", io->path, io->message);
    }
    png_init_io(png, io->fp);
    png_set_IHDR(png, info, (png_uint_32)w, (png_uint_32)h, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                 PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
    png_set_sRGB_gAMA_and_cHRM(png, info, PNG_sRGB_INTENT_PERCEPTUAL);
    png_write_info(png, info);
    png_write_image(png, rows);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    return LU_OK;
}

lu_result lu_png_save(const lu_image *img, const char *path, float exposure, lu_error *err) {
    const int w = img->width, h = img->height;
    const float gain = exp2f(exposure);
    png_bytep pixels = lu_malloc((size_t)w * h * 3);
    png_bytep *rows = lu_malloc((size_t)h * sizeof *rows);
    if (!pixels || !rows) {
        lu_free(pixels), lu_free(rows);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
    }
    for (size_t i = 0; i < (size_t)w * h * 3; i++) {
        float v = lu_srgb_encode(img->rgb[i] * gain); /* <= 0 and NaN give 0 */
        pixels[i] = (png_byte)lrintf(255.0f * (v < 1.0f ? v : 1.0f));
    }
    for (int y = 0; y < h; y++) rows[y] = pixels + (size_t)y * w * 3;
    lu_atomic_file f;
    lu_result res = lu_atomic_open(&f, path, err);
    if (res == LU_OK) {
        png_io io = {.fp = f.fp, .path = path};
        res = encode_png(&io, w, h, rows, err);
        if (res == LU_OK) res = lu_atomic_commit(&f, err);
        else lu_atomic_abort(&f);
    }
    lu_free(pixels);
    lu_free(rows);
    return res;
}

/* Reads the header, checks the size, then the pixels into *img. */
static lu_result decode_png(png_io *io, lu_image *img, png_bytep **rows_out,
                              png_bytep *pixels_out, lu_error *err) {
    png_structp png = png_create_read_struct(PNG_LIBPNG_VER_STRING, io, on_error, on_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    if (!info) {
        png_destroy_read_struct(&png, NULL, NULL);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory creating the PNG reader", io->path);
    }
    if (setjmp(png_jmpbuf(png))) {
        png_destroy_read_struct(&png, &info, NULL);
        return lu_fail(err, LU_ERR_FORMAT, "%s: byte %llu: PNG error: %s", io->path, io->offset, io->message);
    }
    png_set_read_fn(png, io, read_bytes);
    png_set_sig_bytes(png, 8);
    png_read_info(png, info);
    png_uint_32 w = png_get_image_width(png, info), h = png_get_image_height(png, info);
    lu_result res = lu_image_check_dims(io->path, w, h, err);
    if (res != LU_OK) {
        png_destroy_read_struct(&png, &info, NULL);
        return res;
    }
    /* Deflate expands at most 1032:1, so a file far too short for its declared
     * size is rejected here rather than after allocating the image. */
    struct stat st;
    double raw = (double)h * (1.0 + (double)png_get_rowbytes(png, info));
    if (fstat(fileno(io->fp), &st) == 0 && S_ISREG(st.st_mode) && raw > 1032.0 * (double)st.st_size + 65536.0) {
        png_destroy_read_struct(&png, &info, NULL);
        return lu_fail(err, LU_ERR_FORMAT, "%s: byte %lld: file too short for a %ux%u PNG", io->path,
                       (long long)st.st_size, w, h);
    }
    /* Normalise every colour type to 8- or 16-bit RGB; alpha is dropped. */
    int type = png_get_color_type(png, info), depth = png_get_bit_depth(png, info);
    if (type == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if ((type & PNG_COLOR_MASK_COLOR) == 0 && depth < 8) png_set_expand_gray_1_2_4_to_8(png);
    if ((type & PNG_COLOR_MASK_COLOR) == 0) png_set_gray_to_rgb(png);
    /* Expanding a palette also turns tRNS into alpha, so strip after that too. */
    if ((type & PNG_COLOR_MASK_ALPHA) || png_get_valid(png, info, PNG_INFO_tRNS)) png_set_strip_alpha(png);
    png_set_interlace_handling(png);
    png_read_update_info(png, info);
    const int bytes = png_get_bit_depth(png, info) == 16 ? 2 : 1;
    const size_t rowbytes = png_get_rowbytes(png, info);
    if (png_get_channels(png, info) != 3 || rowbytes != (size_t)w * 3 * bytes) {
        png_destroy_read_struct(&png, &info, NULL);
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: unexpected PNG layout after conversion to RGB", io->path);
    }
    png_bytep pixels = *pixels_out = lu_malloc(rowbytes * h);
    png_bytep *rows = *rows_out = lu_malloc(h * sizeof *rows);
    if (!pixels || !rows || lu_image_create(img, (int)w, (int)h, err) != LU_OK) {
        png_destroy_read_struct(&png, &info, NULL);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for a %ux%u image", io->path, w, h);
    }
    for (png_uint_32 y = 0; y < h; y++) rows[y] = pixels + y * rowbytes;
    png_read_image(png, rows);
    png_read_end(png, NULL);
    png_destroy_read_struct(&png, &info, NULL);

    float lut[256];
    for (int i = 0; i < 256; i++) lut[i] = lu_srgb_decode(i / 255.0f);
    const size_t n = (size_t)w * h * 3;
    for (size_t i = 0; i < n; i++)
        img->rgb[i] = bytes == 1 ? lut[pixels[i]]
                                 : lu_srgb_decode((float)((pixels[2 * i] << 8) | pixels[2 * i + 1]) / 65535.0f);
    return LU_OK;
}

lu_result lu_png_load(const char *path, lu_image *img, lu_error *err) {
    memset(img, 0, sizeof *img);
    FILE *fp = fopen(path, "rb");
    if (!fp) return lu_fail(err, LU_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    png_byte sig[8];
    size_t got = fread(sig, 1, sizeof sig, fp);
    if (got < sizeof sig || png_sig_cmp(sig, 0, sizeof sig) != 0) {
        fclose(fp);
        return lu_fail(err, LU_ERR_FORMAT, "%s: byte 0: not a PNG file (bad signature%s)", path,
                       got < sizeof sig ? ", file too short" : "");
    }
    png_io io = {.fp = fp, .path = path, .offset = 8};
    png_bytep *rows = NULL;
    png_bytep pixels = NULL;
    lu_result res = decode_png(&io, img, &rows, &pixels, err);
    lu_free(rows);
    lu_free(pixels);
    fclose(fp);
    if (res != LU_OK) lu_image_destroy(img);
    return res;
}
