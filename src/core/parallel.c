/* The library's one parallel loop and the persistent worker pool behind it.
 *
 * Each lu_parallel_for call is a job on the stack of its caller. The caller
 * queues it, wakes as many sleeping workers as the job can use, runs chunks
 * itself as thread index 0 (so it alone drives the progress bar), and then
 * waits until every worker that joined has left. Chunks come from the job's
 * atomic counter, so which thread runs which chunk never changes a result.
 *
 * Several jobs may be queued at once, from nested calls or from several
 * application threads. A worker joins the oldest queued job that still has
 * unclaimed chunks and a free helper index. A caller only ever waits for
 * workers that are inside its own job running chunks, which finish without
 * anyone's help, so nesting and concurrent callers cannot deadlock. */
#include <lucent/core.h>

#include <ctype.h>
#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

#include "core/memory.h"

/* ---- thread count ----------------------------------------------------- */

static atomic_int g_thread_count; /* set by lu_set_thread_count; 0 = default */

lu_result lu_thread_count_parse(const char *text, const char *where, int *out, lu_error *err) {
    /* Digits only: strtol alone would take " 8", "+8" and "8abc". */
    bool digits = text && *text;
    for (const char *c = text; digits && *c; c++) digits = isdigit((unsigned char)*c);
    errno = 0;
    long n = digits ? strtol(text, NULL, 10) : 0;
    if (!digits || errno || n < 1 || n > LU_MAX_THREADS)
        return lu_fail(err, LU_ERR_RANGE, "%s: \"%s\" is not a thread count (an integer in [1, %d])", where,
                       text ? text : "", LU_MAX_THREADS);
    *out = (int)n;
    return LU_OK;
}

lu_result lu_set_thread_count(int n, lu_error *err) {
    if (n < 0 || n > LU_MAX_THREADS)
        return lu_fail(err, LU_ERR_RANGE, "thread count %d outside [0, %d] (0 = automatic)", n, LU_MAX_THREADS);
    atomic_store(&g_thread_count, n);
    return LU_OK;
}

static pthread_once_t g_cpus_once = PTHREAD_ONCE_INIT;
static int g_cpus;

/* Once: glibc answers _SC_NPROCESSORS_ONLN by reading a /sys file, which
 * would cost more than a small lu_parallel_for itself. */
static void count_cpus(void) {
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    g_cpus = n < 1 ? 1 : (n > LU_MAX_THREADS ? LU_MAX_THREADS : (int)n);
}

int lu_thread_count(void) {
    int n = atomic_load(&g_thread_count);
    if (n > 0) return n;
    pthread_once(&g_cpus_once, count_cpus);
    return g_cpus;
}

/* ---- the pool ----------------------------------------------------------- */

typedef struct job {
    int64_t n, grain;
    lu_range_fn fn;
    void *ctx;
    lu_mem_account *account; /* the caller's: its helpers' allocations are charged to it */
    atomic_llong next; /* first index of the next unclaimed chunk */
    atomic_llong done; /* indices finished, for the progress bar */
    /* Under pool.mu: */
    int free_slots; /* helpers that may still join */
    int next_index; /* thread index the next helper gets */
    int active;     /* helpers inside the job now */
    bool queued;
    struct job *older, *newer;
} job;

static struct {
    pthread_mutex_t mu;
    pthread_cond_t work;   /* idle workers sleep here */
    pthread_cond_t left;   /* callers wait here for their helpers to leave */
    job *oldest, *newest;  /* the queue of joinable jobs */
    int workers;           /* started, never stopped */
} pool = {.mu = PTHREAD_MUTEX_INITIALIZER, .work = PTHREAD_COND_INITIALIZER, .left = PTHREAD_COND_INITIALIZER};

static pthread_once_t g_attr_once = PTHREAD_ONCE_INIT;
static pthread_attr_t g_attr;
static bool g_attr_ok;

static void init_attr(void) {
    g_attr_ok = pthread_attr_init(&g_attr) == 0 &&
                pthread_attr_setdetachstate(&g_attr, PTHREAD_CREATE_DETACHED) == 0;
}

static void enqueue(job *j) {
    j->older = pool.newest;
    j->newer = NULL;
    if (pool.newest) pool.newest->newer = j;
    else pool.oldest = j;
    pool.newest = j;
    j->queued = true;
}

static void dequeue(job *j) {
    if (!j->queued) return;
    if (j->older) j->older->newer = j->newer;
    else pool.oldest = j->newer;
    if (j->newer) j->newer->older = j->older;
    else pool.newest = j->older;
    j->queued = false;
}

static void run_chunks(job *j, int thread_index, lu_progress *progress) {
    for (;;) {
        int64_t begin = atomic_fetch_add(&j->next, j->grain);
        if (begin >= j->n) break;
        int64_t end = begin + j->grain < j->n ? begin + j->grain : j->n;
        j->fn(j->ctx, begin, end, thread_index);
        int64_t d = atomic_fetch_add(&j->done, end - begin) + (end - begin);
        if (progress) lu_progress_update(progress, d);
    }
}

/* Under pool.mu: the oldest job a worker can help, dropping finished ones. */
static job *joinable_job(void) {
    job *j = pool.oldest;
    while (j && atomic_load(&j->next) >= j->n) {
        job *newer = j->newer;
        dequeue(j);
        j = newer;
    }
    return j;
}

static void *worker_main(void *unused) {
    (void)unused;
    pthread_mutex_lock(&pool.mu);
    for (;;) {
        job *j = joinable_job();
        if (!j) {
            pthread_cond_wait(&pool.work, &pool.mu);
            continue;
        }
        int index = j->next_index++;
        j->active++;
        if (--j->free_slots == 0) dequeue(j);
        pthread_mutex_unlock(&pool.mu);
        lu_mem_account_use(j->account);
        run_chunks(j, index, NULL);
        lu_mem_account_use(NULL);
        pthread_mutex_lock(&pool.mu);
        dequeue(j); /* its chunks are all claimed */
        if (--j->active == 0) pthread_cond_broadcast(&pool.left);
    }
    return NULL;
}

/* Under pool.mu. A worker that fails to start only costs parallelism: the
 * caller runs whatever no helper takes. */
static void grow_pool(int want) {
    pthread_once(&g_attr_once, init_attr);
    if (!g_attr_ok) return;
    while (pool.workers < want) {
        pthread_t tid;
        if (pthread_create(&tid, &g_attr, worker_main, NULL) != 0) return;
        pool.workers++;
    }
}

void lu_parallel_for(int64_t n, int64_t grain, lu_range_fn fn, void *ctx, const char *progress_label) {
    if (n <= 0) return;
    int threads = lu_thread_count();
    if (grain <= 0) {
        grain = n / ((int64_t)threads * 16);
        if (grain < 1) grain = 1;
    }
    if (grain > n) grain = n; /* keeps begin + grain from overflowing */
    job j = {.n = n, .grain = grain, .fn = fn, .ctx = ctx, .account = lu_mem_account_current(), .next_index = 1};
    atomic_init(&j.next, 0);
    atomic_init(&j.done, 0);
    int64_t chunks = (n - 1) / grain + 1;
    int helpers = chunks - 1 < threads - 1 ? (int)(chunks - 1) : threads - 1;
    if (helpers > 0) {
        pthread_mutex_lock(&pool.mu);
        grow_pool(helpers);
        j.free_slots = helpers;
        enqueue(&j);
        /* One signal per helper wanted, not a broadcast: a pool grown for a
         * wide job must not wake every worker for each narrow one. */
        for (int i = 0; i < helpers; i++) pthread_cond_signal(&pool.work);
        pthread_mutex_unlock(&pool.mu);
    }
    lu_progress prog;
    if (progress_label) lu_progress_begin(&prog, progress_label, n);
    run_chunks(&j, 0, progress_label ? &prog : NULL);
    if (helpers > 0) {
        pthread_mutex_lock(&pool.mu);
        dequeue(&j);
        while (j.active > 0) pthread_cond_wait(&pool.left, &pool.mu);
        pthread_mutex_unlock(&pool.mu);
    }
    if (progress_label) lu_progress_end(&prog);
}
