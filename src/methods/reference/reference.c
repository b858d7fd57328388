/* reference — the ground truth for single scattering (docs/architecture.md §1, §2).
 *
 * Per camera ray:
 *   1. the closest opaque hit clips the ray (Embree);
 *   2. each medium's presence along the ray: its bounding box, intersected
 *      with the inside of its boundary mesh (crossing parity from outside);
 *   3. a "track" per medium: the ray's cell pieces through the dual grid,
 *      each with the exact cubic density along it, so optical depth to any t
 *      is exact (lu_march.h);
 *   4. in-scattering by adaptive Simpson over each cell piece, starting from
 *      `steps` sub-intervals per voxel length; at every node an exact
 *      shadow ray per light (cell-exact optical depth through every medium,
 *      Fresnel transmittance at each boundary crossing, opaque visibility);
 *   5. boundary reflection (1 - F_t) * Blinn-Phong at each entry into a
 *      bounded medium, the opaque surface or the background, all attenuated
 *      by the exact camera-ray transmittance.
 * Only the in-scattering quadrature has a step; tests prove it converged. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "methods/frame.h"
#include "methods/methods.h"
#include "methods/common/opaque_accel.h"

/* ---- kernel context: how the shared kernels read density on the CPU ---- */
struct lu_k_ctx {
    const lu_medium *media;
};

static inline float lu_k_density(const struct lu_k_ctx *c, int m, lu_vec3 p) {
    const lu_medium *med = &c->media[m];
    return med->kind == LU_DENSITY_CONSTANT ? med->constant : lu_grid_sample(&med->grid, p);
}

#include "kernels/lu_hash.h"
#include "kernels/lu_camera.h"
#include "methods/common/lu_march.h"
#include "kernels/lu_optics.h"

enum { P_SPP, P_STEPS, P_TOLERANCE, P_MAX_DEPTH, P_ENV_SAMPLES, P_COUNT };

static const lu_param_desc k_params[P_COUNT] = {
    [P_SPP] = {"spp", LU_PARAM_INT, 1, 1, 4096, NULL,
               "samples per pixel (1 = through the pixel centre; more = R2-sequence supersampling)"},
    [P_STEPS] = {"steps", LU_PARAM_FLOAT, 1, 0.25, 64, NULL,
                 "initial Simpson sub-intervals of in-scattering per voxel length (transmittance is exact regardless)"},
    [P_TOLERANCE] = {"tolerance", LU_PARAM_FLOAT, 1e-3, 1e-7, 0.5, NULL,
                     "adaptive Simpson: relative agreement of halved and whole estimates per sub-interval"},
    [P_MAX_DEPTH] = {"max_depth", LU_PARAM_INT, 10, 0, 24, NULL,
                     "adaptive Simpson: most halvings of a sub-interval (shadow edges refine to 2^-depth)"},
    [P_ENV_SAMPLES] = {"env_samples", LU_PARAM_INT, 256, 1, 65536, NULL,
                       "directions per point for environment lights (spherical Fibonacci, rotated per pixel)"},
};

#define MAX_CROSSINGS 256
#define CONSTANT_VOXELS 64.0f /* constant media: a virtual voxel is 1/64 of the box's longest side */

typedef struct crossing {
    float t;
    lu_vec3 ng;            /* unit geometric normal, outward */
} crossing;

typedef struct medium_info {
    lu_accel *boundary;    /* NULL without a boundary mesh */
    lu_aabb parity_box;    /* box of the boundary mesh: rays start counting parity outside it */
    lu_vec3 sigma_t;
    int max_pieces;        /* DDA bound along any ray */
    float voxel_len;       /* world length of one voxel along the longest axis, for step control */
} medium_info;

typedef struct piece {
    float ta, tb;
    lu_k_cubic density;    /* over s in [0, 1] = (t - ta) / (tb - ta) */
    float tau_before;      /* this medium's optical depth from the ray start to ta */
} piece;

typedef struct track {
    piece *pieces;
    int count, capacity;
    float tau_total;
} track;

typedef struct thread_scratch {
    track *tracks;         /* one per medium */
    crossing crossings[MAX_CROSSINGS];
} thread_scratch;

typedef struct ref_state {
    int spp, env_samples, max_depth;
    float steps, tolerance;
    lu_accel *opaque;          /* diffuse objects */
    int *opaque_object;        /* accel mesh id -> object index */
    medium_info *media;
    int medium_count;
    float eps;                 /* ray offset: scene size * 1e-5 */
    thread_scratch *scratch;
    int threads;
    /* Per render: */
    const lu_scene *scene;
    struct lu_k_ctx kctx;
    lu_k_camera cam;
    const lu_k_light *klights;   /* the frame's records: every light in scene order */
    lu_image *out;
    bool overflow;             /* a ray crossed more than MAX_CROSSINGS boundary faces */
    bool nomem;                /* a ray's piece list could not grow (its pixel is then wrong) */
} ref_state;

/* ---- geometry helpers ---------------------------------------------------- */

/* Crossings of the line o + t d with a bounded medium's boundary, counted
 * from outside its mesh box so parity starts "outside"; returns the count of
 * crossings with t in (t_lo, t_hi), and whether the point at t_lo is inside. */
static int boundary_crossings(ref_state *st, const medium_info *mi, lu_vec3 o, lu_vec3 d, float t_lo, float t_hi,
                              crossing *out, bool *inside_at_lo) {
    float b0, b1;
    *inside_at_lo = false;
    if (!lu_aabb_ray(mi->parity_box, o, d, -LU_K_FAR, LU_K_FAR, &b0, &b1)) return 0;
    float margin = 1e-3f * (1.0f + lu_v3_maxc(lu_v3_sub(mi->parity_box.hi, mi->parity_box.lo)));
    float start = b0 - margin;
    if (start > t_lo) start = t_lo;  /* never start inside the queried range */
    lu_vec3 so = lu_v3_madd(o, d, start);
    lu_hit hits[MAX_CROSSINGS];
    float end = fminf(t_hi, b1 + margin);
    if (end <= start) return 0;
    int total = lu_accel_all_hits(mi->boundary, so, d, 0.0f, end - start, hits, MAX_CROSSINGS);
    if (total > MAX_CROSSINGS) {
        st->overflow = true;
        total = MAX_CROSSINGS;
    }
    int n = 0;
    bool inside = false;
    for (int i = 0; i < total; i++) {
        float t = hits[i].t + start;
        if (t <= t_lo) {
            inside = !inside;
            continue;
        }
        if (t >= t_hi) break;
        out[n].t = t;
        out[n].ng = hits[i].ng;
        n++;
    }
    *inside_at_lo = inside;
    return n;
}

/* Intervals of [t_lo, t_hi] where medium m is present; writes pairs into iv
 * (at most max_iv pairs) and returns the pair count. Crossings inside the
 * range are returned too (for Fresnel and reflection). */
static int medium_intervals(ref_state *st, int m, lu_vec3 o, lu_vec3 d, float t_lo, float t_hi, float *iv, int max_iv,
                            crossing *cross, int *ncross) {
    const lu_medium *med = &st->scene->media[m];
    const medium_info *mi = &st->media[m];
    *ncross = 0;
    float b0, b1;
    if (!lu_aabb_ray(med->bounds, o, d, t_lo, t_hi, &b0, &b1)) return 0;
    if (!mi->boundary) {
        iv[0] = b0;
        iv[1] = b1;
        return 1;
    }
    bool inside;
    int n = boundary_crossings(st, mi, o, d, t_lo, t_hi, cross, &inside);
    *ncross = n;
    int count = 0;
    float start = t_lo;
    for (int i = 0; i <= n; i++) {
        float t = i < n ? cross[i].t : t_hi;
        if (inside) {
            float a = fmaxf(start, b0), b = fminf(t, b1);
            if (b > a && count < max_iv) {
                iv[2 * count] = a;
                iv[2 * count + 1] = b;
                count++;
            }
        }
        inside = !inside;
        start = t;
    }
    return count;
}

/* ---- transmittance ------------------------------------------------------- */

static float optical_depth(ref_state *st, int m, lu_vec3 o, lu_vec3 d, float ta, float tb) {
    const lu_medium *med = &st->scene->media[m];
    if (med->kind == LU_DENSITY_CONSTANT) return med->constant * (tb - ta);
    lu_vec3 oi = lu_affine_point(&med->world_to_index, o), di = lu_affine_vector(&med->world_to_index, d);
    return lu_k_optical_depth(&st->kctx, m, oi, di, ta, tb, st->media[m].max_pieces);
}

/* Transmittance from x towards direction w over (0, dist): opaque
 * visibility, every medium's exact optical depth, and F_t at each boundary
 * crossing (light entering a translucent object, docs/architecture.md §1). */
static lu_vec3 transmittance(ref_state *st, thread_scratch *ts, lu_vec3 x, lu_vec3 w, float dist) {
    float tmin = st->eps;
    if (st->opaque && lu_accel_occluded(st->opaque, x, w, tmin, dist)) return lu_v3s(0.0f);
    lu_vec3 tau = lu_v3s(0.0f);
    float ft = 1.0f;
    for (int m = 0; m < st->medium_count; m++) {
        float iv[2 * 32];
        int nc;
        int n = medium_intervals(st, m, x, w, 0.0f, dist, iv, 32, ts->crossings, &nc);
        float od = 0.0f;
        for (int i = 0; i < n; i++) od += optical_depth(st, m, x, w, iv[2 * i], iv[2 * i + 1]);
        tau = lu_v3_madd(tau, st->media[m].sigma_t, od);
        for (int i = 0; i < nc; i++)
            ft *= lu_k_fresnel_transmittance(lu_v3_dot(ts->crossings[i].ng, w), st->scene->media[m].eta);
    }
    return lu_v3_scale(lu_v3_exp(lu_v3_neg(tau)), ft);
}

/* ---- environment ---------------------------------------------------------- */

static lu_vec3 env_radiance(const lu_light *l, lu_vec3 dir) { return lu_env_lookup(&l->env, l->env_scale, dir); }

/* Direction i of n on a spherical Fibonacci lattice, rotated about Y by phi0. */
static lu_vec3 fibonacci_dir(int i, int n, float phi0) {
    float z = 1.0f - (2.0f * (float)i + 1.0f) / (float)n;
    float r = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    float phi = phi0 + (float)i * 2.39996322972865332f; /* golden angle */
    return lu_v3(r * cosf(phi), z, r * sinf(phi));
}

/* ---- lights at a point ----------------------------------------------------- */

/* What multiplies L_env(w) * T(x, w) in an environment integral: the phase
 * function at a medium point, or the BRDF times cosine at a surface point. */
typedef struct env_weight {
    enum { ENV_PHASE, ENV_BRDF } kind;
    lu_vec3 dir;             /* ENV_PHASE: the camera ray direction; ENV_BRDF: wo */
    float g;
    lu_vec3 n;               /* ENV_BRDF: the normal facing the viewer */
    const lu_material *mat;
} env_weight;

/* (4 pi / N) * sum over N spherical-Fibonacci directions w of
 * weight(w) * L_env(w) * T(x, w): a quadrature of the sphere that converges as
 * env_samples grows (tests check it against closed forms). */
static lu_vec3 env_integral(ref_state *st, thread_scratch *ts, const lu_light *light, lu_vec3 x, float phi0,
                            const env_weight *wt) {
    lu_vec3 acc = lu_v3s(0.0f);
    for (int i = 0; i < st->env_samples; i++) {
        lu_vec3 w = fibonacci_dir(i, st->env_samples, phi0);
        lu_vec3 f;
        if (wt->kind == ENV_PHASE) {
            f = lu_v3s(lu_k_phase_hg(lu_v3_dot(wt->dir, w), wt->g));
        } else {
            if (lu_v3_dot(w, wt->n) <= 0.0f) continue;
            f = lu_k_blinn_phong(wt->mat->albedo, wt->mat->specular, wt->mat->shininess, wt->n, wt->dir, w);
        }
        lu_vec3 tr = transmittance(st, ts, x, w, LU_K_FAR);
        if (lu_v3_maxc(tr) <= 0.0f) continue;
        acc = lu_v3_add(acc, lu_v3_mul(lu_v3_mul(f, env_radiance(light, w)), tr));
    }
    return lu_v3_scale(acc, 4.0f * LU_PI / (float)st->env_samples);
}



/* In-scattered radiance towards -d at x in medium m: sum over lights of
 * phase * irradiance * transmittance (sigma_s applied by the caller). */
static lu_vec3 inscatter_source(ref_state *st, thread_scratch *ts, int m, lu_vec3 x, lu_vec3 d, float phi0) {
    const lu_scene *s = st->scene;
    float g = s->media[m].phase_g;
    lu_vec3 sum = lu_v3s(0.0f);
    for (int l = 0; l < s->light_count; l++) {
        const lu_light *light = &s->lights[l];
        if (light->type == LU_LIGHT_ENVIRONMENT) {
            env_weight w = {ENV_PHASE, d, g, lu_v3s(0.0f), NULL};
            sum = lu_v3_add(sum, env_integral(st, ts, light, x, phi0, &w));
            continue;
        }
        lu_k_light_sample ls = lu_k_light_arrive(st->klights[l], x);
        if (lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        lu_vec3 tr = transmittance(st, ts, x, ls.wl, ls.dist);
        float p = lu_k_phase_hg(lu_v3_dot(d, ls.wl), g);
        sum = lu_v3_add(sum, lu_v3_scale(lu_v3_mul(ls.irradiance, tr), p));
    }
    return sum;
}

/* Blinn-Phong radiance towards wo from a surface point lit by every light
 * through the media. n faces the viewer; x is already offset off the surface. */
static lu_vec3 surface_radiance(ref_state *st, thread_scratch *ts, lu_vec3 x, lu_vec3 n, lu_vec3 wo,
                                const lu_material *mat, float phi0) {
    const lu_scene *s = st->scene;
    lu_vec3 sum = lu_v3s(0.0f);
    for (int l = 0; l < s->light_count; l++) {
        const lu_light *light = &s->lights[l];
        if (light->type == LU_LIGHT_ENVIRONMENT) {
            env_weight w = {ENV_BRDF, wo, 0.0f, n, mat};
            sum = lu_v3_add(sum, env_integral(st, ts, light, x, phi0, &w));
            continue;
        }
        lu_k_light_sample ls = lu_k_light_arrive(st->klights[l], x);
        lu_vec3 f = lu_k_blinn_phong(mat->albedo, mat->specular, mat->shininess, n, wo, ls.wl);
        if (lu_v3_maxc(f) <= 0.0f || lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        lu_vec3 tr = transmittance(st, ts, x, ls.wl, ls.dist);
        sum = lu_v3_add(sum, lu_v3_mul(lu_v3_mul(f, ls.irradiance), tr));
    }
    return sum;
}

/* ---- camera-ray tracks ------------------------------------------------------ */

static bool track_push(track *tr, piece p) {
    if (tr->count == tr->capacity) {
        int cap = tr->capacity ? 2 * tr->capacity : 256;
        piece *np = lu_realloc(tr->pieces, (size_t)cap * sizeof *np);
        if (!np) return false;
        tr->pieces = np;
        tr->capacity = cap;
    }
    tr->pieces[tr->count++] = p;
    return true;
}

/* Cell pieces of medium m along the ray inside [ta, tb], with exact cubic
 * density per piece; constant media get pieces of one virtual voxel. */
static bool track_add_interval(ref_state *st, track *tr, int m, lu_vec3 o, lu_vec3 d, float ta, float tb) {
    const lu_medium *med = &st->scene->media[m];
    if (med->kind == LU_DENSITY_CONSTANT) {
        float h = st->media[m].voxel_len;
        int n = (int)ceilf((tb - ta) / h);
        if (n < 1) n = 1;
        for (int i = 0; i < n; i++) {
            piece p;
            p.ta = ta + (tb - ta) * (float)i / (float)n;
            p.tb = i + 1 == n ? tb : ta + (tb - ta) * (float)(i + 1) / (float)n;
            p.density = lu_k_cubic_fit(med->constant, med->constant, med->constant, med->constant);
            p.tau_before = tr->tau_total;
            tr->tau_total += med->constant * (p.tb - p.ta);
            if (!track_push(tr, p)) return false;
        }
        return true;
    }
    lu_vec3 oi = lu_affine_point(&med->world_to_index, o), di = lu_affine_vector(&med->world_to_index, d);
    lu_k_dda s = lu_k_dda_begin(oi, di, ta, tb);
    float a = ta;
    float da = lu_k_density(&st->kctx, m, lu_v3_madd(oi, di, a));
    for (int i = 0; i < st->media[m].max_pieces && a < tb; i++) {
        float b = lu_k_dda_step(&s);
        float len = b - a;
        float d1 = lu_k_density(&st->kctx, m, lu_v3_madd(oi, di, a + len * (1.0f / 3.0f)));
        float d2 = lu_k_density(&st->kctx, m, lu_v3_madd(oi, di, a + len * (2.0f / 3.0f)));
        float db = lu_k_density(&st->kctx, m, lu_v3_madd(oi, di, b));
        piece p;
        p.ta = a;
        p.tb = b;
        p.density = lu_k_cubic_fit(da, d1, d2, db);
        p.tau_before = tr->tau_total;
        tr->tau_total += len * lu_k_cubic_integral(p.density, 1.0f);
        if (len > 0.0f && !track_push(tr, p)) return false;
        a = b;
        da = db;
    }
    return true;
}

/* This medium's optical depth from the ray start to t (exact). */
static float track_tau(const track *tr, float t) {
    int lo = 0, hi = tr->count - 1;
    if (tr->count == 0 || t <= tr->pieces[0].ta) return 0.0f;
    if (t >= tr->pieces[hi].tb) return tr->tau_total;
    while (lo < hi) { /* last piece with ta <= t */
        int mid = (lo + hi + 1) / 2;
        if (tr->pieces[mid].ta <= t) lo = mid;
        else hi = mid - 1;
    }
    const piece *p = &tr->pieces[lo];
    if (t >= p->tb) return p->tau_before + (p->tb - p->ta) * lu_k_cubic_integral(p->density, 1.0f);
    float len = p->tb - p->ta;
    return p->tau_before + len * lu_k_cubic_integral(p->density, (t - p->ta) / len);
}

static lu_vec3 camera_transmittance(ref_state *st, thread_scratch *ts, float t) {
    lu_vec3 tau = lu_v3s(0.0f);
    for (int m = 0; m < st->medium_count; m++) tau = lu_v3_madd(tau, st->media[m].sigma_t, track_tau(&ts->tracks[m], t));
    return lu_v3_exp(lu_v3_neg(tau));
}

/* ---- in-scattering quadrature ------------------------------------------------------
 * f(t) = T_camera(t) * D(t) * source(x(t)) is smooth inside a cell piece except
 * where a shadow edge or a spot cone crosses the ray; there Simpson's order
 * collapses, so each sub-interval is refined adaptively until the halved
 * estimate agrees with the whole to `tolerance` (relative), with Richardson's
 * correction, down to 2^-max_depth of the sub-interval. */

typedef struct integrand {
    ref_state *st;
    thread_scratch *ts;
    int m;
    lu_vec3 o, d;
    float phi0;
    const piece *p;
    /* emissive medium: the integrand carries sigma_s (source) + sigma_a Le
     * itself (the caller does not multiply by sigma_s afterwards) */
    const lu_medium *emit;
} integrand;

static lu_vec3 integrand_eval(const integrand *f, float t) {
    const piece *p = f->p;
    float len = p->tb - p->ta;
    float dens = lu_k_cubic_eval(p->density, len > 0.0f ? (t - p->ta) / len : 0.0f);
    if (dens <= 0.0f) return lu_v3s(0.0f);
    /* A node on a boundary face is the limit from inside: evaluating it a hair
     * inside keeps that face's crossing (and its Fresnel factor) on the shadow
     * ray instead of at t = 0, where it would be neither in nor out. */
    float e = f->st->eps;
    float tx = len > 4.0f * e ? fminf(fmaxf(t, p->ta + e), p->tb - e) : t;
    lu_vec3 x = lu_v3_madd(f->o, f->d, tx);
    bool scatters = !f->emit || lu_v3_maxc(f->emit->sigma_s) > 0.0f;
    lu_vec3 src = scatters ? inscatter_source(f->st, f->ts, f->m, x, f->d, f->phi0) : lu_v3s(0.0f);
    if (f->emit) {
        /* Le at the node itself (t, not tx): emission has no shadow edge to keep */
        lu_vec3 xe = lu_v3_madd(f->o, f->d, t);
        lu_vec3 p_index = f->emit->kind == LU_DENSITY_GRID ? lu_affine_point(&f->emit->world_to_index, xe) : xe;
        src = lu_v3_add(lu_v3_mul(f->emit->sigma_s, src),
                        lu_v3_mul(f->emit->sigma_a, lu_medium_emission(f->emit, p_index)));
    }
    return lu_v3_scale(lu_v3_mul(camera_transmittance(f->st, f->ts, t), src), dens);
}

static lu_vec3 simpson3(float len, lu_vec3 fa, lu_vec3 fm, lu_vec3 fb) {
    return lu_v3_scale(lu_v3_add(lu_v3_add(fa, fb), lu_v3_scale(fm, 4.0f)), len * (1.0f / 6.0f));
}

static lu_vec3 adaptive_simpson(const integrand *f, float a, lu_vec3 fa, float m, lu_vec3 fm, float b, lu_vec3 fb,
                                lu_vec3 whole, int depth) {
    float lm = 0.5f * (a + m), rm = 0.5f * (m + b);
    lu_vec3 flm = integrand_eval(f, lm), frm = integrand_eval(f, rm);
    lu_vec3 left = simpson3(m - a, fa, flm, fm), right = simpson3(b - m, fm, frm, fb);
    lu_vec3 halves = lu_v3_add(left, right);
    lu_vec3 diff = lu_v3_sub(halves, whole);
    float err = fmaxf(fabsf(diff.x), fmaxf(fabsf(diff.y), fabsf(diff.z)));
    float scale = fmaxf(fabsf(halves.x), fmaxf(fabsf(halves.y), fabsf(halves.z)));
    if (depth <= 0 || err <= 15.0f * f->st->tolerance * scale || err <= 1e-12f)
        return lu_v3_madd(halves, diff, 1.0f / 15.0f);
    return lu_v3_add(adaptive_simpson(f, a, fa, lm, flm, m, fm, left, depth - 1),
                     adaptive_simpson(f, m, fm, rm, frm, b, fb, right, depth - 1));
}

/* ---- one camera ray ----------------------------------------------------------- */

static lu_vec3 trace(ref_state *st, thread_scratch *ts, lu_vec3 o, lu_vec3 d, float phi0) {
    const lu_scene *s = st->scene;
    lu_hit hit;
    bool has_hit = st->opaque && lu_accel_closest(st->opaque, o, d, 0.0f, LU_K_FAR, &hit);
    float t_end = has_hit ? hit.t : LU_K_FAR;
    lu_vec3 L = lu_v3s(0.0f);

    /* Tracks first: every later term needs the camera transmittance. */
    crossing entries[MAX_CROSSINGS];
    int entry_medium[MAX_CROSSINGS];
    int nentries = 0;
    for (int m = 0; m < st->medium_count; m++) {
        track *tr = &ts->tracks[m];
        tr->count = 0;
        tr->tau_total = 0.0f;
        float iv[2 * 64];
        int nc;
        int n = medium_intervals(st, m, o, d, 0.0f, t_end, iv, 64, ts->crossings, &nc);
        for (int i = 0; i < n; i++)
            if (!track_add_interval(st, tr, m, o, d, iv[2 * i], iv[2 * i + 1])) st->nomem = true;
        for (int i = 0; i < nc && nentries < MAX_CROSSINGS; i++) {
            if (lu_v3_dot(ts->crossings[i].ng, d) >= 0.0f) continue; /* exits show no reflection */
            entries[nentries] = ts->crossings[i];
            entry_medium[nentries++] = m;
        }
    }

    /* In-scattering: adaptive Simpson over each cell piece. */
    for (int m = 0; m < st->medium_count; m++) {
        const track *tr = &ts->tracks[m];
        const lu_medium *med = &s->media[m];
        bool emissive = med->emission != LU_EMISSION_NONE;
        if (lu_v3_maxc(med->sigma_s) <= 0.0f && !emissive) continue;
        lu_vec3 di_len = lu_affine_vector(&med->world_to_index, d);
        float index_per_t = med->kind == LU_DENSITY_CONSTANT ? 1.0f / st->media[m].voxel_len : lu_v3_len(di_len);
        integrand fn = {st, ts, m, o, d, phi0, NULL, emissive ? med : NULL};
        lu_vec3 acc = lu_v3s(0.0f);
        for (int i = 0; i < tr->count; i++) {
            const piece *p = &tr->pieces[i];
            fn.p = p;
            float len = p->tb - p->ta;
            int k = (int)ceilf(len * index_per_t * st->steps);
            if (k < 1) k = 1;
            float a = p->ta;
            lu_vec3 fa = integrand_eval(&fn, a);
            for (int j = 1; j <= k; j++) {
                float b = j == k ? p->tb : p->ta + len * (float)j / (float)k;
                float mid = 0.5f * (a + b);
                lu_vec3 fm = integrand_eval(&fn, mid), fb = integrand_eval(&fn, b);
                lu_vec3 whole = simpson3(b - a, fa, fm, fb);
                acc = lu_v3_add(acc, adaptive_simpson(&fn, a, fa, mid, fm, b, fb, whole, st->max_depth));
                a = b;
                fa = fb;
            }
        }
        L = lu_v3_add(L, emissive ? acc : lu_v3_mul(acc, med->sigma_s));
    }

    /* Boundary reflection, weighted by (1 - F_t) (Bernabei Eq. 4). */
    for (int i = 0; i < nentries; i++) {
        const lu_medium *med = &s->media[entry_medium[i]];
        lu_vec3 n = entries[i].ng;
        lu_vec3 x = lu_v3_madd(lu_v3_madd(o, d, entries[i].t), n, st->eps);
        float fr = lu_k_fresnel_reflectance(lu_v3_dot(n, d), med->eta);
        lu_vec3 lr = surface_radiance(st, ts, x, n, lu_v3_neg(d), &med->surface, phi0);
        L = lu_v3_add(L, lu_v3_scale(lu_v3_mul(camera_transmittance(st, ts, entries[i].t), lr), fr));
    }

    /* What the ray ends on: an opaque surface, or the background / environment. */
    lu_vec3 end_radiance;
    if (has_hit) {
        int obj = st->opaque_object[hit.mesh_id];
        const lu_object *ob = &s->objects[obj];
        lu_vec3 n, ng;
        lu_hit_normals(&ob->mesh, &hit, d, &n, &ng);
        lu_vec3 x = lu_v3_madd(lu_v3_madd(o, d, hit.t), ng, st->eps);
        end_radiance = surface_radiance(st, ts, x, n, lu_v3_neg(d), &ob->material, phi0);
    } else {
        end_radiance = s->background;
        for (int l = 0; l < s->light_count; l++)
            if (s->lights[l].type == LU_LIGHT_ENVIRONMENT)
                end_radiance = lu_v3_add(end_radiance, env_radiance(&s->lights[l], d));
    }
    return lu_v3_add(L, lu_v3_mul(camera_transmittance(st, ts, t_end), end_radiance));
}

/* ---- the method table ------------------------------------------------------------ */

static void render_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    ref_state *st = ctx;
    thread_scratch *ts = &st->scratch[thread];
    const lu_camera *cam = &st->scene->camera;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < cam->width; x++) {
            uint32_t h = lu_k_mix32((uint32_t)(y * cam->width + x) * 2654435761u + 12345u);
            float phi0 = (float)(h & 0xffffff) * (2.0f * LU_PI / 16777216.0f);
            lu_vec3 acc = lu_v3s(0.0f);
            for (int i = 0; i < st->spp; i++) {
                /* R2 sequence offsets; i = 0 is the pixel centre. */
                float ox = fmodf(0.5f + 0.7548776662466927f * (float)i, 1.0f);
                float oy = fmodf(0.5f + 0.5698402909980532f * (float)i, 1.0f);
                lu_vec3 d = lu_k_camera_dir(st->cam, (float)x + ox, (float)y + oy);
                acc = lu_v3_add(acc, trace(st, ts, cam->position, d, phi0));
            }
            float *px = lu_image_px(st->out, x, (int)y);
            px[0] = acc.x / (float)st->spp;
            px[1] = acc.y / (float)st->spp;
            px[2] = acc.z / (float)st->spp;
        }
    }
}

static void ref_destroy(void *state) {
    ref_state *st = state;
    if (!st) return;
    if (st->opaque) lu_accel_destroy(st->opaque);
    for (int m = 0; st->media && m < st->medium_count; m++)
        if (st->media[m].boundary) lu_accel_destroy(st->media[m].boundary);
    if (st->scratch)
        for (int t = 0; t < st->threads; t++) {
            for (int m = 0; st->scratch[t].tracks && m < st->medium_count; m++) lu_free(st->scratch[t].tracks[m].pieces);
            lu_free(st->scratch[t].tracks);
        }
    lu_free(st->scratch);
    lu_free(st->media);
    lu_free(st->opaque_object);
    lu_free(st);
}

static lu_result ref_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                             lu_error *err) {
    ref_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "reference: out of memory");
    st->spp = (int)params[P_SPP];
    st->steps = (float)params[P_STEPS];
    st->tolerance = (float)params[P_TOLERANCE];
    st->max_depth = (int)params[P_MAX_DEPTH];
    st->env_samples = (int)params[P_ENV_SAMPLES];
    lu_result r = LU_OK;

    st->eps = lu_scene_ray_epsilon(scene);

    r = lu_opaque_accel_build(scene, &st->opaque, &st->opaque_object, err);

    st->medium_count = scene->medium_count;
    st->media = lu_calloc((size_t)(scene->medium_count ? scene->medium_count : 1), sizeof *st->media);
    if (!st->media && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "reference: out of memory");
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        const lu_medium *med = &scene->media[m];
        medium_info *mi = &st->media[m];
        mi->sigma_t = lu_v3_add(med->sigma_a, med->sigma_s);
        lu_vec3 ext = lu_v3_sub(med->bounds.hi, med->bounds.lo);
        mi->voxel_len = fmaxf(lu_v3_maxc(ext), 1e-6f) / CONSTANT_VOXELS;
        mi->max_pieces = med->kind == LU_DENSITY_GRID ? med->grid.nx + med->grid.ny + med->grid.nz + 8 : 1;
        if (med->has_boundary) {
            mi->parity_box = lu_mesh_bounds(&med->boundary);
            r = lu_mesh_accel_build(&med->boundary, &mi->boundary, err);
        }
    }

    st->threads = lu_thread_count();
    st->scratch = lu_calloc((size_t)st->threads, sizeof *st->scratch);
    if (!st->scratch && r == LU_OK) r = lu_fail(err, LU_ERR_NOMEM, "reference: out of memory");
    for (int t = 0; t < st->threads && r == LU_OK; t++) {
        st->scratch[t].tracks = lu_calloc((size_t)(scene->medium_count ? scene->medium_count : 1), sizeof(track));
        if (!st->scratch[t].tracks) r = lu_fail(err, LU_ERR_NOMEM, "reference: out of memory");
    }
    if (r != LU_OK) {
        ref_destroy(st);
        return r;
    }
    (void)backend;
    *out = st;
    return LU_OK;
}

static lu_result ref_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    const lu_scene *scene = frame->scene;
    ref_state *st = state;
    if (scene->medium_count != st->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "reference: the scene's media changed since prepare");
    st->scene = scene;
    st->kctx.media = scene->media;
    st->out = out;
    st->overflow = false;
    st->nomem = false;
    st->cam = frame->rec->cam;
    st->klights = frame->rec->scene_lights;
    lu_frame_for_rows(frame, 1, render_rows, st, "reference");
    if (st->nomem) return lu_fail(err, LU_ERR_NOMEM, "reference: out of memory (a ray's transmittance pieces)");
    if (st->overflow)
        return lu_fail(err, LU_ERR_LIMIT, "reference: a ray crossed more than %d boundary faces", MAX_CROSSINGS);
    return LU_OK;
}

const lu_method lu_method_reference = {
    .name = "reference",
    .summary = "ground truth single scattering: exact cell-wise transmittance, Simpson in-scattering, exact shadow rays",
    .backends = LU_BACKEND_CPU,
    .params = k_params,
    .param_count = P_COUNT,
    /* media coefficients and densities are read at prepare (majorants, sigma_t) */
    .prepare_deps = LU_CHANGE_MEDIA,
    .prepare = ref_prepare,
    .render = ref_render,
    .destroy = ref_destroy,
};
