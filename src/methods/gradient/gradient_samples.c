/* The gradient family's samples on the CPU side (Ren et al. 2008 Sec. 4-5):
 * initial samples (Gaussian centres with a coverage fill, or jittered
 * stratified), their evaluation on the backend, recursive splitting by the
 * local shading error (Eq. 5), the final set and its cell lists. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "methods/common/lu_sampling.h"
#include "methods/gradient/gradient_cpu.h"

/* ---- samples ---- */

static lu_result grow(lu_gr_state *st, int need, lu_error *err) {
    if (need <= st->cap) return LU_OK;
    int cap = st->cap ? st->cap : 1024;
    while (cap < need) cap *= 2;
    float *s = lu_realloc(st->smp, (size_t)cap * LU_K_GR_SAMPLE_FLOATS * sizeof(float));
    if (s) st->smp = s;
    float *t = lu_realloc(st->tau, (size_t)cap * sizeof(float));
    if (t) st->tau = t;
    float *e = lu_realloc(st->E, (size_t)cap * sizeof(float));
    if (e) st->E = e;
    unsigned char *a = lu_realloc(st->active, (size_t)cap);
    if (a) st->active = a;
    float *v = lu_realloc(st->Ev, (size_t)cap * sizeof(float));
    if (v) st->Ev = v;
    if (!s || !t || !e || !a || !v) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for %d samples", need);
    st->cap = cap;
    return LU_OK;
}

static lu_result add_sample(lu_gr_state *st, lu_vec3 x, float R, float wgt, float rr, float tau, lu_error *err) {
    lu_result r = grow(st, st->n + 1, err);
    if (r != LU_OK) return r;
    float *s = st->smp + (size_t)st->n * LU_K_GR_SAMPLE_FLOATS;
    memset(s, 0, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
    s[0] = x.x, s[1] = x.y, s[2] = x.z, s[3] = R, s[4] = wgt, s[5] = rr;
    st->tau[st->n] = tau;
    st->E[st->n] = 0.0f;
    st->active[st->n] = 1;
    st->n++;
    return LU_OK;
}

static uint32_t hash3(uint32_t a, uint32_t b, uint32_t c) {
    return lu_k_hash_u32(a * 73856093u ^ b * 19349663u ^ c * 83492791u);
}

/* Coverage fill (an extension): the paper assumes the Gaussians' valid
 * spheres cover every point with density; a greedy fit with small radii
 * leaves gaps, which would render black. Vertices of the 16^3 grid G1 with
 * density within half an interval and outside every root sphere become
 * samples of valid radius one interval (every point of a covered G1 cell is
 * within sqrt(3)/2 interval of a vertex). */
static lu_result coverage_fill(lu_gr_state *st, lu_error *err) {
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float h = lu_v3_maxc(ext) / 16.0f;
    int n[3] = {(int)floorf(ext.x / h) + 1, (int)floorf(ext.y / h) + 1, (int)floorf(ext.z / h) + 1};
    int roots = st->n;
    for (int k = 0; k < n[2]; k++)
        for (int j = 0; j < n[1]; j++)
            for (int i = 0; i < n[0]; i++) {
                lu_vec3 q = lu_v3_add(st->box.lo, lu_v3((float)i * h, (float)j * h, (float)k * h));
                bool dense = false;
                for (int c = 0; c < 27 && !dense; c++) {
                    lu_vec3 o = lu_v3((float)(c % 3 - 1), (float)(c / 3 % 3 - 1), (float)(c / 9 - 1));
                    dense = lu_k_gr_total_density(&st->kctx, lu_v3_madd(q, o, 0.5f * h)) > 0.0f;
                }
                if (!dense) continue;
                bool covered = false;
                for (int s = 0; s < roots && !covered; s++) {
                    const float *p = st->smp + (size_t)s * LU_K_GR_SAMPLE_FLOATS;
                    lu_vec3 d = lu_v3_sub(q, lu_v3(p[0], p[1], p[2]));
                    float R = p[3] - 0.87f * h;
                    covered = R > 0.0f && lu_v3_dot(d, d) < R * R;
                }
                if (covered) continue;
                lu_result r = add_sample(st, q, h, 1.0f, h / 3.0f, -1.0f, err);
                if (r != LU_OK) return r;
            }
    st->stats.fill_samples = st->n - roots;
    return LU_OK;
}

static lu_result root_samples(lu_gr_state *st, const lu_scene *scene, lu_error *err) {
    int seeds = (int)st->p[P_SEEDS];
    bool any_grid = false;
    for (int m = 0; m < scene->medium_count; m++) any_grid = any_grid || scene->media[m].kind == LU_DENSITY_GRID;
    bool stratified = seeds == 2 || (seeds == 0 && !any_grid);
    if (!stratified) {
        for (int m = 0; m < scene->medium_count; m++) {
            const lu_medium *med = &scene->media[m];
            float vs = lu_gr_index_scale(&med->index_to_world);
            for (int j = 0; j < st->fits[m].count; j++) {
                const lu_gauss *q = &st->fits[m].g[j];
                float rw = q->r * vs;
                lu_result r = add_sample(st, lu_affine_point(&med->index_to_world, q->c), 3.0f * rw, q->w, rw, -1.0f, err);
                if (r != LU_OK) return r;
            }
        }
        return coverage_fill(st, err);
    }
    /* Jittered stratified: cubic cells of volume V / count over the media box. */
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float h = cbrtf(ext.x * ext.y * ext.z / (float)st->p[P_GAUSSIANS]);
    int n[3] = {(int)ceilf(ext.x / h), (int)ceilf(ext.y / h), (int)ceilf(ext.z / h)};
    for (int z = 0; z < n[2]; z++)
        for (int y = 0; y < n[1]; y++)
            for (int x = 0; x < n[0]; x++) {
                uint32_t hsh = hash3((uint32_t)x, (uint32_t)y, (uint32_t)z);
                float jx = ((float)(hsh & 1023u) / 1023.0f - 0.5f) * 0.5f;
                float jy = ((float)((hsh >> 10) & 1023u) / 1023.0f - 0.5f) * 0.5f;
                float jz = ((float)((hsh >> 20) & 1023u) / 1023.0f - 0.5f) * 0.5f;
                lu_vec3 c = lu_v3(fminf(st->box.lo.x + ((float)x + 0.5f + jx) * h, st->box.hi.x),
                                  fminf(st->box.lo.y + ((float)y + 0.5f + jy) * h, st->box.hi.y),
                                  fminf(st->box.lo.z + ((float)z + 0.5f + jz) * h, st->box.hi.z));
                /* Jitter of a quarter cell: every point is within 1.2 h of a sample. */
                lu_result r = add_sample(st, c, 1.5f * h, 1.0f, 0.5f * h, -1.0f, err);
                if (r != LU_OK) return r;
            }
    return LU_OK;
}

typedef struct eval_job {
    lu_gr_state *st;
    float *rec, *ev;
    int want_error;
} eval_job;

static void eval_range(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    eval_job *job = ctx;
    lu_gr_state *st = job->st;
    for (int64_t i = begin; i < end; i++) {
        float *s = job->rec + (size_t)i * LU_K_GR_SAMPLE_FLOATS;
        lu_vec3 F, gx, gy, gz;
        float E, tau;
        lu_k_gr_eval(&st->kctx, st->kctx.G, lu_v3(s[0], s[1], s[2]), s[3], 1.0f, job->want_error, &F, &gx, &gy, &gz, &E,
                     &tau);
        memcpy(s + 8, &F, 12);
        memcpy(s + 12, &gx, 12);
        memcpy(s + 16, &gy, 12);
        memcpy(s + 20, &gz, 12);
        job->ev[i] = E;
    }
}

/* Evaluates count sample records in place (value, gradient) on the backend
 * and writes their view-free error (E_j of Eq. 5 without tau_v) to ev. */
static lu_result eval_records(lu_gr_state *st, const lu_scene *scene, float *rec, int count, int want_error, float *ev,
                              lu_error *err) {
    if (count <= 0) return LU_OK;
    st->stats.evaluated += count;
    if (st->backend == LU_BACKEND_GPU) {
        st->frame.samples = rec;
        st->frame.sample_count = count;
        float *et = lu_malloc((size_t)count * 3 * sizeof(float));
        if (!et) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory");
        float *ones = et + 2 * (size_t)count;
        for (int i = 0; i < count; i++) ones[i] = 1.0f;
        lu_result r = lu_gradient_gpu_eval(st->gpu, scene, &st->frame, 0, count, want_error, ones, et, err);
        for (int i = 0; r == LU_OK && i < count; i++) ev[i] = et[2 * i];
        lu_free(et);
        return r;
    }
    eval_job job = {st, rec, ev, want_error};
    lu_parallel_for(count, 16, eval_range, &job, NULL);
    return LU_OK;
}

static void tau_range(void *ctx, int64_t begin, int64_t end, int thread) {
    (void)thread;
    lu_gr_state *st = ctx;
    for (int64_t j = begin; j < end; j++) {
        const float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        st->tau[j] = lu_k_gr_view_tau(&st->kctx, st->kctx.G, lu_v3(s[0], s[1], s[2]));
    }
}

/* tau_v of the roots smp[0 .. count): the camera-dependent part of E_j. */
static lu_result view_tau(lu_gr_state *st, const lu_scene *scene, int count, lu_error *err) {
    if (count <= 0) return LU_OK;
    if (st->backend == LU_BACKEND_GPU) {
        st->frame.samples = st->smp;
        st->frame.sample_count = count;
        return lu_gradient_gpu_view_tau(st->gpu, scene, &st->frame, count, st->tau, err);
    }
    lu_parallel_for(count, 16, tau_range, st, NULL);
    return LU_OK;
}

/* ---- evaluations kept between frames ---- */

/* Grid vertices of split level L: spacing and count per axis. */
static float level_grid(const lu_gr_state *st, int level, int n[3]) {
    lu_vec3 ext = lu_v3_sub(st->box.hi, st->box.lo);
    float h = lu_v3_maxc(ext) / (float)(16 << level);
    n[0] = (int)floorf(ext.x / h) + 1, n[1] = (int)floorf(ext.y / h) + 1, n[2] = (int)floorf(ext.z / h) + 1;
    return h;
}

static lu_result memo_reset(lu_gr_state *st, int levels, lu_error *err) {
    st->memo_n = 0;
    for (int L = 0; L < LU_GR_MEMO_LEVELS; L++) {
        size_t nv = 0;
        if (L < levels) {
            int n[3];
            level_grid(st, L, n);
            nv = (size_t)n[0] * n[1] * n[2];
        }
        if (nv > st->memo_map_cap[L]) {
            lu_free(st->memo_map[L]);
            st->memo_map[L] = lu_malloc(nv * sizeof(int));
            st->memo_map_cap[L] = st->memo_map[L] ? nv : 0;
            if (!st->memo_map[L]) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for kept samples");
        }
        for (size_t i = 0; i < nv; i++) st->memo_map[L][i] = -1;
    }
    return LU_OK;
}

#define MEMO_FLOATS (LU_K_GR_SAMPLE_FLOATS + 1) /* the record, then its view-free error */

/* The children split_level added, smp[first .. n): copied from the kept
 * evaluations where their vertex was evaluated before, evaluated (and kept)
 * otherwise. An evaluation depends on the vertex alone, not on which parent
 * split or on the camera, so a kept one equals a fresh one bit for bit. */
static lu_result children(lu_gr_state *st, const lu_scene *scene, int level, int first, const int *vertex,
                          int want_error, lu_error *err) {
    int count = st->n - first, miss = 0;
    int *map = st->memo_map[level];
    float *rec = lu_malloc(((size_t)count * (LU_K_GR_SAMPLE_FLOATS + 1) + 1) * sizeof(float));
    int *which = lu_malloc(((size_t)count + 1) * sizeof(int));
    lu_result r = rec && which ? LU_OK : lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory splitting");
    for (int c = 0; c < count && r == LU_OK; c++) {
        int j = first + c, m = map[vertex[c]];
        float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        if (m >= 0) {
            memcpy(s, st->memo + (size_t)m * MEMO_FLOATS, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
            st->Ev[j] = st->memo[(size_t)m * MEMO_FLOATS + LU_K_GR_SAMPLE_FLOATS];
            continue;
        }
        memcpy(rec + (size_t)miss * LU_K_GR_SAMPLE_FLOATS, s, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
        which[miss++] = c;
    }
    float *ev = rec + (size_t)count * LU_K_GR_SAMPLE_FLOATS;
    if (r == LU_OK) r = eval_records(st, scene, rec, miss, want_error, ev, err);
    if (r == LU_OK && st->memo_n + miss > st->memo_cap) {
        int cap = st->memo_cap ? st->memo_cap : 4096;
        while (cap < st->memo_n + miss) cap *= 2;
        float *p = lu_realloc(st->memo, (size_t)cap * MEMO_FLOATS * sizeof(float));
        if (p) st->memo = p, st->memo_cap = cap;
        else r = lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for kept samples");
    }
    for (int k = 0; k < miss && r == LU_OK; k++) {
        int j = first + which[k];
        const float *src = rec + (size_t)k * LU_K_GR_SAMPLE_FLOATS;
        memcpy(st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS, src, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
        st->Ev[j] = ev[k];
        float *m = st->memo + (size_t)st->memo_n * MEMO_FLOATS;
        memcpy(m, src, LU_K_GR_SAMPLE_FLOATS * sizeof(float));
        m[LU_K_GR_SAMPLE_FLOATS] = ev[k];
        map[vertex[which[k]]] = st->memo_n++;
    }
    lu_free(rec);
    lu_free(which);
    return r;
}

/* Mean shading magnitude of the root samples, R^3 avg(F N) D tau: the unit
 * of the relative split threshold. */
static double error_unit(lu_gr_state *st, int count) {
    double sum = 0.0;
    for (int j = 0; j < count; j++) {
        const float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        lu_vec3 x = lu_v3(s[0], s[1], s[2]);
        lu_vec3 N = st->kctx.G.normalize ? lu_k_gr_norm(&st->kctx, st->kctx.G, x) : lu_v3s(1.0f);
        lu_vec3 F = lu_v3(s[8], s[9], s[10]);
        double mag = lu_v3_avg(lu_v3_mul(F, N));
        sum += (double)s[3] * s[3] * s[3] * mag * lu_k_gr_total_density(&st->kctx, x) * st->tau[j];
    }
    return count ? sum / count : 0.0;
}

/* Recursive splitting (Sec. 5): samples of the last level whose E_j exceeds
 * the threshold are replaced by the vertices of the next grid inside their
 * valid sphere (valid radius = that grid's interval), each vertex once;
 * *vertex gets each child's vertex index (malloc'd, NULL when none). */
static lu_result split_level(lu_gr_state *st, int level, int first, int count, double threshold, int **vertex,
                             lu_error *err) {
    int n[3];
    float h = level_grid(st, level, n);
    size_t nv = (size_t)n[0] * n[1] * n[2];
    int children = 0, cap = 0;
    *vertex = NULL;
    unsigned char *mark = lu_calloc(nv, 1);
    if (!mark) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory splitting");
    int splits = 0;
    lu_result r = LU_OK;
    for (int j = first; j < first + count && r == LU_OK; j++) {
        if (!(st->E[j] > threshold)) continue;
        splits++;
        st->active[j] = 0;
        const float *s = st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
        lu_vec3 x = lu_v3(s[0], s[1], s[2]);
        float R = s[3], tau = st->tau[j];
        int lo[3], hi[3];
        float xc[3] = {x.x, x.y, x.z}, bl[3] = {st->box.lo.x, st->box.lo.y, st->box.lo.z};
        for (int a = 0; a < 3; a++) {
            lo[a] = (int)ceilf((xc[a] - R - bl[a]) / h);
            hi[a] = (int)floorf((xc[a] + R - bl[a]) / h);
            if (lo[a] < 0) lo[a] = 0;
            if (hi[a] > n[a] - 1) hi[a] = n[a] - 1;
        }
        for (int k = lo[2]; k <= hi[2] && r == LU_OK; k++)
            for (int jj = lo[1]; jj <= hi[1] && r == LU_OK; jj++)
                for (int i = lo[0]; i <= hi[0] && r == LU_OK; i++) {
                    lu_vec3 q = lu_v3(bl[0] + (float)i * h, bl[1] + (float)jj * h, bl[2] + (float)k * h);
                    lu_vec3 dq = lu_v3_sub(q, x);
                    if (lu_v3_dot(dq, dq) >= R * R) continue;
                    size_t id = ((size_t)k * n[1] + jj) * n[0] + i;
                    if (mark[id]) continue;
                    mark[id] = 1;
                    r = add_sample(st, q, h, 1.0f, h / 3.0f, tau, err);
                    if (r == LU_OK && children == cap) {
                        cap = cap ? 2 * cap : 1024;
                        int *v = lu_realloc(*vertex, (size_t)cap * sizeof(int));
                        if (v) *vertex = v;
                        else r = lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory splitting");
                    }
                    if (r == LU_OK) (*vertex)[children++] = (int)id;
                }
    }
    lu_free(mark);
    if (level < 4) st->stats.split[level] = splits;
    return r;
}

/* ---- cell lists of the final samples ---- */

static lu_result build_cells(lu_gr_state *st, lu_error *err) {
    lu_k_gr_params *G = &st->kctx.G;
    int nc = G->cx * G->cy * G->cz;
    if ((size_t)nc + 1 > st->cells_cap) {
        lu_free(st->cell_begin);
        st->cell_begin = lu_malloc(((size_t)nc + 1) * sizeof(int));
        st->cells_cap = st->cell_begin ? (size_t)nc + 1 : 0;
        if (!st->cell_begin) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for cell lists");
    }
    memset(st->cell_begin, 0, ((size_t)nc + 1) * sizeof(int));
    /* Two passes: count, then fill; a sample enters every cell its sphere touches. */
    for (int pass = 0; pass < 2; pass++) {
        int *fillp = NULL;
        if (pass == 1) {
            for (int c = 0; c < nc; c++) st->cell_begin[c + 1] += st->cell_begin[c];
            size_t items = (size_t)st->cell_begin[nc];
            if (items > st->items_cap) {
                lu_free(st->cell_items);
                st->cell_items = lu_malloc((items ? items : 1) * sizeof(int));
                st->items_cap = st->cell_items ? items : 0;
                if (!st->cell_items) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for cell lists");
            }
            fillp = lu_calloc((size_t)nc, sizeof(int));
            if (!fillp) return lu_fail(err, LU_ERR_NOMEM, "gradient: out of memory for cell lists");
        }
        for (int j = 0; j < st->nfinal; j++) {
            const float *s = st->final + (size_t)j * LU_K_GR_SAMPLE_FLOATS;
            float R = s[3];
            float xc[3] = {s[0], s[1], s[2]}, lo[3] = {G->lo.x, G->lo.y, G->lo.z},
                  cs[3] = {G->cell.x, G->cell.y, G->cell.z};
            int cn[3] = {G->cx, G->cy, G->cz}, a0[3], a1[3];
            for (int a = 0; a < 3; a++) {
                a0[a] = (int)floorf((xc[a] - R - lo[a]) / cs[a]);
                a1[a] = (int)floorf((xc[a] + R - lo[a]) / cs[a]);
                if (a0[a] < 0) a0[a] = 0;
                if (a1[a] > cn[a] - 1) a1[a] = cn[a] - 1;
            }
            for (int z = a0[2]; z <= a1[2]; z++)
                for (int y = a0[1]; y <= a1[1]; y++)
                    for (int x = a0[0]; x <= a1[0]; x++) {
                        /* distance from the sample to the cell's box */
                        float d2 = 0.0f;
                        int idx[3] = {x, y, z};
                        for (int a = 0; a < 3; a++) {
                            float b0 = lo[a] + (float)idx[a] * cs[a], b1 = b0 + cs[a];
                            float dd = xc[a] < b0 ? b0 - xc[a] : (xc[a] > b1 ? xc[a] - b1 : 0.0f);
                            d2 += dd * dd;
                        }
                        if (d2 >= R * R) continue;
                        int c = (z * G->cy + y) * G->cx + x;
                        if (pass == 0) st->cell_begin[c + 1]++;
                        else st->cell_items[st->cell_begin[c] + fillp[c]++] = j;
                    }
        }
        lu_free(fillp);
    }
    st->stats.cell_items = st->cell_begin[nc];
    return LU_OK;
}

/* Samples: roots, then splitting levels, the final set and its cell lists.
 * keep: the roots' evaluations and the kept ones of split vertices are
 * still valid (only tau_v, the splitting and what follows are redone). */
lu_result lu_gr_build_samples(lu_gr_state *st, const lu_scene *scene, int levels, bool keep, lu_error *err) {
    lu_result r = LU_OK;
    int want = levels > 0 ? 1 : 0;
    if (!keep) {
        st->n = 0;
        r = root_samples(st, scene, err);
        if (r == LU_OK) r = eval_records(st, scene, st->smp, st->n, want, st->Ev, err);
        if (r == LU_OK) r = memo_reset(st, levels, err);
        if (r != LU_OK) return r;
        st->nroots = st->n;
        st->nfill = st->stats.fill_samples;
    }
    int roots = st->n = st->nroots;
    if (roots) memset(st->active, 1, (size_t)roots);
    st->stats.root_samples = roots;
    st->stats.fill_samples = st->nfill;
    memset(st->stats.level_samples, 0, sizeof st->stats.level_samples);
    memset(st->stats.split, 0, sizeof st->stats.split);
    st->stats.level_samples[0] = roots;
    if (want) r = view_tau(st, scene, roots, err);
    if (r != LU_OK) return r;
    for (int j = 0; j < roots && want; j++) st->E[j] = st->Ev[j] * st->tau[j];
    int first = 0, count = roots;
    double threshold = want ? st->p[P_EPSILON] * error_unit(st, roots) : 0.0;
    for (int level = 0; level < levels && r == LU_OK; level++) {
        int *vertex = NULL;
        r = split_level(st, level, first, count, threshold, &vertex, err);
        first += count;
        count = st->n - first;
        if (r == LU_OK && count > 0) {
            int more = level + 1 < levels ? 1 : 0;
            r = children(st, scene, level, first, vertex, more, err);
            for (int j = first; j < st->n && more; j++) st->E[j] = st->Ev[j] * st->tau[j];
            st->stats.level_samples[level + 1] = count;
        }
        lu_free(vertex);
        if (count == 0) break;
    }
    if (r != LU_OK) return r;
    /* The final set: every sample not split, over all levels. */
    lu_free(st->final);
    st->final = lu_malloc((st->n ? (size_t)st->n : 1u) * LU_K_GR_SAMPLE_FLOATS * sizeof(float));
    if (!st->final) return lu_fail(err, LU_ERR_NOMEM, "%s: out of memory", st->who);
    st->nfinal = 0;
    for (int j = 0; j < st->n; j++)
        if (st->active[j])
            memcpy(st->final + (size_t)st->nfinal++ * LU_K_GR_SAMPLE_FLOATS, st->smp + (size_t)j * LU_K_GR_SAMPLE_FLOATS,
                   LU_K_GR_SAMPLE_FLOATS * sizeof(float));
    st->stats.samples = st->nfinal;
    return build_cells(st, err);
}

/* pervoxel has no samples: empty cell lists. */
lu_result lu_gr_empty_cells(lu_gr_state *st, lu_error *err) {
    const lu_k_gr_params *G = &st->kctx.G;
    st->nfinal = 0;
    size_t nc = (size_t)G->cx * G->cy * G->cz + 1;
    if (nc > st->cells_cap) {
        lu_free(st->cell_begin);
        st->cell_begin = lu_calloc(nc, sizeof(int));
        st->cells_cap = st->cell_begin ? nc : 0;
        if (!st->cell_begin) return lu_fail(err, LU_ERR_NOMEM, "pervoxel: out of memory");
    } else {
        memset(st->cell_begin, 0, nc * sizeof(int));
    }
    return LU_OK;
}
