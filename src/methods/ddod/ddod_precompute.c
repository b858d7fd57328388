/* ddod precomputation: optical depth sweeps, first moment and divergence,
 * the attenuation at the samples and its SH, the partition of unity (see
 * ddod.h for the steps; the Poisson-disk sampling is ddod_poisson.c, the
 * on-disk cache ddod_cache.c).
 * Over 800 lines because steps 1, 2, 4 and 5 all read one private voxel
 * grid (vgrid: density, inside and blocked masks, and the sweeps over it);
 * splitting them would make that struct and its sweep an interface. */
#include "methods/ddod/ddod.h"
#include "methods/ddod/ddod_poisson.h"
#include "core/rng.h"

#include <errno.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>

#include "methods/methods.h"
#include "methods/common/opaque_accel.h"

#define DDOD_BLOCK_DENSITY 1.0e4f   /* per world unit: opaque voxels stop every ray */
#define DDOD_FIX 1048576.0f         /* 2^20: fixed point of the first-moment sums */
#define DDOD_MAX_CROSSINGS 64
/* Directions of the first moment T (at most; fewer when n is smaller). */
#define DDOD_MOMENT_DIRS 32

/* Processor time of the process (all threads), for the timing breakdown. */
static double cpu_seconds(void) {
    struct rusage ru;
    if (getrusage(RUSAGE_SELF, &ru) != 0) return 0.0;
    return (double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + (double)ru.ru_stime.tv_sec + ru.ru_stime.tv_usec * 1e-6;
}

/* ---- directions and SH ---------------------------------------------------- */

void lu_ddod_directions(int n, lu_vec3 *out) {
    for (int i = 0; i < n; i++) {
        double z = 1.0 - (2.0 * i + 1.0) / n;
        double r = sqrt(fmax(0.0, 1.0 - z * z));
        double phi = i * 2.39996322972865332; /* golden angle */
        out[i] = lu_v3((float)(r * cos(phi)), (float)(r * sin(phi)), (float)z);
    }
}

/* acc[k] += sum_j f_j Y[j][k] over n rows of a basis table Y (nc per row). */
static void sh_accumulate(int n, const float *Y, int nc, const float *f, double *acc) {
    for (int j = 0; j < n; j++)
        for (int k = 0; k < nc; k++) acc[k] += (double)f[j] * Y[(size_t)j * nc + k];
}

void lu_ddod_sh_project(int n, const lu_vec3 *dirs, const float *f, int bands, float *c) {
    int nc = bands * bands;
    double acc[LU_SH_MAX_COEFFS] = {0};
    float Y[32 * LU_SH_MAX_COEFFS]; /* the basis at 32 directions at a time */
    for (int j0 = 0; j0 < n; j0 += 32) {
        int m = n - j0 < 32 ? n - j0 : 32;
        float y[LU_SH_MAX_COEFFS];
        for (int j = 0; j < m; j++) {
            lu_k_sh_eval(dirs[j0 + j], bands, y);
            memcpy(Y + (size_t)j * nc, y, (size_t)nc * sizeof *y);
        }
        sh_accumulate(m, Y, nc, f + j0, acc);
    }
    for (int k = 0; k < nc; k++) c[k] = (float)(acc[k] * 4.0 * M_PI / n);
}

/* ---- the voxel grid of one medium ------------------------------------------ */

typedef struct vgrid {
    int n[3];
    size_t count;
    lu_vec3 lo;            /* corner: voxel i spans lo + [i, i + 1] h */
    float h;
    float *density;        /* D at voxel centres, unmasked */
    float *inside;         /* fraction of the voxel inside the boundary */
    float *blocked;        /* fraction inside opaque objects (NULL: none) */
    float *perm[3];        /* masked density (blocked: DDOD_BLOCK_DENSITY), permuted per sweep axis */
    float *perm_raw[3];    /* unmasked density, permuted */
} vgrid;

static void vgrid_free(vgrid *g) {
    lu_free(g->density);
    lu_free(g->inside);
    lu_free(g->blocked);
    for (int a = 0; a < 3; a++) {
        lu_free(g->perm[a]);
        lu_free(g->perm_raw[a]);
    }
    memset(g, 0, sizeof *g);
}

/* Axis order of the sweep along axis a: slices along a, then in-slice axes
 * b (fastest) and c. */
static void axes_of(int a, int *b, int *c) {
    *b = a == 0 ? 1 : 0;
    *c = a == 2 ? 1 : 2;
}

static size_t vidx(const vgrid *g, int x, int y, int z) { return ((size_t)z * g->n[1] + y) * g->n[0] + x; }

/* Index of native voxel (x, y, z) in the layout permuted for axis a. */
static size_t pidx(const vgrid *g, int a, const int v[3]) {
    int b, c;
    axes_of(a, &b, &c);
    return ((size_t)v[a] * g->n[c] + v[c]) * g->n[b] + v[b];
}

static float medium_density(const lu_medium *m, lu_vec3 p) {
    if (m->kind == LU_DENSITY_CONSTANT) return m->constant;
    return lu_grid_sample(&m->grid, lu_affine_point(&m->world_to_index, p));
}

static lu_vec3 voxel_centre(const vgrid *g, int x, int y, int z) {
    return lu_v3(g->lo.x + ((float)x + 0.5f) * g->h, g->lo.y + ((float)y + 0.5f) * g->h, g->lo.z + ((float)z + 0.5f) * g->h);
}

typedef struct build_job {
    vgrid *g;
    const lu_medium *m;
} build_job;

static void density_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    build_job *j = ctx;
    vgrid *g = j->g;
    for (int64_t r = begin; r < end; r++) {
        int y = (int)(r % g->n[1]), z = (int)(r / g->n[1]);
        for (int x = 0; x < g->n[0]; x++) g->density[vidx(g, x, y, z)] = medium_density(j->m, voxel_centre(g, x, y, z));
    }
}

/* Voxel grid over the boundary's box padded by one voxel (so every point of
 * the box interpolates between voxel centres). */
static lu_result vgrid_build(vgrid *g, const lu_medium *m, const lu_accel *boundary, const lu_accel *opaque, int res,
                             lu_error *err) {
    memset(g, 0, sizeof *g);
    lu_aabb b = lu_mesh_bounds(&m->boundary);
    lu_vec3 ext = lu_v3_sub(b.hi, b.lo);
    float longest = fmaxf(lu_v3_maxc(ext), 1e-6f);
    g->h = longest / (float)res;
    g->lo = lu_v3_sub(b.lo, lu_v3s(g->h));
    for (int a = 0; a < 3; a++) g->n[a] = (int)ceilf(lu_v3_get(ext, a) / g->h - 1e-4f) + 2;
    for (int a = 0; a < 3; a++)
        if (g->n[a] < 3) g->n[a] = 3;
    g->count = (size_t)g->n[0] * g->n[1] * g->n[2];
    g->density = lu_malloc(g->count * sizeof(float));
    for (int a = 0; a < 3; a++) {
        g->perm[a] = lu_malloc(g->count * sizeof(float));
        g->perm_raw[a] = lu_malloc(g->count * sizeof(float));
        if (!g->perm[a] || !g->perm_raw[a]) g->density = (lu_free(g->density), NULL);
    }
    if (!g->density) {
        vgrid_free(g);
        return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for a %dx%dx%d voxel grid", g->n[0], g->n[1], g->n[2]);
    }
    build_job j = {g, m};
    lu_parallel_for((int64_t)g->n[1] * g->n[2], 0, density_rows, &j, NULL);
    /* Inside fractions: lu_voxelize over the same grid (its voxel centres are
     * bounds.lo + (i + 0.5) h with h = longest side / resolution). */
    int vres = 0;
    for (int a = 0; a < 3; a++) vres = g->n[a] > vres ? g->n[a] : vres;
    /* lu_voxelize takes n = ceil(extent / h): shorter axes get a quarter
     * voxel less so float rounding cannot add a voxel. */
    float ext_v[3];
    for (int a = 0; a < 3; a++) ext_v[a] = ((float)g->n[a] - (g->n[a] == vres ? 0.0f : 0.25f)) * g->h;
    lu_aabb box = {g->lo, lu_v3_add(g->lo, lu_v3(ext_v[0], ext_v[1], ext_v[2]))};
    lu_grid in;
    lu_result r = lu_voxelize(boundary, box, vres, 2, &in, err);
    if (r != LU_OK) {
        vgrid_free(g);
        return r;
    }
    if (in.nx != g->n[0] || in.ny != g->n[1] || in.nz != g->n[2]) {
        lu_fail(err, LU_ERR_INVALID_ARG, "ddod: voxelisation gave %dx%dx%d voxels, expected %dx%dx%d", in.nx, in.ny,
                in.nz, g->n[0], g->n[1], g->n[2]);
        lu_grid_destroy(&in);
        vgrid_free(g);
        return LU_ERR_INVALID_ARG;
    }
    g->inside = in.data;
    if (opaque) {
        lu_grid bl;
        r = lu_voxelize(opaque, box, vres, 2, &bl, err);
        if (r != LU_OK) {
            vgrid_free(g);
            return r;
        }
        g->blocked = bl.data;
    }
    int v[3];
    for (v[2] = 0; v[2] < g->n[2]; v[2]++)
        for (v[1] = 0; v[1] < g->n[1]; v[1]++)
            for (v[0] = 0; v[0] < g->n[0]; v[0]++) {
                size_t i = vidx(g, v[0], v[1], v[2]);
                float raw = g->density[i];
                float masked = raw * g->inside[i];
                if (g->blocked && g->blocked[i] > 0.5f) masked = DDOD_BLOCK_DENSITY;
                for (int a = 0; a < 3; a++) {
                    size_t p = pidx(g, a, v);
                    g->perm[a][p] = masked;
                    g->perm_raw[a][p] = raw;
                }
            }
    return LU_OK;
}

/* ---- the sweep: optical depth for every voxel along one direction ---- */

typedef struct sweep_out {
    /* either: accumulate exp(-sigma_t tau) w into fixed-point sums (permuted layout of the axis) */
    int32_t *acc[3];       /* per component, NULL when not accumulating */
    float sigma_t;
    /* or: store tau (density integral) in the permuted layout of the axis */
    float *tau;
} sweep_out;

/* One row of a sweep step: tau at the voxels from the previous slice's q
 * (bilinear upstream) and the density, and this slice's q = tau + (L/2) D.
 * A loop of its own so that it vectorises. */
static void sweep_row(const float *restrict qp, float *restrict qc, const float *restrict drow, float *restrict tau,
                      int nb, ptrdiff_t pb, float w00, float w10, float w01, float w11, float half_len) {
    for (int jb = 0; jb < nb; jb++) {
        float up = w00 * qp[jb] + w10 * qp[jb + 1] + w01 * qp[jb + pb] + w11 * qp[jb + pb + 1];
        float dh = half_len * drow[jb];
        float t = up + dh;
        qc[jb] = t + dh;
        tau[jb] = t;
    }
}

/* The first-moment contributions of one sweep row: exp(-sigma_t tau) w in
 * fixed point, nothing in blocked voxels. */
static void moment_row(const float *restrict drow, const float *restrict tau, float sigma_t, float fx, float fy,
                       float fz, int32_t *restrict ax, int32_t *restrict ay, int32_t *restrict az, int nb) {
    /* Adding and removing 1.5 * 2^23 rounds to the nearest integer (ties to
     * even) for |x| < 2^22, as lrintf does, without a library call: the
     * products are at most DDOD_FIX = 2^20. */
    const float magic = 12582912.0f;
    for (int jb = 0; jb < nb; jb++) {
        if (!(drow[jb] < DDOD_BLOCK_DENSITY)) continue;
        float e = expf(-sigma_t * tau[jb]);
        ax[jb] += (int32_t)((e * fx + magic) - magic);
        ay[jb] += (int32_t)((e * fy + magic) - magic);
        az[jb] += (int32_t)((e * fz + magic) - magic);
    }
}

/* One direction w over grid g: slices along the dominant axis a, from the
 * far side (+w) back. q holds tau + (L/2) D of the previous slice, padded
 * by one voxel of zeros (outside the grid nothing attenuates). */
static void sweep(const vgrid *g, lu_vec3 w, bool masked, float *q_prev, float *q_cur, const sweep_out *o) {
    float wv[3] = {w.x, w.y, w.z};
    int a = fabsf(wv[0]) >= fabsf(wv[1]) && fabsf(wv[0]) >= fabsf(wv[2]) ? 0 : (fabsf(wv[1]) >= fabsf(wv[2]) ? 1 : 2);
    int b, c;
    axes_of(a, &b, &c);
    int na = g->n[a], nb = g->n[b], nc = g->n[c];
    int pb = nb + 2;
    size_t slice_pad = (size_t)pb * (nc + 2);
    float inv = 1.0f / fabsf(wv[a]);
    float ub = wv[b] * inv, uc = wv[c] * inv;   /* in-slice offset of the upstream point, voxels, in [-1, 1] */
    float half_len = 0.5f * g->h * inv;         /* half the world length between slices */
    int fb = (int)floorf(ub), fc = (int)floorf(uc);
    float tb = ub - (float)fb, tc = uc - (float)fc;
    if (fb >= 1) fb = 0, tb = 1.0f;
    if (fc >= 1) fc = 0, tc = 1.0f;
    float w00 = (1 - tb) * (1 - tc), w10 = tb * (1 - tc), w01 = (1 - tb) * tc, w11 = tb * tc;
    ptrdiff_t off = (ptrdiff_t)fb + (ptrdiff_t)fc * pb;
    float *row = q_prev + slice_pad; /* past the slice: see max_slice */
    memset(q_prev, 0, slice_pad * sizeof(float));
    memset(q_cur, 0, slice_pad * sizeof(float));
    const float *dens = masked ? g->perm[a] : g->perm_raw[a];
    float fx = wv[0] * DDOD_FIX, fy = wv[1] * DDOD_FIX, fz = wv[2] * DDOD_FIX;
    for (int step = 0; step < na; step++) {
        int k = wv[a] > 0.0f ? na - 1 - step : step;
        const float *ds = dens + (size_t)k * nb * nc;
        for (int jc = 0; jc < nc; jc++) {
            const float *drow = ds + (size_t)jc * nb;
            const float *qp = q_prev + (size_t)(jc + 1) * pb + 1 + off;
            float *qc = q_cur + (size_t)(jc + 1) * pb + 1;
            size_t out_base = ((size_t)k * nc + jc) * nb;
            float *tau = o->tau ? o->tau + out_base : row;
            sweep_row(qp, qc, drow, tau, nb, pb, w00, w10, w01, w11, half_len);
            if (o->acc[0])
                moment_row(drow, tau, o->sigma_t, fx, fy, fz, o->acc[0] + out_base, o->acc[1] + out_base,
                           o->acc[2] + out_base, nb);
        }
        float *t = q_prev;
        q_prev = q_cur;
        q_cur = t;
    }
}

/* ---- step 1 + 2: first moment over all directions ---- */

typedef struct moment_job {
    const vgrid *g;
    const lu_vec3 *dirs;
    int ndirs, groups;
    float sigma_t;
    int32_t **acc;         /* groups x 3 axes x 3 components, permuted layouts */
    float **scratch;       /* groups x 2 slices */
    float *T;              /* the result: 3 component arrays, native layout */
} moment_job;

/* T of rows (y, z) of the native layout: the integer sums of all groups and
 * axes, scaled by the quadrature weight. */
static void moment_sum_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    moment_job *j = ctx;
    const vgrid *g = j->g;
    double wq = 4.0 * M_PI / j->ndirs / DDOD_FIX;
    for (int64_t r = begin; r < end; r++) {
        int v[3] = {0, (int)(r % g->n[1]), (int)(r / g->n[1])};
        for (v[0] = 0; v[0] < g->n[0]; v[0]++) {
            int64_t s[3] = {0, 0, 0};
            for (int gi = 0; gi < j->groups; gi++)
                for (int a = 0; a < 3; a++) {
                    size_t p = pidx(g, a, v);
                    for (int comp = 0; comp < 3; comp++) s[comp] += j->acc[(gi * 3 + a) * 3 + comp][p];
                }
            size_t i = vidx(g, v[0], v[1], v[2]);
            for (int comp = 0; comp < 3; comp++) j->T[comp * g->count + i] = (float)(s[comp] * wq);
        }
    }
}

static void moment_groups(void *ctx, int64_t begin, int64_t end, int thread) {
    moment_job *j = ctx;
    for (int64_t gi = begin; gi < end; gi++) {
        float *q0 = j->scratch[2 * gi], *q1 = j->scratch[2 * gi + 1];
        for (int d = (int)gi; d < j->ndirs; d += j->groups) {
            lu_vec3 w = j->dirs[d];
            float wv[3] = {w.x, w.y, w.z};
            int a = fabsf(wv[0]) >= fabsf(wv[1]) && fabsf(wv[0]) >= fabsf(wv[2]) ? 0 : (fabsf(wv[1]) >= fabsf(wv[2]) ? 1 : 2);
            int32_t **acc = j->acc + (gi * 3 + a) * 3;
            sweep_out o = {{acc[0], acc[1], acc[2]}, j->sigma_t, NULL};
            sweep(j->g, w, true, q0, q1, &o);
        }
    }
}

/* Floats of one sweep scratch buffer: a padded slice and one row. */
static size_t max_slice(const vgrid *g) {
    size_t slice = 0;
    for (int a = 0; a < 3; a++) {
        int b, c;
        axes_of(a, &b, &c);
        size_t s = (size_t)(g->n[b] + 2) * (g->n[c] + 2) + (size_t)g->n[b];
        slice = s > slice ? s : slice;
    }
    return slice;
}

/* T (3 arrays of one component each, native layout) from the sweeps; sums are integers,
 * so the result does not depend on how directions meet threads. */
static lu_result first_moment(const vgrid *g, const lu_vec3 *dirs, int ndirs, float sigma_t, float *T, lu_error *err) {
    int groups = lu_thread_count();
    if (groups > ndirs) groups = ndirs;
    if (groups > 8) groups = 8;
    moment_job j = {g, dirs, ndirs, groups, sigma_t, NULL, NULL, NULL};
    j.acc = lu_calloc((size_t)groups * 9, sizeof *j.acc);
    j.scratch = lu_calloc((size_t)groups * 2, sizeof *j.scratch);
    bool ok = j.acc && j.scratch;
    size_t slice = max_slice(g);
    for (int i = 0; ok && i < groups * 9; i++) ok = (j.acc[i] = lu_calloc(g->count, sizeof(int32_t))) != NULL;
    for (int i = 0; ok && i < groups * 2; i++) ok = (j.scratch[i] = lu_malloc(slice * sizeof(float))) != NULL;
    if (ok) {
        lu_parallel_for(groups, 1, moment_groups, &j, "ddod: optical depth");
        j.T = T;
        lu_parallel_for((int64_t)g->n[1] * g->n[2], 0, moment_sum_rows, &j, NULL);
    }
    for (int i = 0; j.acc && i < groups * 9; i++) lu_free(j.acc[i]);
    for (int i = 0; j.scratch && i < groups * 2; i++) lu_free(j.scratch[i]);
    lu_free(j.acc);
    lu_free(j.scratch);
    return ok ? LU_OK : lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for the first-moment sums");
}

/* ---- step 4: attenuation at the samples ---- */

typedef struct psi_job {
    const vgrid *g;
    const lu_medium *m;
    const lu_accel *boundary, *opaque;
    const lu_vec3 *dirs;
    int ndirs;
    const float *pts;
    int count;
    float *tau;            /* count x ndirs: density integral to the boundary (inf: blocked) */
    float *ft;             /* count x ndirs: product of F_t over the crossings */
    float **vol;           /* per thread: unmasked sweep (grid media) */
    float **scratch;       /* per thread: 2 slices */
    atomic_int failed;
} psi_job;

/* Trilinear in a permuted volume at world point p (clamped to voxel centres). */
static float vol_sample(const vgrid *g, int a, const float *vol, lu_vec3 p) {
    int b, c;
    axes_of(a, &b, &c);
    size_t stride[3];
    stride[a] = (size_t)g->n[b] * g->n[c];
    stride[b] = 1;
    stride[c] = (size_t)g->n[b];
    float pv[3] = {p.x, p.y, p.z}, lov[3] = {g->lo.x, g->lo.y, g->lo.z};
    int i0[3];
    float t[3];
    for (int k = 0; k < 3; k++) {
        float u = (pv[k] - lov[k]) / g->h - 0.5f;
        u = u < 0.0f ? 0.0f : (u > (float)(g->n[k] - 1) ? (float)(g->n[k] - 1) : u);
        int i = (int)u;
        if (i > g->n[k] - 2) i = g->n[k] - 2;
        i0[k] = i;
        t[k] = u - (float)i;
    }
    size_t base = i0[0] * stride[0] + i0[1] * stride[1] + i0[2] * stride[2];
    float acc = 0.0f;
    for (int corner = 0; corner < 8; corner++) {
        float wgt = 1.0f;
        size_t o = base;
        for (int k = 0; k < 3; k++) {
            int bit = (corner >> k) & 1;
            wgt *= bit ? t[k] : 1.0f - t[k];
            o += bit ? stride[k] : 0;
        }
        acc += wgt * vol[o];
    }
    return acc;
}

bool lu_ddod_ray(const lu_accel *boundary, const lu_accel *opaque, float eta, lu_vec3 b, lu_vec3 w, float tmax,
                 lu_ddod_span_fn span, void *user, float *tau, float *ft) {
    lu_hit hits[DDOD_MAX_CROSSINGS];
    *tau = 0.0f;
    *ft = 1.0f;
    if (opaque && lu_accel_occluded(opaque, b, w, 0.0f, tmax)) {
        *tau = INFINITY;
        *ft = 0.0f;
        return true;
    }
    int n = lu_accel_all_hits(boundary, b, w, 0.0f, tmax, hits, DDOD_MAX_CROSSINGS);
    bool ok = n >= 0;
    if (n < 0) n = 0;
    if (n > DDOD_MAX_CROSSINGS) n = DDOD_MAX_CROSSINGS;
    /* b is inside: spans [0, t0], [t1, t2], ..., and [t_last, tmax] when the
     * ray ends inside (a light within the object). */
    float acc = 0.0f, f = 1.0f, start = 0.0f;
    for (int k = 0; k < n; k++) {
        f *= lu_k_fresnel_transmittance(lu_v3_dot(hits[k].ng, w), eta);
        if ((k & 1) == 0) acc += span(user, b, w, start, hits[k].t);
        else start = hits[k].t;
    }
    if ((n & 1) == 0 && tmax < 1e29f) acc += span(user, b, w, start, tmax);
    *tau = acc > 0.0f ? acc : 0.0f;
    *ft = f;
    return ok;
}

/* Span integrals of the precomputation: exact for constant media, the
 * difference of the direction's unmasked sweep for grids. */
typedef struct psi_span {
    const vgrid *g;
    const lu_medium *m;
    const float *vol;
    int axis;
} psi_span;

static float psi_span_depth(void *user, lu_vec3 b, lu_vec3 w, float t0, float t1) {
    const psi_span *s = user;
    if (s->m->kind != LU_DENSITY_GRID) return s->m->constant * (t1 - t0);
    return vol_sample(s->g, s->axis, s->vol, lu_v3_madd(b, w, t0)) - vol_sample(s->g, s->axis, s->vol, lu_v3_madd(b, w, t1));
}

static void psi_dirs(void *ctx, int64_t begin, int64_t end, int thread) {
    psi_job *j = ctx;
    const vgrid *g = j->g;
    bool grid = j->m->kind == LU_DENSITY_GRID;
    for (int64_t d = begin; d < end; d++) {
        lu_vec3 w = j->dirs[d];
        float wv[3] = {w.x, w.y, w.z};
        int a = fabsf(wv[0]) >= fabsf(wv[1]) && fabsf(wv[0]) >= fabsf(wv[2]) ? 0 : (fabsf(wv[1]) >= fabsf(wv[2]) ? 1 : 2);
        if (grid) {
            sweep_out o = {{NULL, NULL, NULL}, 0.0f, j->vol[thread]};
            sweep(g, w, false, j->scratch[2 * thread], j->scratch[2 * thread + 1], &o);
        }
        psi_span sp = {g, j->m, grid ? j->vol[thread] : NULL, a};
        for (int i = 0; i < j->count; i++) {
            lu_vec3 b = lu_v3(j->pts[3 * i], j->pts[3 * i + 1], j->pts[3 * i + 2]);
            size_t at = (size_t)i * j->ndirs + (size_t)d;
            if (!lu_ddod_ray(j->boundary, j->opaque, j->m->eta, b, w, 1e30f, psi_span_depth, &sp, &j->tau[at],
                             &j->ft[at]))
                atomic_store(&j->failed, 1);
        }
    }
}

/* ---- step 5: partition of unity ---- */

typedef struct pou_job {
    float *rec;            /* sample records (LU_K_DDOD_SAMPLE_FLOATS each) */
    int count;
    lu_vec3 lo;
    int cn[3], reach;
    float cell;
    const int *head, *next;
    int64_t *start;        /* CSR: neighbours of sample i at [start[i], start[i + 1]) */
    int *nb;
    float *w;              /* gamma_j(b_i) / A_j: the Gaussian's shape, fixed during the fit */
    bool fill;             /* false: count into start[i + 1]; true: write nb and w */
    float *S;              /* per sample: sum_j A_j gamma_j(b_i) */
} pou_job;

/* S_i of one Jacobi step (each i on its own: the split over threads does not
 * change the sums). */
static void pou_sums(void *ctx, int64_t begin, int64_t end, int thread) {
    pou_job *j = ctx;
    for (int64_t i = begin; i < end; i++) {
        double sum = 0.0;
        for (int64_t k = j->start[i]; k < j->start[i + 1]; k++)
            sum += (double)j->rec[(size_t)j->nb[k] * LU_K_DDOD_SAMPLE_FLOATS + LU_K_DDOD_SAMPLE_AMP] * j->w[k];
        j->S[i] = (float)sum;
    }
}

/* Every sample j whose ball (3 s_j) holds b_i: counted, or written with its weight. */
static void pou_neighbours(void *ctx, int64_t begin, int64_t end, int thread) {
    pou_job *j = ctx;
    for (int64_t i = begin; i < end; i++) {
        const float *si = j->rec + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
        lu_vec3 p = lu_v3(si[0], si[1], si[2]);
        int c[3] = {(int)((p.x - j->lo.x) / j->cell), (int)((p.y - j->lo.y) / j->cell), (int)((p.z - j->lo.z) / j->cell)};
        int64_t k = j->fill ? j->start[i] : 0;
        for (int cz = c[2] - j->reach; cz <= c[2] + j->reach; cz++)
            for (int cy = c[1] - j->reach; cy <= c[1] + j->reach; cy++)
                for (int cx = c[0] - j->reach; cx <= c[0] + j->reach; cx++) {
                    if (cx < 0 || cy < 0 || cz < 0 || cx >= j->cn[0] || cy >= j->cn[1] || cz >= j->cn[2]) continue;
                    for (int q = j->head[((size_t)cz * j->cn[1] + cy) * j->cn[0] + cx]; q >= 0; q = j->next[q]) {
                        const float *s = j->rec + (size_t)q * LU_K_DDOD_SAMPLE_FLOATS;
                        float ddx = p.x - s[0], ddy = p.y - s[1], ddz = p.z - s[2], sd = s[LU_K_DDOD_SAMPLE_S];
                        float d2 = ddx * ddx + ddy * ddy + ddz * ddz;
                        if (d2 >= LU_K_DDOD_CUTOFF * LU_K_DDOD_CUTOFF * sd * sd) continue;
                        if (j->fill) {
                            j->nb[k] = q;
                            j->w[k] = expf(-0.5f * d2 / (sd * sd));
                        }
                        k++;
                    }
                }
        if (!j->fill) j->start[i + 1] = k;
    }
}

/* `iters` damped Jacobi updates A_i <- A_i / S(b_i)^0.7 of the amplitudes
 * towards sum_j A_j gamma_j(b_i) = 1 at every sample (see ddod.h, step 5).
 * The Gaussians' shapes do not change, so the neighbour weights are found
 * once and each iteration is a sparse product. */
static lu_result fit_partition(float *rec, int count, int iters, lu_error *err) {
    if (iters <= 0 || count == 0) return LU_OK;
    pou_job j;
    memset(&j, 0, sizeof j);
    j.rec = rec;
    j.count = count;
    float smax = 0.0f, ssum = 0.0f;
    lu_vec3 lo = lu_v3s(1e30f), hi = lu_v3s(-1e30f);
    for (int i = 0; i < count; i++) {
        const float *s = rec + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
        smax = fmaxf(smax, s[LU_K_DDOD_SAMPLE_S]);
        ssum += s[LU_K_DDOD_SAMPLE_S];
        lo = lu_v3_min(lo, lu_v3(s[0], s[1], s[2]));
        hi = lu_v3_max(hi, lu_v3(s[0], s[1], s[2]));
    }
    /* cells of the mean support radius; search as far as the largest reaches */
    j.cell = fmaxf(LU_K_DDOD_CUTOFF * ssum / (float)count, 1e-6f);
    lu_vec3 ext = lu_v3_sub(hi, lo);
    for (int a = 0; a < 3; a++) j.cn[a] = (int)fminf(lu_v3_get(ext, a) / j.cell, 1000.0f) + 1;
    j.cell = fmaxf(j.cell, fmaxf(ext.x / (float)j.cn[0], fmaxf(ext.y / (float)j.cn[1], ext.z / (float)j.cn[2])));
    j.reach = (int)ceilf(LU_K_DDOD_CUTOFF * smax / j.cell);
    j.lo = lo;
    size_t ncell = (size_t)j.cn[0] * j.cn[1] * j.cn[2];
    int *head = lu_malloc(ncell * sizeof *head), *next = lu_malloc((size_t)count * sizeof *next);
    j.start = lu_calloc((size_t)count + 1, sizeof *j.start);
    float *S = lu_malloc((size_t)count * sizeof *S);
    lu_result r = LU_OK;
    if (!head || !next || !j.start || !S) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for the partition fit");
    if (r == LU_OK) {
        for (size_t c = 0; c < ncell; c++) head[c] = -1;
        for (int i = count - 1; i >= 0; i--) {
            const float *s = rec + (size_t)i * LU_K_DDOD_SAMPLE_FLOATS;
            int c[3];
            float pv[3] = {s[0] - lo.x, s[1] - lo.y, s[2] - lo.z};
            for (int a = 0; a < 3; a++) {
                c[a] = (int)(pv[a] / j.cell);
                c[a] = c[a] < 0 ? 0 : (c[a] >= j.cn[a] ? j.cn[a] - 1 : c[a]);
            }
            size_t ci = ((size_t)c[2] * j.cn[1] + c[1]) * j.cn[0] + c[0];
            next[i] = head[ci];
            head[ci] = i;
        }
        j.head = head;
        j.next = next;
        lu_parallel_for(count, 0, pou_neighbours, &j, NULL);
        for (int i = 0; i < count; i++) j.start[i + 1] += j.start[i];
        j.nb = lu_malloc((size_t)j.start[count] * sizeof *j.nb);
        j.w = lu_malloc((size_t)j.start[count] * sizeof *j.w);
        if (!j.nb || !j.w) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for the partition fit");
    }
    if (r == LU_OK) {
        j.fill = true;
        lu_parallel_for(count, 0, pou_neighbours, &j, NULL);
        j.S = S;
        for (int it = 0; it < iters; it++) {
            lu_parallel_for(count, 0, pou_sums, &j, NULL);
            for (int i = 0; i < count; i++)
                if (S[i] > 0.0f) rec[(size_t)i * LU_K_DDOD_SAMPLE_FLOATS + LU_K_DDOD_SAMPLE_AMP] /= powf(S[i], 0.7f);
        }
    }
    lu_free(head);
    lu_free(next);
    lu_free(j.start);
    lu_free(j.nb);
    lu_free(j.w);
    lu_free(S);
    return r;
}

/* ---- one medium, end to end ---- */

typedef struct valid_ctx {
    const lu_medium *m;
    const lu_accel *boundary, *opaque;
    const vgrid *g;
} valid_ctx;

/* Density > 0, inside the boundary, outside opaque objects; the ray-cast
 * inside tests only in voxels the voxelisation found partly covered. */
static bool sample_valid(void *user, lu_vec3 p) {
    valid_ctx *v = user;
    if (!(medium_density(v->m, p) > 0.0f)) return false;
    const vgrid *g = v->g;
    int c[3];
    float pv[3] = {p.x - g->lo.x, p.y - g->lo.y, p.z - g->lo.z};
    for (int a = 0; a < 3; a++) {
        c[a] = (int)(pv[a] / g->h);
        c[a] = c[a] < 0 ? 0 : (c[a] >= g->n[a] ? g->n[a] - 1 : c[a]);
    }
    size_t i = vidx(g, c[0], c[1], c[2]);
    /* Sub-samples can all be inside while the boundary clips a corner:
     * trust the grid only where the whole 3x3x3 neighbourhood is inside. */
    bool surely = true;
    for (int dz = -1; dz <= 1 && surely; dz++)
        for (int dy = -1; dy <= 1 && surely; dy++)
            for (int dx = -1; dx <= 1 && surely; dx++) {
                int x = c[0] + dx, y = c[1] + dy, z = c[2] + dz;
                surely = x >= 0 && y >= 0 && z >= 0 && x < g->n[0] && y < g->n[1] && z < g->n[2] &&
                         g->inside[vidx(g, x, y, z)] >= 1.0f;
            }
    if (!surely && !lu_accel_inside(v->boundary, p)) return false;
    return !(v->opaque && g->blocked[i] > 0.0f && lu_accel_inside(v->opaque, p));
}

typedef struct sh_job {
    const float *Y;        /* ndirs x bands^2: the basis at the directions, evaluated once */
    int ndirs, bands, channels, stride, count;
    lu_vec3 sigma_t;
    const float *tau, *ft;
    float *sh;
    atomic_int failed;     /* a worker could not get its scratch */
} sh_job;

/* Per sample: psi and psi^F at the directions, projected as lu_ddod_sh_project
 * does (same sums in the same order) but from the shared basis table. */
static void sh_samples(void *ctx, int64_t begin, int64_t end, int thread) {
    sh_job *j = ctx;
    float *f = lu_malloc((size_t)j->ndirs * 2 * sizeof *f);
    if (!f) {
        atomic_store(&j->failed, 1);
        return;
    }
    float *fF = f + j->ndirs;
    int nc = j->bands * j->bands;
    double scale = 4.0 * M_PI / j->ndirs;
    for (int64_t i = begin; i < end; i++) {
        const float *tau = j->tau + (size_t)i * j->ndirs, *ft = j->ft + (size_t)i * j->ndirs;
        for (int c = 0; c < j->channels; c++) {
            float st = j->channels == 1 ? lu_v3_avg(j->sigma_t) : lu_v3_get(j->sigma_t, c);
            for (int d = 0; d < j->ndirs; d++) {
                f[d] = isinf(tau[d]) ? 0.0f : expf(-st * tau[d]);
                fF[d] = f[d] * ft[d];
            }
            for (int set = 0; set < 2; set++) {
                double acc[LU_SH_MAX_COEFFS] = {0};
                sh_accumulate(j->ndirs, j->Y, nc, set == 0 ? f : fF, acc);
                float *out = j->sh + (size_t)i * j->stride + (size_t)(set * j->channels + c) * nc;
                for (int k = 0; k < nc; k++) out[k] = (float)(acc[k] * scale);
            }
        }
    }
    lu_free(f);
}

/* Spreads the low 10 bits of x to every third bit. */
static uint32_t morton_spread(uint32_t x) {
    x &= 0x3ff;
    x = (x | (x << 16)) & 0x030000ff;
    x = (x | (x << 8)) & 0x0300f00f;
    x = (x | (x << 4)) & 0x030c30c3;
    x = (x | (x << 2)) & 0x09249249;
    return x;
}

static int cmp_u64(const void *a, const void *b) {
    uint64_t x = *(const uint64_t *)a, y = *(const uint64_t *)b;
    return (x > y) - (x < y);
}

/* Reorders the samples along a Morton curve over box [lo, lo + ext]: dart
 * throwing leaves them in random order, and every later stage (ray casts per
 * direction, neighbour sums of the fit, the renderer's tiles) reads
 * neighbours together. */
static lu_result sort_samples(float *pts, float *rad, int count, lu_vec3 lo, lu_vec3 ext, lu_error *err) {
    uint64_t *key = lu_malloc((size_t)count * sizeof *key);
    float *tmp = lu_malloc((size_t)count * 4 * sizeof *tmp);
    if (!key || !tmp) {
        lu_free(key), lu_free(tmp);
        return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory sorting %d samples", count);
    }
    float e = fmaxf(lu_v3_maxc(ext), 1e-30f);
    for (int i = 0; i < count; i++) {
        uint32_t m = 0;
        for (int a = 0; a < 3; a++) {
            float u = (pts[3 * i + a] - lu_v3_get(lo, a)) / e * 1024.0f;
            uint32_t q = u <= 0.0f ? 0u : (u >= 1023.0f ? 1023u : (uint32_t)u);
            m |= morton_spread(q) << a;
        }
        key[i] = (uint64_t)m << 32 | (uint32_t)i;
    }
    qsort(key, (size_t)count, sizeof *key, cmp_u64);
    memcpy(tmp, pts, (size_t)count * 3 * sizeof *tmp);
    memcpy(tmp + (size_t)count * 3, rad, (size_t)count * sizeof *tmp);
    for (int k = 0; k < count; k++) {
        int i = (int)(uint32_t)key[k];
        memcpy(pts + 3 * (size_t)k, tmp + 3 * (size_t)i, 3 * sizeof *pts);
        rad[k] = tmp[(size_t)count * 3 + i];
    }
    lu_free(key);
    lu_free(tmp);
    return LU_OK;
}

/* The k-th smallest of a[0 .. n) (0-based), which it partially reorders:
 * afterwards a[0 .. k) holds values <= it (quickselect, Hoare partition). */
static float select_kth(float *a, int n, int k) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        float pivot = a[lo + (hi - lo) / 2];
        int i = lo, j = hi;
        while (i <= j) {
            while (a[i] < pivot) i++;
            while (a[j] > pivot) j--;
            if (i <= j) {
                float t = a[i];
                a[i] = a[j];
                a[j] = t;
                i++;
                j--;
            }
        }
        if (k <= j) hi = j;
        else if (k >= i) lo = i;
        else break;
    }
    return a[k];
}

static bool grey(lu_vec3 v) { return v.x == v.y && v.y == v.z; }

/* Samples of medium m (target n_target) appended to out. */
static lu_result compute_medium(const lu_scene *scene, int mi, const lu_accel *opaque, const lu_ddod_params *p,
                                const lu_vec3 *dirs, int n_target, lu_ddod_set *out, lu_error *err) {
    const lu_medium *m = &scene->media[mi];
    lu_accel *boundary = NULL;
    lu_result r = lu_mesh_accel_build(&m->boundary, &boundary, err);
    vgrid g;
    memset(&g, 0, sizeof g);
    float *T = NULL, *radius = NULL, *pts = NULL, *rad = NULL, *tau = NULL, *ft = NULL;
    psi_job pj;
    memset(&pj, 0, sizeof pj);
    int threads = lu_thread_count();
    lu_vec3 sigma_t = lu_v3_add(m->sigma_a, m->sigma_s);

    /* 1 + 2: optical depth sweeps and the first moment. T only steers the
     * sample density (through rho), and as an integral over the sphere it is
     * smooth in the direction: it is summed over a spherical-Fibonacci set
     * of min(n, DDOD_MOMENT_DIRS) directions, a quadrature of the same
     * integral with fewer nodes (docs/ddod.md: the image error does not
     * change against all n). */
    double t0 = lu_time_seconds(), c0 = cpu_seconds();
    if (r == LU_OK) r = vgrid_build(&g, m, boundary, opaque, p->res, err);
    double c0g = cpu_seconds();
    int md = p->dirs < DDOD_MOMENT_DIRS ? p->dirs : DDOD_MOMENT_DIRS;
    lu_vec3 *mdirs = NULL;
    if (r == LU_OK && !(T = lu_calloc(g.count * 3, sizeof *T))) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    if (r == LU_OK && !(mdirs = lu_malloc((size_t)md * sizeof *mdirs))) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    if (r == LU_OK) {
        lu_ddod_directions(md, mdirs);
        r = first_moment(&g, mdirs, md, lu_v3_avg(sigma_t), T, err);
    }
    lu_free(mdirs);
    double t1 = lu_time_seconds(), c1 = cpu_seconds();

    /* divergence -> local radius */
    int cnt = 0;
    double volume = 0.0;
    if (r == LU_OK && !(radius = lu_calloc(g.count, sizeof *radius))) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    float *inv = NULL;
    if (r == LU_OK && !(inv = lu_malloc(g.count * sizeof *inv))) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    if (r == LU_OK) {
        float h2 = 2.0f * g.h;
        for (int z = 0; z < g.n[2]; z++)
            for (int y = 0; y < g.n[1]; y++)
                for (int x = 0; x < g.n[0]; x++) {
                    size_t v = vidx(&g, x, y, z);
                    bool ok = g.inside[v] > 0.0f && g.density[v] > 0.0f && !(g.blocked && g.blocked[v] >= 1.0f);
                    inv[v] = -1.0f;
                    if (!ok) continue;
                    volume += (double)g.inside[v] * g.h * g.h * g.h;
                    /* central differences (one-sided at the grid's edge) */
                    float div = 0.0f;
                    int c3[3] = {x, y, z};
                    for (int a = 0; a < 3; a++) {
                        int lo[3] = {x, y, z}, hi[3] = {x, y, z};
                        lo[a] = c3[a] > 0 ? c3[a] - 1 : c3[a];
                        hi[a] = c3[a] < g.n[a] - 1 ? c3[a] + 1 : c3[a];
                        float span = (float)(hi[a] - lo[a]) * g.h;
                        div += (T[a * g.count + vidx(&g, hi[0], hi[1], hi[2])] - T[a * g.count + vidx(&g, lo[0], lo[1], lo[2])]) /
                               (span > 0.0f ? span : h2);
                    }
                    float rho = fabsf(div);
                    inv[v] = 1.0f / fmaxf(rho, 1e-12f);
                    cnt++;
                }
    }
    double t2 = lu_time_seconds(), c2 = cpu_seconds();
    if (r == LU_OK && cnt == 0) r = lu_fail(err, LU_ERR_INVALID_ARG, "ddod: medium %d has no density inside its boundary", mi);

    /* 3: 1/rho mapped linearly into [r/2, 2r] between its 2nd and 98th
     * percentiles (a few voxels at corners and in empty pockets would
     * otherwise squash the map), then one common scale for the count. */
    int count = 0;
    if (r == LU_OK) {
        float *sorted = lu_malloc((size_t)cnt * sizeof *sorted);
        if (!sorted) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
        if (r == LU_OK) {
            int k = 0;
            for (size_t v = 0; v < g.count; v++)
                if (inv[v] >= 0.0f) sorted[k++] = inv[v];
            int klo = (int)(0.02 * (cnt - 1)), khi = (int)(0.98 * (cnt - 1));
            float hi = select_kth(sorted, cnt, khi);
            float lo = select_kth(sorted, khi, klo); /* the first khi now hold the smaller values */
            lu_free(sorted);
            float base = (float)cbrt(volume / (2.0 * n_target));
            for (size_t v = 0; v < g.count; v++) {
                if (inv[v] < 0.0f) continue;
                float t = hi > lo ? (fminf(fmaxf(inv[v], lo), hi) - lo) / (hi - lo) : 0.5f;
                radius[v] = base * (0.5f + 1.5f * t);
            }
            lu_ddod_field f = {{g.n[0], g.n[1], g.n[2]}, g.lo, g.h, radius};
            valid_ctx vc = {m, boundary, opaque, &g};
            lu_ddod_valid pv = {sample_valid, &vc};
            /* Dart throwing with 8 candidates per target point lands about
             * 1.8 N_s points at scale 1 (measured), hence cbrt(1.8) to start. */
            float scale = 1.21f;
            int candidates = 8 * n_target;
            lu_ddod_darts darts;
            r = lu_ddod_darts_draw(&f, candidates, p->seed + (uint32_t)mi * 7919u, &darts, err);
            for (int it = 0; it < 8 && r == LU_OK; it++) {
                lu_free(pts);
                lu_free(rad);
                r = lu_ddod_darts_throw(&f, &darts, scale, &pv, &pts, &rad, &count, err);
                if (r != LU_OK || count == 0) break;
                double ratio = (double)count / n_target;
                lu_log_msg(LU_LOG_DEBUG, "ddod: sampling pass %d: scale %.4f, %d samples\n", it, scale, count);
                if (fabs(ratio - 1.0) <= 0.05) break;
                scale *= (float)cbrt(ratio);
            }
            lu_ddod_darts_free(&darts);
            if (r == LU_OK && count == 0) r = lu_fail(err, LU_ERR_INVALID_ARG, "ddod: medium %d: no sample fits", mi);
            if (r == LU_OK)
                r = sort_samples(pts, rad, count, g.lo,
                                 lu_v3((float)g.n[0] * g.h, (float)g.n[1] * g.h, (float)g.n[2] * g.h), err);
        }
    }
    lu_free(inv);
    double t3 = lu_time_seconds(), c3 = cpu_seconds();

    /* 4: attenuation per sample and direction, then SH */
    if (r == LU_OK) {
        tau = lu_malloc((size_t)count * p->dirs * sizeof *tau);
        ft = lu_malloc((size_t)count * p->dirs * sizeof *ft);
        pj.vol = lu_calloc((size_t)threads, sizeof *pj.vol);
        pj.scratch = lu_calloc((size_t)threads * 2, sizeof *pj.scratch);
        if (!tau || !ft || !pj.vol || !pj.scratch) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
        bool grid = m->kind == LU_DENSITY_GRID;
        for (int t = 0; grid && r == LU_OK && t < threads; t++) {
            pj.vol[t] = lu_malloc(g.count * sizeof(float));
            pj.scratch[2 * t] = lu_malloc(max_slice(&g) * sizeof(float));
            pj.scratch[2 * t + 1] = lu_malloc(max_slice(&g) * sizeof(float));
            if (!pj.vol[t] || !pj.scratch[2 * t] || !pj.scratch[2 * t + 1])
                r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for per-thread sweeps");
        }
    }
    if (r == LU_OK) {
        pj.g = &g;
        pj.m = m;
        pj.boundary = boundary;
        pj.opaque = opaque;
        pj.dirs = dirs;
        pj.ndirs = p->dirs;
        pj.pts = pts;
        pj.count = count;
        pj.tau = tau;
        pj.ft = ft;
        atomic_init(&pj.failed, 0);
        lu_parallel_for(p->dirs, 1, psi_dirs, &pj, "ddod: sample optical depth");
        if (atomic_load(&pj.failed)) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory in ray queries");
    }
    double t4 = lu_time_seconds(), fit_s = 0.0, c4 = cpu_seconds(), fit_c = 0.0;
    if (r == LU_OK) {
        int base = out->count;
        size_t total = (size_t)base + count;
        float *ns = lu_realloc(out->samples, total * LU_K_DDOD_SAMPLE_FLOATS * sizeof *ns);
        if (ns) out->samples = ns;
        float *nh = ns ? lu_realloc(out->sh, total * out->stride * sizeof *nh) : NULL;
        if (nh) out->sh = nh;
        if (!ns || !nh) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for %zu samples", total);
        if (r == LU_OK) {
            /* Amplitudes: each sample stands for a share of the volume
             * proportional to its radius cubed. */
            double sum_r3 = 0.0;
            for (int i = 0; i < count; i++) sum_r3 += (double)rad[i] * rad[i] * rad[i];
            for (int i = 0; i < count; i++) {
                float *s = out->samples + (size_t)(base + i) * LU_K_DDOD_SAMPLE_FLOATS;
                lu_vec3 b = lu_v3(pts[3 * i], pts[3 * i + 1], pts[3 * i + 2]);
                float sd = p->width * rad[i];
                double vol_i = volume * (double)rad[i] * rad[i] * rad[i] / sum_r3;
                s[LU_K_DDOD_SAMPLE_X] = b.x;
                s[LU_K_DDOD_SAMPLE_X + 1] = b.y;
                s[LU_K_DDOD_SAMPLE_X + 2] = b.z;
                s[LU_K_DDOD_SAMPLE_S] = sd;
                s[LU_K_DDOD_SAMPLE_DENSITY] = medium_density(m, b);
                s[LU_K_DDOD_SAMPLE_AMP] = (float)(vol_i / (pow(2.0 * M_PI, 1.5) * (double)sd * sd * sd));
                s[LU_K_DDOD_SAMPLE_MEDIUM] = (float)mi;
                s[7] = 0.0f;
            }
            double tf = lu_time_seconds(), cf = cpu_seconds();
            r = fit_partition(out->samples + (size_t)base * LU_K_DDOD_SAMPLE_FLOATS, count, p->fit, err);
            fit_s = lu_time_seconds() - tf;
            fit_c = cpu_seconds() - cf;
            out->timing.sampling_s += fit_s;
            int nc = out->bands * out->bands;
            float *Y = r == LU_OK ? lu_malloc((size_t)p->dirs * nc * sizeof *Y) : NULL;
            if (r == LU_OK && !Y) r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory for the SH table");
            for (int d = 0; r == LU_OK && d < p->dirs; d++) {
                float y[LU_SH_MAX_COEFFS];
                lu_k_sh_eval(dirs[d], out->bands, y);
                memcpy(Y + (size_t)d * nc, y, (size_t)nc * sizeof *y);
            }
            sh_job sj = {Y, p->dirs, out->bands, out->channels, out->stride, count, sigma_t, tau, ft,
                         out->sh + (size_t)base * out->stride, 0};
            if (r == LU_OK) lu_parallel_for(count, 0, sh_samples, &sj, NULL);
            if (r == LU_OK && atomic_load(&sj.failed))
                r = lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory in the SH projection");
            lu_free(Y);
            out->count = (int)total;
        }
    }
    double t5 = lu_time_seconds() - fit_s, c5 = cpu_seconds() - fit_c;
    lu_log_msg(LU_LOG_DEBUG,
                "ddod: medium %d processor s: voxel grid %.2f, moment sweeps %.2f, divergence %.2f, sampling %.2f, sample attenuation "
                "%.2f, fit %.2f, SH %.2f\n",
                mi, c0g - c0, c1 - c0g, c2 - c1, c3 - c2, c4 - c3, fit_c, c5 - c4);
    out->timing.optical_depth_s += (t1 - t0) + (t4 - t3);
    out->timing.divergence_s += t2 - t1;
    out->timing.sampling_s += t3 - t2;
    out->timing.sh_s += t5 - t4;

    for (int t = 0; pj.vol && t < threads; t++) lu_free(pj.vol[t]);
    for (int t = 0; pj.scratch && t < 2 * threads; t++) lu_free(pj.scratch[t]);
    lu_free(pj.vol);
    lu_free(pj.scratch);
    lu_free(tau);
    lu_free(ft);
    lu_free(pts);
    lu_free(rad);
    lu_free(radius);
    lu_free(T);
    vgrid_free(&g);
    if (boundary) lu_accel_destroy(boundary);
    return r;
}

lu_result lu_ddod_compute(const lu_scene *scene, const lu_ddod_params *p, lu_ddod_set *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    if (scene->medium_count == 0) return lu_fail(err, LU_ERR_INVALID_ARG, "ddod: the scene has no medium");
    bool all_grey = true;
    double total_volume = 0.0;
    for (int m = 0; m < scene->medium_count; m++) {
        const lu_medium *med = &scene->media[m];
        if (!med->has_boundary)
            return lu_fail(err, LU_ERR_UNSUPPORTED,
                           "ddod: medium %d has no boundary mesh (ddod renders translucent objects: media inside a "
                           "closed mesh)",
                           m);
        all_grey = all_grey && grey(lu_v3_add(med->sigma_a, med->sigma_s));
        lu_aabb b = lu_mesh_bounds(&med->boundary);
        lu_vec3 e = lu_v3_sub(b.hi, b.lo);
        total_volume += (double)e.x * e.y * e.z;
    }
    out->bands = p->bands;
    out->channels = all_grey ? 1 : 3;
    out->stride = 2 * out->channels * p->bands * p->bands;
    double t0 = lu_time_seconds(), c0 = cpu_seconds();
    lu_vec3 *dirs = lu_malloc((size_t)p->dirs * sizeof *dirs);
    if (!dirs) return lu_fail(err, LU_ERR_NOMEM, "ddod: out of memory");
    lu_ddod_directions(p->dirs, dirs);
    /* Opaque objects block: they join the optical depth as infinite. */
    lu_accel *opaque = NULL;
    int *object_of = NULL;
    lu_result r = lu_opaque_accel_build(scene, &opaque, &object_of, err);
    lu_free(object_of);
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        lu_aabb b = lu_mesh_bounds(&scene->media[m].boundary);
        lu_vec3 e = lu_v3_sub(b.hi, b.lo);
        int target = (int)lround(p->samples * ((double)e.x * e.y * e.z / total_volume));
        r = compute_medium(scene, m, opaque, p, dirs, target > 16 ? target : 16, out, err);
    }
    if (opaque) lu_accel_destroy(opaque);
    lu_free(dirs);
    out->timing.total_s = lu_time_seconds() - t0;
    out->timing.cpu_s = cpu_seconds() - c0;
    if (r != LU_OK) lu_ddod_set_free(out);
    return r;
}

void lu_ddod_set_free(lu_ddod_set *s) {
    lu_free(s->samples);
    lu_free(s->sh);
    memset(s, 0, sizeof *s);
}
