/* lucent/core.h — results and errors, settings, threads, progress, time.
 *
 * Every fallible call returns an lu_result and, on failure, fills an lu_error
 * whose message names the file, the line / byte offset / JSON path, and the
 * reason: "scenes/x.json: $.lights[1].type: unknown light type \"area\"".
 * Nothing in liblucent aborts on bad input. */
#ifndef LUCENT_CORE_H
#define LUCENT_CORE_H

#include <stdbool.h>
#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

/* ---- version -------------------------------------------------------------
 * MAJOR changes when a program built against an older header may no longer
 * build or run (docs/architecture.md §10 says what is stable); MINOR when
 * something is added; PATCH for fixes only. CMake reads the project version
 * from these three lines, so the header is the one place it is written. */
#define LU_VERSION_MAJOR 0
#define LU_VERSION_MINOR 3
#define LU_VERSION_PATCH 0
#define LU_VERSION_STRING "0.3.0"
/* One number that orders versions: (MAJOR << 16) | (MINOR << 8) | PATCH. */
#define LU_VERSION ((LU_VERSION_MAJOR << 16) | (LU_VERSION_MINOR << 8) | LU_VERSION_PATCH)

/* The library's own version (the header's LU_VERSION when both match); a
 * program linked against a shared library can compare the two majors. */
uint32_t lu_version(void);
const char *lu_version_string(void);

/* ---- results ---------------------------------------------------------- */

typedef enum lu_result {
    LU_OK = 0,
    LU_ERR_INVALID_ARG,   /* a caller passed something meaningless           */
    LU_ERR_IO,            /* open/read/write/rename failed                   */
    LU_ERR_FORMAT,        /* malformed file: bad header, truncated, bad token */
    LU_ERR_NONFINITE,     /* NaN or infinity where a finite number belongs   */
    LU_ERR_RANGE,         /* a value outside its allowed range               */
    LU_ERR_LIMIT,         /* input larger than an explicit limit (LU_MAX_*)  */
    LU_ERR_NOMEM,         /* allocation failed                               */
    LU_ERR_UNSUPPORTED,   /* valid input we do not handle (e.g. vec3 grids)  */
    LU_ERR_SCENE,         /* scene JSON: unknown key, wrong type, missing key */
    LU_ERR_BACKEND,       /* GPU / EGL / GL failure                          */
    LU_ERR_COUNT
} lu_result;

/* Short stable identifier for a result: "LU_ERR_FORMAT". */
const char *lu_result_name(lu_result r);

typedef struct lu_error {
    lu_result code;
    char message[768];
} lu_error;

/* Formats message into err (if err is non-NULL) and returns code, so a
 * failing path reads: return lu_fail(err, LU_ERR_FORMAT, "%s:%d: ...", ...); */
lu_result lu_fail(lu_error *err, lu_result code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Explicit limits: inputs beyond these are rejected with LU_ERR_LIMIT. */
#define LU_MAX_IMAGE_DIM      16384
#define LU_MAX_GRID_VOXELS    (512ull * 512ull * 512ull)   /* dense grids (4 bytes a voxel) */
/* Sparse grids (NanoVDB trees read in place, lucent/grid.h): the tree's
 * buffer (memory scales with it, not with the bounding box), each side of
 * the active bounding box (index coordinates are floats: a side of 2^15
 * keeps 9 bits of sub-voxel position), and a .nvdb file, which is mapped
 * rather than read, so LU_MAX_FILE_BYTES does not apply to it. */
#define LU_MAX_TREE_BYTES     (64ull * 1024ull * 1024ull * 1024ull)
#define LU_MAX_GRID_SIDE      32768
#define LU_MAX_GRID_FILE_BYTES (256ull * 1024ull * 1024ull * 1024ull)
#define LU_MAX_TRIANGLES      (64u * 1024u * 1024u)
#define LU_MAX_VERTICES       (64u * 1024u * 1024u)
#define LU_MAX_FILE_BYTES     (2ull * 1024ull * 1024ull * 1024ull)

/* ---- settings: named values --------------------------------------------
 * A small ordered list of key -> number(s) or string. Used for method
 * parameters (--set afm.coeffs=16) and procedural generator parameters
 * ({"procedural": "fbm_cloud", "octaves": 5}). Consumers reject keys they do
 * not know (lu_kv_check_known) so typos are errors, not silent defaults. */

#define LU_KV_KEY_MAX 64
#define LU_KV_STR_MAX 256

typedef struct lu_kv {
    char key[LU_KV_KEY_MAX];
    int count;                 /* numbers in v (1..4); 0 means a string value */
    double v[4];
    char str[LU_KV_STR_MAX];
} lu_kv;

typedef struct lu_kvlist {
    lu_kv *items;
    int count, capacity;
} lu_kvlist;

void lu_kv_free(lu_kvlist *list);
lu_result lu_kv_set_number(lu_kvlist *list, const char *key, const double *v, int count, lu_error *err);
lu_result lu_kv_set_string(lu_kvlist *list, const char *key, const char *value, lu_error *err);
/* Parses "key=value" where value is a number, a comma list of up to 4
 * numbers, or a string. */
lu_result lu_kv_parse_assignment(lu_kvlist *list, const char *text, lu_error *err);
const lu_kv *lu_kv_find(const lu_kvlist *list, const char *key);
/* Number lookup with default; fails if the key exists but is not a number
 * or is outside [lo, hi]. `where` prefixes the error ("afm", "$.media[0].density"). */
lu_result lu_kv_number(const lu_kvlist *list, const char *key, double def, double lo, double hi,
                       double *out, const char *where, lu_error *err);
lu_result lu_kv_vec3(const lu_kvlist *list, const char *key, const double def[3], double out[3],
                     const char *where, lu_error *err);
/* Fails naming the first key not in the NULL-terminated `known` array. */
lu_result lu_kv_check_known(const lu_kvlist *list, const char *const *known, const char *where,
                            lu_error *err);

/* ---- the host: memory, log, threads, cache folder ---------------------------
 * What a program embedding lucent decides for the whole process, set once
 * with lu_host_set before any other lu_ call (a zero-initialised lu_host is
 * the default everywhere). The library reads no environment variable: the
 * CLI reads LUCENT_THREADS, LUCENT_CACHE_DIR (else XDG), LUCENT_QUIET,
 * LUCENT_GPU, LUCENT_GPU_DEVICE, LUCENT_DEBUG and LUCENT_VDB_CONVERTER and
 * passes them in here.
 *
 * Memory: every allocation of the library itself goes through alloc /
 * realloc / free (all three or none; NULL: the C library's). Each block
 * asks the hook for its size plus one max_align_t, a header that records
 * the size and the account it is charged to (lu_memory_get,
 * lu_renderer_stats.memory). Memory an lu_ call hands to the caller to
 * release (lu_read_file's buffer) is released with lu_free. The libraries
 * lucent uses (Embree, FFTW, libpng, zlib, OpenEXR, cJSON, the GL driver)
 * allocate through their own allocators. */

typedef enum lu_log_level {
    LU_LOG_ERROR = 0,
    LU_LOG_WARNING,
    LU_LOG_INFO,
    LU_LOG_PROGRESS,   /* progress bars: "\r"-terminated while running on a terminal */
    LU_LOG_DEBUG       /* only with lu_host.debug */
} lu_log_level;

/* message is complete text (ends with "\n", or "\r" for a progress bar). */
typedef void (*lu_log_fn)(lu_log_level level, const char *message, void *user);

/* Which GPU device AUTO contexts take. */
typedef enum lu_gpu_choice {
    LU_GPU_CHOICE_AUTO = 0,     /* a hardware EGL device, else Mesa's software one */
    LU_GPU_CHOICE_HARDWARE,     /* hardware devices only */
    LU_GPU_CHOICE_SOFTWARE      /* software (llvmpipe) only */
} lu_gpu_choice;

typedef struct lu_host {
    void *(*alloc)(size_t size, void *user);
    void *(*realloc)(void *ptr, size_t size, void *user);
    void (*free)(void *ptr, void *user);
    lu_log_fn log;              /* NULL: stderr */
    int threads;                /* 0: the online processors (capped at LU_MAX_THREADS) */
    const char *cache_dir;      /* NULL: no on-disk cache (copied) */
    bool quiet;                 /* only errors and warnings reach the log: no progress, no reports */
    bool debug;                 /* diagnostics (LU_LOG_DEBUG): sampling passes, coverage */
    lu_gpu_choice gpu;
    bool gpu_device_only;       /* use only EGL device gpu_device (as `lucent info --gpu` lists them) */
    int gpu_device;
    /* The OpenVDB converter that .vdb input runs (lu_grid_load_vdb); NULL:
     * beside the executable, then the install's libexec/lucent (copied). */
    const char *vdb_converter;
    void *user;                 /* passed to alloc, realloc, free and log */
} lu_host;

/* Validates and installs host (NULL: the defaults). The allocator may change
 * only while no memory from the previous one is alive: call it first. */
lu_result lu_host_set(const lu_host *host, lu_error *err);
/* The host in effect, defaults resolved (threads as lu_thread_count says;
 * cache_dir points to the library's copy). */
void lu_host_get(lu_host *out);

void *lu_malloc(size_t size);
void *lu_calloc(size_t count, size_t size);   /* zeroed; NULL on overflow */
void *lu_realloc(void *ptr, size_t size);
void lu_free(void *ptr);
char *lu_strdup(const char *s);

/* Memory, counted where it is allocated. bytes, peak_bytes and blocks are
 * the library's own heap blocks through lu_malloc (sizes as asked, headers
 * left out); accel_bytes is what Embree reports for its acceleration
 * structures (its memory monitor); gpu_bytes the GPU buffers and textures
 * lucent created, at their storage size. Not counted: other libraries'
 * allocations, mapped files (a sparse .nvdb grid read in place), and what
 * the GL driver keeps for itself. */
typedef struct lu_memory {
    size_t bytes;
    size_t peak_bytes;             /* the most bytes held at once */
    size_t blocks;
    size_t accel_bytes;
    size_t gpu_bytes;
} lu_memory;
/* The whole process's figures: every account together, and what was
 * allocated outside any renderer (scenes, grids, images). */
void lu_memory_get(lu_memory *out);
/* The process's resident memory in KiB (Linux /proc/self/statm; 0 where
 * unknown): the whole process, the libraries lucent uses included, for
 * soak runs and the viewer's --stats. */
long lu_resident_kb(void);

/* Formats one message and hands it to the host's log (stderr by default);
 * LU_LOG_DEBUG only with lu_host.debug; LU_LOG_INFO and LU_LOG_PROGRESS not
 * with lu_host.quiet. (Not lu_log: that is the kernels' logarithm.) */
void lu_log_msg(lu_log_level level, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 2, 3)))
#endif
    ;
bool lu_log_enabled(lu_log_level level);

/* ---- threads -----------------------------------------------------------
 * One persistent worker pool per process, started by the first
 * lu_parallel_for that can use a helper and grown (never shrunk) to the
 * largest thread count asked for since. Idle workers sleep; they do not spin.
 *
 * Thread count: the value given to lu_set_thread_count (or lu_host.threads),
 * else the number of online processors capped at LU_MAX_THREADS. The library
 * reads no environment variable: the CLI reads LUCENT_THREADS and passes it.
 *
 * Work is handed out in chunks from an atomic counter, so results never
 * depend on scheduling (each index is computed by exactly one call, with no
 * shared accumulation). */

#define LU_MAX_THREADS 256

typedef void (*lu_range_fn)(void *ctx, int64_t begin, int64_t end, int thread_index);

int lu_thread_count(void);
/* n in [1, LU_MAX_THREADS] fixes the count for later lu_parallel_for calls
 * (calls already running keep theirs); 0 returns to the default above.
 * Anything else is LU_ERR_RANGE and changes nothing. */
lu_result lu_set_thread_count(int n, lu_error *err);
/* Parses a thread count as LUCENT_THREADS spells it: decimal digits only,
 * value in [1, LU_MAX_THREADS]. `where` prefixes the error. */
lu_result lu_thread_count_parse(const char *text, const char *where, int *out, lu_error *err);
/* Calls fn over [0, n) split into chunks of `grain` (0 picks a default),
 * using up to lu_thread_count() threads: the caller and pool workers.
 * thread_index is in [0, lu_thread_count()) as read at the start of the call,
 * and no two threads running chunks of the same call share one, so it can
 * index per-thread scratch sized by lu_thread_count() (scratch sized before
 * a later lu_set_thread_count raised the count is too small). Index 0 is
 * always the calling thread. Returns once every chunk has finished.
 *
 * Nested and concurrent calls: every call is queued as a job of its own,
 * whether fn calls lu_parallel_for again or several application threads call
 * it at once; workers join the oldest job with chunks left, and each caller
 * runs its own job's chunks too, so every call completes (a call that finds
 * every worker busy starts on its caller alone, and workers join it as they
 * come free). Callers at once share the workers: together they get at most
 * the pool's size (the largest count asked for, minus one), each at most its
 * own count minus one, plus themselves. Thread indices are unique per
 * call, not across calls: scratch indexed by thread_index must belong to one
 * call at a time.
 *
 * progress_label, when non-NULL, drives a progress bar on stderr for runs
 * over a second (see lu_progress), updated by the calling thread. */
void lu_parallel_for(int64_t n, int64_t grain, lu_range_fn fn, void *ctx, const char *progress_label);

/* ---- progress ------------------------------------------------------------
 * Silent for the first second; then a bar with percent and ETA on a TTY, or
 * a line per 25 % otherwise, through the log (LU_LOG_PROGRESS); lu_host.quiet
 * silences it (the CLI sets that from LUCENT_QUIET). */

typedef struct lu_progress {
    const char *label;
    int64_t total;
    double start_s;
    double last_print_s;
    int last_quarter;
    bool printed;
} lu_progress;

void lu_progress_begin(lu_progress *p, const char *label, int64_t total);
void lu_progress_update(lu_progress *p, int64_t done);
void lu_progress_end(lu_progress *p);

/* ---- time and memory -------------------------------------------------- */

double lu_time_seconds(void);         /* monotonic clock */
size_t lu_peak_rss_bytes(void);       /* peak resident set of this process (since the last reset) */
/* Restarts peak-RSS accounting (Linux: /proc/self/clear_refs), so a bench can
 * report each method's own peak. Returns false where unsupported. */
bool lu_peak_rss_reset(void);

/* ---- small file helpers ------------------------------------------------
 * Outputs are written to "<path>.tmp.<pid>" and renamed into place, so a
 * failed write never leaves a half-written file under the final name. */

typedef struct lu_atomic_file {
    void *fp;                  /* FILE*, opened "wb" */
    char final_path[1024];
    char temp_path[1100];
} lu_atomic_file;

lu_result lu_atomic_open(lu_atomic_file *f, const char *path, lu_error *err);
/* Flushes, closes and renames; on any earlier failure call lu_atomic_abort. */
lu_result lu_atomic_commit(lu_atomic_file *f, lu_error *err);
void lu_atomic_abort(lu_atomic_file *f);

/* Opens a regular file for binary reading and reports its size; errors name
 * the path (LU_ERR_IO for a missing file or a directory). */
lu_result lu_open_regular(const char *path, void **fp, uint64_t *size, lu_error *err);
/* Reads a whole file (up to max_bytes) into a NUL-terminated buffer, which
 * the caller releases with lu_free. */
lu_result lu_read_file(const char *path, size_t max_bytes, char **data, size_t *size, lu_error *err);
/* Lower-case extension after the last '.', "" if none; ".ply.gz" -> "gz". */
const char *lu_path_ext(const char *path);
bool lu_path_has_suffix(const char *path, const char *suffix); /* case-insensitive */
/* Joins dir-of(base_file) with rel (unless rel is absolute) into out. */
void lu_path_resolve(const char *base_file, const char *rel, char *out, size_t out_size);

/* ---- the cache folder ----------------------------------------------------
 * Every on-disk cache lives in one folder: the one set here or in
 * lu_host.cache_dir. With none set the library keeps no cache on disk (ddod
 * computes its precomputation every time). NULL unsets it. */
lu_result lu_set_cache_dir(const char *dir, lu_error *err);
/* The folder set, or LU_ERR_UNSUPPORTED "no cache folder" when none is. */
lu_result lu_cache_dir(char *out, size_t cap, lu_error *err);
bool lu_cache_enabled(void);
/* <cache folder>/name, creating the folder first when create_dir. */
lu_result lu_cache_path(const char *name, bool create_dir, char *out, size_t cap, lu_error *err);
/* The conventional folder, from values a host read from its environment (any
 * may be NULL): lucent_cache_dir when set, else xdg_cache_home/lucent when it
 * is absolute (XDG ignores relative values), else home/.cache/lucent. The CLI
 * passes $LUCENT_CACHE_DIR, $XDG_CACHE_HOME and $HOME. LU_ERR_IO when all are
 * unset. */
lu_result lu_cache_dir_conventional(const char *lucent_cache_dir, const char *xdg_cache_home, const char *home,
                                    char *out, size_t cap, lu_error *err);

#ifdef __cplusplus
}
#endif
#endif
