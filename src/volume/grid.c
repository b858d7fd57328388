/* Density grids: dense and sparse storage, trilinear sampling, raw float32 files. */
#include <lucent/grid.h>

#include <errno.h>
#include <float.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>
#include <sys/stat.h>

#include "kernels/lu_grid_tree.h"
#include "volume/grid_internal.h"

/* One counter for every grid of the process: a grid destroyed and another
 * allocated in its place never repeat a stamp a renderer may have kept. */
static atomic_uint_fast64_t g_generation;

static uint64_t next_generation(void) { return (uint64_t)atomic_fetch_add(&g_generation, 1) + 1; }

void lu_grid_stamp_new(lu_grid *g) {
    g->prev_generation = 0;
    g->generation = next_generation();
    for (int a = 0; a < 3; a++) g->edit_lo[a] = 0;
    g->edit_hi[0] = g->nx;
    g->edit_hi[1] = g->ny;
    g->edit_hi[2] = g->nz;
}

lu_result lu_grid_alloc(lu_grid *g, int nx, int ny, int nz, lu_error *err) {
    memset(g, 0, sizeof *g);
    g->index_to_world = lu_affine_identity();
    if (nx < 1 || ny < 1 || nz < 1)
        return lu_fail(err, LU_ERR_INVALID_ARG, "grid dimensions %d x %d x %d: every side must be at least 1", nx, ny,
                       nz);
    /* Each side is below 2^31, so the pairwise product fits in 64 bits and is
     * compared before the third factor can overflow. */
    uint64_t xy = (uint64_t)nx * (uint64_t)ny;
    if (xy > LU_MAX_GRID_VOXELS || xy * (uint64_t)nz > LU_MAX_GRID_VOXELS)
        return lu_fail(err, LU_ERR_LIMIT, "grid of %d x %d x %d voxels exceeds the limit of %llu voxels", nx, ny, nz,
                       (unsigned long long)LU_MAX_GRID_VOXELS);
    size_t count = (size_t)(xy * (uint64_t)nz);
    float *data = lu_calloc(count, sizeof *data);
    if (!data)
        return lu_fail(err, LU_ERR_NOMEM, "out of memory allocating a %d x %d x %d grid (%zu bytes)", nx, ny, nz,
                       count * sizeof *data);
    g->nx = nx;
    g->ny = ny;
    g->nz = nz;
    g->data = data;
    lu_grid_stamp_new(g);
    return LU_OK;
}

void lu_grid_tree_owner_free(lu_grid_tree_owner *o) {
    if (!o) return;
    if (o->map) munmap(o->map, o->map_bytes);
    lu_free(o->words);
    lu_free(o);
}

void lu_grid_destroy(lu_grid *g) {
    if (!g) return;
    lu_free(g->data);
    lu_grid_tree_owner_free(g->tree_owner);
    memset(g, 0, sizeof *g);
}

lu_k_tree lu_grid_tree_view(const lu_grid *g) {
    lu_k_tree t;
    /* PNanoVDB's C buffer is not const, but nothing here writes through it. */
    t.buf = pnanovdb_make_buf((uint32_t *)(uintptr_t)g->tree, (g->tree_bytes + 7u) / 8u * 2u);
    pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
    t.root = pnanovdb_tree_get_root(t.buf, pnanovdb_grid_get_tree(t.buf, grid));
    t.lo_x = g->tree_lo[0], t.lo_y = g->tree_lo[1], t.lo_z = g->tree_lo[2];
    t.nx = g->nx, t.ny = g->ny, t.nz = g->nz;
    return t;
}

float lu_grid_tree_at(const lu_grid *g, int x, int y, int z) {
    if (!g->tree) return 0.0f;
    return lu_tree_voxel(lu_grid_tree_view(g), x, y, z);
}

uint64_t lu_grid_storage_bytes(const lu_grid *g) {
    if (g->data) return (uint64_t)g->nx * (uint64_t)g->ny * (uint64_t)g->nz * sizeof(float);
    return g->tree ? g->tree_bytes : 0;
}

uint64_t lu_grid_active_voxels(const lu_grid *g) {
    if (!g->data) {
        if (!g->tree) return 0;
        lu_k_tree t = lu_grid_tree_view(g);
        pnanovdb_grid_handle_t grid = {pnanovdb_address_null()};
        return pnanovdb_tree_get_voxel_count(t.buf, pnanovdb_grid_get_tree(t.buf, grid));
    }
    uint64_t n = 0, count = (uint64_t)g->nx * (uint64_t)g->ny * (uint64_t)g->nz;
    for (uint64_t i = 0; i < count; i++) n += g->data[i] > 0.0f;
    return n;
}

typedef struct densify_ctx {
    const lu_grid *src;
    lu_grid *dst;
} densify_ctx;

static void densify_rows(void *p, int64_t begin, int64_t end, int thread_index) {
    (void)thread_index;
    densify_ctx *c = p;
    lu_k_tree t = lu_grid_tree_view(c->src);
    pnanovdb_readaccessor_t acc;
    pnanovdb_readaccessor_init(&acc, t.root);
    for (int64_t row = begin; row < end; row++) {
        int y = (int)(row % c->dst->ny), z = (int)(row / c->dst->ny);
        float *dst = c->dst->data + (size_t)row * (size_t)c->dst->nx;
        for (int x = 0; x < c->dst->nx; x++) dst[x] = lu_tree_at(t, &acc, x, y, z);
    }
}

lu_result lu_grid_densify(const lu_grid *src, lu_grid *dst, lu_error *err) {
    memset(dst, 0, sizeof *dst);
    if (!src || !lu_grid_has_values(src)) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_grid_densify: no grid");
    lu_result r = lu_grid_alloc(dst, src->nx, src->ny, src->nz, err);
    if (r != LU_OK) return r;
    if (src->data) {
        memcpy(dst->data, src->data, (size_t)src->nx * src->ny * src->nz * sizeof(float));
    } else {
        densify_ctx c = {src, dst};
        lu_parallel_for((int64_t)dst->ny * dst->nz, 0, densify_rows, &c, NULL);
    }
    dst->index_to_world = src->index_to_world;
    dst->min_value = src->min_value;
    dst->max_value = src->max_value;
    memcpy(dst->name, src->name, sizeof dst->name);
    return LU_OK;
}

void lu_grid_update_range(lu_grid *g) {
    size_t n = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    if (!g->data || n == 0) {
        g->min_value = g->max_value = 0.0f;
        return;
    }
    float lo = g->data[0], hi = g->data[0];
    for (size_t i = 1; i < n; i++) {
        float v = g->data[i];
        if (v < lo) lo = v;
        if (v > hi) hi = v;
    }
    g->min_value = lo;
    g->max_value = hi;
}

/* ---- edits ---------------------------------------------------------------- */

static lu_result check_value(const lu_grid *g, float v, int x, int y, int z, const char *fn, lu_error *err) {
    if (!isfinite(v))
        return lu_fail(err, LU_ERR_NONFINITE, "%s: grid \"%s\" voxel (%d, %d, %d): density is not a finite number", fn,
                       g->name, x, y, z);
    if (v < 0.0f)
        return lu_fail(err, LU_ERR_RANGE, "%s: grid \"%s\" voxel (%d, %d, %d): density %g is negative", fn, g->name, x,
                       y, z, (double)v);
    return LU_OK;
}

static void stamp_edit(lu_grid *g, const int lo[3], const int hi[3]) {
    g->prev_generation = g->generation;
    g->generation = next_generation();
    for (int a = 0; a < 3; a++) {
        g->edit_lo[a] = lo[a];
        g->edit_hi[a] = hi[a];
    }
}

static lu_result refuse_sparse(const lu_grid *g, const char *fn, lu_error *err) {
    return lu_fail(err, LU_ERR_UNSUPPORTED,
                   "%s: grid \"%s\" is sparse (a NanoVDB tree read in place) and cannot be edited; load it with "
                   "storage \"dense\" (LU_GRID_STORAGE_DENSE) or edit a lu_grid_densify copy",
                   fn, g->name);
}

lu_result lu_grid_set_values(lu_grid *g, const float *values, size_t count, lu_error *err) {
    if (g && lu_grid_is_sparse(g)) return refuse_sparse(g, "lu_grid_set_values", err);
    if (!g || !g->data || !values) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_grid_set_values: no grid or no values");
    size_t n = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    if (count != n)
        return lu_fail(err, LU_ERR_INVALID_ARG, "lu_grid_set_values: grid \"%s\" has %d x %d x %d = %zu voxels, got %zu values",
                       g->name, g->nx, g->ny, g->nz, n, count);
    for (size_t i = 0; i < n; i++)
        if (!(isfinite(values[i]) && values[i] >= 0.0f)) {
            int x = (int)(i % (size_t)g->nx), y = (int)(i / (size_t)g->nx % (size_t)g->ny);
            int z = (int)(i / ((size_t)g->nx * (size_t)g->ny));
            return check_value(g, values[i], x, y, z, "lu_grid_set_values", err);
        }
    memmove(g->data, values, n * sizeof *values);
    lu_grid_update_range(g);
    const int lo[3] = {0, 0, 0}, hi[3] = {g->nx, g->ny, g->nz};
    stamp_edit(g, lo, hi);
    return LU_OK;
}

lu_result lu_grid_apply(lu_grid *g, const int lo[3], const int hi[3], lu_grid_edit_fn fn, void *ctx,
                        lu_error *err) {
    if (g && lu_grid_is_sparse(g)) return refuse_sparse(g, "lu_grid_apply", err);
    if (!g || !g->data || !lo || !hi || !fn)
        return lu_fail(err, LU_ERR_INVALID_ARG, "lu_grid_apply: no grid, box or function");
    const int n[3] = {g->nx, g->ny, g->nz};
    for (int a = 0; a < 3; a++)
        if (!(lo[a] >= 0 && lo[a] < hi[a] && hi[a] <= n[a]))
            return lu_fail(err, LU_ERR_INVALID_ARG,
                           "lu_grid_apply: box [%d, %d) x [%d, %d) x [%d, %d) is empty or outside grid \"%s\" of "
                           "%d x %d x %d voxels",
                           lo[0], hi[0], lo[1], hi[1], lo[2], hi[2], g->name, n[0], n[1], n[2]);
    /* New values go to a scratch box first, so a rejected value leaves the
     * grid as it was. */
    int bx = hi[0] - lo[0], by = hi[1] - lo[1], bz = hi[2] - lo[2];
    float *box = lu_malloc((size_t)bx * (size_t)by * (size_t)bz * sizeof *box);
    if (!box) return lu_fail(err, LU_ERR_NOMEM, "lu_grid_apply: out of memory for a %d x %d x %d box", bx, by, bz);
    float old_lo = FLT_MAX, old_hi = -FLT_MAX, new_lo = FLT_MAX, new_hi = -FLT_MAX;
    size_t k = 0;
    for (int z = lo[2]; z < hi[2]; z++)
        for (int y = lo[1]; y < hi[1]; y++)
            for (int x = lo[0]; x < hi[0]; x++, k++) {
                float old = g->data[((size_t)z * g->ny + y) * g->nx + x];
                float v = fn(ctx, x, y, z, old);
                lu_result r = check_value(g, v, x, y, z, "lu_grid_apply", err);
                if (r != LU_OK) {
                    lu_free(box);
                    return r;
                }
                box[k] = v;
                old_lo = fminf(old_lo, old), old_hi = fmaxf(old_hi, old);
                new_lo = fminf(new_lo, v), new_hi = fmaxf(new_hi, v);
            }
    k = 0;
    for (int z = lo[2]; z < hi[2]; z++)
        for (int y = lo[1]; y < hi[1]; y++, k += (size_t)bx)
            memcpy(g->data + ((size_t)z * g->ny + y) * g->nx + lo[0], box + k, (size_t)bx * sizeof *box);
    lu_free(box);
    /* The range changes locally unless the box held the old extreme and
     * gave it up; only then is the whole grid rescanned. */
    if ((old_hi >= g->max_value && new_hi < old_hi) || (old_lo <= g->min_value && new_lo > old_lo)) {
        lu_grid_update_range(g);
    } else {
        g->min_value = fminf(g->min_value, new_lo);
        g->max_value = fmaxf(g->max_value, new_hi);
    }
    stamp_edit(g, lo, hi);
    return LU_OK;
}

/* Texel centres sit on integers and every texel outside [0, n-1] reads 0,
 * exactly like a GL_LINEAR texture with a zero border: weights come from the
 * fractional part, the eight neighbours from lu_grid_at. */
float lu_grid_sample(const lu_grid *g, lu_vec3 p) {
    if (!g->data) return g->tree ? lu_tree_sample(lu_grid_tree_view(g), p) : 0.0f;
    /* Also rejects NaN, and keeps the integer conversions in range. */
    if (!(p.x >= -1.0f && p.y >= -1.0f && p.z >= -1.0f && p.x <= (float)g->nx && p.y <= (float)g->ny &&
          p.z <= (float)g->nz))
        return 0.0f;
    /* p + 1 >= 0, so truncation is floor (floorf is a libm call on baseline x86-64,
     * and this is the reference renderer's innermost loop). */
    int x = (int)(p.x + 1.0f) - 1, y = (int)(p.y + 1.0f) - 1, z = (int)(p.z + 1.0f) - 1;
    float tx = p.x - (float)x, ty = p.y - (float)y, tz = p.z - (float)z;
    float c000, c100, c010, c110, c001, c101, c011, c111;
    if (x >= 0 && y >= 0 && z >= 0 && x < g->nx - 1 && y < g->ny - 1 && z < g->nz - 1) {
        /* Interior: all eight corners exist, no per-corner checks. */
        size_t sx = 1, sy = (size_t)g->nx, sz = (size_t)g->nx * g->ny;
        const float *c = g->data + (size_t)z * sz + (size_t)y * sy + (size_t)x;
        c000 = c[0], c100 = c[sx], c010 = c[sy], c110 = c[sy + sx];
        c001 = c[sz], c101 = c[sz + sx], c011 = c[sz + sy], c111 = c[sz + sy + sx];
    } else {
        c000 = lu_grid_at(g, x, y, z), c100 = lu_grid_at(g, x + 1, y, z);
        c010 = lu_grid_at(g, x, y + 1, z), c110 = lu_grid_at(g, x + 1, y + 1, z);
        c001 = lu_grid_at(g, x, y, z + 1), c101 = lu_grid_at(g, x + 1, y, z + 1);
        c011 = lu_grid_at(g, x, y + 1, z + 1), c111 = lu_grid_at(g, x + 1, y + 1, z + 1);
    }
    float c00 = c000 + tx * (c100 - c000), c10 = c010 + tx * (c110 - c010);
    float c01 = c001 + tx * (c101 - c001), c11 = c011 + tx * (c111 - c011);
    float c0 = c00 + ty * (c10 - c00), c1 = c01 + ty * (c11 - c01);
    return c0 + tz * (c1 - c0);
}

lu_aabb lu_grid_index_support(const lu_grid *g) {
    lu_aabb b = {lu_v3(-1.0f, -1.0f, -1.0f), lu_v3((float)g->nx, (float)g->ny, (float)g->nz)};
    return b;
}

/* ---- index spaces -------------------------------------------------------- */

static bool close_to(float x, float y, float scale) {
    return fabsf(x - y) <= 1e-5f * fmaxf(scale, fmaxf(fabsf(x), fabsf(y)));
}

bool lu_grid_shared_index_space(const lu_grid *d, const lu_grid *e, int k[3]) {
    const lu_affine *a = &d->index_to_world, *b = &e->index_to_world;
    float scale = 0.0f;
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++) scale = fmaxf(scale, fabsf(a->m[i][j]));
    for (int i = 0; i < 3; i++)
        for (int j = 0; j < 3; j++)
            if (!close_to(a->m[i][j], b->m[i][j], scale)) return false;
    lu_affine inv;
    if (!lu_affine_invert(a, &inv)) return false;
    lu_vec3 o = lu_affine_point(&inv, lu_v3(b->m[0][3], b->m[1][3], b->m[2][3]));
    for (int i = 0; i < 3; i++) {
        float v = lu_v3_get(o, i), r = roundf(v);
        if (fabsf(v - r) > 1e-3f) return false;
        k[i] = (int)r;
    }
    return true;
}

lu_result lu_grid_embed(const lu_grid *e, const int k[3], int nx, int ny, int nz, const lu_affine *index_to_world,
                        lu_grid *out, lu_error *err) {
    lu_result r = lu_grid_alloc(out, nx, ny, nz, err);
    if (r != LU_OK) return r;
    for (int z = 0; z < nz; z++)
        for (int y = 0; y < ny; y++)
            for (int x = 0; x < nx; x++)
                out->data[((size_t)z * ny + y) * nx + x] = lu_grid_at(e, x - k[0], y - k[1], z - k[2]);
    out->index_to_world = *index_to_world;
    memcpy(out->name, e->name, sizeof out->name);
    lu_grid_update_range(out);
    return LU_OK;
}

/* ---- raw float32 little-endian ------------------------------------------ */

static float le_to_float(const unsigned char *b) {
    uint32_t u = (uint32_t)b[0] | ((uint32_t)b[1] << 8) | ((uint32_t)b[2] << 16) | ((uint32_t)b[3] << 24);
    float f;
    memcpy(&f, &u, sizeof f);
    return f;
}

static void float_to_le(float f, unsigned char *b) {
    uint32_t u;
    memcpy(&u, &f, sizeof u);
    b[0] = (unsigned char)u;
    b[1] = (unsigned char)(u >> 8);
    b[2] = (unsigned char)(u >> 16);
    b[3] = (unsigned char)(u >> 24);
}

lu_result lu_grid_load_raw(const char *path, int nx, int ny, int nz, lu_grid *g, lu_error *err) {
    memset(g, 0, sizeof *g);
    if (nx < 1 || ny < 1 || nz < 1)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: raw grid dimensions %d x %d x %d: every side must be at least 1",
                       path, nx, ny, nz);
    uint64_t xy = (uint64_t)nx * (uint64_t)ny;
    if (xy > LU_MAX_GRID_VOXELS || xy * (uint64_t)nz > LU_MAX_GRID_VOXELS)
        return lu_fail(err, LU_ERR_LIMIT, "%s: raw grid of %d x %d x %d voxels exceeds the limit of %llu voxels", path,
                       nx, ny, nz, (unsigned long long)LU_MAX_GRID_VOXELS);
    uint64_t expect = xy * (uint64_t)nz * 4u;
    FILE *fp;
    uint64_t file_size;
    lu_result opened = lu_open_regular(path, (void **)&fp, &file_size, err);
    if (opened != LU_OK) return opened;
    if (file_size != expect) {
        fclose(fp);
        return lu_fail(err, LU_ERR_FORMAT,
                       "%s: raw float32 grid of %d x %d x %d voxels needs %llu bytes, but the file has %llu bytes", path,
                       nx, ny, nz, (unsigned long long)expect, (unsigned long long)file_size);
    }
    lu_result r = lu_grid_alloc(g, nx, ny, nz, err);
    if (r != LU_OK) {
        fclose(fp);
        return r;
    }
    size_t count = (size_t)(expect / 4u);
    unsigned char buf[1 << 16];
    size_t done = 0;
    while (done < count) {
        size_t want = count - done;
        if (want > sizeof buf / 4) want = sizeof buf / 4;
        size_t got = fread(buf, 4, want, fp);
        if (got != want) {
            fclose(fp);
            lu_grid_destroy(g);
            return lu_fail(err, LU_ERR_IO, "%s: short read at byte offset %llu", path,
                           (unsigned long long)(done + got) * 4u);
        }
        for (size_t i = 0; i < want; i++) {
            float v = le_to_float(buf + 4 * i);
            unsigned long long off = (unsigned long long)(done + i) * 4u;
            if (!isfinite(v)) {
                fclose(fp);
                lu_grid_destroy(g);
                return lu_fail(err, LU_ERR_NONFINITE, "%s: byte offset %llu: density is not a finite number", path,
                               off);
            }
            if (v < 0.0f) {
                fclose(fp);
                lu_grid_destroy(g);
                return lu_fail(err, LU_ERR_RANGE, "%s: byte offset %llu: density %g is negative", path, off,
                               (double)v);
            }
            g->data[done + i] = v;
        }
        done += want;
    }
    fclose(fp);
    const char *slash = strrchr(path, '/');
    snprintf(g->name, sizeof g->name, "%s", slash ? slash + 1 : path);
    lu_grid_update_range(g);
    return LU_OK;
}

lu_result lu_grid_save_raw(const lu_grid *g, const char *path, lu_error *err) {
    if (!g || !g->data || g->nx < 1 || g->ny < 1 || g->nz < 1)
        return lu_fail(err, LU_ERR_INVALID_ARG, "%s: cannot save an empty grid", path);
    lu_atomic_file f;
    lu_result r = lu_atomic_open(&f, path, err);
    if (r != LU_OK) return r;
    size_t count = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    unsigned char buf[1 << 16];
    size_t done = 0;
    while (done < count) {
        size_t n = count - done;
        if (n > sizeof buf / 4) n = sizeof buf / 4;
        for (size_t i = 0; i < n; i++) float_to_le(g->data[done + i], buf + 4 * i);
        if (fwrite(buf, 4, n, (FILE *)f.fp) != n) {
            lu_atomic_abort(&f);
            return lu_fail(err, LU_ERR_IO, "%s: write failed: %s", path, strerror(errno));
        }
        done += n;
    }
    return lu_atomic_commit(&f, err);
}
