/* Shared by the mesh loaders: a chunked (optionally gzip) input stream, number
 * parsing that ignores the C locale, and growable vertex/triangle arrays. */
#ifndef LU_MESH_INTERNAL_H
#define LU_MESH_INTERNAL_H

#include <lucent/mesh.h>

#include <stdint.h>
#include <zlib.h>

/* Reads through gzread, which passes plain files through unchanged, so one path
 * serves .ply and .ply.gz. Data is parsed in place in one large buffer. */
typedef struct lu_stream {
    gzFile gz;
    const char *path;
    char *buf;       /* cap + 1 bytes; buf[len] is always NUL */
    size_t cap, pos, len;
    uint64_t base;   /* offset of buf[0] in the (decompressed) stream */
    long line;       /* number of the last line returned by lu_stream_line */
    bool eof;
} lu_stream;

lu_result lu_stream_open(lu_stream *s, const char *path, lu_error *err);
void lu_stream_close(lu_stream *s);
/* Next line without its "\n" / "\r\n", NUL-terminated and writable; *line is
 * NULL at the end of the data. */
lu_result lu_stream_line(lu_stream *s, char **line, lu_error *err);
/* Makes n (<= cap) bytes available at buf + pos. Returns 1 on success, 0 if the
 * data ends first, -1 on a read error (err filled). */
int lu_stream_need(lu_stream *s, size_t n, lu_error *err);
static inline uint64_t lu_stream_offset(const lu_stream *s) { return s->base + s->pos; }

/* Decimal number at p (no leading blanks): [+-] digits [. digits] [e[+-]digits],
 * or nan / inf / infinity. *end is set past it. Independent of setlocale(). */
bool lu_parse_double(const char *p, const char **end, double *out);
/* [+-] digits, without overflow. */
bool lu_parse_int64(const char *p, const char **end, long long *out);

static inline bool lu_is_blank(char c) { return c == ' ' || c == '\t' || c == '\r' || c == '\f' || c == '\v'; }
static inline const char *lu_skip_blank(const char *p) {
    while (lu_is_blank(*p)) p++;
    return p;
}

/* Growable arrays for a mesh under construction. */
typedef struct lu_mesh_builder {
    lu_vec3 *positions, *normals;   /* normals only when the file has them */
    uint32_t *indices;
    size_t vcount, vcap, ncap, tcount, tcap;
} lu_mesh_builder;

lu_result lu_mb_reserve_vertices(lu_mesh_builder *b, size_t n, bool with_normals, const char *path, lu_error *err);
lu_result lu_mb_reserve_triangles(lu_mesh_builder *b, size_t n, const char *path, lu_error *err);
/* Appends a triangle unless two of its indices coincide (such faces carry no
 * area and break edge adjacency, so they are dropped). Caller checks limits. */
static inline lu_result lu_mb_triangle(lu_mesh_builder *b, uint32_t a, uint32_t c, uint32_t d, const char *path,
                                       lu_error *err) {
    if (a == c || c == d || a == d) return LU_OK;
    if (b->tcount == b->tcap) {
        lu_result r = lu_mb_reserve_triangles(b, b->tcount + 1, path, err);
        if (r != LU_OK) return r;
    }
    uint32_t *t = b->indices + 3 * b->tcount++;
    t[0] = a;
    t[1] = c;
    t[2] = d;
    return LU_OK;
}
void lu_mb_free(lu_mesh_builder *b);
/* Moves the arrays into mesh (shrunk to size). Without file normals, or when a
 * file normal has zero length, computes area-weighted normals; file normals are
 * normalised. Fails when there are no triangles. */
lu_result lu_mb_finish(lu_mesh_builder *b, bool have_normals, lu_mesh *mesh, const char *path, lu_error *err);

#endif
