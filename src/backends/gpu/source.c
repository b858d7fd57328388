/* Shader assembly from the embedded sources: #include resolution with #line
 * bookkeeping, and driver info logs translated back to file names. Pure C,
 * built with or without the GPU backend so it is always tested. */
#include "backends/gpu.h"

#include <ctype.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Deep enough for any sane header graph; a cycle cannot happen (each file is
 * included once) but this bounds the C stack regardless. */
#define LU_GPU_MAX_INCLUDE_DEPTH 32
#define LU_GPU_MAX_SOURCE_BYTES (16u * 1024u * 1024u)

bool lu_gpu_compiled_in(void) {
#ifdef LU_HAVE_GPU
    return true;
#else
    return false;
#endif
}

const char *lu_gpu_source_find(const char *name) {
    for (int i = 0; i < lu_gpu_embedded_source_count; i++)
        if (strcmp(lu_gpu_embedded_sources[i].name, name) == 0) return lu_gpu_embedded_sources[i].text;
    return NULL;
}

/* ---- a growable string ---------------------------------------------------- */

typedef struct sbuf {
    char *p;
    size_t len, cap;
    bool failed;
    bool nomem;   /* failed because an allocation did, not the size limit */
} sbuf;

static void sb_put(sbuf *b, const char *s, size_t n) {
    if (b->failed) return;
    if (b->len + n + 1 > LU_GPU_MAX_SOURCE_BYTES) {
        b->failed = true;
        return;
    }
    if (b->len + n + 1 > b->cap) {
        size_t cap = b->cap ? b->cap : 4096;
        while (cap < b->len + n + 1) cap *= 2;
        char *q = lu_realloc(b->p, cap);
        if (!q) {
            b->failed = b->nomem = true;
            return;
        }
        b->p = q;
        b->cap = cap;
    }
    memcpy(b->p + b->len, s, n);
    b->len += n;
    b->p[b->len] = '\0';
}

static void sb_puts(sbuf *b, const char *s) { sb_put(b, s, strlen(s)); }

static void sb_printf(sbuf *b, const char *fmt, int a, int c) {
    char tmp[64];
    int n = snprintf(tmp, sizeof tmp, fmt, a, c);
    if (n > 0) sb_put(b, tmp, (size_t)n);
}

/* ---- name resolution ------------------------------------------------------ */

typedef struct asm_state {
    const lu_gpu_source *overlay;
    int overlay_count;
    lu_gpu_source_map *map;
    sbuf out;
    lu_error *err;
} asm_state;

static const char *lookup(const asm_state *st, const char *name) {
    for (int i = 0; i < st->overlay_count; i++)
        if (st->overlay[i].name && strcmp(st->overlay[i].name, name) == 0) return st->overlay[i].text;
    return lu_gpu_source_find(name);
}

/* Joins dir and rel, folding "." and ".." segments; false if it climbs above
 * the root (src/) or does not fit. */
static bool join_normalise(const char *dir, const char *rel, char *out, size_t out_size) {
    char tmp[512];
    int n = snprintf(tmp, sizeof tmp, "%s%s%s", dir, *dir ? "/" : "", rel);
    if (n < 0 || (size_t)n >= sizeof tmp) return false;
    const char *segs[64];
    size_t lens[64];
    int count = 0;
    const char *s = tmp;
    while (*s) {
        const char *e = strchr(s, '/');
        size_t len = e ? (size_t)(e - s) : strlen(s);
        if (len == 0 || (len == 1 && s[0] == '.')) {
            /* skip */
        } else if (len == 2 && s[0] == '.' && s[1] == '.') {
            if (count == 0) return false;
            count--;
        } else {
            if (count == 64) return false;
            segs[count] = s;
            lens[count] = len;
            count++;
        }
        s += len;
        if (*s == '/') s++;
    }
    size_t pos = 0;
    for (int i = 0; i < count; i++) {
        if (pos + lens[i] + 2 > out_size) return false;
        if (i) out[pos++] = '/';
        memcpy(out + pos, segs[i], lens[i]);
        pos += lens[i];
    }
    if (count == 0) return false;
    out[pos] = '\0';
    return true;
}

static int map_index(const lu_gpu_source_map *map, const char *name) {
    for (int i = 0; i < map->count; i++)
        if (strcmp(map->names[i], name) == 0) return i;
    return -1;
}

/* ---- line classification ---------------------------------------------------- */

/* If the line (outside comments) is a preprocessor directive named `word`,
 * returns a pointer just past the word, else NULL. */
static const char *directive(const char *line, const char *line_end, const char *word) {
    const char *p = line;
    while (p < line_end && (*p == ' ' || *p == '\t')) p++;
    if (p >= line_end || *p != '#') return NULL;
    p++;
    while (p < line_end && (*p == ' ' || *p == '\t')) p++;
    size_t n = strlen(word);
    if ((size_t)(line_end - p) < n || strncmp(p, word, n) != 0) return NULL;
    p += n;
    if (p < line_end && (isalnum((unsigned char)*p) || *p == '_')) return NULL;
    return p;
}

/* Tracks block comments across lines so a commented-out #include is not
 * expanded. Returns whether the line STARTS inside a comment and updates the
 * state to the line's end. */
static bool scan_comments(const char *line, const char *line_end, bool *in_comment) {
    bool starts_inside = *in_comment;
    for (const char *p = line; p < line_end; p++) {
        if (*in_comment) {
            if (p + 1 < line_end && p[0] == '*' && p[1] == '/') {
                *in_comment = false;
                p++;
            }
        } else if (p + 1 < line_end && p[0] == '/' && p[1] == '/') {
            break;
        } else if (p + 1 < line_end && p[0] == '/' && p[1] == '*') {
            *in_comment = true;
            p++;
        }
    }
    return starts_inside;
}

static lu_result emit_file(asm_state *st, const char *name, const char *text, int depth);

static lu_result handle_include(asm_state *st, const char *name, int srcnum, int lineno, const char *arg,
                                const char *line_end, int depth) {
    const char *p = arg;
    while (p < line_end && (*p == ' ' || *p == '\t')) p++;
    if (p < line_end && *p == '<') {
        sb_puts(&st->out, "\n");   /* C-only system header: lu_kernel.h guards them */
        return LU_OK;
    }
    const char *q = (p < line_end && *p == '"') ? memchr(p + 1, '"', (size_t)(line_end - p - 1)) : NULL;
    if (!q)
        return lu_fail(st->err, LU_ERR_FORMAT, "%s:%d: malformed #include (expected \"file\" or <file>)",
                       name, lineno);
    char rel[256];
    size_t rlen = (size_t)(q - p - 1);
    if (rlen == 0 || rlen >= sizeof rel)
        return lu_fail(st->err, LU_ERR_FORMAT, "%s:%d: #include name empty or too long", name, lineno);
    memcpy(rel, p + 1, rlen);
    rel[rlen] = '\0';

    char dir[256];
    const char *slash = strrchr(name, '/');
    size_t dlen = slash ? (size_t)(slash - name) : 0;
    if (dlen >= sizeof dir) dlen = 0;
    memcpy(dir, name, dlen);
    dir[dlen] = '\0';

    char resolved[256];
    const char *text = NULL;
    if (join_normalise(dir, rel, resolved, sizeof resolved)) text = lookup(st, resolved);
    if (!text && join_normalise("", rel, resolved, sizeof resolved)) text = lookup(st, resolved);
    if (!text)
        return lu_fail(st->err, LU_ERR_FORMAT,
                       "%s:%d: #include \"%s\": no such embedded source (looked in \"%s\" and src/)", name,
                       lineno, rel, dir);
    if (map_index(st->map, resolved) >= 0) {
        sb_puts(&st->out, "\n");   /* included before: once per program */
        return LU_OK;
    }
    if (depth + 1 > LU_GPU_MAX_INCLUDE_DEPTH)
        return lu_fail(st->err, LU_ERR_LIMIT, "%s:%d: #include nesting deeper than %d", name, lineno,
                       LU_GPU_MAX_INCLUDE_DEPTH);
    lu_result r = emit_file(st, resolved, text, depth + 1);
    if (r != LU_OK) return r;
    sb_printf(&st->out, "#line %d %d\n", srcnum * LU_GPU_LINE_STRIDE + lineno + 1, srcnum);
    return LU_OK;
}

static lu_result emit_file(asm_state *st, const char *name, const char *text, int depth) {
    lu_gpu_source_map *map = st->map;
    if (map->count >= (int)(sizeof map->names / sizeof map->names[0]))
        return lu_fail(st->err, LU_ERR_LIMIT, "%s: more than %d source files in one program", name,
                       (int)(sizeof map->names / sizeof map->names[0]) - 1);
    if (strlen(name) >= sizeof map->names[0])
        return lu_fail(st->err, LU_ERR_LIMIT, "%s: source name too long", name);
    int srcnum = map->count++;
    strcpy(map->names[srcnum], name);
    sb_printf(&st->out, "#line %d %d\n", srcnum * LU_GPU_LINE_STRIDE + 1, srcnum);

    bool in_comment = false;
    int lineno = 0;
    const char *line = text;
    while (*line) {
        const char *nl = strchr(line, '\n');
        const char *line_end = nl ? nl : line + strlen(line);
        if (++lineno >= LU_GPU_LINE_STRIDE)
            return lu_fail(st->err, LU_ERR_LIMIT, "%s: more than %d lines", name, LU_GPU_LINE_STRIDE - 1);
        bool commented = scan_comments(line, line_end, &in_comment);
        const char *arg;
        if (!commented && (arg = directive(line, line_end, "include")) != NULL) {
            lu_result r = handle_include(st, name, srcnum, lineno, arg, line_end, depth);
            if (r != LU_OK) return r;
        } else if (!commented && directive(line, line_end, "version")) {
            sb_puts(&st->out, "\n");   /* the assembler writes the one #version */
        } else {
            sb_put(&st->out, line, (size_t)(line_end - line));
            sb_puts(&st->out, "\n");
        }
        if (!nl) break;
        line = nl + 1;
    }
    return LU_OK;
}

lu_result lu_gpu_assemble(const char *main_name, const char *defines, const lu_gpu_source *overlay,
                          int overlay_count, char **out_text, lu_gpu_source_map *map, lu_error *err) {
    *out_text = NULL;
    if (!main_name || !*main_name) return lu_fail(err, LU_ERR_INVALID_ARG, "shader name is empty");
    asm_state st = {overlay, overlay_count, map, {0}, err};
    map->count = 0;
    const char *text = lookup(&st, main_name);
    if (!text)
        return lu_fail(err, LU_ERR_INVALID_ARG, "shader \"%s\": no such embedded source (names are paths under src/)",
                       main_name);

    strcpy(map->names[0], "<preamble>");
    map->count = 1;
    sb_puts(&st.out, "#version 450 core\n#define LU_GLSL 1\n");
    if (defines && *defines) {
        sb_puts(&st.out, defines);
        if (defines[strlen(defines) - 1] != '\n') sb_puts(&st.out, "\n");
    }
    lu_result r = emit_file(&st, main_name, text, 0);
    if (r == LU_OK && st.out.nomem)
        r = lu_fail(err, LU_ERR_NOMEM, "%s: out of memory assembling the shader", main_name);
    else if (r == LU_OK && st.out.failed)
        r = lu_fail(err, LU_ERR_LIMIT, "%s: assembled shader too large (limit %u bytes)", main_name,
                    LU_GPU_MAX_SOURCE_BYTES);
    if (r != LU_OK) {
        lu_free(st.out.p);
        return r;
    }
    *out_text = st.out.p;
    return LU_OK;
}

/* ---- info log translation ----------------------------------------------------- */

static bool parse_uint(const char **p, const char *end, int *v) {
    const char *s = *p;
    long x = 0;
    if (s >= end || !isdigit((unsigned char)*s)) return false;
    while (s < end && isdigit((unsigned char)*s)) {
        x = x * 10 + (*s - '0');
        if (x > 100000000) return false;
        s++;
    }
    *v = (int)x;
    *p = s;
    return true;
}

/* Appends one translated line; returns false when out is full. */
static bool out_put(char *out, size_t out_size, size_t *pos, const char *s, size_t n) {
    if (*pos + 1 >= out_size) return false;
    size_t room = out_size - 1 - *pos;
    if (n > room) n = room;
    memcpy(out + *pos, s, n);
    *pos += n;
    out[*pos] = '\0';
    return *pos + 1 < out_size;
}

static size_t translate_line(const char *line, const char *end, const lu_gpu_source_map *map, char *buf,
                             size_t buf_size) {
    const char *p = line;
    const char *prefix_end = p;
    /* "ERROR: " / "WARNING: " prefixes (glslang and several vendors) */
    static const char *const prefixes[] = {"ERROR: ", "WARNING: ", "error: ", "warning: "};
    for (size_t i = 0; i < sizeof prefixes / sizeof prefixes[0]; i++) {
        size_t n = strlen(prefixes[i]);
        if ((size_t)(end - p) > n && strncmp(p, prefixes[i], n) == 0) {
            p += n;
            prefix_end = p;
            break;
        }
    }
    int src, ln, col = -1;
    const char *q = p;
    if (!parse_uint(&q, end, &src) || src >= map->count) return 0;
    if (q < end && *q == ':') {            /* Mesa "N:L(C):" or glslang "N:L:" */
        q++;
        if (!parse_uint(&q, end, &ln)) return 0;
        if (q < end && *q == '(') {
            const char *c = q + 1;
            if (parse_uint(&c, end, &col) && c < end && *c == ')') q = c + 1;
            else col = -1;
        }
    } else if (q < end && *q == '(') {     /* NVIDIA "N(L) :" */
        q++;
        if (!parse_uint(&q, end, &ln) || q >= end || *q != ')') return 0;
        q++;
        if (q + 1 < end && q[0] == ' ' && q[1] == ':') q++;
    } else {
        return 0;
    }
    if (q >= end || *q != ':') return 0;
    if (ln >= LU_GPU_LINE_STRIDE && ln / LU_GPU_LINE_STRIDE < map->count) {
        src = ln / LU_GPU_LINE_STRIDE;   /* the line number carries the file (see gpu.h) */
        ln %= LU_GPU_LINE_STRIDE;
    }
    int n;
    if (col >= 0)
        n = snprintf(buf, buf_size, "%.*s%s:%d:%d%.*s", (int)(prefix_end - line), line, map->names[src], ln,
                     col, (int)(end - q), q);
    else
        n = snprintf(buf, buf_size, "%.*s%s:%d%.*s", (int)(prefix_end - line), line, map->names[src], ln,
                     (int)(end - q), q);
    if (n < 0) return 0;
    return (size_t)n < buf_size ? (size_t)n : buf_size - 1;
}

void lu_gpu_translate_log(const char *log, const lu_gpu_source_map *map, char *out, size_t out_size) {
    if (!out_size) return;
    out[0] = '\0';
    size_t pos = 0;
    const char *line = log ? log : "";
    while (*line) {
        const char *nl = strchr(line, '\n');
        const char *end = nl ? nl : line + strlen(line);
        char buf[1024];
        size_t n = translate_line(line, end, map, buf, sizeof buf);
        bool room = n ? out_put(out, out_size, &pos, buf, n)
                      : out_put(out, out_size, &pos, line, (size_t)(end - line));
        if (!room) return;
        if (!nl) break;
        if (!out_put(out, out_size, &pos, "\n", 1)) return;
        line = nl + 1;
    }
}
