/* lucent/grid.h — float density grids: NanoVDB, OpenVDB, raw, procedural; dense or sparse.
 *
 * Conventions (docs/architecture.md §7): voxel centres sit at integer index coordinates;
 * density between centres is trilinear; values outside [0, n-1] are 0, so the
 * field falls linearly to zero one voxel beyond the outermost centres and its
 * support is the index box [-1, n]. This is exactly what a GL 3D texture with
 * GL_LINEAR and a zero border colour computes, so CPU and GPU agree.
 * `index_to_world` is the file's own map (NanoVDB: voxel size and offset);
 * the scene's transform is composed on top by the scene loader.
 *
 * Storage: a grid is dense (`data`, nx*ny*nz floats) or sparse (`data` is
 * NULL and `tree` is a NanoVDB float grid buffer read in place, on the CPU
 * and, as a storage buffer, on the GPU: src/kernels/lu_grid_tree.h). A
 * sparse grid keeps the same index space (index 0 is the lowest corner of
 * its active bounding box, voxel (x, y, z) is tree voxel tree_lo + (x, y, z),
 * values outside [0, n-1] are 0), so every reader (lu_grid_at,
 * lu_grid_sample, the majorant grids) gives the same numbers for both. */
#ifndef LUCENT_GRID_H
#define LUCENT_GRID_H

#include "core.h"
#include "math.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct lu_grid {
    int nx, ny, nz;
    float *data;               /* nx*ny*nz, x fastest: data[(z*ny + y)*nx + x] */
    lu_affine index_to_world;
    float min_value, max_value;
    char name[64];
    /* Change stamps (see "edits" below): a process-wide increasing number
     * given at allocation and at every edit, so no two states of any grids
     * share one; prev_generation is the stamp before the latest edit (0 after
     * allocation) and [edit_lo, edit_hi) the index box that edit changed. */
    uint64_t generation, prev_generation;
    int edit_lo[3], edit_hi[3];
    /* Sparse storage (data == NULL): the tree's buffer (8-byte aligned,
     * tree_bytes long, validated at load), the tree coordinate of index 0,
     * and the library's owner of the buffer (an allocation or a file
     * mapping), released by lu_grid_destroy. A sparse grid is not copied
     * by assignment into a second owner. */
    const void *tree;
    uint64_t tree_bytes;
    int tree_lo[3];
    void *tree_owner;
} lu_grid;

/* How a .nvdb grid is kept: AUTO (0) and SPARSE read the tree in place;
 * DENSE expands it over its active bounding box (LU_MAX_GRID_VOXELS). */
typedef enum lu_grid_storage {
    LU_GRID_STORAGE_AUTO = 0,
    LU_GRID_STORAGE_DENSE,
    LU_GRID_STORAGE_SPARSE
} lu_grid_storage;

lu_result lu_grid_alloc(lu_grid *g, int nx, int ny, int nz, lu_error *err); /* zero-filled, identity map */
void lu_grid_destroy(lu_grid *g);
void lu_grid_update_range(lu_grid *g);   /* recomputes min_value / max_value */

/* Voxel (x, y, z) of a sparse grid (0 outside the index box). */
float lu_grid_tree_at(const lu_grid *g, int x, int y, int z);
/* A grid holds values: dense data or a sparse tree. */
static inline bool lu_grid_has_values(const lu_grid *g) { return g->data != NULL || g->tree != NULL; }
static inline bool lu_grid_is_sparse(const lu_grid *g) { return g->data == NULL && g->tree != NULL; }

static inline float lu_grid_at(const lu_grid *g, int x, int y, int z) {
    if (x < 0 || y < 0 || z < 0 || x >= g->nx || y >= g->ny || z >= g->nz) return 0.0f;
    if (!g->data) return lu_grid_tree_at(g, x, y, z);
    return g->data[((size_t)z * g->ny + y) * g->nx + x];
}
/* Trilinear at an index-space position (zero outside, see above). */
float lu_grid_sample(const lu_grid *g, lu_vec3 p_index);
/* Support of the field in index space: [-1, n] per axis. */
lu_aabb lu_grid_index_support(const lu_grid *g);
/* A dense copy of any grid (same index space, map, name and values);
 * LU_ERR_LIMIT past LU_MAX_GRID_VOXELS. */
lu_result lu_grid_densify(const lu_grid *src, lu_grid *dst, lu_error *err);
/* Bytes of voxel storage the grid holds (dense array or tree buffer). */
uint64_t lu_grid_storage_bytes(const lu_grid *g);
/* Active voxels: the tree's count (tiles included) for a sparse grid, the
 * voxels above 0 for a dense one. */
uint64_t lu_grid_active_voxels(const lu_grid *g);

/* ---- edits --------------------------------------------------------------
 * Density changes after loading go through these calls, which keep
 * min_value / max_value right and give the grid a new `generation`. A
 * renderer keeps the generation its cached products were built from and
 * compares: equal means unchanged; equal to prev_generation means exactly
 * the latest edit happened, so only [edit_lo, edit_hi) needs refreshing (a
 * texture sub-upload, say); anything else means the whole grid.
 * Both calls speak in voxel indices and values, never in storage, so they
 * keep their meaning for sparse grids. Values must be finite and >= 0; a
 * rejected edit (LU_ERR_NONFINITE / LU_ERR_RANGE naming the voxel,
 * LU_ERR_INVALID_ARG for a bad box or count) leaves the grid unchanged.
 * Every loaded grid (NanoVDB, raw, voxelised, procedural) holds plain values:
 * an edit changes those values; it never re-runs a generator or touches a
 * file. Writing g->data directly skips the stamp, and renderers will then
 * not see the change. Sparse grids are read-only: both calls return
 * LU_ERR_UNSUPPORTED for them (load with LU_GRID_STORAGE_DENSE, or
 * lu_grid_densify, to edit). */

/* Replaces all values: `values` holds count = nx*ny*nz floats, x fastest. */
lu_result lu_grid_set_values(lu_grid *g, const float *values, size_t count, lu_error *err);
/* Called once per voxel of the box, in z, y, x order on the calling thread,
 * with the voxel's current value; returns its new value. */
typedef float (*lu_grid_edit_fn)(void *ctx, int x, int y, int z, float value);
/* Rewrites the voxels of the index box [lo, hi) (0 <= lo < hi <= n per
 * axis) through fn. */
lu_result lu_grid_apply(lu_grid *g, const int lo[3], const int hi[3], lu_grid_edit_fn fn, void *ctx,
                        lu_error *err);

/* ---- files -------------------------------------------------------------- */

/* NanoVDB (.nvdb): the float grid named grid_name (NULL or "" = first float
 * grid), kept sparse (its tree buffer, mapped from the file when the grid is
 * stored uncompressed at an 8-byte aligned offset, else read or inflated
 * into memory); index_to_world from the grid's map. Fails with
 * LU_ERR_UNSUPPORTED for non-float grids, LU_ERR_LIMIT past
 * LU_MAX_TREE_BYTES, LU_MAX_GRID_SIDE or LU_MAX_GRID_FILE_BYTES. Every
 * node, tile and leaf value is checked at load, so sampling never meets an
 * invalid address or a bad value.
 * Details: dense index 0 is the box's lowest corner, so index_to_world is
 * the file's map composed with that offset (world positions are preserved).
 * Codecs NONE and ZIP are read; BLOSC, level sets, a non-zero background,
 * grids without active voxels -> LU_ERR_UNSUPPORTED; negative densities ->
 * LU_ERR_RANGE, NaN/inf -> LU_ERR_NONFINITE (naming the voxel); a name not
 * in the file -> LU_ERR_INVALID_ARG (listing the grids); malformed or
 * truncated files -> LU_ERR_FORMAT with the byte offset. */
lu_result lu_grid_load_nvdb(const char *path, const char *grid_name, lu_grid *g, lu_error *err);
/* The same from a file image in memory (the tree is copied); `label` stands
 * for the path in errors. */
lu_result lu_grid_load_nvdb_memory(const void *data, size_t size, const char *label, const char *grid_name,
                                   lu_grid *g, lu_error *err);
/* Both with the storage chosen: LU_GRID_STORAGE_DENSE expands the tree (with
 * tiles) into the dense bounding box of its active values, LU_ERR_LIMIT past
 * LU_MAX_GRID_VOXELS. */
lu_result lu_grid_load_nvdb_as(const char *path, const char *grid_name, lu_grid_storage storage, lu_grid *g,
                               lu_error *err);
lu_result lu_grid_load_nvdb_memory_as(const void *data, size_t size, const char *label, const char *grid_name,
                                      lu_grid_storage storage, lu_grid *g, lu_error *err);
/* OpenVDB (.vdb): the float grid named grid_name (NULL or "" = the first
 * float grid) with its transform, converted to NanoVDB and then read exactly
 * as lu_grid_load_nvdb reads a file, with the same checks and results.
 * OpenVDB's reader is not hardened against malformed files, so it runs in a
 * child process, the converter lucent-vdb-convert (docs/volumes.md): a
 * converter that crashes gives LU_ERR_FORMAT naming the file and the signal.
 * Further failures, each naming the file: a missing file -> LU_ERR_IO; no
 * converter -> LU_ERR_UNSUPPORTED; a name not in the file ->
 * LU_ERR_INVALID_ARG (listing the grids); a grid of another value type, a
 * non-linear (frustum) transform, a grid without active voxels or no float
 * grid at all -> LU_ERR_UNSUPPORTED; a file OpenVDB cannot read ->
 * LU_ERR_FORMAT with OpenVDB's reason. Safe to call from several threads. */
lu_result lu_grid_load_vdb(const char *path, const char *grid_name, lu_grid *g, lu_error *err);
/* Where lu_grid_load_vdb finds its converter (lu_host.vdb_converter, else
 * beside the running executable, else the install's libexec/lucent), or
 * LU_ERR_UNSUPPORTED saying where it looked. */
lu_result lu_grid_vdb_converter(char *out, size_t cap, lu_error *err);
/* Writes a NanoVDB float grid (values equal to 0 become inactive background),
 * fog-volume class, named g->name ("density" if empty), uncompressed, built
 * by NanoVDB's own GridBuilder (constant regions become tiles). Refuses
 * negative or non-finite values and a singular map. Atomic (temp + rename).
 * A sparse grid is written from its dense expansion (LU_MAX_GRID_VOXELS). */
lu_result lu_grid_save_nvdb(const lu_grid *g, const char *path, lu_error *err);
/* Raw little-endian float32, x fastest; the file size must be nx*ny*nz*4.
 * Loading rejects negative (LU_ERR_RANGE) and NaN/inf values with the byte
 * offset; the map is the identity and the name the file's base name. */
lu_result lu_grid_load_raw(const char *path, int nx, int ny, int nz, lu_grid *g, lu_error *err);
lu_result lu_grid_save_raw(const lu_grid *g, const char *path, lu_error *err);

/* ---- procedural ----------------------------------------------------------
 * Every generator fills a grid over the world box centred at `center`
 * (default [0,0,0]) of extent `size` (default [2,2,2]), `resolution` voxels
 * along the longest side (default 64); voxel centres at lo + (i + 0.5) h.
 *   "uniform_box"    value=1
 *   "sphere"         radius=0.8 value=1            (homogeneous sphere, anti-aliased edge)
 *   "gaussians"      count=8 seed=1 sigma=[0.1,0.3] amplitude=1   (sum of random Gaussians)
 *   "fbm_cloud"      octaves=5 frequency=2 gain=0.5 seed=1 radius=0.9 coverage=0.5
 *   "layered_cube"   layers=6 low=0.2 high=1 axis=1 (parallel slabs of two densities)
 *   "torus_in_cube"  value=1 major_radius=0.5 minor_radius=0.18 (0 inside the torus,
 *                    which the scene places as an opaque object)
 *   "dusty_room"     bottom=0.6 top=0.3 noise=0.15 frequency=3 seed=1 (linear in y + noise)
 *   "smoke_plume"    seed=1 (a rising fBm-modulated plume for smoke-in-a-box)
 * `resolution` may also be [nx, ny, nz]; with one number the other sides get
 * round(N * size_i / longest) voxels; h_i = size_i / n_i so the box is exact.
 * Lengths are world units, noise frequencies cycles per world unit; noise is
 * seeded gradient noise (src/volume/lu_noise.h), identical for any thread
 * count. g->name is the generator name. Details per generator:
 *   sphere: value * clamp(0.5 - (d - radius) / h, 0, 1), h the smallest voxel side;
 *   gaussians: centres uniform in the middle 70 % of the box, sigma uniform
 *     in [min, max] (or one number), every peak `amplitude`;
 *   fbm_cloud: fBm thresholded so about `coverage` of the ball of `radius`
 *     is cloud, times 1 - (r / radius)^2, in [0, 1];
 *   layered_cube: slabs along `axis` (0 x, 1 y, 2 z) starting with `low`,
 *     each voxel the exact average over its extent;
 *   torus_in_cube: torus around the y axis through `center`, ramped edge;
 *   dusty_room: bottom + (top - bottom) * t(y) + noise * fBm(3 octaves), >= 0;
 *   smoke_plume: widening column from the floor centre, peak density ~1;
 *     rise=0 time=0: with rise > 0 the plume is animated, its fBm
 *     turbulence carried up the column by rise * time world units (rise in
 *     world units per second) and the meander of its axis travelling up with
 *     it; time 0 is the still plume.
 * Unknown names or parameters are errors naming `where`. */
lu_result lu_grid_procedural(const char *name, const lu_kvlist *params, lu_grid *g, const char *where,
                             lu_error *err);
/* Whether the generator's output changes with its "time" parameter
 * ("smoke_plume" with rise > 0): a scene medium made by it follows the
 * scene's time (lu_scene_set_time). */
bool lu_grid_procedural_animated(const char *name, const lu_kvlist *params);

#ifdef __cplusplus
}
#endif
#endif
