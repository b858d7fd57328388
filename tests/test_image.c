/* Images: PNG / EXR / PFM round trips and hand-made files, the sRGB curve,
 * metrics against closed forms, the false-colour ramp, malformed inputs. */
#define _XOPEN_SOURCE 700 /* truncate, mkdir */
#include <lucent/lucent.h>

#include <OpenEXR/openexr.h>
#include <png.h>
#include <stdint.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "lu_test.h"

/* The call (which fills `err`) must fail with `want`, and the message must
 * contain s1 and, when not NULL, s2. */
#define CHECK_FAIL(call, want, s1, s2)                                                                          \
    do {                                                                                                        \
        lu_result r_ = (call);                                                                                  \
        const char *s2_ = (s2);                                                                                 \
        CHECK_MSG(r_ == (want), "got %s, want %s: %s", lu_result_name(r_), lu_result_name(want), err.message); \
        CHECK_MSG(strstr(err.message, (s1)) != NULL, "\"%s\" not in \"%s\"", (s1), err.message);               \
        CHECK_MSG(!s2_ || strstr(err.message, s2_) != NULL, "\"%s\" not in \"%s\"", s2_, err.message);         \
    } while (0)

static uint32_t rng_state = 12345u;
static float rnd(void) { /* uniform in [0, 1) */
    rng_state = rng_state * 1664525u + 1013904223u;
    return (float)(rng_state >> 8) / 16777216.0f;
}

static void write_bytes(const char *path, const void *data, size_t n) {
    FILE *fp = fopen(path, "wb");
    if (!fp) return;
    fwrite(data, 1, n, fp);
    fclose(fp);
}

static bool exists(const char *path) { return access(path, F_OK) == 0; }

static void make_image(lu_image *img, int w, int h, float lo, float hi) {
    lu_error err;
    CHECK_OK(lu_image_create(img, w, h, &err), &err);
    for (size_t i = 0; i < (size_t)w * h * 3; i++) img->rgb[i] = lo + (hi - lo) * rnd();
}

/* ---- sRGB ---------------------------------------------------------------- */

static void test_srgb_known_values(void) {
    CHECK(lu_srgb_encode(0.0f) == 0.0f);
    CHECK_NEAR(lu_srgb_encode(0.0031308f), 0.04045, 1e-6); /* the two branches meet here */
    CHECK_NEAR(lu_srgb_encode(0.5f), 0.735356983, 1e-6);  /* 1.055 * 0.5^(1/2.4) - 0.055 */
    CHECK_NEAR(lu_srgb_encode(1.0f), 1.0, 1e-6);
    CHECK(lu_srgb_encode(-1.0f) == 0.0f && lu_srgb_encode(NAN) == 0.0f);
    CHECK_NEAR(lu_srgb_decode(0.735356983f), 0.5, 1e-6);
    CHECK_NEAR(lu_srgb_decode(0.04045f), 0.0031308, 1e-7);
    CHECK_NEAR(lu_srgb_decode(1.0f), 1.0, 1e-6);
    /* Gamma 2.2 would give 0.5^(1/2.2) = 0.7297; the exact curve differs by 0.006. */
    CHECK(fabs(lu_srgb_encode(0.5f) - 0.72974) > 0.005);
    double worst = 0;
    for (int i = 0; i <= 1000; i++) {
        float x = i / 1000.0f;
        worst = fmax(worst, fabs(lu_srgb_decode(lu_srgb_encode(x)) - x));
    }
    CHECK_NEAR(worst, 0, 1e-6);
}

/* ---- PFM ----------------------------------------------------------------- */

static void test_pfm_round_trip_exact(void) {
    lu_error err;
    lu_image a, b;
    make_image(&a, 23, 17, -5.0f, 1000.0f);
    a.rgb[0] = 1e-30f, a.rgb[1] = -0.0f, a.rgb[2] = 3.4e38f;
    const char *path = "test_image_rt.pfm";
    CHECK_OK(lu_image_save(&a, path, NULL, &err), &err);
    CHECK_OK(lu_image_load(path, &b, &err), &err);
    CHECK(b.width == 23 && b.height == 17);
    CHECK(b.rgb && memcmp(a.rgb, b.rgb, sizeof(float) * 23 * 17 * 3) == 0);
    /* The header is exactly what the format page describes, little-endian. */
    FILE *fp = fopen(path, "rb");
    char head[16] = {0};
    CHECK(fp && fread(head, 1, 13, fp) == 13);
    if (fp) fclose(fp);
    CHECK(memcmp(head, "PF\n23 17\n-1.0", 13) == 0);
    remove(path);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

static void test_pfm_hand_written(void) {
    lu_error err;
    lu_image img;
    /* Grey, big-endian (scale > 0). First row in the file is the image's bottom row. */
    const unsigned char grey[] = {'P', 'f', '\n', '2', ' ', '2', '\n', '1', '.', '0', '\n',
                                  0x3f, 0x80, 0, 0, /* 1.0  -> (0, 1) */
                                  0x40, 0x00, 0, 0, /* 2.0  -> (1, 1) */
                                  0x3f, 0x00, 0, 0, /* 0.5  -> (0, 0) */
                                  0xc0, 0x40, 0, 0}; /* -3.0 -> (1, 0) */
    write_bytes("test_image_grey.pfm", grey, sizeof grey);
    CHECK_OK(lu_image_load("test_image_grey.pfm", &img, &err), &err);
    if (img.rgb) {
        CHECK(img.width == 2 && img.height == 2);
        const float want[2][2] = {{0.5f, -3.0f}, {1.0f, 2.0f}}; /* [y][x], row 0 on top */
        for (int y = 0; y < 2; y++)
            for (int x = 0; x < 2; x++)
                for (int c = 0; c < 3; c++) CHECK(lu_image_px(&img, x, y)[c] == want[y][x]);
    }
    lu_image_destroy(&img);
    remove("test_image_grey.pfm");

    /* Colour, little-endian, width and height on separate lines, 1x2. */
    const unsigned char rgb[] = {'P', 'F', '\n', '1', '\n', '2', '\n', '-', '2', '\n',
                                 0, 0, 0x80, 0x3e, 0, 0, 0, 0x3f, 0, 0, 0x80, 0x3f,   /* 0.25 0.5 1 (bottom) */
                                 0, 0, 0x80, 0x40, 0, 0, 0, 0x41, 0, 0, 0x80, 0x41}; /* 4 8 16 (top) */
    write_bytes("test_image_rgb.pfm", rgb, sizeof rgb);
    CHECK_OK(lu_image_load("test_image_rgb.pfm", &img, &err), &err);
    if (img.rgb) {
        CHECK(img.width == 1 && img.height == 2);
        CHECK(img.rgb[0] == 4 && img.rgb[1] == 8 && img.rgb[2] == 16);
        CHECK(img.rgb[3] == 0.25f && img.rgb[4] == 0.5f && img.rgb[5] == 1);
    }
    lu_image_destroy(&img);
    remove("test_image_rgb.pfm");
}

static void test_pfm_malformed(void) {
    lu_error err;
    lu_image img;
    const char *p = "test_image_bad.pfm";
    /* Header "PF\n2 2\n-1\n" is 10 bytes; 48 bytes of pixels are due, 20 are there. */
    unsigned char buf[64] = "PF\n2 2\n-1\n";
    write_bytes(p, buf, 10 + 20);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 30: truncated");
    CHECK(img.rgb == NULL && img.width == 0);

    /* NaN in the second float of the only pixel: byte 10 + 4. */
    const float px[3] = {1.0f, NAN, 2.0f};
    memcpy(buf, "PF\n1 1\n-1\n", 10);
    memcpy(buf + 10, px, sizeof px); /* the test host is little-endian, like the header says */
    write_bytes(p, buf, 10 + sizeof px);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_NONFINITE, p, "byte 14");
    CHECK(strstr(err.message, "NaN") != NULL);

    /* Absurd size, no pixel data at all: rejected at the width, before any read or allocation. */
    write_bytes(p, "PF\n100000 100000\n-1\n", 20);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_LIMIT, p, "byte 3");
    /* Allowed size, but the file cannot hold it: caught from the file size, before allocating. */
    write_bytes(p, "PF\n16384 16384\n-1\n", 18);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 18: truncated");
    write_bytes(p, "PF\n16 16385\n-1\n", 15);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_LIMIT, p, "byte 6");
    write_bytes(p, "PF\n99999999999999999999999 1\n-1\n", 32);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_LIMIT, p, "byte 3");

    write_bytes(p, "P6\n2 2\n255\n", 11);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 0: bad magic");
    write_bytes(p, "PF\n0 2\n-1\n", 10);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 3");
    write_bytes(p, "PF\n2 x2\n-1\n", 11);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 5");
    write_bytes(p, "PF\n2 2\n0.0\n", 11);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 7: scale is zero");
    write_bytes(p, "PF\n2 2\nnan\n", 11);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_NONFINITE, p, "byte 7");
    write_bytes(p, "PF\n2 2", 6);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "truncated header");
    remove(p);
}

/* ---- EXR ----------------------------------------------------------------- */

static void test_exr_float_round_trip_exact(void) {
    lu_error err;
    lu_image a, b;
    make_image(&a, 37, 21, -2.0f, 50.0f); /* 21 rows: the last ZIP chunk is partial */
    a.rgb[5] = 1e-38f, a.rgb[6] = 3e38f;
    const char *path = "test_image_rt.exr";
    CHECK_OK(lu_image_save(&a, path, NULL, &err), &err);
    CHECK_OK(lu_image_load(path, &b, &err), &err);
    CHECK(b.width == 37 && b.height == 21);
    CHECK(b.rgb && memcmp(a.rgb, b.rgb, sizeof(float) * 37 * 21 * 3) == 0);
    remove(path);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

/* A frame whose first ZIP chunk deflates to exactly its packed size: the
 * OpenEXR library stores the zlib bytes then and readers take them for raw
 * pixels, so this file came back with NaN values before lu_exr_save stored
 * the packed pixels in that case (src/image/exr.c). */
static void test_exr_zip_equal_size(void) {
    lu_error err;
    lu_image a = {0}, b = {0};
    CHECK_OK(lu_image_load(LU_SOURCE_DIR "/tests/data/exr_zip_equal_size.pfm", &a, &err), &err);
    const char *path = "test_image_zip_equal.exr";
    CHECK_OK(lu_image_save(&a, path, NULL, &err), &err);
    CHECK_OK(lu_image_load(path, &b, &err), &err);
    CHECK(a.rgb && b.rgb && b.width == a.width && b.height == a.height);
    if (a.rgb && b.rgb && b.width == a.width && b.height == a.height)
        CHECK(memcmp(a.rgb, b.rgb, sizeof(float) * 3 * a.width * a.height) == 0);
    remove(path);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

static void test_exr_half_round_trip(void) {
    lu_error err;
    lu_image a, b;
    make_image(&a, 20, 19, 0.0f, 1.0f);
    for (size_t i = 0; i < 20 * 19 * 3; i++) a.rgb[i] = powf(10.0f, -3.0f + 6.0f * a.rgb[i]); /* 1e-3 .. 1e3 */
    a.rgb[0] = 0.5f, a.rgb[1] = 1.25f, a.rgb[2] = 1024.0f;                                 /* exact in half */
    const char *path = "test_image_half.exr";
    lu_image_save_desc desc = {.exr_half = true};
    CHECK_OK(lu_image_save(&a, path, &desc, &err), &err);
    CHECK_OK(lu_image_load(path, &b, &err), &err);
    if (b.rgb) {
        /* Half has an 11-bit significand: round to nearest is within 2^-11 relative for normals (>= 2^-14). */
        double worst = 0;
        for (size_t i = 0; i < 20 * 19 * 3; i++) worst = fmax(worst, fabs(b.rgb[i] - a.rgb[i]) / a.rgb[i]);
        CHECK(worst <= 1.0 / 2048.0);
        CHECK(worst > 1e-5); /* really stored as half, not float */
        CHECK(b.rgb[0] == 0.5f && b.rgb[1] == 1.25f && b.rgb[2] == 1024.0f);
    }
    struct stat sf, sh;
    CHECK_OK(lu_image_save(&a, "test_image_full.exr", NULL, &err), &err);
    CHECK(stat(path, &sh) == 0 && stat("test_image_full.exr", &sf) == 0 && sh.st_size < sf.st_size);
    remove("test_image_full.exr");
    remove(path);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

/* Writes a one-channel EXR with OpenEXR's C API directly (tiled when tile > 0)
 * so the loader meets layouts and pixel types our writer never produces. */
static exr_result_t write_exr_channel(const char *path, int w, int h, int tile, const char *name,
                                      exr_pixel_type_t type, const void *data) {
    exr_context_t ctx = NULL;
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    int part = 0, bpe = type == EXR_PIXEL_HALF ? 2 : 4;
    exr_result_t rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (!rv) rv = exr_add_part(ctx, NULL, tile ? EXR_STORAGE_TILED : EXR_STORAGE_SCANLINE, &part);
    if (!rv) rv = exr_initialize_required_attr_simple(ctx, part, w, h, EXR_COMPRESSION_ZIP);
    if (!rv && tile) rv = exr_set_tile_descriptor(ctx, part, tile, tile, EXR_TILE_ONE_LEVEL, EXR_TILE_ROUND_DOWN);
    if (!rv) rv = exr_add_channel(ctx, part, name, type, EXR_PERCEPTUALLY_LINEAR, 1, 1);
    if (!rv) rv = exr_write_header(ctx);
    int32_t lines = 1;
    if (!rv && !tile) rv = exr_get_scanlines_per_chunk(ctx, part, &lines);
    int step_x = tile ? tile : w, step_y = tile ? tile : lines;
    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    bool started = false;
    for (int y = 0; !rv && y < h; y += step_y)
        for (int x = 0; !rv && x < w; x += step_x) {
            exr_chunk_info_t ci;
            rv = tile ? exr_write_tile_chunk_info(ctx, part, x / tile, y / tile, 0, 0, &ci)
                      : exr_write_scanline_chunk_info(ctx, part, y, &ci);
            if (!rv && started) rv = exr_encoding_update(ctx, part, &ci, &enc);
            else if (!rv) rv = exr_encoding_initialize(ctx, part, &ci, &enc);
            if (rv) break;
            started = true;
            enc.channels[0].encode_from_ptr = (const uint8_t *)data + ((size_t)y * w + x) * bpe;
            enc.channels[0].user_pixel_stride = bpe;
            enc.channels[0].user_line_stride = bpe * w;
            enc.channels[0].user_data_type = (uint16_t)type;
            enc.channels[0].user_bytes_per_element = (int16_t)bpe;
            rv = exr_encoding_choose_default_routines(ctx, part, &enc);
            if (!rv) rv = exr_encoding_run(ctx, part, &enc);
        }
    if (started) exr_encoding_destroy(ctx, &enc);
    exr_result_t fin = exr_finish(&ctx);
    return rv ? rv : fin;
}

static void test_exr_tiled_uint_grey(void) {
    lu_error err;
    lu_image img;
    enum { W = 19, H = 13 }; /* 8x8 tiles, partial at the right and bottom */
    uint32_t *v = malloc(sizeof(uint32_t) * W * H);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) v[y * W + x] = (uint32_t)(x + 1000 * y);
    const char *path = "test_image_tiled.exr";
    CHECK(write_exr_channel(path, W, H, 8, "Y", EXR_PIXEL_UINT, v) == EXR_ERR_SUCCESS);
    CHECK_OK(lu_image_load(path, &img, &err), &err);
    if (img.rgb) {
        CHECK(img.width == W && img.height == H);
        int bad = 0;
        for (int y = 0; y < H; y++)
            for (int x = 0; x < W; x++)
                for (int c = 0; c < 3; c++) bad += lu_image_px(&img, x, y)[c] != (float)(x + 1000 * y);
        CHECK(bad == 0);
    }
    lu_image_destroy(&img);
    /* A channel set we cannot show: clear error, not a guess. */
    CHECK(write_exr_channel(path, W, H, 0, "Z", EXR_PIXEL_UINT, v) == EXR_ERR_SUCCESS);
    CHECK_FAIL(lu_image_load(path, &img, &err), LU_ERR_UNSUPPORTED, path, "needs R, G and B channels or a Y channel");
    free(v);
    remove(path);
}

static void test_exr_malformed(void) {
    lu_error err;
    lu_image img;
    const char *p = "test_image_bad.exr";
    unsigned char junk[256];
    for (int i = 0; i < 256; i++) junk[i] = (unsigned char)(rnd() * 256);
    write_bytes(p, junk, sizeof junk);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 0");

    /* Right magic, garbage after it: the library's own header check, mapped. */
    junk[0] = 0x76, junk[1] = 0x2f, junk[2] = 0x31, junk[3] = 0x01;
    write_bytes(p, junk, sizeof junk);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "OpenEXR read error");

    /* A valid file cut short inside the pixel data. */
    lu_image a;
    make_image(&a, 64, 64, 0.0f, 1.0f);
    CHECK_OK(lu_image_save(&a, p, NULL, &err), &err);
    struct stat st;
    CHECK(stat(p, &st) == 0);
    CHECK(truncate(p, st.st_size / 2) == 0);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "OpenEXR read error");
    CHECK(strstr(err.message, ": byte ") != NULL);
    CHECK(img.rgb == NULL);

    /* Non-finite pixels are rejected with the pixel named. */
    lu_image_px(&a, 5, 7)[1] = INFINITY;
    CHECK_OK(lu_image_save(&a, p, NULL, &err), &err);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_NONFINITE, p, "pixel (5, 7) channel G is infinite");
    lu_image_destroy(&a);

    /* Wider than LU_MAX_IMAGE_DIM: rejected from the header. */
    uint16_t *row = calloc(20000, sizeof *row);
    CHECK(write_exr_channel(p, 20000, 1, 0, "Y", EXR_PIXEL_HALF, row) == EXR_ERR_SUCCESS);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_LIMIT, p, "20000x1");
    free(row);
    remove(p);
}

/* ---- PNG ----------------------------------------------------------------- */

static double srgb_decode_d(double c) { return c <= 0.04045 ? c / 12.92 : pow((c + 0.055) / 1.055, 2.4); }
static double srgb_encode_d(double v) { return v <= 0.0031308 ? 12.92 * v : 1.055 * pow(v, 1 / 2.4) - 0.055; }

static void test_png_round_trip(void) {
    lu_error err;
    lu_image a, b;
    make_image(&a, 31, 9, 0.0f, 1.0f);
    const char *path = "test_image_rt.png";
    CHECK_OK(lu_image_save(&a, path, NULL, &err), &err);
    CHECK_OK(lu_image_load(path, &b, &err), &err);
    if (b.rgb) {
        CHECK(b.width == 31 && b.height == 9);
        /* Stored byte q = round(255 enc(v)), so |enc(v) - q/255| <= 0.5/255 and the
         * decoded value lies in [dec(enc(v) - 0.5/255), dec(enc(v) + 0.5/255)]. */
        int bad = 0;
        for (size_t i = 0; i < 31 * 9 * 3; i++) {
            double e = srgb_encode_d(a.rgb[i]);
            double lo = srgb_decode_d(fmax(0, e - 0.5 / 255)), hi = srgb_decode_d(fmin(1, e + 0.5 / 255));
            bad += !(b.rgb[i] >= lo - 1e-6 && b.rgb[i] <= hi + 1e-6);
        }
        CHECK_MSG(bad == 0, "%d values outside the 8-bit sRGB quantisation bound", bad);
    }
    lu_image_destroy(&b);
    /* Exposure doubles before encoding; out-of-range values clamp to 0 and 255. */
    a.rgb[0] = 0.25f, a.rgb[1] = 5.0f, a.rgb[2] = -1.0f;
    lu_image_save_desc desc = {.exposure = 1.0f};
    CHECK_OK(lu_image_save(&a, path, &desc, &err), &err);
    CHECK_OK(lu_image_load(path, &b, &err), &err);
    if (b.rgb) {
        CHECK_NEAR(b.rgb[0], srgb_decode_d(188 / 255.0), 1e-6); /* 255 enc(0.5) = 187.52 -> 188 */
        CHECK(b.rgb[1] == 1.0f && b.rgb[2] == 0.0f);
    }
    remove(path);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

/* Writes an 8- or 16-bit PNG of any colour type with libpng directly. */
static void write_png_raw(const char *path, int w, int h, int depth, int type, const png_color *pal, int npal,
                          unsigned char *data, size_t rowbytes) {
    FILE *fp = fopen(path, "wb");
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, NULL, NULL, NULL);
    png_infop info = png_create_info_struct(png);
    png_init_io(png, fp);
    png_set_IHDR(png, info, w, h, depth, type, PNG_INTERLACE_NONE, PNG_COMPRESSION_TYPE_DEFAULT,
                 PNG_FILTER_TYPE_DEFAULT);
    const png_byte trns[1] = {0}; /* palette entry 0 fully transparent: alpha must be dropped */
    if (pal) png_set_PLTE(png, info, pal, npal), png_set_tRNS(png, info, trns, 1, NULL);
    png_write_info(png, info);
    for (int y = 0; y < h; y++) png_write_row(png, data + y * rowbytes);
    png_write_end(png, NULL);
    png_destroy_write_struct(&png, &info);
    fclose(fp);
}

static void test_png_other_layouts(void) {
    lu_error err;
    lu_image img;
    const char *path = "test_image_layout.png";
    /* 16-bit grey + alpha, 2x1: grey 0x8000 and 0xffff, big-endian samples; alpha dropped. */
    unsigned char ga16[8] = {0x80, 0x00, 0x12, 0x34, 0xff, 0xff, 0x00, 0x00};
    write_png_raw(path, 2, 1, 16, PNG_COLOR_TYPE_GRAY_ALPHA, NULL, 0, ga16, sizeof ga16);
    CHECK_OK(lu_image_load(path, &img, &err), &err);
    if (img.rgb) {
        for (int c = 0; c < 3; c++) {
            CHECK_NEAR(img.rgb[c], srgb_decode_d(32768 / 65535.0), 1e-6);
            CHECK_NEAR(img.rgb[3 + c], 1.0, 1e-6);
        }
    }
    lu_image_destroy(&img);
    /* 8-bit palette with a tRNS chunk, 3x1 pixels using entries 2, 0, 1. */
    const png_color pal[3] = {{255, 0, 0}, {0, 128, 0}, {10, 20, 30}};
    unsigned char idx[3] = {2, 0, 1};
    write_png_raw(path, 3, 1, 8, PNG_COLOR_TYPE_PALETTE, pal, 3, idx, sizeof idx);
    CHECK_OK(lu_image_load(path, &img, &err), &err);
    if (img.rgb) {
        const int want[9] = {10, 20, 30, 255, 0, 0, 0, 128, 0};
        for (int i = 0; i < 9; i++) CHECK_NEAR(img.rgb[i], srgb_decode_d(want[i] / 255.0), 1e-6);
    }
    lu_image_destroy(&img);
    remove(path);
}

static void test_png_malformed(void) {
    lu_error err;
    lu_image img, a;
    const char *p = "test_image_bad.png";
    make_image(&a, 40, 40, 0.0f, 1.0f);
    CHECK_OK(lu_image_save(&a, p, NULL, &err), &err);
    struct stat st;
    CHECK(stat(p, &st) == 0);
    CHECK(truncate(p, st.st_size / 2) == 0);
    char at[32];
    snprintf(at, sizeof at, "byte %lld", (long long)(st.st_size / 2)); /* where the data ran out */
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, at);
    CHECK(img.rgb == NULL);
    CHECK(truncate(p, 5) == 0);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 0: not a PNG");
    /* A valid IHDR declaring 16384x16384 RGB, then the start of an IDAT: far too
     * short for that size even at deflate's best ratio, rejected before allocating. */
    unsigned char hdr[8 + 25 + 8 + 16] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n', 0, 0, 0, 13, 'I', 'H', 'D', 'R',
                                         0, 0, 0x40, 0, 0, 0, 0x40, 0, 8, 2, 0, 0, 0};
    uLong crc = crc32(0, hdr + 12, 17);
    for (int i = 0; i < 4; i++) hdr[29 + i] = (unsigned char)(crc >> (24 - 8 * i));
    memcpy(hdr + 33, "\0\0\0\x10IDAT", 8);
    write_bytes(p, hdr, sizeof hdr);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 57: file too short for a 16384x16384 PNG");
    write_bytes(p, "GIF89a....", 10);
    CHECK_FAIL(lu_image_load(p, &img, &err), LU_ERR_FORMAT, p, "byte 0: not a PNG");
    lu_image_destroy(&a);
    remove(p);
}

/* ---- common failures ------------------------------------------------------- */

static void test_missing_and_unwritable(void) {
    lu_error err;
    lu_image img, a;
    const char *missing[] = {"no_such_file.png", "no_such_file.exr", "no_such_file.pfm", "no_such_file.xyz"};
    for (int i = 0; i < 4; i++) CHECK_FAIL(lu_image_load(missing[i], &img, &err), LU_ERR_IO, missing[i], NULL);

    make_image(&a, 4, 4, 0.0f, 1.0f);
    const char *dirs[] = {"no_such_dir/out.png", "no_such_dir/out.exr", "no_such_dir/out.pfm"};
    for (int i = 0; i < 3; i++) {
        CHECK_FAIL(lu_image_save(&a, dirs[i], NULL, &err), LU_ERR_IO, dirs[i], NULL);
        CHECK(!exists(dirs[i]) && !exists("no_such_dir"));
    }
    /* Final name is a directory: the data is written, the rename fails, and the
     * temporary file is removed, so nothing half-written remains. */
    const char *names[] = {"test_image_isdir.png", "test_image_isdir.exr", "test_image_isdir.pfm"};
    for (int i = 0; i < 3; i++) {
        mkdir(names[i], 0755);
        CHECK_FAIL(lu_image_save(&a, names[i], NULL, &err), LU_ERR_IO, names[i], NULL);
        char tmp[256];
        snprintf(tmp, sizeof tmp, "%s.tmp.%ld", names[i], (long)getpid());
        CHECK(!exists(tmp));
        rmdir(names[i]);
    }
    CHECK_FAIL(lu_image_save(&a, "test_image.bmp", NULL, &err), LU_ERR_INVALID_ARG, "test_image.bmp", NULL);
    CHECK(!exists("test_image.bmp"));
    lu_image_destroy(&a);

    CHECK(lu_image_create(&img, LU_MAX_IMAGE_DIM + 1, 1, &err) == LU_ERR_LIMIT && img.rgb == NULL);
    CHECK(lu_image_create(&img, 0, 5, &err) == LU_ERR_INVALID_ARG && img.rgb == NULL);
    CHECK(lu_image_format_from_path("a/b.EXR") == LU_IMAGE_EXR);
    CHECK(lu_image_format_from_path("a.pfm") == LU_IMAGE_PFM);
    CHECK(lu_image_format_from_path("a.png") == LU_IMAGE_PNG);
    CHECK(lu_image_format_from_path("a.exr/b") == LU_IMAGE_AUTO);
}

/* ---- metrics --------------------------------------------------------------- */

static void test_metrics_closed_form(void) {
    lu_error err;
    lu_image a, b;
    lu_metrics m;
    enum { W = 5, H = 3, N = W * H * 3 };
    CHECK_OK(lu_image_create(&a, W, H, &err), &err);
    CHECK_OK(lu_image_create(&b, W, H, &err), &err);
    /* b = 1 everywhere, a = b + 0.25 (exact in float): every value off by d = 0.25.
     * rel_l2 = sqrt(N d^2) / sqrt(N) = d, rel_l1 = d, rmse = d,
     * psnr = 10 log10(1 / d^2) = 20 log10(4), max_abs = d. */
    for (int i = 0; i < N; i++) b.rgb[i] = 1.0f, a.rgb[i] = 1.25f;
    CHECK_OK(lu_image_compare(&a, &b, &m, &err), &err);
    CHECK_NEAR(m.rel_l2, 0.25, 1e-12);
    CHECK_NEAR(m.rel_l1, 0.25, 1e-12);
    CHECK_NEAR(m.rmse, 0.25, 1e-12);
    CHECK_NEAR(m.psnr, 20 * log10(4.0), 1e-9);
    CHECK_NEAR(m.max_abs, 0.25, 1e-12);

    /* b = 2 everywhere, a equal except one value 0.5 higher and one 1.5 lower:
     * sum d^2 = 0.25 + 2.25 = 2.5, ||b||^2 = 4N, sum|d| = 2, sum|b| = 2N, peak 2. */
    for (int i = 0; i < N; i++) b.rgb[i] = a.rgb[i] = 2.0f;
    a.rgb[7] = 2.5f, a.rgb[30] = 0.5f;
    CHECK_OK(lu_image_compare(&a, &b, &m, &err), &err);
    CHECK_NEAR(m.rel_l2, sqrt(2.5) / sqrt(4.0 * N), 1e-12);
    CHECK_NEAR(m.rel_l1, 2.0 / (2.0 * N), 1e-12);
    CHECK_NEAR(m.rmse, sqrt(2.5 / N), 1e-12);
    CHECK_NEAR(m.psnr, 10 * log10(4.0 / (2.5 / N)), 1e-9);
    CHECK_NEAR(m.max_abs, 1.5, 1e-12);

    /* Reference not positive: peak is 1. Equal images: psnr +inf, errors 0. */
    for (int i = 0; i < N; i++) b.rgb[i] = 0.0f, a.rgb[i] = 0.0f;
    a.rgb[0] = 0.1f;
    CHECK_OK(lu_image_compare(&a, &b, &m, &err), &err);
    CHECK_NEAR(m.psnr, 10 * log10(1.0 / ((double)0.1f * 0.1f / N)), 1e-9);
    CHECK(isinf(m.rel_l2) && m.rel_l2 > 0);
    CHECK_OK(lu_image_compare(&b, &b, &m, &err), &err);
    CHECK(isinf(m.psnr) && m.psnr > 0 && m.rel_l2 == 0 && m.rmse == 0 && m.max_abs == 0);

    a.rgb[4] = NAN;
    CHECK(lu_image_compare(&a, &b, &m, &err) == LU_ERR_NONFINITE);
    CHECK(strstr(err.message, "image a pixel (1, 0) channel 1 is NaN") != NULL);
    lu_image c;
    CHECK_OK(lu_image_create(&c, W + 1, H, &err), &err);
    CHECK(lu_image_compare(&c, &b, &m, &err) == LU_ERR_INVALID_ARG);
    CHECK(strstr(err.message, "6x3 vs 5x3") != NULL);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
    lu_image_destroy(&c);
}

/* Block averages by hand, and what they are for: pixel noise of zero mean
 * within each block vanishes, so two images differing by it compare equal. */
static void test_block_average_and_mean_ratio(void) {
    lu_error err;
    lu_image a, b, ab, bb;
    lu_metrics m;
    enum { W = 7, H = 5 }; /* 3 x 2 blocks of 2 x 2; column 6 and row 4 are dropped */
    CHECK_OK(lu_image_create(&a, W, H, &err), &err);
    CHECK_OK(lu_image_create(&b, W, H, &err), &err);
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) {
                float base = (float)(1 + x / 2 + 10 * (y / 2) + 100 * c);
                lu_image_px(&b, x, y)[c] = base;
                /* +-0.5 checkerboard: zero mean over every 2 x 2 block */
                lu_image_px(&a, x, y)[c] = base + (((x + y) & 1) ? 0.5f : -0.5f);
            }
    lu_image_px(&a, 6, 0)[0] = 1e6f; /* outside every whole block */
    CHECK_OK(lu_image_block_average(&a, 2, &ab, &err), &err);
    CHECK_OK(lu_image_block_average(&b, 2, &bb, &err), &err);
    CHECK(ab.width == 3 && ab.height == 2);
    for (int by = 0; by < 2; by++)
        for (int bx = 0; bx < 3; bx++)
            for (int c = 0; c < 3; c++) {
                CHECK_NEAR(lu_image_px(&ab, bx, by)[c], 1 + bx + 10 * by + 100 * c, 1e-5);
                CHECK_NEAR(lu_image_px(&bb, bx, by)[c], 1 + bx + 10 * by + 100 * c, 1e-5);
            }
    CHECK_OK(lu_image_compare(&ab, &bb, &m, &err), &err);
    CHECK(m.rel_l2 == 0 && m.mean_ratio == 1);
    lu_image_destroy(&ab);
    lu_image_destroy(&bb);
    CHECK(lu_image_block_average(&a, 6, &ab, &err) == LU_ERR_INVALID_ARG);
    CHECK(strstr(err.message, "block size 6 not in [1, 5]") != NULL);
    CHECK(lu_image_block_average(&a, 0, &ab, &err) == LU_ERR_INVALID_ARG);
    CHECK_OK(lu_image_block_average(&a, 1, &ab, &err), &err); /* k = 1 is a copy */
    CHECK(ab.width == W && ab.height == H && memcmp(ab.rgb, a.rgb, sizeof(float) * W * H * 3) == 0);
    lu_image_destroy(&ab);

    /* mean ratio: a = 2 b in red, = b in green, 0 in blue. */
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++) {
            float *pa = lu_image_px(&a, x, y), *pb = lu_image_px(&b, x, y);
            pa[0] = 2 * pb[0], pa[1] = pb[1], pa[2] = 0;
        }
    CHECK_OK(lu_image_compare(&a, &b, &m, &err), &err);
    double s[3] = {0};
    for (int y = 0; y < H; y++)
        for (int x = 0; x < W; x++)
            for (int c = 0; c < 3; c++) s[c] += lu_image_px(&b, x, y)[c];
    CHECK_NEAR(m.mean_ratio_rgb[0], 2.0, 1e-12);
    CHECK_NEAR(m.mean_ratio_rgb[1], 1.0, 1e-12);
    CHECK_NEAR(m.mean_ratio_rgb[2], 0.0, 1e-12);
    CHECK_NEAR(m.mean_ratio, (2 * s[0] + s[1]) / (s[0] + s[1] + s[2]), 1e-12);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

static void test_false_colour(void) {
    lu_error err;
    lu_image a, b, out;
    /* The ramp: L* = 100 t exactly (checked through Y of linear sRGB), black to white. */
    for (int i = 0; i <= 20; i++) {
        float t = i / 20.0f, rgb[3];
        lu_false_colour_ramp(t, rgb);
        double Y = 0.2126729 * rgb[0] + 0.7151522 * rgb[1] + 0.0721750 * rgb[2];
        double f = Y > 216.0 / 24389.0 ? cbrt(Y) : (24389.0 / 27.0 * Y + 16) / 116;
        CHECK_NEAR(116 * f - 16, 100 * t, 0.3);
    }
    float c[3];
    lu_false_colour_ramp(0.0f, c);
    CHECK(c[0] == 0 && c[1] == 0 && c[2] == 0);
    lu_false_colour_ramp(0.3f, c);
    CHECK(c[2] > c[1] && c[0] > c[1]); /* purple-red */
    lu_false_colour_ramp(0.8f, c);
    CHECK(c[0] > c[2] && c[1] > c[2]); /* orange-yellow */

    /* 10x10 image, difference luminance d = k / 100 for pixel k = 1..100 (grey
     * differences, so luminance = d). The 99th percentile (index floor(0.99 * 99)
     * = 98 of the sorted values) is 0.99, so d = 0.5 maps to t = 0.5 / 0.99. */
    CHECK_OK(lu_image_create(&a, 10, 10, &err), &err);
    CHECK_OK(lu_image_create(&b, 10, 10, &err), &err);
    for (int k = 0; k < 100; k++)
        for (int ch = 0; ch < 3; ch++) a.rgb[3 * k + ch] = 1.0f, b.rgb[3 * k + ch] = 1.0f + (k + 1) / 100.0f;
    CHECK_OK(lu_image_diff_false_colour(&a, &b, 0.0f, &out, &err), &err);
    CHECK(out.width == 10 && out.height == 10);
    float want[3];
    lu_false_colour_ramp(0.5f / 0.99f, want);
    for (int ch = 0; ch < 3; ch++) CHECK_NEAR(out.rgb[3 * 49 + ch], want[ch], 2e-3);
    lu_false_colour_ramp(1.0f, want);
    for (int ch = 0; ch < 3; ch++) CHECK_NEAR(out.rgb[3 * 99 + ch], want[ch], 1e-6);
    lu_image_destroy(&out);
    /* Explicit scale 2: d = 0.5 maps to t = 0.25. */
    CHECK_OK(lu_image_diff_false_colour(&a, &b, 2.0f, &out, &err), &err);
    lu_false_colour_ramp(0.25f, want);
    for (int ch = 0; ch < 3; ch++) CHECK_NEAR(out.rgb[3 * 49 + ch], want[ch], 2e-3);
    lu_image_destroy(&out);
    /* Equal images: every pixel is the ramp's start, black. */
    CHECK_OK(lu_image_diff_false_colour(&a, &a, 0.0f, &out, &err), &err);
    int nonzero = 0;
    for (int i = 0; i < 300; i++) nonzero += out.rgb[i] != 0.0f;
    CHECK(out.width == 10 && out.height == 10 && nonzero == 0);
    lu_image_destroy(&out);
    CHECK(lu_image_diff_false_colour(&a, &b, -1.0f, &out, &err) == LU_ERR_RANGE);
    lu_image_destroy(&a);
    lu_image_destroy(&b);
}

int main(void) {
    RUN_TEST(test_srgb_known_values);
    RUN_TEST(test_pfm_round_trip_exact);
    RUN_TEST(test_pfm_hand_written);
    RUN_TEST(test_pfm_malformed);
    RUN_TEST(test_exr_float_round_trip_exact);
    RUN_TEST(test_exr_zip_equal_size);
    RUN_TEST(test_exr_half_round_trip);
    RUN_TEST(test_exr_tiled_uint_grey);
    RUN_TEST(test_exr_malformed);
    RUN_TEST(test_png_round_trip);
    RUN_TEST(test_png_other_layouts);
    RUN_TEST(test_png_malformed);
    RUN_TEST(test_missing_and_unwritable);
    RUN_TEST(test_metrics_closed_form);
    RUN_TEST(test_block_average_and_mean_ratio);
    RUN_TEST(test_false_colour);
    TEST_EXIT();
}
