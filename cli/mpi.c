/* A distributed job of lucent processes (cli/mpi_job.h, docs/distributed.md).
 *
 * The work queue is a pair of counters in an MPI window on rank 0 (the next
 * item, the items done), advanced with MPI_Fetch_and_op by whichever rank
 * asks: no rank serves the others, so rank 0 renders like every other. */

#include "mpi_job.h"

#include <pthread.h>
#include <sched.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "cli.h"

#ifdef LU_HAVE_MPI
#include <mpi.h>
#endif

static int g_rank = 0, g_size = 1;
#ifdef LU_HAVE_MPI
static int g_thread_level = MPI_THREAD_SINGLE;   /* what MPI_Init_thread provided */
/* While the queue is open, its calls and the progress thread's take turns. */
static pthread_mutex_t g_mpi_mu = PTHREAD_MUTEX_INITIALIZER;
#endif

int lu_mpi_rank(void) { return g_rank; }
int lu_mpi_size(void) { return g_size; }

/* Whether a launcher started this process as one rank of a job: Open MPI's
 * mpirun, a PMIx launcher (srun --mpi=pmix, prterun) or a PMI one (MPICH's
 * hydra, srun --mpi=pmi2). A plain `lucent` never initialises MPI, so a
 * build with MPI runs single-process exactly as one without. */
static bool launched_as_rank(void) {
    static const char *const vars[] = {"OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"};
    for (size_t i = 0; i < sizeof vars / sizeof vars[0]; i++)
        if (getenv(vars[i])) return true;
    return false;
}

/* A job of one gathers its own bytes. */
static lu_result gather_alone(const void *data, size_t bytes, void **all, size_t *total, lu_error *err) {
    *total = 0;
    *all = malloc(bytes ? bytes : 1);
    if (!*all) return lu_fail(err, LU_ERR_NOMEM, "out of memory");
    memcpy(*all, data, bytes);
    *total = bytes;
    return LU_OK;
}

#ifdef LU_HAVE_MPI

/* The library's progress bars are each rank's own; in a job only rank 0's
 * bar over the whole job's work reaches the log. */
static bool g_job_bar;

static void job_log(lu_log_level level, const char *message, void *user) {
    (void)user;
    if (level == LU_LOG_PROGRESS && !g_job_bar) return;
    fputs(message, stderr);
}

/* Processors this rank may run on: the launcher's binding when it bound the
 * rank to fewer than the machine has, else the node's share of them. */
static int rank_threads(void) {
    MPI_Comm node;
    int local = 1;
    if (MPI_Comm_split_type(MPI_COMM_WORLD, MPI_COMM_TYPE_SHARED, 0, MPI_INFO_NULL, &node) == MPI_SUCCESS) {
        MPI_Comm_size(node, &local);
        MPI_Comm_free(&node);
    }
    long online = sysconf(_SC_NPROCESSORS_ONLN);
    cpu_set_t set;
    int bound = sched_getaffinity(0, sizeof set, &set) == 0 ? CPU_COUNT(&set) : (int)online;
    int n = bound < online ? bound : (int)(online / (local > 0 ? local : 1));
    return n < 1 ? 1 : (n > LU_MAX_THREADS ? LU_MAX_THREADS : n);
}

int lu_mpi_begin(int *argc, char ***argv) {
    if (!launched_as_rank()) return LU_EXIT_OK;
    /* The main thread calls MPI, and on rank 0 the queue's progress thread
     * (below), one at a time (g_mpi_mu); the worker pool never does.
     * SERIALIZED rather than MULTIPLE: Open MPI's one-sided component for
     * TCP refuses MULTIPLE. */
    if (MPI_Init_thread(argc, argv, MPI_THREAD_SERIALIZED, &g_thread_level) != MPI_SUCCESS) {
        fprintf(stderr, "lucent: error: mpi: MPI_Init_thread failed\n");
        return LU_EXIT_FAIL;
    }
    MPI_Comm_rank(MPI_COMM_WORLD, &g_rank);
    MPI_Comm_size(MPI_COMM_WORLD, &g_size);
    if (g_size == 1) return LU_EXIT_OK;
    lu_host host;
    lu_host_get(&host);
    host.log = job_log;
    host.user = NULL;
    if (!lu_cli_threads_from_env) host.threads = rank_threads();
    lu_error err = {0};
    if (lu_host_set(&host, &err) != LU_OK) {
        fprintf(stderr, "lucent: error (rank %d of %d): %s\n", g_rank, g_size, err.message);
        return LU_EXIT_FAIL;
    }
    return LU_EXIT_OK;
}

int lu_mpi_end(int rc) {
    int initialised = 0;
    MPI_Initialized(&initialised);
    if (!initialised) return rc;
    if (rc != LU_EXIT_OK && g_size > 1) {
        fprintf(stderr, "lucent: rank %d of %d failed (exit %d): ending the whole job\n", g_rank, g_size, rc);
        fflush(stderr);
        MPI_Abort(MPI_COMM_WORLD, rc);
    }
    MPI_Finalize();
    return rc;
}

/* ---- the work queue ---- */

enum { Q_NEXT = 0, Q_DONE = 1 };

typedef struct queue {
    MPI_Win win;
    int64_t *counters;   /* rank 0's window: next item, items done */
    int64_t count;
    int64_t local_next;  /* a job of one counts here */
    bool open, holding;  /* holding: an item taken and not yet reported done */
    pthread_t progress;
    bool progress_on;
    atomic_bool stop;
} queue;

static queue g_queue;

/* Where the network has no atomics of its own (TCP: Open MPI's one-sided
 * component then works by messages), a Fetch_and_op on rank 0's counters
 * completes only when rank 0 enters MPI, which the main thread does only
 * between its own bands: the other ranks would wait up to a band for their
 * next one. This thread enters MPI every 2 ms meanwhile. */
static void *progress_main(void *arg) {
    (void)arg;
    while (!atomic_load(&g_queue.stop)) {
        int flag;
        pthread_mutex_lock(&g_mpi_mu);
        MPI_Iprobe(MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_SELF, &flag, MPI_STATUS_IGNORE);
        pthread_mutex_unlock(&g_mpi_mu);
        usleep(2000);
    }
    return NULL;
}

static int64_t queue_op(int slot, int64_t add, MPI_Op op) {
    int64_t got = 0;
    pthread_mutex_lock(&g_mpi_mu);
    MPI_Fetch_and_op(&add, &got, MPI_INT64_T, 0, slot, op, g_queue.win);
    MPI_Win_flush(0, g_queue.win);
    pthread_mutex_unlock(&g_mpi_mu);
    return got;
}

lu_result lu_mpi_queue_open(int count, lu_error *err) {
    memset(&g_queue, 0, sizeof g_queue);
    g_queue.count = count;
    if (g_size == 1) return LU_OK;
    MPI_Aint bytes = g_rank == 0 ? 2 * (MPI_Aint)sizeof(int64_t) : 0;
    if (MPI_Win_allocate(bytes, sizeof(int64_t), MPI_INFO_NULL, MPI_COMM_WORLD, &g_queue.counters, &g_queue.win) !=
        MPI_SUCCESS)
        return lu_fail(err, LU_ERR_NOMEM, "mpi: the work queue's window could not be made");
    if (g_rank == 0) g_queue.counters[Q_NEXT] = g_queue.counters[Q_DONE] = 0;
    /* Nobody takes an item before rank 0's counters are zero. */
    MPI_Barrier(MPI_COMM_WORLD);
    MPI_Win_lock_all(0, g_queue.win);
    g_queue.open = true;
    atomic_store(&g_queue.stop, false);
    if (g_rank == 0 && g_thread_level >= MPI_THREAD_SERIALIZED)
        g_queue.progress_on = pthread_create(&g_queue.progress, NULL, progress_main, NULL) == 0;
    return LU_OK;
}

int lu_mpi_queue_next(void) {
    if (g_size == 1) return g_queue.local_next < g_queue.count ? (int)g_queue.local_next++ : -1;
    if (g_queue.holding) queue_op(Q_DONE, 1, MPI_SUM);
    int64_t k = queue_op(Q_NEXT, 1, MPI_SUM);
    g_queue.holding = k < g_queue.count;
    return g_queue.holding ? (int)k : -1;
}

/* Items finished by every rank so far (rank 0's view of the job). */
static int64_t queue_done(void) { return g_size == 1 ? g_queue.local_next : queue_op(Q_DONE, 0, MPI_NO_OP); }

void lu_mpi_queue_close(void) {
    if (g_queue.progress_on) {
        atomic_store(&g_queue.stop, true);
        pthread_join(g_queue.progress, NULL);
    }
    if (g_size > 1 && g_queue.open) {
        MPI_Win_unlock_all(g_queue.win);
        MPI_Win_free(&g_queue.win);
    }
    memset(&g_queue, 0, sizeof g_queue);
}

/* ---- gathering ---- */

lu_result lu_mpi_gather(const void *data, size_t bytes, void **all, size_t *total, lu_error *err) {
    if (g_size == 1) return gather_alone(data, bytes, all, total, err);
    *all = NULL;
    *total = 0;
    if (bytes > (size_t)0x7fffffff) return lu_fail(err, LU_ERR_LIMIT, "mpi: %zu bytes from one rank (at most 2^31 - 1)", bytes);
    int mine = (int)bytes;
    int *counts = NULL, *displs = NULL;
    if (g_rank == 0) {
        counts = calloc((size_t)g_size, sizeof *counts);
        displs = calloc((size_t)g_size, sizeof *displs);
        if (!counts || !displs) {
            free(counts);
            free(displs);
            return lu_fail(err, LU_ERR_NOMEM, "mpi: out of memory");
        }
    }
    MPI_Gather(&mine, 1, MPI_INT, counts, 1, MPI_INT, 0, MPI_COMM_WORLD);
    size_t sum = 0;
    bool fits = true;
    if (g_rank == 0) {
        for (int i = 0; i < g_size; i++) {
            displs[i] = (int)sum;
            sum += (size_t)counts[i];
            fits = fits && sum <= (size_t)0x7fffffff;
        }
    }
    /* Every rank takes part in the Gatherv, or the others wait forever. */
    char *buf = g_rank == 0 && fits ? malloc(sum ? sum : 1) : NULL;
    if (g_rank == 0 && !buf) {
        free(counts);
        free(displs);
        return fits ? lu_fail(err, LU_ERR_NOMEM, "mpi: out of memory for %zu gathered bytes", sum)
                    : lu_fail(err, LU_ERR_LIMIT, "mpi: %zu gathered bytes (at most 2^31 - 1)", sum);
    }
    MPI_Gatherv(data, mine, MPI_BYTE, buf, counts, displs, MPI_BYTE, 0, MPI_COMM_WORLD);
    free(counts);
    free(displs);
    *all = buf;
    *total = sum;
    return LU_OK;
}

/* ---- single images ---- */

enum { TAG_IMAGE_HEAD = 11, TAG_IMAGE_PIXELS = 12 };

static void wait_asleep(MPI_Request *req) {
    for (int done = 0;;) {
        MPI_Test(req, &done, MPI_STATUS_IGNORE);
        if (done) return;
        usleep(2000);
    }
}

lu_result lu_mpi_send_image(const lu_image *img, double value, lu_error *err) {
    size_t n = (size_t)img->width * img->height * 3;
    if (n > (size_t)0x7fffffff) return lu_fail(err, LU_ERR_LIMIT, "mpi: an image of %zu floats (at most 2^31 - 1)", n);
    double head[3] = {img->width, img->height, value};
    MPI_Request req;
    MPI_Isend(head, 3, MPI_DOUBLE, 0, TAG_IMAGE_HEAD, MPI_COMM_WORLD, &req);
    wait_asleep(&req);
    MPI_Isend(img->rgb, (int)n, MPI_FLOAT, 0, TAG_IMAGE_PIXELS, MPI_COMM_WORLD, &req);
    wait_asleep(&req);
    return LU_OK;
}

lu_result lu_mpi_recv_image(int from, lu_image *img, double *value, lu_error *err) {
    double head[3];
    MPI_Request req;
    MPI_Irecv(head, 3, MPI_DOUBLE, from, TAG_IMAGE_HEAD, MPI_COMM_WORLD, &req);
    wait_asleep(&req);
    int w = (int)head[0], h = (int)head[1];
    if (img->width != w || img->height != h) {
        lu_image_destroy(img);
        lu_result r = lu_image_create(img, w, h, err);
        if (r != LU_OK) return r;
    }
    MPI_Irecv(img->rgb, w * h * 3, MPI_FLOAT, from, TAG_IMAGE_PIXELS, MPI_COMM_WORLD, &req);
    wait_asleep(&req);
    *value = head[2];
    return LU_OK;
}

#else /* no MPI: a job of one */

int lu_mpi_begin(int *argc, char ***argv) {
    (void)argc;
    (void)argv;
    if (launched_as_rank())
        fprintf(stderr, "lucent: note: this lucent is built without MPI: every rank the launcher started does all "
                        "of the work alone\n");
    return LU_EXIT_OK;
}

int lu_mpi_end(int rc) { return rc; }

/* A job of one sends nothing: rank 0 renders every frame itself. */
lu_result lu_mpi_send_image(const lu_image *img, double value, lu_error *err) {
    (void)img;
    (void)value;
    return lu_fail(err, LU_ERR_INVALID_ARG, "mpi: no other rank to send an image to");
}

lu_result lu_mpi_recv_image(int from, lu_image *img, double *value, lu_error *err) {
    (void)img;
    (void)value;
    return lu_fail(err, LU_ERR_INVALID_ARG, "mpi: no rank %d to receive an image from", from);
}

static int64_t g_next, g_count;

lu_result lu_mpi_queue_open(int count, lu_error *err) {
    (void)err;
    g_next = 0;
    g_count = count;
    return LU_OK;
}

int lu_mpi_queue_next(void) { return g_next < g_count ? (int)g_next++ : -1; }
static int64_t queue_done(void) { return g_next; }
void lu_mpi_queue_close(void) { g_next = g_count = 0; }

lu_result lu_mpi_gather(const void *data, size_t bytes, void **all, size_t *total, lu_error *err) {
    return gather_alone(data, bytes, all, total, err);
}

#endif

/* ---- one frame divided among the ranks ---- */

typedef struct band_source {
    int bands, height, rows;   /* rows: per band */
    int *taken;            /* the bands this rank rendered, in order */
    int ntaken;
    double wait_s;         /* in the queue: asking for bands */
    lu_progress bar;       /* rank 0 */
} band_source;

static void job_bar_update(band_source *b) {
    if (lu_mpi_rank() != 0) return;
#ifdef LU_HAVE_MPI
    g_job_bar = true;
#endif
    lu_progress_update(&b->bar, queue_done());
#ifdef LU_HAVE_MPI
    g_job_bar = false;
#endif
}

static bool next_band(void *user, int *y0, int *y1) {
    band_source *b = user;
    double t0 = lu_time_seconds();
    int k = lu_mpi_queue_next();
    job_bar_update(b);
    b->wait_s += lu_time_seconds() - t0;
    if (k < 0) return false;
    b->taken[b->ntaken++] = k;
    *y0 = k * b->rows;
    *y1 = *y0 + b->rows < b->height ? *y0 + b->rows : b->height;
    return true;
}

/* What each rank sends rank 0: its counts and times, then its bands' ids
 * and pixels. */
typedef struct rank_report {
    int32_t bands, pad;
    double render_ms, rows_ms, wait_ms;
} rank_report;

/* Rows of band k of b. */
static int band_rows(const band_source *b, int k) {
    int y0 = k * b->rows;
    return y0 + b->rows < b->height ? b->rows : b->height - y0;
}

lu_result lu_mpi_render(lu_renderer *r, const lu_scene *scene, lu_image *out, int rows_per_band, const char *label,
                        lu_error *err) {
    if (lu_mpi_size() == 1) return lu_renderer_render(r, scene, out, err);
    const lu_camera *c = &scene->camera;
    if (out->width == 0) {
        lu_result e = lu_image_create(out, c->width, c->height, err);
        if (e != LU_OK) return e;
    }
    band_source b = {0};
    b.height = c->height;
    b.rows = rows_per_band > 0 ? rows_per_band : LU_MPI_BAND_ROWS;
    b.bands = (c->height + b.rows - 1) / b.rows;
    b.taken = malloc((size_t)b.bands * sizeof *b.taken);
    if (!b.taken) return lu_fail(err, LU_ERR_NOMEM, "mpi: out of memory");
    lu_result res = lu_mpi_queue_open(b.bands, err);
    if (res != LU_OK) {
        free(b.taken);
        return res;
    }
    lu_progress_begin(&b.bar, label ? label : "render", b.bands);
    res = lu_renderer_render_rows(r, scene, next_band, &b, out, err);
    /* A failed rank ends the job (lu_mpi_end); the others must not wait
     * for its bands here. */
    if (res != LU_OK) {
        free(b.taken);
        return res;
    }
    /* Every rank waits here, asleep, until the last band is in: in the
     * gather an MPI library polls, which would take a processor from the
     * ranks still rendering where ranks share a machine. Rank 0 keeps the
     * job's bar moving meanwhile. */
    while (queue_done() < b.bands) {
        job_bar_update(&b);
        usleep(lu_mpi_rank() == 0 ? 20000 : 50000);
    }
    lu_mpi_queue_close();
    if (lu_mpi_rank() == 0) {
#ifdef LU_HAVE_MPI
        g_job_bar = true;
#endif
        lu_progress_end(&b.bar);
#ifdef LU_HAVE_MPI
        g_job_bar = false;
#endif
    }

    /* Pack: report, band ids, then each band's rows. */
    size_t row_floats = (size_t)c->width * 3;
    size_t rows = 0;
    for (int i = 0; i < b.ntaken; i++) rows += (size_t)band_rows(&b, b.taken[i]);
    size_t bytes = sizeof(rank_report) + (size_t)b.ntaken * sizeof(int32_t) + rows * row_floats * sizeof(float);
    char *pack = malloc(bytes);
    if (!pack) {
        free(b.taken);
        return lu_fail(err, LU_ERR_NOMEM, "mpi: out of memory for %zu bytes of bands", bytes);
    }
    lu_renderer_stats st = lu_cli_stats(r);
    rank_report rep = {b.ntaken, 0, st.render_ms, st.rows_ms, 1e3 * b.wait_s};
    memcpy(pack, &rep, sizeof rep);
    char *p = pack + sizeof rep;
    for (int i = 0; i < b.ntaken; i++, p += sizeof(int32_t)) {
        int32_t id = b.taken[i];
        memcpy(p, &id, sizeof id);
    }
    for (int i = 0; i < b.ntaken; i++) {
        size_t len = (size_t)band_rows(&b, b.taken[i]) * row_floats * sizeof(float);
        memcpy(p, out->rgb + (size_t)b.taken[i] * b.rows * row_floats, len);
        p += len;
    }
    free(b.taken);
    void *all;
    size_t total;
    res = lu_mpi_gather(pack, bytes, &all, &total, err);
    free(pack);
    if (res != LU_OK || lu_mpi_rank() != 0) return res;

    /* Unpack every rank's bands in rank order (rank 0's are in place). */
    const char *q = all, *end = q + total;
    for (int rank = 0; rank < lu_mpi_size() && q + sizeof(rank_report) <= end; rank++) {
        rank_report rr;
        memcpy(&rr, q, sizeof rr);
        q += sizeof rr;
        const char *ids = q;
        q += (size_t)rr.bands * sizeof(int32_t);
        if (label)
            fprintf(stderr,
                    "lucent: rank %d of %d: %d of %d bands; render %.1f ms: global stages %.1f ms, bands %.1f ms, "
                    "queue %.1f ms\n",
                    rank, lu_mpi_size(), rr.bands, b.bands, rr.render_ms, rr.render_ms - rr.rows_ms - rr.wait_ms,
                    rr.rows_ms, rr.wait_ms);
        for (int i = 0; i < rr.bands; i++) {
            int32_t id;
            memcpy(&id, ids + (size_t)i * sizeof id, sizeof id);
            size_t len = (size_t)band_rows(&b, id) * row_floats * sizeof(float);
            if (rank != 0) memcpy(out->rgb + (size_t)id * b.rows * row_floats, q, len);
            q += len;
        }
    }
    free(all);
    return LU_OK;
}
