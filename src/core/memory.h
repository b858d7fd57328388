/* Internal: memory accounts, behind lu_memory_get and lu_renderer_stats.memory.
 *
 * An account is charged with what is allocated while it is in use on a
 * thread: the library's heap blocks (every block's header names the account
 * it was charged to, so the free credits the same one on whatever thread it
 * runs), Embree's memory (lu_accel) and GPU buffers and textures (the GPU
 * objects). A renderer uses its account for the length of each of its
 * calls, and lu_parallel_for carries the caller's account into its workers.
 *
 * An account lives as long as anything charged to it: its owner's reference
 * and one per live block or holder, so a block that outlives its renderer
 * (a product handed on, a cache entry) never credits freed memory. */
#ifndef LU_CORE_MEMORY_H
#define LU_CORE_MEMORY_H

#include <lucent/core.h>

typedef struct lu_mem_account lu_mem_account;

typedef enum lu_mem_kind { LU_MEM_ACCEL, LU_MEM_GPU } lu_mem_kind;

/* A new account with its owner's reference; NULL when out of memory. */
lu_mem_account *lu_mem_account_create(void);
/* Drops one reference: the owner's, or a holder's from lu_mem_account_hold. */
void lu_mem_account_release(lu_mem_account *a);
/* Makes a (NULL: none) this thread's account and returns the one before. */
lu_mem_account *lu_mem_account_use(lu_mem_account *a);
lu_mem_account *lu_mem_account_current(void);
/* This thread's account with a reference for the caller (NULL: none): for
 * an object that charges memory other than heap blocks for its lifetime. */
lu_mem_account *lu_mem_account_hold(void);
/* Adds bytes (negative: frees them) of a kind to a and to the process's
 * totals; a NULL a charges only the totals. Any thread. */
void lu_mem_add(lu_mem_account *a, lu_mem_kind kind, long long bytes);
/* An object's storage of a kind for its lifetime: charged to this thread's
 * account (held) and the process's totals; returns the account, for
 * lu_mem_discharge with the same kind and bytes when the object goes. */
lu_mem_account *lu_mem_charge(lu_mem_kind kind, size_t bytes);
void lu_mem_discharge(lu_mem_account *a, lu_mem_kind kind, size_t bytes);
/* What a holds now; zero for NULL. */
void lu_mem_account_read(const lu_mem_account *a, lu_memory *out);

/* Whether lu_host_set may install h's allocator: all three hooks or none,
 * and no block of the previous one alive unless it is the same. */
lu_result lu_mem_allocator_check(const lu_host *h, lu_error *err);
void lu_mem_set_allocator(const lu_host *h);

#endif
