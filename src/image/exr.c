/* OpenEXR through the library's C API (OpenEXRCore). All file access goes
 * through the read/write callbacks below so the library never opens files
 * itself: reads see our descriptor, writes land in lu_atomic_file's temporary
 * file, which is renamed into place only after the library has finished. */
#include "image/image_internal.h"

#include <errno.h>
#include <fcntl.h>
#include <openexr.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct exr_io {
    int fd;
    const char *path;
    int sys_errno;     /* set when the operating system failed a read/write */
    uint64_t last_read; /* offset of the last read: where the failing structure starts */
    char message[512]; /* the library's first detailed message */
} exr_io;

static void on_error(exr_const_context_t ctxt, exr_result_t code, const char *msg) {
    void *ud = NULL;
    (void)code;
    if (exr_get_user_data(ctxt, &ud) != EXR_ERR_SUCCESS || !ud) return;
    exr_io *io = ud;
    if (!io->message[0]) snprintf(io->message, sizeof io->message, "%s", msg);
}

static int64_t read_fn(exr_const_context_t ctxt, void *ud, void *buf, uint64_t sz, uint64_t off,
                       exr_stream_error_func_ptr_t error_cb) {
    exr_io *io = ud;
    uint64_t done = 0;
    io->last_read = off;
    while (done < sz) {
        ssize_t n = pread(io->fd, (char *)buf + done, sz - done, (off_t)(off + done));
        if (n == 0) break; /* end of file: the library reports the short read */
        if (n < 0) {
            if (errno == EINTR) continue;
            io->sys_errno = errno;
            error_cb(ctxt, EXR_ERR_READ_IO, "read at byte %llu failed: %s", (unsigned long long)(off + done),
                     strerror(errno));
            return -1;
        }
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static int64_t size_fn(exr_const_context_t ctxt, void *ud) {
    struct stat st;
    (void)ctxt;
    return fstat(((exr_io *)ud)->fd, &st) == 0 ? (int64_t)st.st_size : -1;
}

static int64_t write_fn(exr_const_context_t ctxt, void *ud, const void *buf, uint64_t sz, uint64_t off,
                        exr_stream_error_func_ptr_t error_cb) {
    exr_io *io = ud;
    uint64_t done = 0;
    while (done < sz) {
        ssize_t n = pwrite(io->fd, (const char *)buf + done, sz - done, (off_t)(off + done));
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0) {
            io->sys_errno = n < 0 ? errno : EIO;
            error_cb(ctxt, EXR_ERR_WRITE_IO, "write at byte %llu failed: %s", (unsigned long long)(off + done),
                     strerror(io->sys_errno));
            return -1;
        }
        done += (uint64_t)n;
    }
    return (int64_t)done;
}

static lu_result exr_fail(const exr_io *io, exr_result_t rv, bool writing, lu_error *err) {
    lu_result code = LU_ERR_FORMAT;
    if (rv == EXR_ERR_OUT_OF_MEMORY) code = LU_ERR_NOMEM;
    else if (io->sys_errno || writing) code = LU_ERR_IO;
    else if (rv == EXR_ERR_FEATURE_NOT_IMPLEMENTED) code = LU_ERR_UNSUPPORTED;
    const char *msg = io->message[0] ? io->message : exr_get_default_error_message(rv);
    if (writing)
        return lu_fail(err, code, "%s: OpenEXR write error: %s (%s)", io->path, msg, exr_get_error_code_as_string(rv));
    return lu_fail(err, code, "%s: byte %llu: OpenEXR read error: %s (%s)", io->path,
                   (unsigned long long)io->last_read, msg, exr_get_error_code_as_string(rv));
}

/* Output slot of a channel: 0..2 for R, G, B, or 0 for Y in a grey file. */
static int channel_slot(const char *name, bool grey) {
    if (grey) return strcmp(name, "Y") == 0 ? 0 : -1;
    if (strcmp(name, "R") == 0) return 0;
    if (strcmp(name, "G") == 0) return 1;
    if (strcmp(name, "B") == 0) return 2;
    return -1;
}

/* Decodes one chunk whose first pixel lands at image pixel (x0, y0). */
static exr_result_t decode_chunk(exr_const_context_t ctx, const exr_chunk_info_t *ci, exr_decode_pipeline_t *dec,
                                 bool *started, lu_image *img, int x0, int y0, bool grey) {
    if (x0 < 0 || y0 < 0 || ci->width <= 0 || ci->height <= 0 || x0 + ci->width > img->width ||
        y0 + ci->height > img->height)
        return EXR_ERR_BAD_CHUNK_LEADER;
    exr_result_t rv = *started ? exr_decoding_update(ctx, 0, ci, dec) : exr_decoding_initialize(ctx, 0, ci, dec);
    if (rv != EXR_ERR_SUCCESS) return rv;
    *started = true;
    for (int c = 0; c < dec->channel_count; c++) {
        exr_coding_channel_info_t *cc = &dec->channels[c];
        int slot = channel_slot(cc->channel_name, grey);
        cc->decode_to_ptr = slot < 0 ? NULL : (uint8_t *)(lu_image_px(img, x0, y0) + slot);
        cc->user_pixel_stride = 3 * sizeof(float);
        cc->user_line_stride = 3 * sizeof(float) * img->width;
        cc->user_data_type = EXR_PIXEL_FLOAT;
        cc->user_bytes_per_element = sizeof(float);
    }
    rv = exr_decoding_choose_default_routines(ctx, 0, dec);
    return rv == EXR_ERR_SUCCESS ? exr_decoding_run(ctx, 0, dec) : rv;
}

static lu_result read_part(exr_context_t ctx, exr_io *io, lu_image *img, lu_error *err) {
    const char *path = io->path;
    exr_storage_t storage;
    exr_attr_box2i_t dw;
    const exr_attr_chlist_t *chans;
    exr_result_t rv = exr_get_storage(ctx, 0, &storage);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_data_window(ctx, 0, &dw);
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_channels(ctx, 0, &chans);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(io, rv, false, err);
    if (storage != EXR_STORAGE_SCANLINE && storage != EXR_STORAGE_TILED)
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: deep OpenEXR images are not supported", path);
    lu_result res = lu_image_check_dims(path, (long long)dw.max.x - dw.min.x + 1, (long long)dw.max.y - dw.min.y + 1,
                                        err);
    if (res != LU_OK) return res;

    int found[4] = {0}; /* R, G, B, Y */
    for (int i = 0; i < chans->num_channels; i++) {
        const exr_attr_chlist_entry_t *e = &chans->entries[i];
        int slot = strcmp(e->name.str, "Y") == 0 ? 3 : channel_slot(e->name.str, false);
        if (slot < 0) continue;
        if (e->x_sampling != 1 || e->y_sampling != 1)
            return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: channel %s is subsampled (%dx%d); not supported", path,
                           e->name.str, e->x_sampling, e->y_sampling);
        found[slot] = 1;
    }
    const bool grey = !(found[0] && found[1] && found[2]);
    if (grey && !found[3])
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: needs R, G and B channels or a Y channel", path);
    if ((res = lu_image_create(img, dw.max.x - dw.min.x + 1, dw.max.y - dw.min.y + 1, err)) != LU_OK) return res;

    exr_decode_pipeline_t dec = EXR_DECODE_PIPELINE_INITIALIZER;
    bool started = false;
    exr_chunk_info_t ci;
    if (storage == EXR_STORAGE_SCANLINE) {
        int32_t lines = 0;
        rv = exr_get_scanlines_per_chunk(ctx, 0, &lines);
        if (rv == EXR_ERR_SUCCESS && lines <= 0) rv = EXR_ERR_INVALID_ATTR;
        for (int y = 0; rv == EXR_ERR_SUCCESS && y < img->height; y += lines) {
            rv = exr_read_scanline_chunk_info(ctx, 0, dw.min.y + y, &ci);
            if (rv == EXR_ERR_SUCCESS)
                rv = decode_chunk(ctx, &ci, &dec, &started, img, 0, ci.start_y - dw.min.y, grey);
        }
    } else {
        int32_t tw = 0, th = 0;
        rv = exr_get_tile_sizes(ctx, 0, 0, 0, &tw, &th);
        if (rv == EXR_ERR_SUCCESS && (tw <= 0 || th <= 0)) rv = EXR_ERR_INVALID_ATTR;
        for (int ty = 0; rv == EXR_ERR_SUCCESS && ty * (int64_t)th < img->height; ty++)
            for (int tx = 0; rv == EXR_ERR_SUCCESS && tx * (int64_t)tw < img->width; tx++) {
                rv = exr_read_tile_chunk_info(ctx, 0, tx, ty, 0, 0, &ci);
                if (rv == EXR_ERR_SUCCESS) rv = decode_chunk(ctx, &ci, &dec, &started, img, tx * tw, ty * th, grey);
            }
    }
    if (started) exr_decoding_destroy(ctx, &dec);
    if (rv != EXR_ERR_SUCCESS) return exr_fail(io, rv, false, err);

    const size_t n = (size_t)img->width * img->height;
    for (size_t i = 0; i < n; i++) {
        float *p = img->rgb + 3 * i;
        if (grey) p[1] = p[2] = p[0];
        for (int c = 0; c < 3; c++)
            if (!isfinite(p[c]))
                return lu_fail(err, LU_ERR_NONFINITE, "%s: pixel (%d, %d) channel %s is %s", path,
                               (int)(i % img->width) + dw.min.x, (int)(i / img->width) + dw.min.y,
                               grey ? "Y" : (const char *[]){"R", "G", "B"}[c], isnan(p[c]) ? "NaN" : "infinite");
    }
    return LU_OK;
}

lu_result lu_exr_load(const char *path, lu_image *img, lu_error *err) {
    memset(img, 0, sizeof *img);
    exr_io io = {.fd = open(path, O_RDONLY), .path = path};
    if (io.fd < 0) return lu_fail(err, LU_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    static const unsigned char magic[4] = {0x76, 0x2f, 0x31, 0x01};
    unsigned char head[4];
    if (pread(io.fd, head, 4, 0) != 4 || memcmp(head, magic, 4) != 0) {
        close(io.fd);
        return lu_fail(err, LU_ERR_FORMAT, "%s: byte 0: not an OpenEXR file (bad magic number)", path);
    }
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_error;
    init.user_data = &io;
    init.read_fn = read_fn;
    init.size_fn = size_fn;
    /* A damaged offset table is an error, not something to guess around. */
    init.flags = EXR_CONTEXT_FLAG_DISABLE_CHUNK_RECONSTRUCTION;
    exr_context_t ctx = NULL;
    exr_result_t rv = exr_start_read(&ctx, path, &init);
    lu_result res = rv == EXR_ERR_SUCCESS ? read_part(ctx, &io, img, err) : exr_fail(&io, rv, false, err);
    exr_finish(&ctx);
    close(io.fd);
    if (res != LU_OK) lu_image_destroy(img);
    return res;
}

/* OpenEXRCore up to 3.4.7 (this build's is older) keeps the zlib stream of a
 * chunk when it is exactly as long as the packed pixels, and every reader
 * then takes those bytes for raw pixels (upstream issue 2306): a 48x27
 * bssrdf frame came back with 7 NaN values. In that case the packed pixels
 * are stored instead, which is what the format means by equal sizes. */
typedef struct exr_compress_hook {
    exr_result_t (*compress)(exr_encode_pipeline_t *enc);
} exr_compress_hook;

static exr_result_t compress_not_equal(exr_encode_pipeline_t *enc) {
    const exr_compress_hook *hook = enc->encoding_user_data;
    exr_result_t rv = hook->compress(enc);
    if (rv == EXR_ERR_SUCCESS && enc->compressed_bytes == enc->packed_bytes && enc->compressed_buffer &&
        enc->compressed_buffer != enc->packed_buffer)
        memcpy(enc->compressed_buffer, enc->packed_buffer, enc->packed_bytes);
    return rv;
}

lu_result lu_exr_save(const lu_image *img, const char *path, bool half, lu_error *err) {
    lu_atomic_file f;
    lu_result res = lu_atomic_open(&f, path, err);
    if (res != LU_OK) return res;
    exr_io io = {.fd = fileno(f.fp), .path = path};
    exr_context_initializer_t init = EXR_DEFAULT_CONTEXT_INITIALIZER;
    init.error_handler_fn = on_error;
    init.user_data = &io;
    init.write_fn = write_fn;
    exr_context_t ctx = NULL;
    int part = 0;
    static const char *const names[3] = {"R", "G", "B"};
    exr_result_t rv = exr_start_write(&ctx, path, EXR_WRITE_FILE_DIRECTLY, &init);
    if (rv == EXR_ERR_SUCCESS) rv = exr_add_part(ctx, NULL, EXR_STORAGE_SCANLINE, &part);
    if (rv == EXR_ERR_SUCCESS)
        rv = exr_initialize_required_attr_simple(ctx, part, img->width, img->height, EXR_COMPRESSION_ZIP);
    for (int c = 0; c < 3 && rv == EXR_ERR_SUCCESS; c++)
        rv = exr_add_channel(ctx, part, names[c], half ? EXR_PIXEL_HALF : EXR_PIXEL_FLOAT,
                             EXR_PERCEPTUALLY_LOGARITHMIC, 1, 1);
    if (rv == EXR_ERR_SUCCESS) rv = exr_write_header(ctx);
    int32_t lines = 0;
    if (rv == EXR_ERR_SUCCESS) rv = exr_get_scanlines_per_chunk(ctx, part, &lines);

    exr_encode_pipeline_t enc = EXR_ENCODE_PIPELINE_INITIALIZER;
    exr_compress_hook hook = {NULL};
    bool started = false;
    for (int y = 0; rv == EXR_ERR_SUCCESS && y < img->height; y += lines) {
        exr_chunk_info_t ci;
        rv = exr_write_scanline_chunk_info(ctx, part, y, &ci);
        if (rv != EXR_ERR_SUCCESS) break;
        rv = started ? exr_encoding_update(ctx, part, &ci, &enc) : exr_encoding_initialize(ctx, part, &ci, &enc);
        if (rv != EXR_ERR_SUCCESS) break;
        started = true;
        for (int c = 0; c < enc.channel_count; c++) {
            exr_coding_channel_info_t *cc = &enc.channels[c];
            cc->encode_from_ptr = (const uint8_t *)(lu_image_px(img, 0, y) + channel_slot(cc->channel_name, false));
            cc->user_pixel_stride = 3 * sizeof(float);
            cc->user_line_stride = 3 * sizeof(float) * img->width;
            cc->user_data_type = EXR_PIXEL_FLOAT;
            cc->user_bytes_per_element = sizeof(float);
        }
        rv = exr_encoding_choose_default_routines(ctx, part, &enc);
        if (rv == EXR_ERR_SUCCESS && enc.compress_fn) {
            hook.compress = enc.compress_fn;
            enc.encoding_user_data = &hook;
            enc.compress_fn = compress_not_equal;
        }
        if (rv == EXR_ERR_SUCCESS) rv = exr_encoding_run(ctx, part, &enc);
    }
    if (started) exr_encoding_destroy(ctx, &enc);
    exr_result_t finish = exr_finish(&ctx);
    if (rv == EXR_ERR_SUCCESS) rv = finish;
    if (rv != EXR_ERR_SUCCESS) {
        lu_atomic_abort(&f);
        return exr_fail(&io, rv, true, err);
    }
    return lu_atomic_commit(&f, err);
}
