/* Procedural density grids (the list and defaults are in grid.h).
 *
 * Common to all: the world box centred at `center` with extent `size`;
 * `resolution` N (longest side, others in proportion, at least 1) or
 * [nx, ny, nz]; voxel size per axis h_i = size_i / n_i so the box is exact;
 * voxel centres at lo + (i + 0.5) h. Lengths (radius, sigma, ...) are world
 * units, noise `frequency` is in cycles per world unit. Every voxel is
 * computed on its own from its centre, so the result is the same for any
 * thread count. Densities are >= 0 and finite (checked before returning).
 * Shapes with hard edges (sphere, torus, layers) are anti-aliased so their
 * voxel sums match the continuous volumes (see each generator). */
#include <lucent/grid.h>

#include <math.h>
#include <stdio.h>
#include <string.h>

#include "core/rng.h"
#include "lu_noise.h"

#define MAX_RES 4096
#define MAX_VALUE 1e6
#define MAX_LENGTH 1e6
#define MAX_FREQ 1e4
#define MAX_GAUSSIANS 4096

typedef struct gauss { double c[3], inv2s2, amp; } gauss;

typedef struct gen {
    int kind;
    double center[3], size[3], lo[3], h[3], hmin;
    /* parameters (meaning depends on kind) */
    double value, radius, r2, low, high, bottom, top, noise, freq, gain, coverage;
    double rise, time;   /* smoke_plume: advection speed (world units per second) and time */
    int octaves, layers, axis, count;
    uint32_t seed;
    gauss *g;
    lu_grid *grid;
} gen;

enum { K_UNIFORM, K_SPHERE, K_GAUSSIANS, K_FBM, K_LAYERED, K_TORUS, K_DUSTY, K_PLUME, K_COUNT };

static const char *const kind_names[K_COUNT] = {"uniform_box",  "sphere",        "gaussians",  "fbm_cloud",
                                                "layered_cube", "torus_in_cube", "dusty_room", "smoke_plume"};

static double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }
static double smoothstep(double a, double b, double x) {
    double t = clamp01((x - a) / (b - a));
    return t * t * (3.0 - 2.0 * t);
}


/* Layered cube: average of the piecewise-constant layer profile over the
 * voxel's extent along the axis (exact box filter), via its antiderivative
 * in layer units u: layers [0,1) low, [1,2) high, ... */
static double layer_cdf(const gen *G, double u) {
    if (u <= 0.0) return 0.0;
    if (u >= G->layers) u = G->layers;
    double k = floor(u);
    double even = floor((k + 1.0) / 2.0), odd = floor(k / 2.0);
    double cur = fmod(k, 2.0) == 0.0 ? G->low : G->high;
    return even * G->low + odd * G->high + (u - k) * (k < G->layers ? cur : 0.0);
}

/* smoke_plume: a column rising from the floor centre, widening with height,
 * its axis meandering and its density broken up by fBm. The centreline
 * density falls as R0/R: the plume thins as it entrains air.
 * Animated (rise > 0): the flow carries the turbulence up the column by
 * rise * time, and the meander of the axis travels up with it as a wave
 * whose shape drifts slowly (its third noise coordinate), so time 0 is the
 * still plume and every time is a pure function of rise * time.
 * What depends on the height alone is computed once per row of voxels
 * (plume_row_at): the same operations, so the same bits, as per voxel. */
typedef struct plume_row { double s, w, adv, sway, swaz, R, vertical, f; } plume_row;

static void plume_row_at(const gen *G, double y, plume_row *r) {
    r->s = clamp01((y - G->lo[1]) / G->size[1]);
    r->w = fmin(G->size[0], G->size[2]);
    r->adv = G->rise * G->time;
    double a = r->adv / G->size[1], s = r->s, w = r->w;
    r->sway = 0.08 * w * lu_fbm3(1.7 * (s - a), 0.0, 0.5 * a, 2, 0.5, G->seed ^ 0x51u);
    r->swaz = 0.08 * w * lu_fbm3(0.5 * a, 1.7 * (s - a), 0.0, 2, 0.5, G->seed ^ 0xa3u);
    r->R = w * (0.05 + 0.2 * s);
    r->vertical = smoothstep(0.0, 0.04, s) * (0.05 / (0.05 + 0.2 * s)) * (1.0 - smoothstep(0.85, 1.0, s));
    r->f = 4.0 / w;
}

static double plume_at(const gen *G, const plume_row *r, double x, double y, double z) {
    double dx = x - G->center[0], dz = z - G->center[2];
    double ex = dx - r->sway, ez = dz - r->swaz;
    double radial = exp(-(ex * ex + ez * ez) / (r->R * r->R));
    double turb = 0.6 + 0.9 * lu_fbm3(x * r->f, (y - G->lo[1] - r->adv) * r->f - 0.7, z * r->f, 4, 0.55, G->seed);
    return 2.0 * radial * r->vertical * fmax(0.0, turb);
}

static double density(const gen *G, double x, double y, double z) {
    double dx = x - G->center[0], dy = y - G->center[1], dz = z - G->center[2];
    switch (G->kind) {
    case K_UNIFORM:
        return G->value;
    case K_SPHERE: {
        /* Linear ramp one voxel wide across the surface: the continuous
         * integral is (4/3) pi r^3 + pi r h^2 / 3, i.e. relative excess h^2/(4r^2). */
        double d = sqrt(dx * dx + dy * dy + dz * dz);
        return G->value * clamp01(0.5 - (d - G->radius) / G->hmin);
    }
    case K_GAUSSIANS: {
        double s = 0.0;
        for (int i = 0; i < G->count; i++) {
            const gauss *q = &G->g[i];
            double ex = x - q->c[0], ey = y - q->c[1], ez = z - q->c[2];
            s += q->amp * exp(-(ex * ex + ey * ey + ez * ez) * q->inv2s2);
        }
        return s;
    }
    case K_FBM: {
        /* Noise thresholded so about `coverage` of the ball holds cloud,
         * times a falloff 1 - (r/R)^2 that reaches 0 at the radius. fBm is
         * doubled first (its standard deviation is only ~0.16 at 5 octaves)
         * so the densest parts approach 1. */
        double r2 = (dx * dx + dy * dy + dz * dz) / G->r2;
        if (r2 >= 1.0 || G->coverage <= 0.0) return 0.0;
        double f = 2.0 * lu_fbm3(dx * G->freq, dy * G->freq, dz * G->freq, G->octaves, G->gain, G->seed);
        double n = 0.5 + 0.5 * (f > 1.0 ? 1.0 : (f < -1.0 ? -1.0 : f));
        return fmax(0.0, n - (1.0 - G->coverage)) / G->coverage * (1.0 - r2);
    }
    case K_LAYERED: {
        int a = G->axis;
        double p = a == 0 ? x : (a == 1 ? y : z);
        double scale = G->layers / G->size[a];
        double u0 = (p - 0.5 * G->h[a] - G->lo[a]) * scale, u1 = (p + 0.5 * G->h[a] - G->lo[a]) * scale;
        return (layer_cdf(G, u1) - layer_cdf(G, u0)) / (u1 - u0);
    }
    case K_TORUS: {
        /* Torus around the y axis through the centre; the density is 0
         * inside it (an opaque object there) with a one-voxel ramp. */
        double q = sqrt(dx * dx + dz * dz) - G->radius;
        double sdf = sqrt(q * q + dy * dy) - G->low;
        return G->value * clamp01(0.5 + sdf / G->hmin);
    }
    case K_DUSTY: {
        /* Linear from `bottom` at the floor (box lo.y) to `top` at the
         * ceiling, plus `noise` times 3-octave fBm. */
        double t = (y - G->lo[1]) / G->size[1];
        double base = G->bottom + (G->top - G->bottom) * t;
        double n = lu_fbm3(x * G->freq, y * G->freq, z * G->freq, 3, 0.5, G->seed);
        return fmax(0.0, base + G->noise * n);
    }
    case K_PLUME: {
        plume_row r;
        plume_row_at(G, y, &r);
        return plume_at(G, &r, x, y, z);
    }
    }
    return 0.0;
}

static void fill_rows(void *ctx, int64_t begin, int64_t end, int thread_index) {
    (void)thread_index;
    const gen *G = ctx;
    lu_grid *g = G->grid;
    for (int64_t row = begin; row < end; row++) {
        int j = (int)(row % g->ny), k = (int)(row / g->ny);
        double y = G->lo[1] + (j + 0.5) * G->h[1], z = G->lo[2] + (k + 0.5) * G->h[2];
        float *dst = g->data + (size_t)row * (size_t)g->nx;
        if (G->kind == K_PLUME) {
            plume_row r;
            plume_row_at(G, y, &r);
            for (int i = 0; i < g->nx; i++) dst[i] = (float)plume_at(G, &r, G->lo[0] + (i + 0.5) * G->h[0], y, z);
            continue;
        }
        for (int i = 0; i < g->nx; i++) dst[i] = (float)density(G, G->lo[0] + (i + 0.5) * G->h[0], y, z);
    }
}

/* ---- parameters ------------------------------------------------------------ */

static lu_result kv_int(const lu_kvlist *p, const char *key, double def, double lo, double hi, int64_t *out,
                        const char *where, lu_error *err) {
    double v;
    lu_result r = lu_kv_number(p, key, def, lo, hi, &v, where, err);
    if (r != LU_OK) return r;
    if (v != floor(v)) return lu_fail(err, LU_ERR_RANGE, "%s: \"%s\" = %g must be a whole number", where, key, v);
    *out = (int64_t)v;
    return LU_OK;
}

static lu_result kv_seed(const lu_kvlist *p, gen *G, const char *where, lu_error *err) {
    int64_t s = 1;
    lu_result r = kv_int(p, "seed", 1, 0, 4294967295.0, &s, where, err);
    G->seed = (uint32_t)s;
    return r;
}

static lu_result parse_box(const lu_kvlist *p, gen *G, int dims[3], const char *where, lu_error *err) {
    static const double zero[3] = {0, 0, 0}, two[3] = {2, 2, 2};
    lu_result r = lu_kv_vec3(p, "center", zero, G->center, where, err);
    if (r == LU_OK) r = lu_kv_vec3(p, "size", two, G->size, where, err);
    if (r != LU_OK) return r;
    for (int i = 0; i < 3; i++) {
        if (!isfinite(G->center[i]) || fabs(G->center[i]) > MAX_LENGTH)
            return lu_fail(err, LU_ERR_RANGE, "%s: \"center\" component %d = %g is outside [-%g, %g]", where, i,
                           G->center[i], MAX_LENGTH, MAX_LENGTH);
        if (!(G->size[i] > 0.0 && G->size[i] <= MAX_LENGTH))
            return lu_fail(err, LU_ERR_RANGE, "%s: \"size\" component %d = %g is outside (0, %g]", where, i,
                           G->size[i], MAX_LENGTH);
    }
    const lu_kv *res = lu_kv_find(p, "resolution");
    double n[3];
    if (!res) {
        n[0] = 64;
    } else if (res->count == 1 || res->count == 3) {
        for (int i = 0; i < res->count; i++) {
            n[i] = res->v[i];
            if (!(n[i] >= 1 && n[i] <= MAX_RES) || n[i] != floor(n[i]))
                return lu_fail(err, LU_ERR_RANGE, "%s: \"resolution\" %g must be a whole number in [1, %d]", where,
                               n[i], MAX_RES);
        }
    } else {
        return lu_fail(err, LU_ERR_SCENE, "%s: \"resolution\" must be a number or 3 numbers", where);
    }
    if (!res || res->count == 1) {
        double longest = fmax(G->size[0], fmax(G->size[1], G->size[2]));
        double N = n[0];
        for (int i = 0; i < 3; i++) n[i] = fmax(1.0, floor(N * G->size[i] / longest + 0.5));
    }
#ifdef FUZZING_BUILD_MODE_UNSAFE_FOR_PRODUCTION
    /* the fuzzer is after the parser, not the generator's full resolution */
    for (int i = 0; i < 3; i++) n[i] = fmin(n[i], 16.0);
#endif
    G->hmin = INFINITY;
    for (int i = 0; i < 3; i++) {
        dims[i] = (int)n[i];
        G->h[i] = G->size[i] / n[i];
        G->lo[i] = G->center[i] - 0.5 * G->size[i];
        G->hmin = fmin(G->hmin, G->h[i]);
    }
    return LU_OK;
}

static lu_result parse_params(const lu_kvlist *p, gen *G, const char *where, lu_error *err) {
    lu_result r = LU_OK;
    int64_t iv = 0;
#define NUM(key, def, lo, hi, dst)                                      \
    do {                                                                \
        if (r == LU_OK) r = lu_kv_number(p, key, def, lo, hi, &(dst), where, err); \
    } while (0)
    switch (G->kind) {
    case K_UNIFORM:
        NUM("value", 1, 0, MAX_VALUE, G->value);
        break;
    case K_SPHERE:
        NUM("radius", 0.8, 1e-9, MAX_LENGTH, G->radius);
        NUM("value", 1, 0, MAX_VALUE, G->value);
        break;
    case K_GAUSSIANS: {
        r = kv_int(p, "count", 8, 0, MAX_GAUSSIANS, &iv, where, err);
        G->count = (int)iv;
        if (r == LU_OK) r = kv_seed(p, G, where, err);
        NUM("amplitude", 1, 0, MAX_VALUE, G->value);
        if (r != LU_OK) break;
        const lu_kv *s = lu_kv_find(p, "sigma");
        G->low = 0.1;
        G->high = 0.3;
        if (s) {
            if (s->count != 1 && s->count != 2)
                return lu_fail(err, LU_ERR_SCENE, "%s: \"sigma\" must be a number or [min, max]", where);
            G->low = s->v[0];
            G->high = s->count == 2 ? s->v[1] : s->v[0];
            if (!(G->low > 0.0 && G->low <= G->high && G->high <= MAX_LENGTH))
                return lu_fail(err, LU_ERR_RANGE, "%s: \"sigma\" [%g, %g] must satisfy 0 < min <= max <= %g", where,
                               G->low, G->high, MAX_LENGTH);
        }
        break;
    }
    case K_FBM:
        r = kv_int(p, "octaves", 5, 1, 16, &iv, where, err);
        G->octaves = (int)iv;
        NUM("frequency", 2, 1e-9, MAX_FREQ, G->freq);
        NUM("gain", 0.5, 0, 1, G->gain);
        if (r == LU_OK) r = kv_seed(p, G, where, err);
        NUM("radius", 0.9, 1e-9, MAX_LENGTH, G->radius);
        NUM("coverage", 0.5, 0, 1, G->coverage);
        G->r2 = G->radius * G->radius;
        break;
    case K_LAYERED:
        r = kv_int(p, "layers", 6, 1, MAX_RES, &iv, where, err);
        G->layers = (int)iv;
        NUM("low", 0.2, 0, MAX_VALUE, G->low);
        NUM("high", 1, 0, MAX_VALUE, G->high);
        if (r == LU_OK) r = kv_int(p, "axis", 1, 0, 2, &iv, where, err);
        G->axis = (int)iv;
        break;
    case K_TORUS:
        NUM("value", 1, 0, MAX_VALUE, G->value);
        NUM("major_radius", 0.5, 1e-9, MAX_LENGTH, G->radius);
        NUM("minor_radius", 0.18, 1e-9, MAX_LENGTH, G->low); /* stored in `low` */
        break;
    case K_DUSTY:
        NUM("bottom", 0.6, 0, MAX_VALUE, G->bottom);
        NUM("top", 0.3, 0, MAX_VALUE, G->top);
        NUM("noise", 0.15, 0, MAX_VALUE, G->noise);
        NUM("frequency", 3, 1e-9, MAX_FREQ, G->freq);
        if (r == LU_OK) r = kv_seed(p, G, where, err);
        break;
    case K_PLUME:
        r = kv_seed(p, G, where, err);
        NUM("rise", 0, 0, MAX_LENGTH, G->rise);
        NUM("time", 0, -1e6, 1e6, G->time);
        break;
    }
#undef NUM
    return r;
}

lu_result lu_grid_procedural(const char *name, const lu_kvlist *params, lu_grid *g, const char *where,
                             lu_error *err) {
    static const char *const known[K_COUNT][12] = {
        {"center", "size", "resolution", "value", NULL},
        {"center", "size", "resolution", "radius", "value", NULL},
        {"center", "size", "resolution", "count", "seed", "sigma", "amplitude", NULL},
        {"center", "size", "resolution", "octaves", "frequency", "gain", "seed", "radius", "coverage", NULL},
        {"center", "size", "resolution", "layers", "low", "high", "axis", NULL},
        {"center", "size", "resolution", "value", "major_radius", "minor_radius", NULL},
        {"center", "size", "resolution", "bottom", "top", "noise", "frequency", "seed", NULL},
        {"center", "size", "resolution", "seed", "rise", "time", NULL},
    };
    memset(g, 0, sizeof *g);
    if (!where) where = "procedural";
    gen G;
    memset(&G, 0, sizeof G);
    G.kind = -1;
    for (int k = 0; k < K_COUNT; k++)
        if (name && strcmp(name, kind_names[k]) == 0) G.kind = k;
    if (G.kind < 0) {
        char list[256] = "";
        size_t used = 0;
        for (int k = 0; k < K_COUNT; k++)
            used += (size_t)snprintf(list + used, sizeof list - used, "%s%s", k ? ", " : "", kind_names[k]);
        return lu_fail(err, LU_ERR_SCENE, "%s: unknown procedural generator \"%.80s\" (known: %s)", where,
                       name ? name : "(null)", list);
    }
    lu_result r = lu_kv_check_known(params, known[G.kind], where, err);
    int dims[3];
    if (r == LU_OK) r = parse_box(params, &G, dims, where, err);
    if (r == LU_OK) r = parse_params(params, &G, where, err);
    if (r != LU_OK) return r;

    gauss gs[MAX_GAUSSIANS];
    if (G.kind == K_GAUSSIANS) {
        /* Centres uniform in the middle 70 % of the box, sigmas uniform in
         * [min, max], every peak `amplitude`. */
        uint64_t state = G.seed;
        for (int i = 0; i < G.count; i++) {
            for (int a = 0; a < 3; a++) gs[i].c[a] = G.lo[a] + G.size[a] * (0.15 + 0.7 * lu_rng_unit(&state));
            double s = G.low + (G.high - G.low) * lu_rng_unit(&state);
            gs[i].inv2s2 = 1.0 / (2.0 * s * s);
            gs[i].amp = G.value;
        }
        G.g = gs;
    }

    lu_error aerr;
    r = lu_grid_alloc(g, dims[0], dims[1], dims[2], &aerr);
    if (r != LU_OK) return lu_fail(err, r, "%s: %s", where, aerr.message);
    G.grid = g;
    lu_parallel_for((int64_t)g->ny * g->nz, 0, fill_rows, &G, NULL);

    size_t n = (size_t)g->nx * (size_t)g->ny * (size_t)g->nz;
    for (size_t i = 0; i < n; i++) {
        if (!isfinite(g->data[i]) || g->data[i] < 0.0f) {
            lu_grid_destroy(g);
            return lu_fail(err, LU_ERR_NONFINITE, "%s: generator \"%s\" produced an invalid density", where, name);
        }
    }
    g->index_to_world = lu_affine_identity();
    for (int i = 0; i < 3; i++) {
        g->index_to_world.m[i][i] = (float)G.h[i];
        g->index_to_world.m[i][3] = (float)(G.lo[i] + 0.5 * G.h[i]);
    }
    snprintf(g->name, sizeof g->name, "%s", name);
    lu_grid_update_range(g);
    return LU_OK;
}

bool lu_grid_procedural_animated(const char *name, const lu_kvlist *params) {
    if (!name || strcmp(name, kind_names[K_PLUME]) != 0) return false;
    const lu_kv *rise = lu_kv_find(params, "rise");
    return rise && rise->count == 1 && rise->v[0] != 0.0;
}
