/* The library's one parallel loop. Chunks come from an atomic counter; the
 * calling thread works too and, when asked, drives the progress bar. */
#include <lucent/core.h>

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <unistd.h>

int lu_thread_count(void) {
    const char *env = getenv("LUCENT_THREADS");
    if (env && *env) {
        int n = atoi(env);
        if (n >= 1 && n <= 1024) return n;
    }
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : (n > 256 ? 256 : (int)n);
}

typedef struct job {
    int64_t n, grain;
    lu_range_fn fn;
    void *ctx;
    atomic_llong next;
    atomic_llong done;
} job;

typedef struct worker_arg {
    job *j;
    int index;
} worker_arg;

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

static void *worker_main(void *p) {
    worker_arg *a = p;
    run_chunks(a->j, a->index, NULL);
    return NULL;
}

void lu_parallel_for(int64_t n, int64_t grain, lu_range_fn fn, void *ctx, const char *progress_label) {
    if (n <= 0) return;
    int threads = lu_thread_count();
    if (grain <= 0) {
        grain = n / ((int64_t)threads * 16);
        if (grain < 1) grain = 1;
    }
    job j = {.n = n, .grain = grain, .fn = fn, .ctx = ctx};
    atomic_init(&j.next, 0);
    atomic_init(&j.done, 0);
    int64_t chunks = (n + grain - 1) / grain;
    int extra = threads - 1;
    if (extra > chunks - 1) extra = (int)(chunks - 1);
    pthread_t tids[256];
    worker_arg args[256];
    int started = 0;
    for (int i = 0; i < extra; i++) {
        args[i].j = &j;
        args[i].index = i + 1;
        if (pthread_create(&tids[i], NULL, worker_main, &args[i]) != 0) break;
        started++;
    }
    lu_progress prog;
    if (progress_label) lu_progress_begin(&prog, progress_label, n);
    run_chunks(&j, 0, progress_label ? &prog : NULL);
    for (int i = 0; i < started; i++) pthread_join(tids[i], NULL);
    if (progress_label) lu_progress_end(&prog);
}
