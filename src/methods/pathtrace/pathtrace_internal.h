/* Internal pieces of the path tracer that tests reach directly: the coarse
 * majorant grid (per-block maximum density) the tracking kernels walk, and
 * the Dwivedi sampling of the guided walk. */
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

/* Dwivedi guided sampling (pathtrace_guide.c): v0 for a single-scattering
 * albedo; log_ratio = ln((v0 + 1) / (v0 - 1)); the cosine to the outward
 * normal sampled from u in [0, 1); its density per steradian. */
double lu_pt_dwivedi_v0(double albedo);
float lu_pt_dwivedi_log(float v0);
float lu_pt_dwivedi_sample(float v0, float log_ratio, float u);
float lu_pt_dwivedi_pdf(float v0, float log_ratio, float mu0);

#endif
