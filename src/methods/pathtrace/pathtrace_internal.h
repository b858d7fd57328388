/* Internal pieces of the path tracer that tests reach directly: the coarse
 * majorant grid (per-block maximum density) the tracking kernels walk. */
#ifndef LU_PATHTRACE_INTERNAL_H
#define LU_PATHTRACE_INTERNAL_H

#include <lucent/lucent.h>

#include "methods/common/majorant.h"

/* The shared majorant grid (methods/common/majorant.h) under its tracking names. */
typedef lu_majorant lu_pt_majorant;

static inline lu_result lu_pt_majorant_build(const lu_grid *g, int block, lu_pt_majorant *out, lu_error *err) {
    return lu_majorant_build(g, block, out, err);
}
static inline void lu_pt_majorant_destroy(lu_pt_majorant *m) { lu_majorant_destroy(m); }
static inline float lu_pt_majorant_at(const lu_pt_majorant *m, int bx, int by, int bz) {
    return lu_majorant_at(m, bx, by, bz);
}

#endif
