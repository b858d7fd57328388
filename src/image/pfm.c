/* PFM: "PF" (RGB) or "Pf" (grey), then width, height and a scale whose sign
 * gives the byte order (negative = little-endian), separated by whitespace;
 * exactly one whitespace byte ends the header. Rows run bottom to top. */
#include "image/image_internal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

static bool host_little_endian(void) {
    const uint16_t one = 1;
    unsigned char b;
    memcpy(&b, &one, 1);
    return b == 1;
}

static void swap32(float *v, size_t n) {
    for (size_t i = 0; i < n; i++) {
        uint32_t u;
        memcpy(&u, &v[i], 4);
        u = (u >> 24) | ((u >> 8) & 0xff00u) | ((u << 8) & 0xff0000u) | (u << 24);
        memcpy(&v[i], &u, 4);
    }
}

typedef struct pfm_reader {
    FILE *fp;
    long off; /* bytes consumed so far */
} pfm_reader;

/* Reads one whitespace-delimited token and the byte that ends it. Returns its
 * length, 0 at end of file, -1 if it does not fit. *start is its offset. */
static int next_token(pfm_reader *r, char *tok, int cap, long *start, bool *hit_eof) {
    int c;
    while ((c = getc(r->fp)) != EOF && (c == ' ' || c == '\t' || c == '\n' || c == '\r')) r->off++;
    *start = r->off;
    int n = 0;
    for (; c != EOF && c != ' ' && c != '\t' && c != '\n' && c != '\r'; c = getc(r->fp)) {
        r->off++;
        if (n + 1 >= cap) return -1;
        tok[n++] = (char)c;
    }
    tok[n] = '\0';
    *hit_eof = c == EOF;
    if (c != EOF) r->off++; /* the delimiter */
    return n;
}

static lu_result read_dim(pfm_reader *r, const char *path, const char *what, long long *out, lu_error *err) {
    char tok[32];
    long start;
    bool eof;
    int n = next_token(r, tok, sizeof tok, &start, &eof);
    if (n == 0) return lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: truncated header (missing %s)", path, start, what);
    if (n < 0) return lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: %s is not a number", path, start, what);
    char *end;
    errno = 0;
    long long v = strtoll(tok, &end, 10);
    if (*end != '\0' || end == tok)
        return lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: %s \"%s\" is not an integer", path, start, what, tok);
    if (v <= 0) return lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: %s %lld must be positive", path, start, what, v);
    if (errno == ERANGE || v > LU_MAX_IMAGE_DIM)
        return lu_fail(err, LU_ERR_LIMIT, "%s: byte %ld: %s %s exceeds the limit of %d", path, start, what, tok,
                       LU_MAX_IMAGE_DIM);
    *out = v;
    return LU_OK;
}

static lu_result truncated(const char *path, long long at, long long w, long long h, int nc, long data_start,
                           lu_error *err) {
    return lu_fail(err, LU_ERR_FORMAT,
                   "%s: byte %lld: truncated pixel data (%lldx%lld %s needs %lld bytes from byte %ld)", path, at, w, h,
                   nc == 3 ? "PF" : "Pf", w * h * nc * 4, data_start);
}

lu_result lu_pfm_load(const char *path, lu_image *img, lu_error *err) {
    memset(img, 0, sizeof *img);
    FILE *fp = fopen(path, "rb");
    if (!fp) return lu_fail(err, LU_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    pfm_reader r = {fp, 0};
    float *row = NULL;
    lu_result res;
    char magic[3] = {0};
    if (fread(magic, 1, 2, fp) != 2 || magic[0] != 'P' || (magic[1] != 'F' && magic[1] != 'f')) {
        res = lu_fail(err, LU_ERR_FORMAT, "%s: byte 0: bad magic (expected \"PF\" or \"Pf\")", path);
        goto done;
    }
    r.off = 2;
    int c = getc(fp);
    if (c != ' ' && c != '\t' && c != '\n' && c != '\r') {
        res = lu_fail(err, LU_ERR_FORMAT, "%s: byte 2: bad magic (expected whitespace after \"%s\")", path, magic);
        goto done;
    }
    r.off = 3;
    const int nc = magic[1] == 'F' ? 3 : 1;
    long long w, h;
    if ((res = read_dim(&r, path, "width", &w, err)) != LU_OK) goto done;
    if ((res = read_dim(&r, path, "height", &h, err)) != LU_OK) goto done;

    char tok[64];
    long start;
    bool eof;
    int n = next_token(&r, tok, sizeof tok, &start, &eof);
    if (n < 0) {
        res = lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: scale is not a number", path, start);
        goto done;
    }
    if (n == 0 || eof) {
        res = lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: truncated header (missing scale or pixel data)", path, start);
        goto done;
    }
    char *end;
    double scale = strtod(tok, &end);
    if (*end != '\0') {
        res = lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: scale \"%s\" is not a number", path, start, tok);
        goto done;
    }
    if (!isfinite(scale)) {
        res = lu_fail(err, LU_ERR_NONFINITE, "%s: byte %ld: scale \"%s\" is not finite", path, start, tok);
        goto done;
    }
    if (scale == 0.0) {
        res = lu_fail(err, LU_ERR_FORMAT, "%s: byte %ld: scale is zero (its sign gives the byte order)", path, start);
        goto done;
    }
    const bool swap = (scale < 0) != host_little_endian();
    const long data_start = r.off;
    const size_t row_floats = (size_t)w * nc;
    const long long need = w * h * nc * 4;
    struct stat st;
    /* A short file is caught here, before a possibly large allocation. */
    if (fstat(fileno(fp), &st) == 0 && S_ISREG(st.st_mode) && st.st_size - data_start < need) {
        res = truncated(path, (long long)st.st_size, w, h, nc, data_start, err);
        goto done;
    }
    if ((res = lu_image_create(img, (int)w, (int)h, err)) != LU_OK) goto done;
    if (!(row = lu_malloc(row_floats * sizeof *row))) {
        res = lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
        goto done;
    }
    for (long long i = 0; i < h; i++) {
        size_t got = fread(row, sizeof *row, row_floats, fp);
        long long row_off = data_start + (long long)(i * row_floats * 4);
        if (got != row_floats) {
            res = truncated(path, row_off + (long long)got * 4, w, h, nc, data_start, err);
            goto done;
        }
        if (swap) swap32(row, row_floats);
        float *dst = lu_image_px(img, 0, (int)(h - 1 - i));
        for (size_t k = 0; k < row_floats; k++) {
            if (!isfinite(row[k])) {
                res = lu_fail(err, LU_ERR_NONFINITE, "%s: byte %lld: pixel (%lld, %lld) is %s", path,
                              row_off + (long long)k * 4, (long long)k / nc, h - 1 - i,
                              isnan(row[k]) ? "NaN" : "infinite");
                goto done;
            }
            if (nc == 3) dst[k] = row[k];
            else dst[3 * k] = dst[3 * k + 1] = dst[3 * k + 2] = row[k];
        }
    }
    res = LU_OK;
done:
    lu_free(row);
    fclose(fp);
    if (res != LU_OK) lu_image_destroy(img);
    return res;
}

lu_result lu_pfm_save(const lu_image *img, const char *path, lu_error *err) {
    lu_atomic_file f;
    lu_result res = lu_atomic_open(&f, path, err);
    if (res != LU_OK) return res;
    const size_t row_floats = (size_t)img->width * 3;
    float *row = lu_malloc(row_floats * sizeof *row);
    if (!row) {
        lu_atomic_abort(&f);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
    }
    bool ok = fprintf(f.fp, "PF\n%d %d\n-1.0\n", img->width, img->height) > 0;
    for (int y = img->height - 1; ok && y >= 0; y--) {
        memcpy(row, lu_image_px(img, 0, y), row_floats * sizeof *row);
        if (!host_little_endian()) swap32(row, row_floats);
        ok = fwrite(row, sizeof *row, row_floats, f.fp) == row_floats;
    }
    lu_free(row);
    if (!ok) {
        int e = errno;
        lu_atomic_abort(&f);
        return lu_fail(err, LU_ERR_IO, "%s: write failed: %s", path, strerror(e));
    }
    return lu_atomic_commit(&f, err);
}
