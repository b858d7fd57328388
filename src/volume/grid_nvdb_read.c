/* NanoVDB (.nvdb) reader: the file container is parsed here, following the
 * layout of nanovdb/util/IO.h (NanoVDB 32.x); the grid buffer itself is read
 * through PNanoVDB.h. Every size and offset is checked against the file size
 * before use, every tree node address against the grid buffer, and PNanoVDB
 * runs with its buffer bounds check on, so a malformed file can only produce
 * an error, never an out-of-bounds read or an unbounded walk.
 *
 * Container layout (little-endian), repeated per segment until end of file:
 *   header   16 B: magic u64 "NanoVDB0", version u32, grid count u16, codec u16
 *   meta    176 B per grid (+ name bytes): grid size, file size, name hash,
 *                 voxel count, grid type, class, bboxes, voxel size, name size,
 *                 node/tile counts, codec, padding, version
 *   data          per grid: NONE: the grid buffer (file size == grid size);
 *                 ZIP: u64 compressed size, then a zlib stream;
 *                 BLOSC: chunks (not supported here).
 * A grid kept sparse owns its buffer: the file mapped (uncompressed, 8-byte
 * aligned data) or an allocation (compressed, unaligned, or from memory).
 * Over 800 lines because it is one hardened reader: every check on untrusted
 * bytes (container, tree, values for both storages) sits in this file. */
#include <lucent/grid.h>

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>
#include <unistd.h>
#include <zlib.h>

#include "volume/grid_internal.h"   /* PNanoVDB.h, with its buffer bounds check */

#define NVDB_HEADER_SIZE 16u
#define NVDB_META_SIZE 176u
#define NVDB_MAJOR 32u
#define NVDB_MAX_NAME 65536u
#define NVDB_CODEC_NONE 0u
#define NVDB_CODEC_ZIP 1u
#define NVDB_CODEC_BLOSC 2u
/* Deflate emits at most 258 bytes per 2-bit length/distance pair, so no zlib
 * stream expands by more than 1032:1 (plus block overhead); a larger claim is
 * a malformed size, rejected before allocating for it. */
#define NVDB_ZIP_MAX_RATIO 1032u
#define NVDB_ZIP_SLACK 1024u
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
#define NVDB_DENSE_LIMIT (1ull << 22) /* keeps each fuzz input fast */
#else
#define NVDB_DENSE_LIMIT LU_MAX_GRID_VOXELS
#endif

/* ---- byte source: a FILE or a memory image ------------------------------- */

typedef struct nvdb_src {
    FILE *fp;
    const unsigned char *mem;
    uint64_t size;
    const char *label;
} nvdb_src;

static uint16_t rd16(const unsigned char *b) { return (uint16_t)(b[0] | (b[1] << 8)); }
static uint32_t rd32(const unsigned char *b) {
    return (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
}
static uint64_t rd64(const unsigned char *b) { return (uint64_t)rd32(b) | ((uint64_t)rd32(b + 4) << 32); }

/* Reads n bytes at off; fails as truncation if they are not all there. */
static lu_result src_read(nvdb_src *s, uint64_t off, void *dst, uint64_t n, const char *what, lu_error *err) {
    if (off > s->size || n > s->size - off)
        return lu_fail(err, LU_ERR_FORMAT,
                       "%s: truncated at byte offset %llu: %s needs %llu bytes, only %llu remain", s->label,
                       (unsigned long long)off, what, (unsigned long long)n,
                       (unsigned long long)(off > s->size ? 0 : s->size - off));
    if (n == 0) return LU_OK;
    if (s->mem) {
        memcpy(dst, s->mem + off, (size_t)n);
        return LU_OK;
    }
    if (fseeko(s->fp, (off_t)off, SEEK_SET) != 0 || fread(dst, 1, (size_t)n, s->fp) != (size_t)n)
        return lu_fail(err, LU_ERR_IO, "%s: read error at byte offset %llu: %s", s->label, (unsigned long long)off,
                       strerror(errno));
    return LU_OK;
}

/* ---- container ----------------------------------------------------------- */

typedef struct nvdb_meta {
    uint64_t grid_size, file_size;
    uint32_t grid_type, grid_class, name_size, version;
    uint16_t codec;          /* the segment's codec, which governs the data */
    uint64_t meta_offset;    /* byte offset of this grid's metadata record */
    uint64_t data_offset;    /* byte offset of this grid's data */
    char *name;
} nvdb_meta;

typedef struct nvdb_index {
    nvdb_meta *items;
    size_t count, cap;
} nvdb_index;

static void index_free(nvdb_index *ix) {
    for (size_t i = 0; i < ix->count; i++) lu_free(ix->items[i].name);
    lu_free(ix->items);
    memset(ix, 0, sizeof *ix);
}

static const char *grid_type_name(uint32_t t) {
    static const char *names[] = {"Unknown", "Float",  "Double", "Int16", "Int32", "Int64", "Vec3f",
                                  "Vec3d",   "Mask",   "Half",   "UInt32", "Boolean", "RGBA8", "Fp4",
                                  "Fp8",     "Fp16",   "FpN",    "Vec4f", "Vec4d", "Index"};
    return t < sizeof names / sizeof names[0] ? names[t] : "invalid";
}

static void version_str(uint32_t v, char *out, size_t n) {
    snprintf(out, n, "%u.%u.%u", (v >> 21) & 2047u, (v >> 10) & 2047u, v & 1023u);
}

/* Walks every segment header and metadata record, checking each grid's data
 * lies inside the file, without reading the grid data itself. */
static lu_result scan_container(nvdb_src *s, nvdb_index *ix, lu_error *err) {
    uint64_t off = 0;
    int segment = 0;
    unsigned char h[NVDB_HEADER_SIZE], m[NVDB_META_SIZE];
    if (s->size == 0) return lu_fail(err, LU_ERR_FORMAT, "%s: empty file, not a NanoVDB file", s->label);
    while (off < s->size) {
        lu_result r = src_read(s, off, h, NVDB_HEADER_SIZE, "a segment header", err);
        if (r != LU_OK) return r;
        uint64_t magic = rd64(h);
        uint32_t version = rd32(h + 8);
        uint16_t count = rd16(h + 12), codec = rd16(h + 14);
        if (magic != PNANOVDB_MAGIC_NUMBER) {
            if (memcmp(h, "NanoVDB", 7) == 0)
                return lu_fail(err, LU_ERR_UNSUPPORTED,
                               "%s: byte offset %llu: NanoVDB file revision \"NanoVDB%c\" is not supported "
                               "(this reader handles \"NanoVDB0\", NanoVDB 32.x)",
                               s->label, (unsigned long long)off, h[7] >= 32 && h[7] < 127 ? h[7] : '?');
            if (memcmp(h, "0BDVonaN", 8) == 0)
                return lu_fail(err, LU_ERR_UNSUPPORTED,
                               "%s: byte offset %llu: big-endian NanoVDB file is not supported", s->label,
                               (unsigned long long)off);
            return lu_fail(err, LU_ERR_FORMAT, "%s: byte offset %llu: bad magic number 0x%016llx, %s", s->label,
                           (unsigned long long)off, (unsigned long long)magic,
                           segment == 0 ? "not a NanoVDB file" : "expected another NanoVDB segment header");
        }
        if (((version >> 21) & 2047u) != NVDB_MAJOR) {
            char vs[32];
            version_str(version, vs, sizeof vs);
            return lu_fail(err, LU_ERR_UNSUPPORTED,
                           "%s: byte offset %llu: NanoVDB file version %s is not supported (major version %u only)",
                           s->label, (unsigned long long)(off + 8), vs, NVDB_MAJOR);
        }
        if (count == 0)
            return lu_fail(err, LU_ERR_FORMAT, "%s: byte offset %llu: segment header declares 0 grids", s->label,
                           (unsigned long long)(off + 12));
        if (codec > NVDB_CODEC_BLOSC)
            return lu_fail(err, LU_ERR_FORMAT, "%s: byte offset %llu: unknown compression codec %u", s->label,
                           (unsigned long long)(off + 14), codec);
        off += NVDB_HEADER_SIZE;
        size_t first = ix->count;
        for (unsigned i = 0; i < count; i++) {
            r = src_read(s, off, m, NVDB_META_SIZE, "grid metadata", err);
            if (r != LU_OK) return r;
            if (ix->count == ix->cap) {
                size_t cap = ix->cap ? ix->cap * 2 : 4;
                nvdb_meta *items = lu_realloc(ix->items, cap * sizeof *items);
                if (!items) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory indexing grids", s->label);
                ix->items = items;
                ix->cap = cap;
            }
            nvdb_meta *g = &ix->items[ix->count];
            memset(g, 0, sizeof *g);
            g->meta_offset = off;
            g->grid_size = rd64(m + 0);
            g->file_size = rd64(m + 8);
            g->grid_type = rd32(m + 32);
            g->grid_class = rd32(m + 36);
            g->name_size = rd32(m + 136);
            g->version = rd32(m + 172);
            g->codec = codec;
            if (g->name_size == 0 || g->name_size > NVDB_MAX_NAME)
                return lu_fail(err, LU_ERR_FORMAT, "%s: byte offset %llu: grid name size %u is outside [1, %u]",
                               s->label, (unsigned long long)(off + 136), g->name_size, NVDB_MAX_NAME);
            off += NVDB_META_SIZE;
            g->name = lu_malloc(g->name_size + 1u);
            if (!g->name) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory reading a grid name", s->label);
            ix->count++;
            r = src_read(s, off, g->name, g->name_size, "a grid name", err);
            if (r != LU_OK) return r;
            g->name[g->name_size] = '\0';
            off += g->name_size;
        }
        for (size_t i = first; i < ix->count; i++) {
            nvdb_meta *g = &ix->items[i];
            g->data_offset = off;
            if (g->file_size > s->size - off)
                return lu_fail(err, LU_ERR_FORMAT,
                               "%s: truncated at byte offset %llu: grid \"%.64s\" data needs %llu bytes, only %llu "
                               "remain",
                               s->label, (unsigned long long)off, g->name, (unsigned long long)g->file_size,
                               (unsigned long long)(s->size - off));
            off += g->file_size;
        }
        segment++;
    }
    return LU_OK;
}

/* ---- grid buffer --------------------------------------------------------- */

typedef struct nvdb_buf {
    uint32_t *words;
    void *map;               /* words lie in this file mapping (not allocated) */
    size_t map_bytes;
    uint64_t size;           /* bytes that hold the grid */
    pnanovdb_buf_t buf;
    uint64_t file_base;      /* file offset of byte 0 (NONE codec), else 0 */
    bool compressed;
    const char *label;
    uint64_t data_offset;
} nvdb_buf;

/* Error location inside the grid buffer, as the user can find it. */
static const char *where_in(const nvdb_buf *b, uint64_t rel, char *out, size_t n) {
    if (b->compressed)
        snprintf(out, n, "byte offset %llu of the grid decompressed from file offset %llu", (unsigned long long)rel,
                 (unsigned long long)b->data_offset);
    else
        snprintf(out, n, "byte offset %llu", (unsigned long long)(b->file_base + rel));
    return out;
}

static lu_result load_buffer(nvdb_src *s, const nvdb_meta *g, nvdb_buf *b, lu_error *err) {
    memset(b, 0, sizeof *b);
    b->label = s->label;
    b->data_offset = g->data_offset;
    if (g->codec == NVDB_CODEC_BLOSC)
        return lu_fail(err, LU_ERR_UNSUPPORTED,
                       "%s: byte offset %llu: grid \"%.64s\" is BLOSC-compressed, which this reader does not support; "
                       "re-export it uncompressed or with ZIP compression",
                       s->label, (unsigned long long)g->meta_offset, g->name);
    if (g->grid_size > LU_MAX_TREE_BYTES)
        return lu_fail(err, LU_ERR_LIMIT,
                       "%s: byte offset %llu: grid \"%.64s\" of %llu bytes exceeds the limit of %llu (LU_MAX_TREE_BYTES)",
                       s->label, (unsigned long long)g->meta_offset, g->name, (unsigned long long)g->grid_size,
                       (unsigned long long)LU_MAX_TREE_BYTES);
    if (g->grid_size < PNANOVDB_GRID_SIZE + PNANOVDB_TREE_SIZE)
        return lu_fail(err, LU_ERR_FORMAT,
                       "%s: byte offset %llu: grid \"%.64s\" size %llu is smaller than a grid and tree header (%u)",
                       s->label, (unsigned long long)g->meta_offset, g->name, (unsigned long long)g->grid_size,
                       PNANOVDB_GRID_SIZE + PNANOVDB_TREE_SIZE);
    unsigned char *zbuf = NULL;
    uint64_t csize = 0;
    if (g->codec == NVDB_CODEC_NONE) {
        if (g->file_size != g->grid_size)
            return lu_fail(err, LU_ERR_FORMAT,
                           "%s: byte offset %llu: uncompressed grid \"%.64s\" stores %llu bytes but declares a size "
                           "of %llu",
                           s->label, (unsigned long long)g->meta_offset, g->name, (unsigned long long)g->file_size,
                           (unsigned long long)g->grid_size);
    } else {
        unsigned char c8[8];
        if (g->file_size < 8)
            return lu_fail(err, LU_ERR_FORMAT, "%s: byte offset %llu: ZIP grid \"%.64s\" data is only %llu bytes",
                           s->label, (unsigned long long)g->data_offset, g->name, (unsigned long long)g->file_size);
        lu_result r = src_read(s, g->data_offset, c8, 8, "the compressed size", err);
        if (r != LU_OK) return r;
        csize = rd64(c8);
        if (csize > g->file_size - 8)
            return lu_fail(err, LU_ERR_FORMAT,
                           "%s: byte offset %llu: compressed size %llu exceeds the %llu bytes stored for grid "
                           "\"%.64s\"",
                           s->label, (unsigned long long)g->data_offset, (unsigned long long)csize,
                           (unsigned long long)(g->file_size - 8), g->name);
        if (g->grid_size > csize * NVDB_ZIP_MAX_RATIO + NVDB_ZIP_SLACK)
            return lu_fail(err, LU_ERR_FORMAT,
                           "%s: byte offset %llu: grid \"%.64s\" claims %llu bytes from %llu compressed bytes, more "
                           "than zlib can produce",
                           s->label, (unsigned long long)g->meta_offset, g->name, (unsigned long long)g->grid_size,
                           (unsigned long long)csize);
        zbuf = lu_malloc(csize ? (size_t)csize : 1u);
        if (!zbuf) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory reading %llu compressed bytes", s->label,
                                  (unsigned long long)csize);
        r = src_read(s, g->data_offset + 8, zbuf, csize, "the compressed grid", err);
        if (r != LU_OK) {
            lu_free(zbuf);
            return r;
        }
    }
    uint64_t words = (g->grid_size + 7u) / 8u * 2u;
    /* Mapped, not read: pages come in as the walk and the renderer touch
     * them, and the file's size is no longer bounded by what one read takes. */
    long page = sysconf(_SC_PAGESIZE);
    if (g->codec == NVDB_CODEC_NONE && s->fp && g->data_offset % 8u == 0 && g->grid_size % 8u == 0 && page > 0) {
        uint64_t base = g->data_offset / (uint64_t)page * (uint64_t)page, delta = g->data_offset - base;
        void *map = mmap(NULL, (size_t)(delta + g->grid_size), PROT_READ, MAP_PRIVATE, fileno(s->fp), (off_t)base);
        if (map != MAP_FAILED) {
            b->map = map;
            b->map_bytes = (size_t)(delta + g->grid_size);
            b->words = (uint32_t *)(void *)((unsigned char *)map + delta);
            b->size = g->grid_size;
            b->file_base = g->data_offset;
            b->buf = pnanovdb_make_buf(b->words, words);
            return LU_OK;
        }
    }
    /* Whole 64-bit words, zero padded: PNanoVDB reads 8 bytes at a time. */
    b->words = lu_calloc((size_t)words, sizeof(uint32_t));
    if (!b->words) {
        lu_free(zbuf);
        return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory for a %llu-byte grid", s->label,
                       (unsigned long long)g->grid_size);
    }
    b->size = g->grid_size;
    if (g->codec == NVDB_CODEC_NONE) {
        b->file_base = g->data_offset;
        lu_result r = src_read(s, g->data_offset, b->words, g->grid_size, "the grid", err);
        if (r != LU_OK) return r;
    } else {
        b->compressed = true;
        uLongf out = (uLongf)g->grid_size;
        int zr = uncompress((Bytef *)b->words, &out, zbuf, (uLong)csize);
        lu_free(zbuf);
        if (zr != Z_OK || (uint64_t)out != g->grid_size)
            return lu_fail(err, LU_ERR_FORMAT,
                           "%s: byte offset %llu: ZIP data of grid \"%.64s\" does not decompress to its declared %llu "
                           "bytes (%s)",
                           s->label, (unsigned long long)(g->data_offset + 8), g->name,
                           (unsigned long long)g->grid_size,
                           zr == Z_OK ? "size mismatch" : zr == Z_MEM_ERROR ? "out of memory" : "corrupt stream");
    }
    b->buf = pnanovdb_make_buf(b->words, words);
    return LU_OK;
}

/* ---- tree validation and active bounding box ------------------------------ */

typedef struct tree_walk {
    nvdb_buf *b;
    uint64_t first_node;     /* nodes cannot overlap the grid and tree headers */
    uint32_t count[3];       /* leaf, lower, upper nodes the tree declares */
    uint32_t seen[3];
    int64_t lo[3], hi[3];    /* active bounding box, inclusive */
    bool any;
} tree_walk;

static void grow(tree_walk *w, int64_t x0, int64_t y0, int64_t z0, int64_t x1, int64_t y1, int64_t z1) {
    if (!w->any) {
        w->lo[0] = x0, w->lo[1] = y0, w->lo[2] = z0;
        w->hi[0] = x1, w->hi[1] = y1, w->hi[2] = z1;
        w->any = true;
        return;
    }
    if (x0 < w->lo[0]) w->lo[0] = x0;
    if (y0 < w->lo[1]) w->lo[1] = y0;
    if (z0 < w->lo[2]) w->lo[2] = z0;
    if (x1 > w->hi[0]) w->hi[0] = x1;
    if (y1 > w->hi[1]) w->hi[1] = y1;
    if (z1 > w->hi[2]) w->hi[2] = z1;
}

/* `ref` is where the child pointer is stored, named in the error. Counting
 * visits against the declared node counts (each bounded by the buffer size)
 * bounds the walk even if pointers are duplicated. */
static lu_result check_node(tree_walk *w, uint64_t ref, uint64_t addr, uint32_t size, int level, lu_error *err) {
    static const char *names[] = {"leaf", "lower internal", "upper internal"};
    char at[160];
    if (addr < w->first_node || addr % 32u != 0 || addr > w->b->size || size > w->b->size - addr)
        return lu_fail(err, LU_ERR_FORMAT,
                       "%s: %s: child pointer to a %s node at grid byte %llu is outside the %llu-byte grid or "
                       "misaligned",
                       w->b->label, where_in(w->b, ref, at, sizeof at), names[level], (unsigned long long)addr,
                       (unsigned long long)w->b->size);
    if (++w->seen[level] > w->count[level])
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s: more %s nodes are referenced than the %u the tree declares",
                       w->b->label, where_in(w->b, ref, at, sizeof at), names[level], w->count[level]);
    return LU_OK;
}

static void leaf_bbox(tree_walk *w, pnanovdb_leaf_handle_t leaf, int64_t ox, int64_t oy, int64_t oz) {
    /* Voxel n = x<<6 | y<<3 | z: word k holds x = k/2, y = 4*(k&1) + byte,
     * z = bit within the byte; so the box follows from OR-ed masks. */
    int xmin = 8, xmax = -1;
    uint32_t ymask = 0, zmask = 0;
    for (uint32_t k = 0; k < 16; k++) {
        uint32_t v = pnanovdb_read_uint32(w->b->buf, pnanovdb_address_offset(leaf.address, PNANOVDB_LEAF_OFF_VALUE_MASK + 4u * k));
        if (!v) continue;
        int x = (int)(k >> 1);
        if (x < xmin) xmin = x;
        if (x > xmax) xmax = x;
        for (uint32_t j = 0; j < 4; j++) {
            uint32_t byte = (v >> (8u * j)) & 0xFFu;
            if (byte) {
                ymask |= 1u << (4u * (k & 1u) + j);
                zmask |= byte;
            }
        }
    }
    if (xmax < 0) return;
    int ymin = __builtin_ctz(ymask), ymax = 31 - __builtin_clz(ymask);
    int zmin = __builtin_ctz(zmask), zmax = 31 - __builtin_clz(zmask);
    grow(w, ox + xmin, oy + ymin, oz + zmin, ox + xmax, oy + ymax, oz + zmax);
}

static lu_result walk_lower(tree_walk *w, pnanovdb_lower_handle_t lower, int64_t ox, int64_t oy, int64_t oz,
                            lu_error *err) {
    const pnanovdb_grid_type_t t = PNANOVDB_GRID_TYPE_FLOAT;
    for (uint32_t k = 0; k < PNANOVDB_LOWER_TABLE_COUNT / 32u; k++) {
        uint32_t child = pnanovdb_read_uint32(w->b->buf, pnanovdb_address_offset(lower.address, PNANOVDB_LOWER_OFF_CHILD_MASK + 4u * k));
        uint32_t value = pnanovdb_read_uint32(w->b->buf, pnanovdb_address_offset(lower.address, PNANOVDB_LOWER_OFF_VALUE_MASK + 4u * k));
        uint32_t bits = child | value;
        while (bits) {
            uint32_t bit = (uint32_t)__builtin_ctz(bits);
            bits &= bits - 1u;
            uint32_t n = 32u * k + bit;
            int64_t x = ox + (int64_t)((n >> 8) & 15u) * 8, y = oy + (int64_t)((n >> 4) & 15u) * 8,
                    z = oz + (int64_t)(n & 15u) * 8;
            if (child & (1u << bit)) {
                pnanovdb_leaf_handle_t leaf = pnanovdb_lower_get_child(t, w->b->buf, lower, n);
                lu_result r = check_node(w, pnanovdb_lower_get_table_address(t, w->b->buf, lower, n).byte_offset,
                                         leaf.address.byte_offset, PNANOVDB_GRID_TYPE_GET(t, leaf_size), 0, err);
                if (r != LU_OK) return r;
                leaf_bbox(w, leaf, x, y, z);
            } else {
                grow(w, x, y, z, x + 7, y + 7, z + 7);
            }
        }
    }
    return LU_OK;
}

static lu_result walk_upper(tree_walk *w, pnanovdb_upper_handle_t upper, int64_t ox, int64_t oy, int64_t oz,
                            lu_error *err) {
    const pnanovdb_grid_type_t t = PNANOVDB_GRID_TYPE_FLOAT;
    for (uint32_t k = 0; k < PNANOVDB_UPPER_TABLE_COUNT / 32u; k++) {
        uint32_t child = pnanovdb_read_uint32(w->b->buf, pnanovdb_address_offset(upper.address, PNANOVDB_UPPER_OFF_CHILD_MASK + 4u * k));
        uint32_t value = pnanovdb_read_uint32(w->b->buf, pnanovdb_address_offset(upper.address, PNANOVDB_UPPER_OFF_VALUE_MASK + 4u * k));
        uint32_t bits = child | value;
        while (bits) {
            uint32_t bit = (uint32_t)__builtin_ctz(bits);
            bits &= bits - 1u;
            uint32_t n = 32u * k + bit;
            int64_t x = ox + (int64_t)((n >> 10) & 31u) * 128, y = oy + (int64_t)((n >> 5) & 31u) * 128,
                    z = oz + (int64_t)(n & 31u) * 128;
            if (child & (1u << bit)) {
                pnanovdb_lower_handle_t lower = pnanovdb_upper_get_child(t, w->b->buf, upper, n);
                lu_result r = check_node(w, pnanovdb_upper_get_table_address(t, w->b->buf, upper, n).byte_offset,
                                         lower.address.byte_offset, PNANOVDB_GRID_TYPE_GET(t, lower_size), 1, err);
                if (r != LU_OK) return r;
                r = walk_lower(w, lower, x, y, z, err);
                if (r != LU_OK) return r;
            } else {
                grow(w, x, y, z, x + 127, y + 127, z + 127);
            }
        }
    }
    return LU_OK;
}

/* ---- dense expansion ------------------------------------------------------- */

typedef struct fill_ctx {
    pnanovdb_buf_t buf;
    pnanovdb_root_handle_t root;
    int32_t lo[3];
    lu_grid *g;
} fill_ctx;

static void fill_rows(void *p, int64_t begin, int64_t end, int thread_index) {
    (void)thread_index;
    fill_ctx *c = p;
    lu_grid *g = c->g;
    pnanovdb_readaccessor_t acc;
    pnanovdb_readaccessor_init(&acc, c->root);
    for (int64_t row = begin; row < end; row++) {
        int y = (int)(row % g->ny), z = (int)(row / g->ny);
        float *dst = g->data + (size_t)row * (size_t)g->nx;
        pnanovdb_coord_t ijk = {c->lo[0], c->lo[1] + y, c->lo[2] + z};
        for (int x = 0; x < g->nx; x++) {
            ijk.x = c->lo[0] + x;
            pnanovdb_address_t a = pnanovdb_readaccessor_get_value_address(PNANOVDB_GRID_TYPE_FLOAT, c->buf, &acc, &ijk);
            dst[x] = pnanovdb_read_float(c->buf, a);
        }
    }
}

static void buf_free(nvdb_buf *b) {
    if (b->map) munmap(b->map, b->map_bytes);
    else lu_free(b->words);
    b->map = NULL;
    b->words = NULL;
}

/* Sparse load: every value the dense expansion would read (leaf values and
 * tiles inside the active box) is checked as it would be, and the range is
 * taken over the same voxels (0 where no node covers one). */
typedef struct value_scan {
    const lu_grid *g;
    const char *label;
    uint64_t covered;
    float lo, hi;
    bool bad;
    int64_t at[3];
    float bad_value;
} value_scan;

static void scan_node(void *p, const int64_t o[3], int dim, const float *leaf, float tile) {
    value_scan *c = p;
    int lo[3], hi[3];
    if (c->bad || !lu_grid_tree_clip(c->g, o, dim, lo, hi)) return;
    c->covered += (uint64_t)(hi[0] - lo[0]) * (uint64_t)(hi[1] - lo[1]) * (uint64_t)(hi[2] - lo[2]);
    if (!leaf) {
        if (!(isfinite(tile) && tile >= 0.0f)) {
            c->bad = true;
            c->bad_value = tile;
            for (int a = 0; a < 3; a++) c->at[a] = (int64_t)lo[a] + c->g->tree_lo[a];
            return;
        }
        c->lo = fminf(c->lo, tile), c->hi = fmaxf(c->hi, tile);
        return;
    }
    for (int x = lo[0]; x < hi[0]; x++)
        for (int y = lo[1]; y < hi[1]; y++)
            for (int z = lo[2]; z < hi[2]; z++) {
                int lx = (int)(x + c->g->tree_lo[0] - o[0]), ly = (int)(y + c->g->tree_lo[1] - o[1]),
                    lz = (int)(z + c->g->tree_lo[2] - o[2]);
                float v = leaf[(lx * 8 + ly) * 8 + lz];
                if (!(isfinite(v) && v >= 0.0f)) {
                    c->bad = true;
                    c->bad_value = v;
                    c->at[0] = o[0] + lx, c->at[1] = o[1] + ly, c->at[2] = o[2] + lz;
                    return;
                }
                c->lo = fminf(c->lo, v), c->hi = fmaxf(c->hi, v);
            }
}

static lu_result read_grid(nvdb_buf *b, const nvdb_meta *m, lu_grid_storage storage, lu_grid *g, lu_error *err) {
    char at[160];
    const char *lb = b->label;
    pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
    pnanovdb_buf_t buf = b->buf;
    const pnanovdb_grid_type_t t = PNANOVDB_GRID_TYPE_FLOAT;

    if (pnanovdb_grid_get_magic(buf, grid) != PNANOVDB_MAGIC_NUMBER)
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s: grid \"%.64s\" buffer has a bad magic number", lb,
                       where_in(b, 0, at, sizeof at), m->name);
    uint32_t version = pnanovdb_grid_get_version(buf, grid);
    if (pnanovdb_version_get_major(version) != NVDB_MAJOR) {
        char vs[32];
        version_str(version, vs, sizeof vs);
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: %s: grid \"%.64s\" has NanoVDB version %s (major %u only)", lb,
                       where_in(b, PNANOVDB_GRID_OFF_VERSION, at, sizeof at), m->name, vs, NVDB_MAJOR);
    }
    uint32_t type = pnanovdb_grid_get_grid_type(buf, grid);
    if (type != m->grid_type)
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s: grid \"%.64s\" buffer says type %s but its metadata says %s", lb,
                       where_in(b, PNANOVDB_GRID_OFF_GRID_TYPE, at, sizeof at), m->name, grid_type_name(type),
                       grid_type_name(m->grid_type));
    if (type != PNANOVDB_GRID_TYPE_FLOAT)
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: grid \"%.64s\" has value type %s; only Float density grids are supported",
                       lb, m->name, grid_type_name(type));
    if (pnanovdb_grid_get_grid_class(buf, grid) == PNANOVDB_GRID_CLASS_LEVEL_SET)
        return lu_fail(err, LU_ERR_UNSUPPORTED,
                       "%s: grid \"%.64s\" is a level set (signed distances), not a density; convert it to a fog "
                       "volume first",
                       lb, m->name);
    uint64_t declared = pnanovdb_grid_get_grid_size(buf, grid);
    if (declared < PNANOVDB_GRID_SIZE + PNANOVDB_TREE_SIZE || declared > b->size)
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s: grid size field %llu does not fit the %llu-byte grid buffer", lb,
                       where_in(b, PNANOVDB_GRID_OFF_GRID_SIZE, at, sizeof at), (unsigned long long)declared,
                       (unsigned long long)b->size);

    pnanovdb_tree_handle_t tree = pnanovdb_grid_get_tree(buf, grid);
    pnanovdb_root_handle_t root = pnanovdb_tree_get_root(buf, tree);
    uint64_t root_addr = root.address.byte_offset;
    uint32_t tiles = pnanovdb_root_get_tile_count(buf, root);
    uint64_t root_bytes = PNANOVDB_GRID_TYPE_GET(t, root_size);
    uint64_t tile_bytes = PNANOVDB_GRID_TYPE_GET(t, root_tile_size);
    uint64_t first_node = PNANOVDB_GRID_SIZE + PNANOVDB_TREE_SIZE;
    if (root_addr < first_node || root_addr % 32u != 0 || root_addr > b->size || root_bytes > b->size - root_addr)
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s: root node offset %llu is outside the %llu-byte grid or misaligned",
                       lb, where_in(b, PNANOVDB_GRID_SIZE + PNANOVDB_TREE_OFF_NODE_OFFSET_ROOT, at, sizeof at),
                       (unsigned long long)(root_addr - PNANOVDB_GRID_SIZE), (unsigned long long)b->size);
    if ((uint64_t)tiles > (b->size - root_addr - root_bytes) / tile_bytes)
        return lu_fail(err, LU_ERR_FORMAT, "%s: %s: root table of %u tiles does not fit the %llu-byte grid", lb,
                       where_in(b, root_addr + PNANOVDB_ROOT_OFF_TABLE_SIZE, at, sizeof at), tiles,
                       (unsigned long long)b->size);
    tree_walk w = {.b = b, .first_node = first_node};
    w.count[0] = pnanovdb_tree_get_node_count_leaf(buf, tree);
    w.count[1] = pnanovdb_tree_get_node_count_lower(buf, tree);
    w.count[2] = pnanovdb_tree_get_node_count_upper(buf, tree);
    static const uint32_t node_bytes[3] = {2144u, 33856u, 270400u};
    for (int l = 0; l < 3; l++)
        if ((uint64_t)w.count[l] * node_bytes[l] > b->size)
            return lu_fail(err, LU_ERR_FORMAT, "%s: %s: %u level-%d nodes cannot fit the %llu-byte grid", lb,
                           where_in(b, PNANOVDB_GRID_SIZE + PNANOVDB_TREE_OFF_NODE_COUNT_LEAF + 4u * (unsigned)l, at,
                                    sizeof at),
                           w.count[l], l, (unsigned long long)b->size);

    /* Partial checksum (NanoVDB's "head" CRC-32): grid, tree and root table. */
    uint64_t checksum = pnanovdb_grid_get_checksum(buf, grid);
    uint32_t head = (uint32_t)checksum;
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
    head = 0xFFFFFFFFu; /* lets the fuzzer past the header into the tree walk */
#endif
    if (checksum != 0 && head != 0xFFFFFFFFu) {
        uint64_t end = first_node + root_bytes + (uint64_t)tiles * tile_bytes;
        if (end <= b->size) {
            uLong crc = crc32(0L, Z_NULL, 0);
            crc = crc32(crc, (const Bytef *)b->words + 16, (uInt)(end - 16));
            if ((uint32_t)crc != head)
                return lu_fail(err, LU_ERR_FORMAT,
                               "%s: %s: grid \"%.64s\" header checksum mismatch (stored 0x%08x, computed 0x%08x): the "
                               "file is corrupt",
                               lb, where_in(b, PNANOVDB_GRID_OFF_CHECKSUM, at, sizeof at), m->name, head,
                               (uint32_t)crc);
        }
    }

    float background = pnanovdb_read_float(buf, pnanovdb_address_offset(root.address, PNANOVDB_GRID_TYPE_GET(t, root_off_background)));
    if (background != 0.0f)
        return lu_fail(err, LU_ERR_UNSUPPORTED,
                       "%s: %s: grid \"%.64s\" has background value %g; densities must fall to 0 outside the grid", lb,
                       where_in(b, root_addr + PNANOVDB_GRID_TYPE_GET(t, root_off_background), at, sizeof at), m->name,
                       (double)background);

    for (uint32_t i = 0; i < tiles; i++) {
        pnanovdb_root_tile_handle_t tile = pnanovdb_root_get_tile(t, root, i);
        int64_t o[3];
        if (!lu_nvdb_key_origin(pnanovdb_root_tile_get_key(buf, tile), o))
            return lu_fail(err, LU_ERR_FORMAT, "%s: %s: root tile %u has an invalid key", lb,
                           where_in(b, tile.address.byte_offset, at, sizeof at), i);
        if (pnanovdb_root_tile_get_child(buf, tile) != 0) {
            pnanovdb_upper_handle_t upper = pnanovdb_root_get_child(t, buf, root, tile);
            lu_result r = check_node(&w, tile.address.byte_offset + PNANOVDB_ROOT_TILE_OFF_CHILD,
                                     upper.address.byte_offset, PNANOVDB_GRID_TYPE_GET(t, upper_size), 2, err);
            if (r != LU_OK) return r;
            r = walk_upper(&w, upper, o[0], o[1], o[2], err);
            if (r != LU_OK) return r;
        } else if (pnanovdb_root_tile_get_state(buf, tile)) {
            grow(&w, o[0], o[1], o[2], o[0] + 4095, o[1] + 4095, o[2] + 4095);
        }
    }
    if (!w.any)
        return lu_fail(err, LU_ERR_UNSUPPORTED, "%s: grid \"%.64s\" has no active voxels", lb, m->name);

    int64_t dim[3];
    if (storage != LU_GRID_STORAGE_DENSE) {
        for (int i = 0; i < 3; i++)
            if (w.hi[i] - w.lo[i] + 1 > LU_MAX_GRID_SIDE)
                return lu_fail(err, LU_ERR_LIMIT,
                               "%s: grid \"%.64s\": active bounding box [%lld,%lld,%lld]..[%lld,%lld,%lld] is wider "
                               "than the limit of %d voxels a side (LU_MAX_GRID_SIDE)",
                               lb, m->name, (long long)w.lo[0], (long long)w.lo[1], (long long)w.lo[2],
                               (long long)w.hi[0], (long long)w.hi[1], (long long)w.hi[2], LU_MAX_GRID_SIDE);
    }
    for (int i = 0; i < 3; i++) {
        dim[i] = w.hi[i] - w.lo[i] + 1;
        if (dim[i] > (int64_t)NVDB_DENSE_LIMIT)
            dim[i] = (int64_t)NVDB_DENSE_LIMIT + 1; /* keeps the product below from overflowing */
    }
    uint64_t voxels = (uint64_t)dim[0] * (uint64_t)dim[1];
    if (voxels <= NVDB_DENSE_LIMIT) voxels *= (uint64_t)dim[2];
    if (voxels > NVDB_DENSE_LIMIT && storage == LU_GRID_STORAGE_DENSE)
        return lu_fail(err, LU_ERR_LIMIT,
                       "%s: grid \"%.64s\": active bounding box [%lld,%lld,%lld]..[%lld,%lld,%lld] exceeds the limit "
                       "of %llu dense voxels",
                       lb, m->name, (long long)w.lo[0], (long long)w.lo[1], (long long)w.lo[2], (long long)w.hi[0],
                       (long long)w.hi[1], (long long)w.hi[2], (unsigned long long)NVDB_DENSE_LIMIT);

    /* index_to_world = grid map composed with the shift to the box corner. */
    pnanovdb_map_handle_t map = pnanovdb_grid_get_map(buf, grid);
    double mat[9], vec[3];
    for (uint32_t i = 0; i < 9; i++) mat[i] = pnanovdb_map_get_matd(buf, map, i);
    for (uint32_t i = 0; i < 3; i++) vec[i] = pnanovdb_map_get_vecd(buf, map, i);
    bool finite = true;
    for (int i = 0; i < 9; i++) finite = finite && isfinite(mat[i]);
    for (int i = 0; i < 3; i++) finite = finite && isfinite(vec[i]);
    double det = mat[0] * (mat[4] * mat[8] - mat[5] * mat[7]) - mat[1] * (mat[3] * mat[8] - mat[5] * mat[6]) +
                 mat[2] * (mat[3] * mat[7] - mat[4] * mat[6]);
    if (!finite || !(fabs(det) > 0.0) || !isfinite(det))
        return lu_fail(err, finite ? LU_ERR_FORMAT : LU_ERR_NONFINITE,
                       "%s: %s: grid \"%.64s\" index-to-world map is %s", lb,
                       where_in(b, PNANOVDB_GRID_OFF_MAP + PNANOVDB_MAP_OFF_MATD, at, sizeof at), m->name,
                       finite ? "singular" : "not finite");

    if (storage != LU_GRID_STORAGE_DENSE) {
        lu_grid_tree_owner *own = lu_calloc(1, sizeof *own);
        if (!own) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", lb);
        memset(g, 0, sizeof *g);
        g->nx = (int)(w.hi[0] - w.lo[0] + 1);
        g->ny = (int)(w.hi[1] - w.lo[1] + 1);
        g->nz = (int)(w.hi[2] - w.lo[2] + 1);
        g->tree = b->words;
        g->tree_bytes = b->size;
        for (int i = 0; i < 3; i++) g->tree_lo[i] = (int)w.lo[i];
        own->map = b->map;
        own->map_bytes = b->map_bytes;
        own->words = b->map ? NULL : b->words;
        g->tree_owner = own;
        b->map = NULL;
        b->words = NULL;
        value_scan vs = {.g = g, .label = lb, .lo = INFINITY, .hi = -INFINITY};
        lu_grid_tree_visit(g, scan_node, &vs);
        if (vs.bad) {
            lu_grid_destroy(g);
            if (!isfinite(vs.bad_value))
                return lu_fail(err, LU_ERR_NONFINITE,
                               "%s: grid \"%.64s\": voxel (%lld,%lld,%lld) is not a finite number", lb, m->name,
                               (long long)vs.at[0], (long long)vs.at[1], (long long)vs.at[2]);
            return lu_fail(err, LU_ERR_RANGE, "%s: grid \"%.64s\": voxel (%lld,%lld,%lld) has negative density %g", lb,
                           m->name, (long long)vs.at[0], (long long)vs.at[1], (long long)vs.at[2],
                           (double)vs.bad_value);
        }
        if (vs.covered < (uint64_t)g->nx * (uint64_t)g->ny * (uint64_t)g->nz) vs.lo = fminf(vs.lo, 0.0f), vs.hi = fmaxf(vs.hi, 0.0f);
        g->min_value = vs.lo;
        g->max_value = vs.hi;
        lu_grid_stamp_new(g);
    } else {
    lu_result r = lu_grid_alloc(g, (int)dim[0], (int)dim[1], (int)dim[2], err);
    if (r != LU_OK) return r;
    fill_ctx fc = {.buf = buf, .root = root, .lo = {(int32_t)w.lo[0], (int32_t)w.lo[1], (int32_t)w.lo[2]}, .g = g};
    lu_parallel_for((int64_t)g->ny * g->nz, 0, fill_rows, &fc, NULL);

    size_t n = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    for (size_t i = 0; i < n; i++) {
        float v = g->data[i];
        if (isfinite(v) && v >= 0.0f) continue;
        long long x = (long long)(i % (size_t)g->nx) + w.lo[0];
        long long y = (long long)(i / (size_t)g->nx % (size_t)g->ny) + w.lo[1];
        long long z = (long long)(i / ((size_t)g->nx * (size_t)g->ny)) + w.lo[2];
        lu_grid_destroy(g);
        if (!isfinite(v))
            return lu_fail(err, LU_ERR_NONFINITE, "%s: grid \"%.64s\": voxel (%lld,%lld,%lld) is not a finite number",
                           lb, m->name, x, y, z);
        return lu_fail(err, LU_ERR_RANGE, "%s: grid \"%.64s\": voxel (%lld,%lld,%lld) has negative density %g", lb,
                       m->name, x, y, z, (double)v);
    }
    lu_grid_update_range(g);
    }
    for (int i = 0; i < 3; i++) {
        double t0 = vec[i];
        for (int j = 0; j < 3; j++) {
            g->index_to_world.m[i][j] = (float)mat[3 * i + j];
            t0 += mat[3 * i + j] * (double)w.lo[j];
        }
        g->index_to_world.m[i][3] = (float)t0;
    }
    snprintf(g->name, sizeof g->name, "%s", m->name);
    return LU_OK;
}

/* ---- entry points ---------------------------------------------------------- */

static lu_result load_from(nvdb_src *s, const char *grid_name, lu_grid_storage storage, lu_grid *g,
                           lu_error *err) {
    nvdb_index ix = {0};
    lu_result r = scan_container(s, &ix, err);
    if (r != LU_OK) {
        index_free(&ix);
        return r;
    }
    const nvdb_meta *pick = NULL;
    bool by_name = grid_name && grid_name[0];
    for (size_t i = 0; i < ix.count && !pick; i++) {
        if (by_name ? strcmp(ix.items[i].name, grid_name) == 0 : ix.items[i].grid_type == PNANOVDB_GRID_TYPE_FLOAT)
            pick = &ix.items[i];
    }
    if (!pick) {
        char list[400] = "";
        size_t used = 0;
        for (size_t i = 0; i < ix.count && used + 1 < sizeof list; i++)
            used += (size_t)snprintf(list + used, sizeof list - used, "%s\"%.40s\" (%s)", i ? ", " : "",
                                     ix.items[i].name, grid_type_name(ix.items[i].grid_type));
        r = by_name ? lu_fail(err, LU_ERR_INVALID_ARG, "%s: no grid named \"%.64s\"; the file holds %s", s->label,
                              grid_name, list)
                    : lu_fail(err, LU_ERR_UNSUPPORTED, "%s: no Float grid; the file holds %s", s->label, list);
        index_free(&ix);
        return r;
    }
    if (pick->grid_type != PNANOVDB_GRID_TYPE_FLOAT) {
        r = lu_fail(err, LU_ERR_UNSUPPORTED,
                    "%s: byte offset %llu: grid \"%.64s\" has value type %s; only Float density grids are supported",
                    s->label, (unsigned long long)(pick->meta_offset + 32), pick->name,
                    grid_type_name(pick->grid_type));
        index_free(&ix);
        return r;
    }
    nvdb_buf b;
    r = load_buffer(s, pick, &b, err);
    if (r == LU_OK) r = read_grid(&b, pick, storage, g, err);
    buf_free(&b);
    index_free(&ix);
    return r;
}

lu_result lu_grid_load_nvdb(const char *path, const char *grid_name, lu_grid *g, lu_error *err) {
    return lu_grid_load_nvdb_as(path, grid_name, LU_GRID_STORAGE_AUTO, g, err);
}

lu_result lu_grid_load_nvdb_memory(const void *data, size_t size, const char *label, const char *grid_name,
                                   lu_grid *g, lu_error *err) {
    return lu_grid_load_nvdb_memory_as(data, size, label, grid_name, LU_GRID_STORAGE_AUTO, g, err);
}

lu_result lu_grid_load_nvdb_as(const char *path, const char *grid_name, lu_grid_storage storage, lu_grid *g,
                               lu_error *err) {
    memset(g, 0, sizeof *g);
    FILE *fp;
    uint64_t file_size;
    lu_result opened = lu_open_regular(path, (void **)&fp, &file_size, err);
    if (opened != LU_OK) return opened;
    if (file_size > LU_MAX_GRID_FILE_BYTES) {
        fclose(fp);
        return lu_fail(err, LU_ERR_LIMIT, "%s: file of %llu bytes exceeds the limit of %llu (LU_MAX_GRID_FILE_BYTES)",
                       path, (unsigned long long)file_size, (unsigned long long)LU_MAX_GRID_FILE_BYTES);
    }
    nvdb_src s = {.fp = fp, .size = file_size, .label = path};
    lu_result r = load_from(&s, grid_name, storage, g, err);
    fclose(fp);   /* a mapping outlives its descriptor */
    return r;
}

lu_result lu_grid_load_nvdb_memory_as(const void *data, size_t size, const char *label, const char *grid_name,
                                      lu_grid_storage storage, lu_grid *g, lu_error *err) {
    memset(g, 0, sizeof *g);
    nvdb_src s = {.mem = data, .size = size, .label = label ? label : "(memory)"};
    if (!data && size) return lu_fail(err, LU_ERR_INVALID_ARG, "%s: no data", s.label);
    return load_from(&s, grid_name, storage, g, err);
}
