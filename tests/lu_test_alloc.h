/* The tests' host allocator (lu_host): it counts the library's
 * allocations, can refuse the N-th one, and links every live block with its
 * allocation number and size, so a leak is named and the live blocks and
 * bytes are known exactly in every build. Used by test_alloc_fail (the
 * refusal sweep) and test_soak (the bytes held per frame). */
#ifndef LU_TEST_ALLOC_H
#define LU_TEST_ALLOC_H

#include <lucent/lucent.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stddef.h>
#include <stdio.h>
#include <stdlib.h>

static atomic_long g_count;   /* allocations (and reallocations) since the counter was reset */
static atomic_long g_fail_at; /* 0: never fail */
static atomic_long g_failed;  /* how many were refused */
static atomic_long g_live;    /* blocks alive */
static atomic_llong g_bytes;  /* bytes alive */

/* Each block carries a header linking it into the list of live blocks, so
 * a leak can be named by its allocation number and size. max_align_t keeps
 * the block's alignment that of malloc. */
typedef union block {
    struct {
        union block *prev, *next;
        long index;
        size_t size;
    } h;
    max_align_t align;
} block;
static block g_head = {.h = {&g_head, &g_head, 0, 0}};
static pthread_mutex_t g_lock = PTHREAD_MUTEX_INITIALIZER;

static void link_block(block *b, long index, size_t size) {
    b->h.index = index, b->h.size = size;
    pthread_mutex_lock(&g_lock);
    b->h.next = g_head.h.next, b->h.prev = &g_head;
    g_head.h.next->h.prev = b, g_head.h.next = b;
    pthread_mutex_unlock(&g_lock);
    atomic_fetch_add(&g_live, 1);
    atomic_fetch_add(&g_bytes, (long long)size);
}

static void unlink_block(block *b) {
    pthread_mutex_lock(&g_lock);
    b->h.prev->h.next = b->h.next, b->h.next->h.prev = b->h.prev;
    pthread_mutex_unlock(&g_lock);
    atomic_fetch_sub(&g_live, 1);
    atomic_fetch_sub(&g_bytes, (long long)b->h.size);
}

/* A breakpoint for a debugger: `break refused` stops at each refusal. */
__attribute__((noinline)) static void refused(void) { __asm__ volatile(""); }

/* The allocation's number in the job, or 0 when it is to be refused. */
static long next_index(void) {
    long n = atomic_fetch_add(&g_count, 1) + 1;
    if (n != atomic_load(&g_fail_at)) return n;
    atomic_fetch_add(&g_failed, 1);
    refused();
    return 0;
}

static void *t_alloc(size_t size, void *user) {
    (void)user;
    long n = next_index();
    block *b = n ? malloc(sizeof(block) + size) : NULL;
    if (!b) return NULL;
    link_block(b, n, size);
    return b + 1;
}

static void *t_realloc(void *ptr, size_t size, void *user) {
    if (!ptr) return t_alloc(size, user);
    long n = next_index();
    if (!n) return NULL;
    block *b = (block *)ptr - 1;
    unlink_block(b);
    block *nb = realloc(b, sizeof(block) + size);
    if (!nb) {
        link_block(b, b->h.index, b->h.size);
        return NULL;
    }
    link_block(nb, n, size);
    return nb + 1;
}

static void t_free(void *ptr, void *user) {
    (void)user;
    if (!ptr) return;
    block *b = (block *)ptr - 1;
    unlink_block(b);
    free(b);
}

/* Prints the blocks allocated since the job began (those numbered by it)
 * that are still alive: the leak's allocation numbers and sizes. */
static inline void print_leaks(const char *what, long live0) {
    long shown = 0;
    pthread_mutex_lock(&g_lock);
    for (block *b = g_head.h.next; b != &g_head && shown < 8; b = b->h.next, shown++)
        if (shown < atomic_load(&g_live) - live0)
            fprintf(stderr, "    %s: alive: allocation %ld of the job, %zu bytes\n", what, b->h.index, b->h.size);
    pthread_mutex_unlock(&g_lock);
}

static const lu_host k_test_alloc_host = {.alloc = t_alloc, .realloc = t_realloc, .free = t_free};

#endif
