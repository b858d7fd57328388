/* The library's one choke point of memory: every block goes through the
 * host's allocator with a header naming its size and account (memory.h),
 * so figures are exact without asking the host's allocator for sizes. */
#include <lucent/core.h>

#include <stdatomic.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "core/memory.h"

struct lu_mem_account {
    atomic_llong bytes, peak, blocks, accel, gpu;
    atomic_long refs;   /* the owner's, plus one per block and holder charged to it */
};

/* max_align_t keeps the block after the header as aligned as malloc's. */
typedef union block_header {
    struct {
        size_t size;
        lu_mem_account *account;
    } h;
    max_align_t align;
} block_header;

static struct {
    void *(*alloc)(size_t size, void *user);
    void *(*realloc)(void *ptr, size_t size, void *user);
    void (*free)(void *ptr, void *user);
    void *user;
} g_hooks;

static lu_mem_account g_total;   /* the process: never freed, refs unused */
static _Thread_local lu_mem_account *t_account;

static void *raw_alloc(size_t n) { return g_hooks.alloc ? g_hooks.alloc(n, g_hooks.user) : malloc(n); }
static void raw_free(void *p) {
    if (g_hooks.free) g_hooks.free(p, g_hooks.user);
    else free(p);
}

static void raise_peak(lu_mem_account *a, long long now) {
    long long peak = atomic_load_explicit(&a->peak, memory_order_relaxed);
    while (now > peak && !atomic_compare_exchange_weak_explicit(&a->peak, &peak, now, memory_order_relaxed,
                                                                memory_order_relaxed)) {
    }
}

/* Heap bytes and blocks into one account. */
static void charge(lu_mem_account *a, long long bytes, long long blocks) {
    long long now = atomic_fetch_add_explicit(&a->bytes, bytes, memory_order_relaxed) + bytes;
    if (blocks) atomic_fetch_add_explicit(&a->blocks, blocks, memory_order_relaxed);
    if (bytes > 0) raise_peak(a, now);
}

/* ---- accounts ---------------------------------------------------------- */

/* An account is a block charged to itself, without the reference a block
 * holds (it would keep itself alive): the owner's figures include the
 * bookkeeping, and the host's allocator sees exactly lu_memory_get's blocks. */
lu_mem_account *lu_mem_account_create(void) {
    block_header *b = raw_alloc(sizeof *b + sizeof(lu_mem_account));
    if (!b) return NULL;
    lu_mem_account *a = (lu_mem_account *)(b + 1);
    memset(a, 0, sizeof *a);
    atomic_init(&a->refs, 1);
    b->h.size = sizeof *a;
    b->h.account = a;
    charge(&g_total, (long long)sizeof *a, 1);
    charge(a, (long long)sizeof *a, 1);
    return a;
}

void lu_mem_account_release(lu_mem_account *a) {
    if (!a || atomic_fetch_sub_explicit(&a->refs, 1, memory_order_acq_rel) != 1) return;
    charge(&g_total, -(long long)sizeof *a, -1);
    raw_free((block_header *)a - 1);
}

lu_mem_account *lu_mem_account_use(lu_mem_account *a) {
    lu_mem_account *prev = t_account;
    t_account = a;
    return prev;
}

lu_mem_account *lu_mem_account_current(void) { return t_account; }

lu_mem_account *lu_mem_account_hold(void) {
    lu_mem_account *a = t_account;
    if (a) atomic_fetch_add_explicit(&a->refs, 1, memory_order_relaxed);
    return a;
}

void lu_mem_add(lu_mem_account *a, lu_mem_kind kind, long long bytes) {
    lu_mem_account *to[2] = {&g_total, a};
    for (int i = 0; i < 2 && to[i]; i++)
        atomic_fetch_add_explicit(kind == LU_MEM_GPU ? &to[i]->gpu : &to[i]->accel, bytes, memory_order_relaxed);
}

lu_mem_account *lu_mem_charge(lu_mem_kind kind, size_t bytes) {
    lu_mem_account *a = lu_mem_account_hold();
    lu_mem_add(a, kind, (long long)bytes);
    return a;
}

void lu_mem_discharge(lu_mem_account *a, lu_mem_kind kind, size_t bytes) {
    lu_mem_add(a, kind, -(long long)bytes);
    lu_mem_account_release(a);
}

static size_t as_size(long long v) { return v > 0 ? (size_t)v : 0; }

void lu_mem_account_read(const lu_mem_account *a, lu_memory *out) {
    memset(out, 0, sizeof *out);
    if (!a) return;
    lu_mem_account *m = (lu_mem_account *)a;   /* atomic loads take non-const pointers */
    out->bytes = as_size(atomic_load(&m->bytes));
    out->peak_bytes = as_size(atomic_load(&m->peak));
    out->blocks = as_size(atomic_load(&m->blocks));
    out->accel_bytes = as_size(atomic_load(&m->accel));
    out->gpu_bytes = as_size(atomic_load(&m->gpu));
}

void lu_memory_get(lu_memory *out) { lu_mem_account_read(&g_total, out); }

static bool same_allocator(const lu_host *h) {
    return h->alloc == g_hooks.alloc && h->realloc == g_hooks.realloc && h->free == g_hooks.free &&
           (h->alloc == NULL || h->user == g_hooks.user);
}

lu_result lu_mem_allocator_check(const lu_host *h, lu_error *err) {
    int hooks = (h->alloc != NULL) + (h->realloc != NULL) + (h->free != NULL);
    if (hooks != 0 && hooks != 3)
        return lu_fail(err, LU_ERR_INVALID_ARG, "host: alloc, realloc and free are set together or not at all");
    long long live = atomic_load(&g_total.blocks);
    if (!same_allocator(h) && live > 0)
        return lu_fail(err, LU_ERR_INVALID_ARG,
                       "host: the allocator cannot change while %lld allocations of the previous one are alive", live);
    return LU_OK;
}

void lu_mem_set_allocator(const lu_host *h) {
    g_hooks.alloc = h->alloc;
    g_hooks.realloc = h->realloc;
    g_hooks.free = h->free;
    g_hooks.user = h->user;
}

/* ---- blocks -------------------------------------------------------------- */

static void *finish_block(block_header *b, size_t size) {
    if (!b) return NULL;
    lu_mem_account *a = t_account;
    b->h.size = size;
    b->h.account = a;
    charge(&g_total, (long long)size, 1);
    if (a) {
        atomic_fetch_add_explicit(&a->refs, 1, memory_order_relaxed);
        charge(a, (long long)size, 1);
    }
    return b + 1;
}

void *lu_malloc(size_t size) {
    if (size > SIZE_MAX - sizeof(block_header)) return NULL;
    return finish_block(raw_alloc(sizeof(block_header) + (size ? size : 1)), size);
}

void *lu_calloc(size_t count, size_t size) {
    if (size && count > SIZE_MAX / size) return NULL;
    size_t n = count * size;
    if (n > SIZE_MAX - sizeof(block_header)) return NULL;
    size_t total = sizeof(block_header) + (n ? n : 1);
    /* calloc where it is the allocator: large zeroed blocks come zeroed from the kernel */
    block_header *b = g_hooks.alloc ? g_hooks.alloc(total, g_hooks.user) : calloc(total, 1);
    if (b && g_hooks.alloc) memset(b, 0, total);
    return finish_block(b, n);
}

void *lu_realloc(void *ptr, size_t size) {
    if (!ptr) return lu_malloc(size);
    if (size > SIZE_MAX - sizeof(block_header)) return NULL;
    block_header *b = (block_header *)ptr - 1;
    size_t old = b->h.size;
    size_t total = sizeof(block_header) + (size ? size : 1);
    block_header *n = g_hooks.realloc ? g_hooks.realloc(b, total, g_hooks.user) : realloc(b, total);
    if (!n) return NULL;
    /* The block stays with the account it was first charged to. */
    n->h.size = size;
    long long d = (long long)size - (long long)old;
    charge(&g_total, d, 0);
    if (n->h.account) charge(n->h.account, d, 0);
    return n + 1;
}

void lu_free(void *ptr) {
    if (!ptr) return;
    block_header *b = (block_header *)ptr - 1;
    long long size = (long long)b->h.size;
    lu_mem_account *a = b->h.account;
    raw_free(b);
    charge(&g_total, -size, -1);
    if (a) {
        charge(a, -size, -1);
        lu_mem_account_release(a);
    }
}

char *lu_strdup(const char *s) {
    size_t n = strlen(s) + 1;
    char *p = lu_malloc(n);
    if (p) memcpy(p, s, n);
    return p;
}

long lu_resident_kb(void) {
    FILE *f = fopen("/proc/self/statm", "r");
    long pages = 0, res = 0;
    if (!f) return 0;
    if (fscanf(f, "%ld %ld", &pages, &res) != 2) res = 0;
    fclose(f);
    return res * (sysconf(_SC_PAGESIZE) / 1024);
}
