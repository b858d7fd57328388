/* Stanford PLY: ascii, binary_little_endian and binary_big_endian, plain or
 * gzip-compressed (gzread passes plain files through). Any elements and
 * properties are accepted; the loader keeps vertex x,y,z (and nx,ny,nz when
 * all three exist) and face vertex_indices / vertex_index, and skips the rest.
 * Errors name the line (ascii) or byte offset (binary; offsets count
 * decompressed bytes for .gz files). */
#include "mesh_internal.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef enum { PT_NONE, PT_I8, PT_U8, PT_I16, PT_U16, PT_I32, PT_U32, PT_F32, PT_F64 } ply_type;

static const struct {
    const char *name;
    ply_type type;
} k_type_names[] = {
    {"char", PT_I8},     {"int8", PT_I8},     {"uchar", PT_U8}, {"uint8", PT_U8},   {"short", PT_I16},
    {"int16", PT_I16},   {"ushort", PT_U16},  {"uint16", PT_U16}, {"int", PT_I32},  {"int32", PT_I32},
    {"uint", PT_U32},    {"uint32", PT_U32},  {"float", PT_F32}, {"float32", PT_F32}, {"double", PT_F64},
    {"float64", PT_F64},
};
static const unsigned k_size[] = {0, 1, 1, 2, 2, 4, 4, 4, 8};
static const double k_lo[] = {0, -128.0, 0, -32768.0, 0, -2147483648.0, 0, 0, 0};
static const double k_hi[] = {0, 127.0, 255.0, 32767.0, 65535.0, 2147483647.0, 4294967295.0, 0, 0};
static bool is_int_type(ply_type t) { return t >= PT_I8 && t <= PT_U32; }

enum { ROLE_OTHER = -1, ROLE_X = 0, ROLE_NX = 3, ROLE_INDICES = 6 };
enum { FMT_ASCII, FMT_LE, FMT_BE };

#define PLY_NAME_MAX 64
#define PLY_MAX_ELEMENTS 256
#define PLY_MAX_PROPERTIES 256

typedef struct {
    char name[PLY_NAME_MAX];
    ply_type type;       /* scalar type, or list item type */
    ply_type count_type; /* PT_NONE for a scalar */
    int role;
} ply_prop;

typedef struct {
    char name[PLY_NAME_MAX];
    long long count;
    ply_prop *props;
    int nprops, cap;
    long header_line;
} ply_elem;

typedef struct {
    lu_stream s;
    const char *path;
    lu_error *err;
    int format;
    ply_elem *elems;
    int nelems, cap;
    lu_mesh_builder b;
    const char *cur;       /* ascii: unread part of the current line */
    uint64_t val_off;      /* binary: offset reported by errors */
    const ply_elem *elem;  /* element being read, for messages */
    long long inst;        /* instance index within it */
} ply_state;

static bool host_is_le(void) {
    uint16_t one = 1;
    unsigned char c;
    memcpy(&c, &one, 1);
    return c == 1;
}

/* Prefixes the location: "file:line" for ascii, "file: byte offset N" for binary. */
static lu_result failf(ply_state *st, lu_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;
static lu_result failf(ply_state *st, lu_result code, const char *fmt, ...) {
    char reason[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    if (st->format == FMT_ASCII) return lu_fail(st->err, code, "%s:%ld: %s", st->path, st->s.line, reason);
    return lu_fail(st->err, code, "%s: byte offset %llu%s: %s", st->path, (unsigned long long)st->val_off,
                   st->s.gz && !gzdirect(st->s.gz) ? " (decompressed)" : "", reason);
}

/* ---- header -------------------------------------------------------------- */

static int split(char *line, char **tok, int max) {
    int n = 0;
    char *p = line;
    for (;;) {
        while (lu_is_blank(*p)) p++;
        if (!*p) break;
        if (n == max) return max + 1;
        tok[n++] = p;
        while (*p && !lu_is_blank(*p)) p++;
        if (*p) *p++ = '\0';
    }
    return n;
}

static ply_type type_of(const char *name) {
    for (size_t i = 0; i < sizeof k_type_names / sizeof k_type_names[0]; i++)
        if (strcmp(name, k_type_names[i].name) == 0) return k_type_names[i].type;
    return PT_NONE;
}

static lu_result header_element(ply_state *st, char **tok, int n) {
    if (n != 3) return failf(st, LU_ERR_FORMAT, "expected \"element NAME COUNT\"");
    if (strlen(tok[1]) >= PLY_NAME_MAX) return failf(st, LU_ERR_FORMAT, "element name too long");
    for (int i = 0; i < st->nelems; i++)
        if (strcmp(st->elems[i].name, tok[1]) == 0) return failf(st, LU_ERR_FORMAT, "duplicate element \"%s\"", tok[1]);
    if (st->nelems == PLY_MAX_ELEMENTS) return failf(st, LU_ERR_LIMIT, "more than %d elements", PLY_MAX_ELEMENTS);
    const char *t = tok[2], *d = t + (*t == '-' || *t == '+'), *e;
    if (*d == '\0' || strspn(d, "0123456789") != strlen(d))
        return failf(st, LU_ERR_FORMAT, "element \"%s\" count \"%.40s\" is not an integer", tok[1], t);
    long long count;
    if (!lu_parse_int64(t, &e, &count)) {
        if (*t == '-') return failf(st, LU_ERR_FORMAT, "element \"%s\" has negative count %.40s", tok[1], t);
        return failf(st, LU_ERR_LIMIT, "element \"%s\" count %.40s is absurdly large", tok[1], t);
    }
    if (count < 0) return failf(st, LU_ERR_FORMAT, "element \"%s\" has negative count %lld", tok[1], count);
    unsigned long long limit = strcmp(tok[1], "vertex") == 0 ? LU_MAX_VERTICES
                               : strcmp(tok[1], "face") == 0 ? LU_MAX_TRIANGLES
                                                             : LU_MAX_FILE_BYTES;
    if ((unsigned long long)count > limit)
        return failf(st, LU_ERR_LIMIT, "element \"%s\" count %lld exceeds the limit of %llu", tok[1], count, limit);
    if (st->nelems == st->cap) {
        int cap = st->cap ? st->cap * 2 : 8;
        ply_elem *el = lu_realloc(st->elems, (size_t)cap * sizeof *el);
        if (!el) return lu_fail(st->err, LU_ERR_NOMEM, "%s: out of memory", st->path);
        st->elems = el;
        st->cap = cap;
    }
    ply_elem *el = &st->elems[st->nelems++];
    memset(el, 0, sizeof *el);
    snprintf(el->name, sizeof el->name, "%s", tok[1]);
    el->count = count;
    el->header_line = st->s.line;
    return LU_OK;
}

static lu_result header_property(ply_state *st, char **tok, int n) {
    if (st->nelems == 0) return failf(st, LU_ERR_FORMAT, "property before any element");
    ply_elem *el = &st->elems[st->nelems - 1];
    ply_prop p = {.role = ROLE_OTHER};
    const char *name;
    if (n >= 2 && strcmp(tok[1], "list") == 0) {
        if (n != 5) return failf(st, LU_ERR_FORMAT, "expected \"property list COUNT_TYPE ITEM_TYPE NAME\"");
        p.count_type = type_of(tok[2]);
        p.type = type_of(tok[3]);
        if (p.count_type == PT_NONE) return failf(st, LU_ERR_FORMAT, "unknown type \"%s\"", tok[2]);
        if (p.type == PT_NONE) return failf(st, LU_ERR_FORMAT, "unknown type \"%s\"", tok[3]);
        if (!is_int_type(p.count_type))
            return failf(st, LU_ERR_FORMAT, "list count type \"%s\" is not an integer type", tok[2]);
        name = tok[4];
    } else {
        if (n != 3) return failf(st, LU_ERR_FORMAT, "expected \"property TYPE NAME\"");
        p.type = type_of(tok[1]);
        if (p.type == PT_NONE) return failf(st, LU_ERR_FORMAT, "unknown type \"%s\"", tok[1]);
        name = tok[2];
    }
    if (strlen(name) >= PLY_NAME_MAX) return failf(st, LU_ERR_FORMAT, "property name too long");
    snprintf(p.name, sizeof p.name, "%s", name);
    if (el->nprops == PLY_MAX_PROPERTIES)
        return failf(st, LU_ERR_LIMIT, "element \"%s\" has more than %d properties", el->name, PLY_MAX_PROPERTIES);
    if (el->nprops == el->cap) {
        int cap = el->cap ? el->cap * 2 : 8;
        ply_prop *props = lu_realloc(el->props, (size_t)cap * sizeof *props);
        if (!props) return lu_fail(st->err, LU_ERR_NOMEM, "%s: out of memory", st->path);
        el->props = props;
        el->cap = cap;
    }
    el->props[el->nprops++] = p;
    return LU_OK;
}

static lu_result read_header(ply_state *st) {
    char *line;
    lu_result r = lu_stream_line(&st->s, &line, st->err);
    if (r != LU_OK) return r;
    st->format = FMT_ASCII; /* header errors are reported by line */
    if (!line || strncmp(line, "ply", 3) != 0 || *lu_skip_blank(line + 3) != '\0')
        return lu_fail(st->err, LU_ERR_FORMAT, "%s:1: not a PLY file (the first line must be \"ply\")", st->path);
    int format = -1;
    for (;;) {
        r = lu_stream_line(&st->s, &line, st->err);
        if (r != LU_OK) return r;
        if (!line) return lu_fail(st->err, LU_ERR_FORMAT, "%s:%ld: the header has no end_header", st->path, st->s.line);
        char *tok[6];
        const char *first = lu_skip_blank(line);
        if (strncmp(first, "comment", 7) == 0 && (first[7] == '\0' || lu_is_blank(first[7]))) continue;
        if (strncmp(first, "obj_info", 8) == 0 && (first[8] == '\0' || lu_is_blank(first[8]))) continue;
        int n = split(line, tok, 5);
        if (n == 0) continue;
        if (strcmp(tok[0], "format") == 0) {
            double version;
            const char *e;
            if (format >= 0) return failf(st, LU_ERR_FORMAT, "second format line");
            if (n != 3) return failf(st, LU_ERR_FORMAT, "expected \"format TYPE 1.0\"");
            if (strcmp(tok[1], "ascii") == 0) format = FMT_ASCII;
            else if (strcmp(tok[1], "binary_little_endian") == 0) format = FMT_LE;
            else if (strcmp(tok[1], "binary_big_endian") == 0) format = FMT_BE;
            else return failf(st, LU_ERR_FORMAT, "unknown format \"%s\"", tok[1]);
            if (!lu_parse_double(tok[2], &e, &version) || *e || version != 1.0)
                return failf(st, LU_ERR_UNSUPPORTED, "PLY version \"%s\" (only 1.0 is defined)", tok[2]);
        } else if (strcmp(tok[0], "element") == 0) {
            if (format < 0) return failf(st, LU_ERR_FORMAT, "element before the format line");
            r = header_element(st, tok, n);
        } else if (strcmp(tok[0], "property") == 0) {
            r = header_property(st, tok, n);
        } else if (strcmp(tok[0], "end_header") == 0) {
            if (n != 1) return failf(st, LU_ERR_FORMAT, "unexpected text after end_header");
            break;
        } else {
            return failf(st, LU_ERR_FORMAT, "unknown header keyword \"%.40s\"", tok[0]);
        }
        if (r != LU_OK) return r;
    }
    if (format < 0) return failf(st, LU_ERR_FORMAT, "the header has no format line");
    st->format = format;
    return LU_OK;
}

/* Assigns roles and checks that vertex positions and face indices exist. */
static lu_result bind_roles(ply_state *st, ply_elem **vert, ply_elem **face, bool *normals) {
    static const char *const k_vnames[6] = {"x", "y", "z", "nx", "ny", "nz"};
    *vert = *face = NULL;
    bool strips = false;
    for (int i = 0; i < st->nelems; i++) {
        ply_elem *el = &st->elems[i];
        if (strcmp(el->name, "vertex") == 0) *vert = el;
        else if (strcmp(el->name, "face") == 0) *face = el;
        else if (strcmp(el->name, "tristrips") == 0) strips = true;
    }
    if (!*vert) return lu_fail(st->err, LU_ERR_FORMAT, "%s: the header declares no vertex element", st->path);
    if (!*face) {
        if (strips)
            return lu_fail(st->err, LU_ERR_UNSUPPORTED, "%s: triangle strips (element tristrips) are not supported",
                           st->path);
        return lu_fail(st->err, LU_ERR_FORMAT, "%s: the header declares no face element", st->path);
    }
    bool have[6] = {false};
    for (int i = 0; i < (*vert)->nprops; i++) {
        ply_prop *p = &(*vert)->props[i];
        for (int k = 0; k < 6; k++) {
            if (strcmp(p->name, k_vnames[k]) != 0 || have[k]) continue;
            if (p->count_type != PT_NONE)
                return lu_fail(st->err, LU_ERR_FORMAT, "%s:%ld: vertex property \"%s\" is a list, expected a number",
                               st->path, (*vert)->header_line, p->name);
            p->role = k;
            have[k] = true;
        }
    }
    for (int k = 0; k < 3; k++)
        if (!have[k])
            return lu_fail(st->err, LU_ERR_FORMAT, "%s:%ld: the vertex element has no property \"%s\"", st->path,
                           (*vert)->header_line, k_vnames[k]);
    *normals = have[3] && have[4] && have[5];
    if (!*normals)
        for (int i = 0; i < (*vert)->nprops; i++)
            if ((*vert)->props[i].role >= ROLE_NX) (*vert)->props[i].role = ROLE_OTHER;
    bool found = false;
    for (int i = 0; i < (*face)->nprops && !found; i++) {
        ply_prop *p = &(*face)->props[i];
        if (strcmp(p->name, "vertex_indices") != 0 && strcmp(p->name, "vertex_index") != 0) continue;
        if (p->count_type == PT_NONE)
            return lu_fail(st->err, LU_ERR_FORMAT, "%s:%ld: face property \"%s\" is not a list", st->path,
                           (*face)->header_line, p->name);
        if (!is_int_type(p->type))
            return lu_fail(st->err, LU_ERR_FORMAT, "%s:%ld: face property \"%s\" has non-integer indices", st->path,
                           (*face)->header_line, p->name);
        p->role = ROLE_INDICES;
        found = true;
    }
    if (!found)
        return lu_fail(st->err, LU_ERR_FORMAT, "%s:%ld: the face element has no list property vertex_indices",
                       st->path, (*face)->header_line);
    return LU_OK;
}

/* ---- body ---------------------------------------------------------------- */

static double decode(const unsigned char *p, ply_type t, bool swap) {
    unsigned char b[8];
    unsigned n = k_size[t];
    for (unsigned i = 0; i < n; i++) b[i] = swap ? p[n - 1 - i] : p[i];
    switch (t) {
    case PT_I8: return (double)(int8_t)b[0];
    case PT_U8: return (double)b[0];
    case PT_I16: { int16_t v; memcpy(&v, b, 2); return v; }
    case PT_U16: { uint16_t v; memcpy(&v, b, 2); return v; }
    case PT_I32: { int32_t v; memcpy(&v, b, 4); return v; }
    case PT_U32: { uint32_t v; memcpy(&v, b, 4); return v; }
    case PT_F32: { float v; memcpy(&v, b, 4); return v; }
    case PT_F64: { double v; memcpy(&v, b, 8); return v; }
    default: return 0.0;
    }
}

static lu_result truncated(ply_state *st) {
    if (st->format == FMT_ASCII) {
        st->s.line++; /* the missing line */
        return failf(st, LU_ERR_FORMAT, "unexpected end of data: element \"%s\" index %lld of %lld is missing",
                     st->elem->name, st->inst, st->elem->count);
    }
    st->val_off = st->s.base + st->s.len;
    return failf(st, LU_ERR_FORMAT, "unexpected end of data in element \"%s\" index %lld of %lld", st->elem->name,
                 st->inst, st->elem->count);
}

static lu_result get_value(ply_state *st, ply_type t, double *out) {
    if (st->format != FMT_ASCII) {
        st->val_off = lu_stream_offset(&st->s);
        int k = lu_stream_need(&st->s, k_size[t], st->err);
        if (k < 0) return st->err ? st->err->code : LU_ERR_IO;
        if (k == 0) return truncated(st);
        *out = decode((const unsigned char *)st->s.buf + st->s.pos, t, (st->format == FMT_LE) != host_is_le());
        st->s.pos += k_size[t];
        return LU_OK;
    }
    const char *p = lu_skip_blank(st->cur), *e;
    if (*p == '\0')
        return failf(st, LU_ERR_FORMAT, "too few values for element \"%s\" %lld", st->elem->name, st->inst);
    if (!lu_parse_double(p, &e, out) || !(*e == '\0' || lu_is_blank(*e))) {
        int len = 0;
        while (p[len] && !lu_is_blank(p[len]) && len < 40) len++;
        return failf(st, LU_ERR_FORMAT, "bad number \"%.*s\"", len, p);
    }
    if (is_int_type(t) && !(*out == floor(*out) && *out >= k_lo[t] && *out <= k_hi[t])) {
        int len = (int)(e - p) < 40 ? (int)(e - p) : 40;
        return failf(st, LU_ERR_FORMAT, "\"%.*s\" is not a valid %s", len, p, k_type_names[2 * (t - 1)].name);
    }
    st->cur = e;
    return LU_OK;
}

static lu_result begin_instance(ply_state *st) {
    if (st->format != FMT_ASCII) return LU_OK;
    for (;;) {
        char *line;
        lu_result r = lu_stream_line(&st->s, &line, st->err);
        if (r != LU_OK) return r;
        if (!line) return truncated(st);
        const char *p = lu_skip_blank(line);
        if (*p) {
            st->cur = p;
            return LU_OK;
        }
    }
}

static lu_result end_instance(ply_state *st) {
    if (st->format != FMT_ASCII) return LU_OK;
    if (*lu_skip_blank(st->cur))
        return failf(st, LU_ERR_FORMAT, "more values than element \"%s\" declares", st->elem->name);
    return LU_OK;
}

static lu_result list_count(ply_state *st, const ply_prop *p, double *count) {
    lu_result r = get_value(st, p->count_type, count);
    if (r == LU_OK && *count < 0)
        return failf(st, LU_ERR_FORMAT, "negative list length %.0f in property \"%s\"", *count, p->name);
    return r;
}

static lu_result skip_property(ply_state *st, const ply_prop *p) {
    double v, n = 1;
    lu_result r = LU_OK;
    if (p->count_type != PT_NONE) r = list_count(st, p, &n);
    for (double i = 0; r == LU_OK && i < n; i++) r = get_value(st, p->type, &v);
    return r;
}

static lu_result skip_bytes(ply_state *st, uint64_t n) {
    while (n > 0) {
        if (st->s.pos == st->s.len) {
            int k = lu_stream_need(&st->s, 1, st->err);
            if (k < 0) return st->err ? st->err->code : LU_ERR_IO;
            if (k == 0) return truncated(st);
        }
        size_t take = st->s.len - st->s.pos;
        if (take > n) take = (size_t)n;
        st->s.pos += take;
        n -= take;
    }
    return LU_OK;
}

static lu_result read_vertices(ply_state *st, const ply_elem *el, bool normals) {
    lu_mesh_builder *b = &st->b;
    for (st->inst = 0; st->inst < el->count; st->inst++) {
        uint64_t start = lu_stream_offset(&st->s);
        lu_result r = begin_instance(st);
        double v[6] = {0, 0, 0, 0, 0, 0};
        for (int i = 0; r == LU_OK && i < el->nprops; i++) {
            const ply_prop *p = &el->props[i];
            if (p->role >= 0) r = get_value(st, p->type, &v[p->role]);
            else r = skip_property(st, p);
        }
        if (r == LU_OK) r = end_instance(st);
        if (r != LU_OK) return r;
        st->val_off = start;
        for (int k = 0; k < (normals ? 6 : 3); k++)
            if (!isfinite((float)v[k]))
                return failf(st, LU_ERR_NONFINITE, "vertex %lld has a non-finite %s", st->inst,
                             k < 3 ? "position" : "normal");
        if (b->vcount == b->vcap) {
            r = lu_mb_reserve_vertices(b, b->vcount + 1, normals, st->path, st->err);
            if (r != LU_OK) return r;
        }
        b->positions[b->vcount] = lu_v3((float)v[0], (float)v[1], (float)v[2]);
        if (normals) b->normals[b->vcount] = lu_v3((float)v[3], (float)v[4], (float)v[5]);
        b->vcount++;
    }
    return LU_OK;
}

static lu_result read_faces(ply_state *st, const ply_elem *el, long long nverts) {
    for (st->inst = 0; st->inst < el->count; st->inst++) {
        lu_result r = begin_instance(st);
        for (int i = 0; r == LU_OK && i < el->nprops; i++) {
            const ply_prop *p = &el->props[i];
            if (p->role != ROLE_INDICES) {
                r = skip_property(st, p);
                continue;
            }
            double n;
            r = list_count(st, p, &n);
            if (r == LU_OK && n < 3)
                r = failf(st, LU_ERR_FORMAT, "face %lld has %.0f vertices (at least 3 needed)", st->inst, n);
            uint32_t first = 0, prev = 0;
            for (double k = 0; r == LU_OK && k < n; k++) {
                double idx;
                r = get_value(st, p->type, &idx);
                if (r != LU_OK) break;
                if (idx < 0 || idx >= (double)nverts)
                    return failf(st, LU_ERR_RANGE, "face %lld: vertex index %.0f out of range [0, %lld)", st->inst, idx,
                                 nverts);
                uint32_t v = (uint32_t)idx;
                if (k == 0) first = v;
                if (k >= 2) {
                    if (st->b.tcount >= LU_MAX_TRIANGLES)
                        return failf(st, LU_ERR_LIMIT, "more than %u triangles", LU_MAX_TRIANGLES);
                    r = lu_mb_triangle(&st->b, first, prev, v, st->path, st->err);
                }
                prev = v;
            }
        }
        if (r == LU_OK) r = end_instance(st);
        if (r != LU_OK) return r;
    }
    return LU_OK;
}

static lu_result skip_element(ply_state *st, const ply_elem *el) {
    bool fixed = st->format != FMT_ASCII;
    uint64_t row = 0;
    for (int i = 0; i < el->nprops; i++) {
        if (el->props[i].count_type != PT_NONE) fixed = false;
        row += k_size[el->props[i].type];
    }
    if (el->nprops == 0) return LU_OK;
    if (fixed) {
        st->inst = 0;
        return skip_bytes(st, row * (uint64_t)el->count);
    }
    for (st->inst = 0; st->inst < el->count; st->inst++) {
        lu_result r = begin_instance(st);
        for (int i = 0; r == LU_OK && i < el->nprops; i++) r = skip_property(st, &el->props[i]);
        if (r == LU_OK) r = end_instance(st);
        if (r != LU_OK) return r;
    }
    return LU_OK;
}

lu_result lu_mesh_load_ply(const char *path, lu_mesh *mesh, lu_error *err) {
    memset(mesh, 0, sizeof *mesh);
    ply_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
    st->path = path;
    st->err = err;
    ply_elem *vert = NULL, *face = NULL;
    bool normals = false;
    lu_result r = lu_stream_open(&st->s, path, err);
    if (r == LU_OK) r = read_header(st);
    if (r == LU_OK) r = bind_roles(st, &vert, &face, &normals);
    if (r == LU_OK) {
        /* Reserve what the header promises only up to a modest size: arrays
         * grow with the data actually present, so a tiny file claiming
         * millions of vertices fails on truncation, not on allocation. */
        size_t nv = (size_t)vert->count, nt = (size_t)face->count;
        r = lu_mb_reserve_vertices(&st->b, nv < 65536 ? nv : 65536, normals, path, err);
        if (r == LU_OK) r = lu_mb_reserve_triangles(&st->b, nt < 65536 ? nt : 65536, path, err);
    }
    for (int i = 0; r == LU_OK && i < st->nelems; i++) {
        const ply_elem *el = &st->elems[i];
        st->elem = el;
        if (el == vert) r = read_vertices(st, el, normals);
        else if (el == face) r = read_faces(st, el, vert->count);
        else r = skip_element(st, el);
    }
    lu_stream_close(&st->s);
    if (r == LU_OK) r = lu_mb_finish(&st->b, normals, mesh, path, err);
    lu_mb_free(&st->b);
    for (int i = 0; i < st->nelems; i++) lu_free(st->elems[i].props);
    lu_free(st->elems);
    lu_free(st);
    return r;
}

/* ---- writer -------------------------------------------------------------- */

typedef struct {
    unsigned char buf[1 << 16];
    size_t n;
    FILE *fp;
    bool ok;
} out_buf;

static void put_bytes(out_buf *o, const void *p, size_t n) {
    if (o->n + n > sizeof o->buf) {
        if (fwrite(o->buf, 1, o->n, o->fp) != o->n) o->ok = false;
        o->n = 0;
    }
    memcpy(o->buf + o->n, p, n);
    o->n += n;
}

static void put_u32le(out_buf *o, uint32_t v) {
    unsigned char b[4] = {(unsigned char)v, (unsigned char)(v >> 8), (unsigned char)(v >> 16), (unsigned char)(v >> 24)};
    put_bytes(o, b, 4);
}

static void put_f32le(out_buf *o, float f) {
    uint32_t v;
    memcpy(&v, &f, 4);
    put_u32le(o, v);
}

lu_result lu_mesh_save_ply(const lu_mesh *mesh, const char *path, lu_error *err) {
    for (uint64_t i = 0; i < 3ull * mesh->triangle_count; i++)
        if (mesh->indices[i] >= mesh->vertex_count)
            return lu_fail(err, LU_ERR_INVALID_ARG, "%s: triangle %llu refers to vertex %u of %u", path,
                           (unsigned long long)(i / 3), mesh->indices[i], mesh->vertex_count);
    lu_atomic_file f;
    lu_result r = lu_atomic_open(&f, path, err);
    if (r != LU_OK) return r;
    out_buf *o = lu_malloc(sizeof *o);
    if (!o) {
        lu_atomic_abort(&f);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", path);
    }
    o->n = 0;
    o->fp = f.fp;
    o->ok = true;
    bool normals = mesh->normals != NULL;
    char header[512];
    int hn = snprintf(header, sizeof header,
                      "ply\nformat binary_little_endian 1.0\ncomment written by lucent " LU_VERSION_STRING "\n"
                      "element vertex %u\nproperty float x\nproperty float y\nproperty float z\n%s"
                      "element face %u\nproperty list uchar int vertex_indices\nend_header\n",
                      mesh->vertex_count,
                      normals ? "property float nx\nproperty float ny\nproperty float nz\n" : "",
                      mesh->triangle_count);
    put_bytes(o, header, (size_t)hn);
    for (uint32_t i = 0; i < mesh->vertex_count; i++) {
        lu_vec3 p = mesh->positions[i];
        put_f32le(o, p.x);
        put_f32le(o, p.y);
        put_f32le(o, p.z);
        if (normals) {
            lu_vec3 n = mesh->normals[i];
            put_f32le(o, n.x);
            put_f32le(o, n.y);
            put_f32le(o, n.z);
        }
    }
    for (uint32_t t = 0; t < mesh->triangle_count; t++) {
        unsigned char three = 3;
        put_bytes(o, &three, 1);
        for (int k = 0; k < 3; k++) put_u32le(o, mesh->indices[3 * (size_t)t + k]);
    }
    if (o->n && fwrite(o->buf, 1, o->n, o->fp) != o->n) o->ok = false;
    bool ok = o->ok;
    lu_free(o);
    if (!ok) {
        lu_atomic_abort(&f);
        return lu_fail(err, LU_ERR_IO, "%s: write failed", path);
    }
    return lu_atomic_commit(&f, err);
}
