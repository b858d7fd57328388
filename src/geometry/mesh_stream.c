/* Chunked input for the mesh loaders: big gzread calls into one buffer, lines
 * and binary fields parsed in place (no per-token allocation). */
#include "mesh_internal.h"

#include <errno.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#define LU_STREAM_CHUNK (1u << 20)

lu_result lu_stream_open(lu_stream *s, const char *path, lu_error *err) {
    memset(s, 0, sizeof *s);
    s->path = path;
    struct stat st;
    if (stat(path, &st) != 0) return lu_fail(err, LU_ERR_IO, "%s: cannot open: %s", path, strerror(errno));
    if (!S_ISREG(st.st_mode)) return lu_fail(err, LU_ERR_IO, "%s: not a regular file", path);
    if ((unsigned long long)st.st_size > LU_MAX_FILE_BYTES)
        return lu_fail(err, LU_ERR_LIMIT, "%s: %lld bytes exceeds the limit of %llu", path, (long long)st.st_size,
                       (unsigned long long)LU_MAX_FILE_BYTES);
    s->buf = lu_malloc(LU_STREAM_CHUNK + 1);
    if (!s->buf) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for the read buffer", path);
    s->buf[0] = '\0';
    s->cap = LU_STREAM_CHUNK;
    errno = 0;
    s->gz = gzopen(path, "rb");
    if (!s->gz) {
        int e = errno;
        lu_free(s->buf);
        s->buf = NULL;
        return lu_fail(err, e ? LU_ERR_IO : LU_ERR_NOMEM, "%s: cannot open: %s", path,
                       e ? strerror(e) : "out of memory");
    }
    gzbuffer(s->gz, 256u * 1024u);
    return LU_OK;
}

void lu_stream_close(lu_stream *s) {
    if (s->gz) gzclose(s->gz);
    lu_free(s->buf);
    s->gz = NULL;
    s->buf = NULL;
}

/* Moves unread bytes to the front and reads more behind them. */
static lu_result fill(lu_stream *s, lu_error *err) {
    if (s->pos > 0) {
        memmove(s->buf, s->buf + s->pos, s->len - s->pos);
        s->base += s->pos;
        s->len -= s->pos;
        s->pos = 0;
    }
    while (!s->eof && s->len < s->cap) {
        int n = gzread(s->gz, s->buf + s->len, (unsigned)(s->cap - s->len));
        if (n > 0) {
            s->len += (size_t)n;
            continue;
        }
        int zerr = Z_OK;
        const char *msg = gzerror(s->gz, &zerr);
        if (n < 0 || (zerr != Z_OK && zerr != Z_STREAM_END)) {
            s->buf[s->len] = '\0';
            if (zerr == Z_ERRNO)
                return lu_fail(err, LU_ERR_IO, "%s: read failed: %s", s->path, strerror(errno));
            /* gzerror prefixes the path, which the message already names. */
            size_t pl = strlen(s->path);
            if (msg && strncmp(msg, s->path, pl) == 0 && msg[pl] == ':') msg += pl + (msg[pl + 1] == ' ' ? 2 : 1);
            /* Z_BUF_ERROR here means the compressed stream stopped early. */
            return lu_fail(err, LU_ERR_FORMAT, "%s: byte offset %llu (decompressed): corrupt or truncated gzip data: %s",
                           s->path, (unsigned long long)(s->base + s->len), msg ? msg : "unknown zlib error");
        }
        s->eof = true;
    }
    s->buf[s->len] = '\0';
    return LU_OK;
}

lu_result lu_stream_line(lu_stream *s, char **line, lu_error *err) {
    *line = NULL;
    size_t scanned = s->pos;
    char *nl;
    for (;;) {
        nl = memchr(s->buf + scanned, '\n', s->len - scanned);
        if (nl || s->eof) break;
        if (s->pos == 0 && s->len == s->cap)
            return lu_fail(err, LU_ERR_LIMIT, "%s:%ld: line longer than %u bytes", s->path, s->line + 1,
                           LU_STREAM_CHUNK);
        size_t rel = scanned - s->pos;
        lu_result r = fill(s, err);
        if (r != LU_OK) return r;
        scanned = rel;
    }
    char *start = s->buf + s->pos, *end;
    if (nl) {
        end = nl;
        s->pos = (size_t)(nl - s->buf) + 1;
    } else {
        if (s->pos == s->len) return LU_OK; /* end of data */
        end = s->buf + s->len;
        s->pos = s->len;
    }
    if (end > start && end[-1] == '\r') end--;
    *end = '\0';
    /* An embedded NUL would silently cut the line short; treat it as an error. */
    if (memchr(start, '\0', (size_t)(end - start)))
        return lu_fail(err, LU_ERR_FORMAT, "%s:%ld: NUL byte in a text line", s->path, s->line + 1);
    s->line++;
    *line = start;
    return LU_OK;
}

int lu_stream_need(lu_stream *s, size_t n, lu_error *err) {
    while (s->len - s->pos < n) {
        if (s->eof) return 0;
        if (fill(s, err) != LU_OK) return -1;
    }
    return 1;
}
