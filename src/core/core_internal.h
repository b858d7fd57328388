/* Internal: what the core's files share with each other. */
#ifndef LU_CORE_INTERNAL_H
#define LU_CORE_INTERNAL_H

/* The cache folder set (lu_set_cache_dir), or NULL. */
const char *lu_cache_dir_copy(void);

#endif
