/* lu_parallel_for and its pool: thread-count validation, each index exactly
 * once, thread indices in range and never shared by two threads of one call,
 * nested calls, and concurrent callers checked against closed-form sums. */
#include "lu_test.h"

#include <errno.h>
#include <pthread.h>
#include <stdatomic.h>
#include <time.h>
#include <unistd.h>

static int cpu_default(void) {
    long n = sysconf(_SC_NPROCESSORS_ONLN);
    return n < 1 ? 1 : (n > LU_MAX_THREADS ? LU_MAX_THREADS : (int)n);
}

static void test_thread_count_parse(void) {
    static const struct {
        const char *text;
        int value; /* 0: must be rejected */
    } cases[] = {{"1", 1},   {"2", 2},     {"256", 256}, {"007", 7}, {"0", 0},      {"257", 0},
                 {"1000", 0}, {"-1", 0},    {"+4", 0},    {" 4", 0},  {"4 ", 0},     {"4x", 0},
                 {"abc", 0},  {"", 0},      {"0x10", 0},  {"1e2", 0}, {"99999999999999999999", 0}};
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        lu_error err = {0};
        int n = -1;
        lu_result r = lu_thread_count_parse(cases[i].text, "LUCENT_THREADS", &n, &err);
        if (cases[i].value) {
            CHECK_MSG(r == LU_OK && n == cases[i].value, "\"%s\" -> %s %d", cases[i].text, lu_result_name(r), n);
        } else {
            CHECK_MSG(r == LU_ERR_RANGE && n == -1, "\"%s\" -> %s %d", cases[i].text, lu_result_name(r), n);
            CHECK_MSG(strstr(err.message, "LUCENT_THREADS") && strstr(err.message, cases[i].text), "%s",
                      err.message);
        }
    }
    lu_error err = {0};
    int n = -1;
    CHECK(lu_thread_count_parse(NULL, "x", &n, &err) == LU_ERR_RANGE && n == -1);
}

static void square_range(void *p, int64_t b, int64_t e, int thread) {
    int64_t *out = p;
    for (int64_t i = b; i < e; i++) out[i] += i * i;
}

static void test_set_thread_count(void) {
    lu_error err = {0};
    unsetenv("LUCENT_THREADS");
    CHECK(lu_thread_count() == cpu_default());
    CHECK_OK(lu_set_thread_count(3, &err), &err);
    CHECK(lu_thread_count() == 3);
    CHECK(lu_set_thread_count(1000, &err) == LU_ERR_RANGE);
    CHECK_MSG(strstr(err.message, "1000") != NULL, "%s", err.message);
    CHECK(lu_set_thread_count(LU_MAX_THREADS + 1, &err) == LU_ERR_RANGE);
    CHECK(lu_set_thread_count(-1, &err) == LU_ERR_RANGE);
    CHECK(lu_thread_count() == 3); /* rejected values changed nothing */
    /* The library reads no environment variable (the CLI passes
     * LUCENT_THREADS in, tests/cli/threads.sh). */
    setenv("LUCENT_THREADS", "5", 1);
    CHECK_OK(lu_set_thread_count(0, &err), &err);
    CHECK(lu_thread_count() == cpu_default());
    /* The most threads there can be: 256 once overflowed a 256-entry thread table. */
    CHECK_OK(lu_set_thread_count(LU_MAX_THREADS, &err), &err);
    enum { N = 20000 };
    int64_t *out = calloc(N, sizeof *out);
    lu_parallel_for(N, 1, square_range, out, NULL);
    int64_t wrong = 0;
    for (int64_t i = 0; i < N; i++) wrong += out[i] != i * i;
    CHECK(wrong == 0);
    free(out);
    unsetenv("LUCENT_THREADS");
    CHECK_OK(lu_set_thread_count(0, &err), &err);
}

/* ---- each index once, indices in range and unshared ---------------------- */

typedef struct visit_ctx {
    atomic_int *visits;
    atomic_int busy[LU_MAX_THREADS]; /* threads inside a chunk, per index */
    atomic_int bad_index, shared_index, calls, wrong_caller;
    int threads;
    pthread_t caller;
} visit_ctx;

static void visit_init(visit_ctx *c, atomic_int *visits, int64_t n, int threads) {
    c->visits = visits;
    for (int64_t i = 0; i < n; i++) atomic_init(&visits[i], 0);
    for (int i = 0; i < LU_MAX_THREADS; i++) atomic_init(&c->busy[i], 0);
    atomic_init(&c->bad_index, 0);
    atomic_init(&c->shared_index, 0);
    atomic_init(&c->calls, 0);
    atomic_init(&c->wrong_caller, 0);
    c->threads = threads;
    c->caller = pthread_self();
}

static void visit_range(void *p, int64_t b, int64_t e, int thread) {
    visit_ctx *c = p;
    atomic_fetch_add(&c->calls, 1);
    if (thread < 0 || thread >= c->threads) {
        atomic_fetch_add(&c->bad_index, 1);
        return;
    }
    if ((thread == 0) != (pthread_equal(pthread_self(), c->caller) != 0)) atomic_fetch_add(&c->wrong_caller, 1);
    if (atomic_fetch_add(&c->busy[thread], 1) != 0) atomic_fetch_add(&c->shared_index, 1);
    for (int64_t i = b; i < e; i++) atomic_fetch_add(&c->visits[i], 1);
    atomic_fetch_sub(&c->busy[thread], 1);
}

/* Checks a finished visit_ctx; returns the number of indices not visited once. */
static int64_t visit_errors(visit_ctx *c, int64_t n) {
    int64_t wrong = 0;
    for (int64_t i = 0; i < n; i++) wrong += atomic_load(&c->visits[i]) != 1;
    return wrong;
}

static void test_each_index_once(void) {
    lu_error err = {0};
    enum { N = 100003 };
    atomic_int *visits = malloc(N * sizeof *visits);
    visit_ctx *c = malloc(sizeof *c);
    const int threads[] = {1, 2, 3, 8, LU_MAX_THREADS};
    const int64_t ns[] = {1, 2, 97, N};
    const int64_t grains[] = {0, 1, 7, 1000, N, (int64_t)1 << 62};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        CHECK_OK(lu_set_thread_count(threads[t], &err), &err);
        for (size_t k = 0; k < sizeof ns / sizeof ns[0]; k++)
            for (size_t g = 0; g < sizeof grains / sizeof grains[0]; g++) {
                int64_t n = ns[k], grain = grains[g];
                visit_init(c, visits, n, threads[t]);
                lu_parallel_for(n, grain, visit_range, c, NULL);
                int64_t wrong = visit_errors(c, n);
                /* A grain of 0 picks its own chunk size, so only a lower bound. */
                int64_t chunks = grain > 0 ? (grain >= n ? 1 : (n + grain - 1) / grain) : 1;
                int calls = atomic_load(&c->calls);
                CHECK_MSG(wrong == 0 && atomic_load(&c->bad_index) == 0 && atomic_load(&c->shared_index) == 0 &&
                              atomic_load(&c->wrong_caller) == 0 && (grain > 0 ? calls == chunks : calls >= 1),
                          "threads %d n %lld grain %lld: %lld indices not visited once, %d bad, %d shared "
                          "indices, %d chunks on the wrong thread, %d calls (expected %lld)",
                          threads[t], (long long)n, (long long)grain, (long long)wrong, atomic_load(&c->bad_index),
                          atomic_load(&c->shared_index), atomic_load(&c->wrong_caller), calls, (long long)chunks);
            }
    }
    int before = atomic_load(&c->calls);
    lu_parallel_for(0, 1, visit_range, c, NULL); /* nothing to do: no call */
    lu_parallel_for(-5, 1, visit_range, c, NULL);
    CHECK(atomic_load(&c->calls) == before);
    CHECK_OK(lu_set_thread_count(0, &err), &err);
    free(c);
    free(visits);
}

/* ---- the pool really runs threads side by side ---------------------------- */

/* Every chunk waits (bounded) until `want` chunks are inside at once, which
 * only happens if the pool lends want - 1 helpers to the call. Optionally each
 * then runs a nested call while every worker is busy. */
typedef struct gather_ctx {
    pthread_mutex_t mu;
    pthread_cond_t cv;
    int inside, want;
    bool timed_out;
    int seen_index[LU_MAX_THREADS];
    bool nest;
    atomic_int nested_wrong;
} gather_ctx;

static void gather_range(void *p, int64_t b, int64_t e, int thread) {
    gather_ctx *g = p;
    struct timespec until;
    clock_gettime(CLOCK_REALTIME, &until);
    until.tv_sec += 30;
    pthread_mutex_lock(&g->mu);
    if (thread >= 0 && thread < LU_MAX_THREADS) g->seen_index[thread]++;
    g->inside++;
    pthread_cond_broadcast(&g->cv);
    while (g->inside < g->want && !g->timed_out)
        if (pthread_cond_timedwait(&g->cv, &g->mu, &until) == ETIMEDOUT) g->timed_out = true;
    pthread_mutex_unlock(&g->mu);
    if (g->nest) {
        enum { M = 5000 };
        atomic_int *visits = malloc(M * sizeof *visits);
        visit_ctx *c = malloc(sizeof *c);
        visit_init(c, visits, M, lu_thread_count());
        lu_parallel_for(M, 3, visit_range, c, NULL);
        if (visit_errors(c, M) || atomic_load(&c->bad_index) || atomic_load(&c->shared_index) ||
            atomic_load(&c->wrong_caller))
            atomic_fetch_add(&g->nested_wrong, 1);
        free(c);
        free(visits);
    }
}

static void gather(int threads, bool nest) {
    lu_error err = {0};
    CHECK_OK(lu_set_thread_count(threads, &err), &err);
    gather_ctx g = {.want = threads, .nest = nest};
    pthread_mutex_init(&g.mu, NULL);
    pthread_cond_init(&g.cv, NULL);
    atomic_init(&g.nested_wrong, 0);
    lu_parallel_for(threads, 1, gather_range, &g, NULL);
    int distinct = 0;
    for (int i = 0; i < threads; i++) distinct += g.seen_index[i] == 1;
    CHECK_MSG(!g.timed_out && g.inside == threads && distinct == threads,
              "%d threads: %d chunks met (timed out: %d), %d indices used once", threads, g.inside, g.timed_out,
              distinct);
    CHECK_MSG(atomic_load(&g.nested_wrong) == 0, "%d nested calls went wrong", atomic_load(&g.nested_wrong));
    pthread_cond_destroy(&g.cv);
    pthread_mutex_destroy(&g.mu);
    CHECK_OK(lu_set_thread_count(0, &err), &err);
}

/* Must run before anything grows the pool past 3 workers: only then are all
 * of them held inside the outer call when the nested calls start. */
static void test_nested_in_full_pool(void) {
    gather(2, true);
    gather(4, true);
}

static void test_threads_side_by_side(void) {
    gather(2, false);
    gather(3, false);
    gather(16, false);
}

/* ---- nested calls -------------------------------------------------------- */

enum { OUTER = 12, MID = 6, INNER = 700 };

typedef struct nest_ctx {
    atomic_int *visits; /* OUTER * MID * INNER */
    atomic_int bad;
} nest_ctx;

typedef struct nest_level {
    nest_ctx *root;
    int64_t base;  /* first cell of this call's block */
    int64_t width; /* cells per index below this level */
    int depth;
    atomic_int busy[LU_MAX_THREADS];
} nest_level;

static void nest_range(void *p, int64_t b, int64_t e, int thread) {
    nest_level *l = p;
    if (thread < 0 || thread >= lu_thread_count() || atomic_fetch_add(&l->busy[thread], 1) != 0)
        atomic_fetch_add(&l->root->bad, 1);
    for (int64_t i = b; i < e; i++) {
        if (l->depth == 2) {
            atomic_fetch_add(&l->root->visits[l->base + i], 1);
            continue;
        }
        nest_level *child = malloc(sizeof *child);
        child->root = l->root;
        child->base = l->base + i * l->width;
        child->depth = l->depth + 1;
        child->width = child->depth == 1 ? INNER : 1;
        for (int t = 0; t < LU_MAX_THREADS; t++) atomic_init(&child->busy[t], 0);
        lu_parallel_for(child->depth == 1 ? MID : INNER, child->depth == 1 ? 1 : 13, nest_range, child, NULL);
        free(child);
    }
    if (thread >= 0 && thread < lu_thread_count()) atomic_fetch_sub(&l->busy[thread], 1);
}

static void test_nested(void) {
    lu_error err = {0};
    enum { CELLS = OUTER * MID * INNER };
    atomic_int *visits = malloc(CELLS * sizeof *visits);
    nest_level *top = malloc(sizeof *top);
    const int threads[] = {1, 2, 3, 7};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        CHECK_OK(lu_set_thread_count(threads[t], &err), &err);
        for (int rep = 0; rep < 5; rep++) {
            nest_ctx root = {.visits = visits};
            atomic_init(&root.bad, 0);
            for (int i = 0; i < CELLS; i++) atomic_init(&visits[i], 0);
            *top = (nest_level){.root = &root, .base = 0, .width = MID * INNER, .depth = 0};
            for (int i = 0; i < LU_MAX_THREADS; i++) atomic_init(&top->busy[i], 0);
            lu_parallel_for(OUTER, 1, nest_range, top, NULL);
            int wrong = 0;
            for (int i = 0; i < CELLS; i++) wrong += atomic_load(&visits[i]) != 1;
            CHECK_MSG(wrong == 0 && atomic_load(&root.bad) == 0,
                      "threads %d: %d cells not visited once, %d bad thread indices", threads[t], wrong,
                      atomic_load(&root.bad));
        }
    }
    CHECK_OK(lu_set_thread_count(0, &err), &err);
    free(top);
    free(visits);
}

/* ---- concurrent callers ---------------------------------------------------- */

enum { SERIES_N = 1 << 20, SERIES_REPS = 150 };

typedef struct series_job {
    int power; /* sum of i^power over [0, SERIES_N) */
    atomic_ullong sum;
    atomic_int busy[LU_MAX_THREADS];
    atomic_int bad;
    int threads;
} series_job;

static void series_range(void *p, int64_t b, int64_t e, int thread) {
    series_job *j = p;
    if (thread < 0 || thread >= j->threads || atomic_fetch_add(&j->busy[thread], 1) != 0)
        atomic_fetch_add(&j->bad, 1);
    uint64_t s = 0;
    for (int64_t i = b; i < e; i++) s += j->power == 1 ? (uint64_t)i : (uint64_t)i * (uint64_t)i;
    atomic_fetch_add(&j->sum, s);
    if (thread >= 0 && thread < j->threads) atomic_fetch_sub(&j->busy[thread], 1);
}

typedef struct series_caller {
    int power;
    int wrong_sums, bad_indices;
} series_caller;

static void *series_main(void *p) {
    series_caller *c = p;
    const uint64_t n = SERIES_N;
    uint64_t expect = c->power == 1 ? n * (n - 1) / 2 : (n - 1) * n * (2 * n - 1) / 6;
    series_job *j = malloc(sizeof *j);
    for (int rep = 0; rep < SERIES_REPS; rep++) {
        j->power = c->power;
        j->threads = lu_thread_count();
        atomic_init(&j->sum, 0);
        atomic_init(&j->bad, 0);
        for (int i = 0; i < LU_MAX_THREADS; i++) atomic_init(&j->busy[i], 0);
        /* Uneven grains so the two callers' chunks interleave differently. */
        lu_parallel_for(SERIES_N, c->power == 1 ? 4099 : 1021, series_range, j, NULL);
        c->wrong_sums += atomic_load(&j->sum) != expect;
        c->bad_indices += atomic_load(&j->bad);
    }
    free(j);
    return NULL;
}

static void test_concurrent_callers(void) {
    lu_error err = {0};
    const int threads[] = {1, 3};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        CHECK_OK(lu_set_thread_count(threads[t], &err), &err);
        series_caller callers[2] = {{.power = 1}, {.power = 2}};
        pthread_t tid[2];
        for (int i = 0; i < 2; i++) CHECK(pthread_create(&tid[i], NULL, series_main, &callers[i]) == 0);
        for (int i = 0; i < 2; i++) pthread_join(tid[i], NULL);
        for (int i = 0; i < 2; i++)
            CHECK_MSG(callers[i].wrong_sums == 0 && callers[i].bad_indices == 0,
                      "threads %d, sum of i^%d: %d of %d sums wrong, %d bad thread indices", threads[t],
                      callers[i].power, callers[i].wrong_sums, SERIES_REPS, callers[i].bad_indices);
    }
    CHECK_OK(lu_set_thread_count(0, &err), &err);
}

int main(void) {
    RUN_TEST(test_nested_in_full_pool); /* first: see there */
    RUN_TEST(test_thread_count_parse);
    RUN_TEST(test_set_thread_count);
    RUN_TEST(test_each_index_once);
    RUN_TEST(test_threads_side_by_side);
    RUN_TEST(test_nested);
    RUN_TEST(test_concurrent_callers);
    TEST_EXIT();
}
