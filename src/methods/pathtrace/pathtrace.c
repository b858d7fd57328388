/* pathtrace — unbiased, progressive Monte Carlo volumetric path tracing: the
 * multiple-scattering truth (docs/architecture.md §2). Documented in docs/pathtrace.md.
 *
 * Per camera sample (one PCG stream per pixel and sample index, so images do
 * not depend on the thread count):
 *   - free flight by null-collision tracking against a coarse majorant grid
 *     per medium (lu_tracking.h); RGB by a hero channel with spectral MIS
 *     (default) or spectral tracking; absorption is folded into the weights
 *     and paths end by Russian roulette; overlapping media are superposed
 *     (each runs its own tentative-collision process, the earliest wins);
 *   - direct light: point and spot lights per path segment by equiangular
 *     sampling; directional and environment lights at each scattering vertex
 *     and surface hit, environments importance sampled from the map's
 *     luminance with MIS (power heuristic) against phase / BRDF sampling;
 *     shadow transmittance by ratio tracking (or exact, an option), exact for
 *     constant density; the path continues by sampling the phase function or
 *     the Blinn-Phong lobes;
 *   - bounded media ("boundary" meshes, translucent objects): "straight"
 *     boundaries are the seed model the reference renders (no refraction, F_t
 *     on every crossing except the camera ray's own, the boundary's coat
 *     reflecting direct light weighted by F_r); "refract" boundaries are smooth
 *     dielectrics (Fresnel reflection or refraction, radiance scaled by
 *     (eta_i / eta_t)^2, total internal reflection); "diffuse" boundaries are
 *     white Lambertian transmitters both ways (Chiang, Kutz and Burley 2016),
 *     so a walk ends at its first boundary hit; inside a sealed (refracting
 *     or diffuse) constant medium the ray cast is fused with the free flight,
 *     and guide=dwivedi mixes Dwivedi-guided steps into the walk
 *     (pathtrace_guide.c);
 *   - a delta light behind a refracting boundary cannot be reached by a
 *     straight shadow ray. Through exactly one refraction, manifold
 *     next-event estimation (pathtrace_mnee.c) finds the boundary points
 *     where its light refracts towards each camera vertex (single scattering
 *     along the camera ray included; the walk samples internal reflections
 *     itself). Longer specular chains: light subpaths carry the light
 *     through them, their segments after the second specular event (or
 *     after a first one that is not a refraction into a medium) are
 *     "beams", and each camera vertex connects to a point on each beam
 *     (equiangular or exponential, Kulla and Fajardo 2012); the segment
 *     after a single refraction is no beam, so nothing is counted twice.
 * Depth counts scattering vertices (volume events and surface bounces, not
 * dielectric interface events): depth 1 is single scattering and reproduces
 * `reference`.
 *
 * Over 800 lines: one path's strategies (next-event estimation, beams, light
 * subpaths, the interface events) share its private state
 * (pathtrace_state.h) and helpers; free flight and the subsurface walk's
 * steps live in pathtrace_walk.c, the Dwivedi sampling in pathtrace_guide.c,
 * the manifold solver in pathtrace_mnee.c. */
#include <lucent/lucent.h>

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "methods/frame.h"
#include "methods/methods.h"
#include "methods/common/mesh_adjacency.h"
#include "methods/pathtrace/pathtrace_state.h"

enum {
    P_SPP,
    P_MAX_DEPTH,
    P_RR,
    P_RR_DEPTH,
    P_SEED,
    P_BOUNDARY,
    P_BLOCK,
    P_JITTER,
    P_LIGHT_PATHS,
    P_SPECTRAL,
    P_EQUIANGULAR,
    P_TRANSMITTANCE,
    P_STATS,
    P_GUIDE,
    P_COUNT
};

enum { TR_RATIO = 0, TR_EXACT };

enum { SPECTRAL_HERO = 0, SPECTRAL_TRACKING };

enum { BOUNDARY_AUTO = 0, BOUNDARY_STRAIGHT, BOUNDARY_REFRACT, BOUNDARY_DIFFUSE };

static const lu_param_desc k_params[P_COUNT] = {
    [P_SPP] = {"spp", LU_PARAM_INT, 16, 1, 1 << 20, NULL, "samples (passes) per pixel"},
    [P_MAX_DEPTH] = {"max_depth", LU_PARAM_INT, 4096, 0, 1 << 20, NULL,
                     "most scattering vertices per path (1 = single scattering, as `reference`)"},
    [P_RR] = {"russian_roulette", LU_PARAM_BOOL, 1, 0, 1, NULL, "end low-throughput paths at random (unbiased)"},
    [P_RR_DEPTH] = {"rr_depth", LU_PARAM_INT, 3, 0, 1 << 20, NULL,
                    "scattering vertices before Russian roulette starts"},
    [P_SEED] = {"seed", LU_PARAM_INT, 1, 0, 2147483647, NULL, "random seed (one PCG stream per pixel and sample)"},
    [P_BOUNDARY] = {"boundary", LU_PARAM_CHOICE, 0, 0, 3, "auto|straight|refract|diffuse",
                    "medium boundaries: straight (the reference's model), refract (smooth dielectric), auto "
                    "(translucent objects refract, media boundaries are straight), diffuse (Lambertian "
                    "transmission both ways, no Fresnel: production random walks)"},
    [P_BLOCK] = {"majorant_block", LU_PARAM_INT, 8, 1, 256, NULL, "voxels per majorant block side"},
    [P_JITTER] = {"jitter", LU_PARAM_BOOL, 1, 0, 1, NULL,
                  "random position in the pixel (box filter); off = through the pixel centre like reference spp=1"},
    [P_LIGHT_PATHS] = {"light_paths", LU_PARAM_INT, 1, 0, 64, NULL,
                       "light subpaths per sample and delta light for lights behind refracting boundaries"},
    [P_SPECTRAL] = {"spectral", LU_PARAM_CHOICE, 0, 0, 1, "hero|tracking",
                    "RGB free-flight sampling: hero channel + spectral MIS, or spectral tracking (Kutz et al. 2017)"},
    [P_EQUIANGULAR] =
        {"equiangular", LU_PARAM_BOOL, 1, 0, 1, NULL,
         "point/spot light in media: per segment by equiangular sampling (on) or at free-flight vertices (off)"},
    [P_TRANSMITTANCE] = {"transmittance", LU_PARAM_CHOICE, 0, 0, 1, "ratio|exact",
                         "shadow-ray transmittance in grids: ratio tracking (unbiased estimate) or exact cell-wise "
                         "optical depth (lu_march.h)"},
    [P_STATS] = {"stats", LU_PARAM_BOOL, 0, 0, 1, NULL,
                 "print walk counters on stderr after a render (vertices, boundary hits, internal reflections)"},
    [P_GUIDE] = {"guide", LU_PARAM_CHOICE, 0, 0, 1, "off|dwivedi",
                 "walks in sealed constant media (refract or diffuse boundaries, hero spectral): off, or a one-sample "
                 "mixture of the classical walk and Dwivedi sampling towards the last boundary point (unbiased)"},
};

/* ---- environment ------------------------------------------------------------------- */

static lu_vec3 env_radiance(const lu_light *l, lu_vec3 dir) { return lu_env_lookup(&l->env, l->env_scale, dir); }

static void env_destroy(pt_env *e) {
    lu_free(e->cdf_rows);
    lu_free(e->cdf_cols);
    lu_free(e->prob);
}

/* Piecewise-constant distribution over (u, v) cells, weight = luminance x
 * sin(theta). Small maps (a constant environment is 1x1) are resampled to
 * 64 x 32 cells so the sin(theta) factor is resolved. A cell's luminance is the
 * largest bilinear value near it, so bright texels' filter footprints are
 * covered; phase / BRDF sampling (MIS) covers everything else. */
static lu_result env_build(const lu_light *l, int light_index, pt_env *e, lu_error *err) {
    memset(e, 0, sizeof *e);
    e->light = light_index;
    const lu_image *im = &l->env;
    bool texel = im->height >= 32;
    e->w = texel ? im->width : 64;
    e->h = texel ? im->height : 32;
    size_t n = (size_t)e->w * e->h;
    e->prob = lu_calloc(n, sizeof *e->prob);
    e->cdf_rows = lu_calloc((size_t)e->h + 1, sizeof *e->cdf_rows);
    e->cdf_cols = lu_calloc((size_t)e->h * (e->w + 1), sizeof *e->cdf_cols);
    if (!e->prob || !e->cdf_rows || !e->cdf_cols) {
        env_destroy(e);
        return lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory for the environment distribution");
    }
    double total = 0.0;
    for (int y = 0; y < e->h; y++) {
        float st = sinf(((float)y + 0.5f) / (float)e->h * LU_PI);
        double row = 0.0;
        for (int x = 0; x < e->w; x++) {
            float lum = 0.0f;
            for (int j = -1; j <= 1; j++)
                for (int i = -1; i <= 1; i++) {
                    float u = ((float)x + 0.5f + 0.5f * (float)i) / (float)e->w;
                    float v = fminf(fmaxf(((float)y + 0.5f + 0.5f * (float)j) / (float)e->h, 0.0f), 1.0f);
                    lu_vec3 c = env_radiance(l, lu_k_env_dir(u, v));
                    lum = fmaxf(lum, 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z);
                }
            float wgt = lum * st;
            e->prob[(size_t)y * e->w + x] = wgt;
            row += wgt;
            e->cdf_cols[(size_t)y * (e->w + 1) + x + 1] = (float)row;
        }
        total += row;
        e->cdf_rows[y + 1] = (float)total;
    }
    if (!(total > 0.0)) { /* black map: nothing to sample; NEE skips it */
        memset(e->prob, 0, n * sizeof *e->prob);
        return LU_OK;
    }
    for (int y = 0; y < e->h; y++) {
        float *c = &e->cdf_cols[(size_t)y * (e->w + 1)];
        float rt = c[e->w];
        for (int x = 0; x <= e->w; x++) c[x] = rt > 0.0f ? c[x] / rt : (float)x / (float)e->w;
    }
    for (int y = 0; y <= e->h; y++) e->cdf_rows[y] = (float)(e->cdf_rows[y] / total);
    for (size_t i = 0; i < n; i++) e->prob[i] = (float)(e->prob[i] / total);
    return LU_OK;
}

/* Last index i in [0, n) with cdf[i] <= u. */
static int cdf_find(const float *cdf, int n, float u) {
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        int mid = (lo + hi + 1) / 2;
        if (cdf[mid] <= u)
            lo = mid;
        else
            hi = mid - 1;
    }
    return lo;
}

static float env_pdf(const pt_env *e, lu_vec3 dir) {
    float u = lu_k_env_u(dir), v = lu_k_env_v(dir);
    int x = (int)(u * (float)e->w), y = (int)(v * (float)e->h);
    x = x < 0 ? 0 : (x >= e->w ? e->w - 1 : x);
    y = y < 0 ? 0 : (y >= e->h ? e->h - 1 : y);
    float p = e->prob[(size_t)y * e->w + x] * (float)e->w * (float)e->h;
    return lu_k_env_pdf_solid_angle(p, v);
}

/* Returns false if the map has nothing to sample. */
static bool env_sample(const pt_env *e, float u1, float u2, lu_vec3 *dir, float *pdf) {
    if (!(e->cdf_rows[e->h] > 0.0f)) return false;
    int y = cdf_find(e->cdf_rows, e->h, u1);
    const float *c = &e->cdf_cols[(size_t)y * (e->w + 1)];
    int x = cdf_find(c, e->w, u2);
    float pr = e->cdf_rows[y + 1] - e->cdf_rows[y], pc = c[x + 1] - c[x];
    if (!(pr > 0.0f) || !(pc > 0.0f)) return false;
    float fy = (u1 - e->cdf_rows[y]) / pr, fx = (u2 - c[x]) / pc;
    float u = ((float)x + fminf(fmaxf(fx, 0.0f), 0.999999f)) / (float)e->w;
    float v = ((float)y + fminf(fmaxf(fy, 0.0f), 0.999999f)) / (float)e->h;
    *dir = lu_k_env_dir(u, v);
    *pdf = lu_k_env_pdf_solid_angle(e->prob[(size_t)y * e->w + x] * (float)e->w * (float)e->h, v);
    return *pdf > 0.0f;
}

/* Transmittance over (0, t_end) of the media active under `mask` (no
 * surfaces): exact for constant density; for grids ratio tracking (an
 * unbiased estimate) or, with transmittance=exact, the cell-exact optical
 * depth the reference uses. */
static lu_vec3 media_transmittance(const pt_state *st, lu_vec3 o, lu_vec3 d, float t_end, uint64_t mask,
                                   lu_k_rng *rng) {
    lu_vec3 tr = lu_v3s(1.0f);
    for (int m = 0; m < st->medium_count && lu_v3_maxc(tr) > 0.0f; m++) {
        const pt_medium *pm = &st->media[m];
        float a, b;
        if (!medium_active(pm, mask) || !medium_span(pm, o, d, t_end, &a, &b)) continue;
        if (pm->constant) {
            tr = lu_v3_mul(tr, lu_v3_exp(lu_v3_scale(pm->sigma_t, -pm->cdens * (b - a))));
            continue;
        }
        const lu_medium *med = &st->scene->media[m];
        lu_vec3 oi = lu_affine_point(&med->world_to_index, o), di = lu_affine_vector(&med->world_to_index, d);
        if (st->transmittance == TR_EXACT) {
            float tau = lu_k_optical_depth(&st->kctx, m, oi, di, a, b, pm->max_pieces);
            tr = lu_v3_mul(tr, lu_v3_exp(lu_v3_scale(pm->sigma_t, -tau)));
        } else {
            tr = lu_v3_mul(tr,
                           lu_k_ratio_tracking(&st->kctx, m, oi, di, a, b, st->block, pm->sigma_t, pm->sigma_max, rng));
        }
    }
    return tr;
}

/* Shadow transmittance from x along unit w over (0, dist): opaque surfaces
 * and refracting boundaries block (a specular interface cannot be
 * connected through), straight boundaries pass with F_t and switch their
 * medium on or off. */
static lu_vec3 transmit(const pt_state *st, lu_vec3 x, lu_vec3 w, float dist, uint64_t mask, lu_k_rng *rng) {
    lu_vec3 tr = lu_v3s(1.0f);
    lu_vec3 o = x;
    float left = dist;
    for (int i = 0; i < PT_MAX_CROSSINGS; i++) {
        lu_hit hit;
        bool has = st->surf && lu_accel_closest(st->surf, o, w, 0.0f, left, &hit);
        float seg = has ? hit.t : left;
        tr = lu_v3_mul(tr, media_transmittance(st, o, w, seg, mask, rng));
        if (!has || lu_v3_maxc(tr) <= 0.0f) return has ? lu_v3s(0.0f) : tr;
        const pt_surf *sf = &st->surf_info[hit.mesh_id];
        if (sf->kind == SURF_OPAQUE) return lu_v3s(0.0f);
        const pt_medium *pm = &st->media[sf->index];
        if (pm->refract || pm->diffuse) return lu_v3s(0.0f);
        float c = lu_v3_dot(hit.ng, w);
        tr = lu_v3_scale(tr, lu_k_fresnel_transmittance(c, pm->eta));
        mask = mask_set(mask, pm->bit, c < 0.0f);
        lu_vec3 p = lu_v3_madd(o, w, hit.t);
        o = offset_point(p, hit.ng, w, st->eps);
        left -= hit.t;
        if (!(left > 0.0f)) return tr;
    }
    return lu_v3s(0.0f);
}

/* ---- vertices and light connections ------------------------------------------------------ */

typedef struct pt_vertex {
    bool surface;
    bool lambert_t; /* surface: a diffuse interface, Lambertian (albedo 1) about n, the side left towards */
    lu_vec3 x; /* surfaces: offset off the surface on wo's side */
    lu_vec3 d; /* medium: direction the path arrived in */
    float g;
    lu_vec3 n, wo; /* surface: shading normal facing wo, direction to the previous vertex */
    const lu_material *mat;
    uint64_t mask; /* media present at x */
    bool has_seed_n;
    lu_vec3 seed_n; /* outward normal at the path's last sealed boundary point: a guess for mnee */
} pt_vertex;

/* Scattering function towards wl (phase, or BRDF x cos) and the pdf with
 * which the path would have sampled wl. */
static lu_vec3 vertex_eval(const pt_vertex *v, lu_vec3 wl, float *pdf) {
    if (!v->surface) {
        float p = lu_k_phase_hg(lu_v3_dot(v->d, wl), v->g);
        *pdf = p;
        return lu_v3s(p);
    }
    if (v->lambert_t) {
        float c = fmaxf(lu_v3_dot(v->n, wl), 0.0f) * LU_K_INV_PI;
        *pdf = c;
        return lu_v3s(c);
    }
    const lu_material *m = v->mat;
    *pdf = lu_k_blinn_phong_pdf(m->albedo, m->specular, m->shininess, v->n, v->wo, wl);
    return lu_k_blinn_phong(m->albedo, m->specular, m->shininess, v->n, v->wo, wl);
}

/* Delta light l seen from v through exactly one refraction, into the one
 * sealed medium that holds v and not the light (manifold next-event
 * estimation, pathtrace_mnee.c): light x Fresnel transmittance x the
 * refraction's irradiance factor x transmittance both sides x scattering at
 * v. No radiance factor eta^2: the light's flux is what is carried (as on
 * light subpaths). The search starts from two guesses, the straight line to
 * the light and the light refracted at the path's last boundary normal;
 * solutions on distinct facets are distinct paths and all count. */
static lu_vec3 mnee(const pt_state *st, const pt_vertex *v, int l, lu_k_rng *rng) {
    lu_vec3 sum = lu_v3s(0.0f);
    uint64_t need = v->mask & st->sealed_bits & ~st->light_mask[l];
    if (!need || (need & (need - 1))) return sum; /* two or more refractions: light subpaths only */
    int bit = 0;
    while (!((need >> bit) & 1u)) bit++;
    int m = st->bit_medium[bit];
    const pt_medium *pm = &st->media[m];
    if (!pm->refract) return sum;
    const lu_k_light kl = st->klights[l];
    lu_vec3 seeds[2];
    int ns = 0;
    lu_k_light_sample l0 = lu_k_light_arrive(kl, v->x);
    seeds[ns++] = l0.wl;
    lu_vec3 tr0;
    if (v->has_seed_n && lu_v3_dot(v->seed_n, l0.wl) > 0.0f && lu_k_refract(lu_v3_neg(l0.wl), v->seed_n, pm->eta, &tr0))
        seeds[ns++] = lu_v3_neg(tr0);
    pt_mnee_path paths[PT_MNEE_MAX];
    int np = lu_pt_mnee_solve(st, m, kl, v->x, seeds, ns, paths, PT_MNEE_MAX);
    uint64_t outside = mask_set(v->mask, pm->bit, false);
    for (int k = 0; k < np; k++) {
        const pt_mnee_path mp = paths[k];
        lu_vec3 s_out = lu_v3_madd(mp.s, mp.ns, st->eps);
        lu_k_light_sample ls = lu_k_light_arrive(kl, s_out);
        if (lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        lu_vec3 wl = lu_v3_neg(mp.t);
        float pv;
        lu_vec3 f = vertex_eval(v, wl, &pv);
        if (lu_v3_maxc(f) <= 0.0f) continue;
        float left = mp.dist - st->eps;
        lu_vec3 tin = left > 0.0f ? transmit(st, v->x, wl, left, v->mask, rng) : lu_v3s(1.0f);
        if (lu_v3_maxc(tin) <= 0.0f) continue;
        lu_vec3 tout = transmit(st, s_out, ls.wl, ls.dist, outside, rng);
        if (lu_v3_maxc(tout) <= 0.0f) continue;
        float k_ref = mp.gain * lu_k_fresnel_transmittance(mp.cos_i, pm->eta);
        sum = lu_v3_add(sum, lu_v3_scale(lu_v3_mul(lu_v3_mul(f, ls.irradiance), lu_v3_mul(tin, tout)), k_ref));
    }
    return sum;
}

/* Next-event estimation to every light. `mis`: the path will also sample a
 * continuation from this vertex (so environment hits are shared by MIS). */
static lu_vec3 nee(const pt_state *st, const pt_vertex *v, bool mis, lu_k_rng *rng) {
    const lu_scene *s = st->scene;
    lu_vec3 sum = lu_v3s(0.0f);
    int env_i = 0;
    /* A light outside a sealed medium the vertex is in cannot be connected
     * to by a straight shadow ray (it would meet the interface): a delta
     * light behind one refraction is reached by mnee, the rest by the path. */
    uint64_t enclosing = v->mask & st->sealed_bits;
    for (int l = 0; l < s->light_count; l++) {
        const lu_light *light = &s->lights[l];
        if (enclosing & ~st->light_mask[l]) {
            if (light->type == LU_LIGHT_ENVIRONMENT) env_i++;
            else sum = lu_v3_add(sum, mnee(st, v, l, rng));
            continue;
        }
        if (light->type == LU_LIGHT_ENVIRONMENT) {
            const pt_env *e = &st->envs[env_i++];
            lu_vec3 wl;
            float pl, pv;
            float u1 = rnd(rng), u2 = rnd(rng);
            if (!env_sample(e, u1, u2, &wl, &pl)) continue;
            lu_vec3 f = vertex_eval(v, wl, &pv);
            if (lu_v3_maxc(f) <= 0.0f) continue;
            lu_vec3 tr = transmit(st, v->x, wl, LU_K_FAR, v->mask, rng);
            if (lu_v3_maxc(tr) <= 0.0f) continue;
            float w = mis ? lu_k_power_heuristic(pl, pv) : 1.0f;
            lu_vec3 le = env_radiance(light, wl);
            sum = lu_v3_add(sum, lu_v3_scale(lu_v3_mul(lu_v3_mul(f, le), tr), w / pl));
            continue;
        }
        /* Point and spot lights reach medium vertices through segment_nee. */
        if (!v->surface && st->equiangular && light->type != LU_LIGHT_DIRECTIONAL) continue;
        lu_k_light_sample ls = lu_k_light_arrive(st->klights[l], v->x);
        if (lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        float pv;
        lu_vec3 f = vertex_eval(v, ls.wl, &pv);
        if (lu_v3_maxc(f) <= 0.0f) continue;
        lu_vec3 tr = transmit(st, v->x, ls.wl, ls.dist, v->mask, rng);
        sum = lu_v3_add(sum, lu_v3_mul(lu_v3_mul(f, ls.irradiance), tr));
    }
    return sum;
}

/* MIS weight of an environment hit reached by sampling with pdf `pdf_path`. */
static float env_hit_weight(const pt_state *st, const pt_env *e, lu_vec3 dir, float pdf_path) {
    (void)st;
    return lu_k_power_heuristic(pdf_path, env_pdf(e, dir));
}

/* Scattering coefficient times phase at a beam point y, light travelling
 * along u and leaving towards v (unit). */
static lu_vec3 beam_scatter(const pt_state *st, lu_vec3 y, lu_vec3 u, lu_vec3 v, uint64_t mask) {
    lu_vec3 sum = lu_v3s(0.0f);
    for (int m = 0; m < st->medium_count; m++) {
        const pt_medium *pm = &st->media[m];
        if (!medium_active(pm, mask)) continue;
        const lu_medium *med = &st->scene->media[m];
        if (y.x < pm->box.lo.x || y.y < pm->box.lo.y || y.z < pm->box.lo.z || y.x > pm->box.hi.x ||
            y.y > pm->box.hi.y || y.z > pm->box.hi.z)
            continue;
        float dens = pm->constant ? pm->cdens : lu_grid_sample(&med->grid, lu_affine_point(&med->world_to_index, y));
        if (dens <= 0.0f) continue;
        sum = lu_v3_madd(sum, med->sigma_s, dens * lu_k_phase_hg(lu_v3_dot(u, v), med->phase_g));
    }
    return sum;
}

/* Clips [*a, *b] of the line o + t d to a spot light's outer cone (its
 * falloff is exactly zero outside). A cone of half-angle below 90 degrees
 * meets a line in one interval: cut at the roots of the cone's quadratic and
 * keep the hull of the pieces whose midpoints are inside. */
static bool clip_to_cone(lu_k_light kl, lu_vec3 o, lu_vec3 d, float *a, float *b) {
    float c = kl.cos_outer;
    if (!(c > 0.0f)) return true;
    lu_vec3 w = lu_v3_sub(o, kl.position);
    float wa = lu_v3_dot(w, kl.direction), da = lu_v3_dot(d, kl.direction);
    float qa = da * da - c * c, qb = 2.0f * (wa * da - c * c * lu_v3_dot(w, d)), qc = wa * wa - c * c * lu_v3_dot(w, w);
    float cut[4] = {*a, *b, *a, *a};
    int n = 2;
    float disc = qb * qb - 4.0f * qa * qc;
    if (disc >= 0.0f && qa != 0.0f) {
        float sq = sqrtf(disc);
        float r1 = (-qb - sq) / (2.0f * qa), r2 = (-qb + sq) / (2.0f * qa);
        if (r1 > *a && r1 < *b) cut[n++] = r1;
        if (r2 > *a && r2 < *b) cut[n++] = r2;
    }
    for (int i = 1; i < n; i++) /* sort the few cut points */
        for (int j = i; j > 0 && cut[j] < cut[j - 1]; j--) {
            float t = cut[j];
            cut[j] = cut[j - 1];
            cut[j - 1] = t;
        }
    float lo = INFINITY, hi = -INFINITY;
    for (int i = 0; i + 1 < n; i++) {
        float m = 0.5f * (cut[i] + cut[i + 1]);
        lu_vec3 y = lu_v3_sub(lu_v3_madd(o, d, m), kl.position);
        float len = lu_v3_len(y);
        if (len > 0.0f && lu_v3_dot(y, kl.direction) >= c * len) {
            lo = fminf(lo, cut[i]);
            hi = fmaxf(hi, cut[i + 1]);
        }
    }
    *a = lo;
    *b = hi;
    return hi > lo;
}

/* Direct light from point and spot lights scattered towards -d anywhere on
 * the segment o + t d, t in (0, t_end), through the media active under
 * `mask`. Free-flight vertices near such a light carry 1 / d^2, a weight of
 * infinite variance; sampling t equiangularly about the light (Kulla and
 * Fajardo 2012) cancels it. One sample per light, from the equiangular or an
 * exponential density (rate: the media's typical extinction) with
 * probability 1/2 each, divided by the mixture (one-sample balance MIS);
 * transmittance to t is estimated independently (exact or ratio tracking). */
static lu_vec3 segment_nee(const pt_state *st, lu_vec3 o, lu_vec3 d, float t_end, uint64_t mask, lu_k_rng *rng) {
    const lu_scene *sc = st->scene;
    lu_vec3 sum = lu_v3s(0.0f);
    float a0 = INFINITY, b0 = -INFINITY, lambda = 0.0f;
    for (int m = 0; m < st->medium_count; m++) {
        const pt_medium *pm = &st->media[m];
        float a, b;
        if (!medium_active(pm, mask) || !medium_span(pm, o, d, t_end, &a, &b)) continue;
        a0 = fminf(a0, a);
        b0 = fmaxf(b0, b);
        lambda = fmaxf(lambda, pm->lambda);
    }
    if (!(b0 > a0)) return sum;
    uint64_t enclosing = mask & st->sealed_bits;
    for (int l = 0; l < sc->light_count; l++) {
        lu_light_type type = sc->lights[l].type;
        if (type != LU_LIGHT_POINT && type != LU_LIGHT_SPOT) continue;
        if (enclosing & ~st->light_mask[l]) continue;
        const lu_k_light kl = st->klights[l];
        float ta = a0, tb = b0;
        if (type == LU_LIGHT_SPOT && !clip_to_cone(kl, o, d, &ta, &tb)) continue;
        float len = tb - ta;
        lu_vec3 start = lu_v3_madd(o, d, ta);
        lu_k_equiangular eq = lu_k_equiangular_make(kl.position, start, d, len);
        bool use_exp = lambda * len > 1e-4f;
        float pick = rnd(rng), u = rnd(rng);
        float s = !use_exp || pick < 0.5f ? lu_k_equiangular_sample(eq, u) : lu_k_trunc_exp_sample(lambda, len, u);
        s = fminf(fmaxf(s, 0.0f), len);
        float pdf = lu_k_equiangular_pdf(eq, s);
        if (use_exp) pdf = 0.5f * (pdf + lu_k_trunc_exp_pdf(lambda, len, s));
        if (!(pdf > 0.0f) || !isfinite(pdf)) continue;
        lu_vec3 y = lu_v3_madd(start, d, s);
        lu_k_light_sample ls = lu_k_light_arrive(kl, y);
        if (lu_v3_maxc(ls.irradiance) <= 0.0f) continue;
        lu_vec3 sy = beam_scatter(st, y, lu_v3_neg(ls.wl), lu_v3_neg(d), mask);
        if (lu_v3_maxc(sy) <= 0.0f) continue;
        lu_vec3 t0 = media_transmittance(st, o, d, ta + s, mask, rng);
        if (lu_v3_maxc(t0) <= 0.0f) continue;
        lu_vec3 tl = transmit(st, y, ls.wl, ls.dist, mask, rng);
        if (lu_v3_maxc(tl) <= 0.0f) continue;
        lu_vec3 c = lu_v3_mul(lu_v3_mul(t0, sy), lu_v3_mul(ls.irradiance, tl));
        sum = lu_v3_add(sum, lu_v3_scale(c, 1.0f / pdf));
    }
    return sum;
}

/* Whether segment_nee on a ray under `mask` at this depth has nothing to do
 * (off, or every point and spot light lies outside a sealed medium the ray
 * is in): it would then draw no random numbers and return zero. */
static bool segment_nee_idle(const pt_state *st, uint64_t mask, int depth) {
    if (!(st->equiangular && st->have_point_lights && depth + 1 <= st->max_depth)) return true;
    uint64_t enclosing = mask & st->sealed_bits;
    if (!enclosing) return false;
    const lu_scene *sc = st->scene;
    for (int l = 0; l < sc->light_count; l++) {
        lu_light_type type = sc->lights[l].type;
        if ((type == LU_LIGHT_POINT || type == LU_LIGHT_SPOT) && !(enclosing & ~st->light_mask[l])) return false;
    }
    return true;
}

/* Contribution of one beam to vertex v through a point y on it. */
static lu_vec3 beam_contrib(const pt_state *st, const pt_vertex *v, const pt_beam *b, lu_k_rng *rng) {
    /* One sample of y, from the equiangular or the exponential density with
     * probability 1/2 each: the one-sample balance heuristic divides by the
     * mixture density. */
    lu_k_equiangular eq = lu_k_equiangular_make(v->x, b->o, b->u, b->len);
    bool use_exp = b->lambda * b->len > 1e-4f;
    float pick = rnd(rng), u = rnd(rng);
    float s = !use_exp || pick < 0.5f ? lu_k_equiangular_sample(eq, u) : lu_k_trunc_exp_sample(b->lambda, b->len, u);
    s = fminf(fmaxf(s, 0.0f), b->len);
    float pdf = lu_k_equiangular_pdf(eq, s);
    if (use_exp) pdf = 0.5f * (pdf + lu_k_trunc_exp_pdf(b->lambda, b->len, s));
    if (!(pdf > 0.0f) || !isfinite(pdf)) return lu_v3s(0.0f);
    lu_vec3 y = lu_v3_madd(b->o, b->u, s);
    lu_vec3 to = lu_v3_sub(v->x, y);
    float d2 = lu_v3_dot(to, to);
    if (!(d2 > 0.0f)) return lu_v3s(0.0f);
    float dist = sqrtf(d2);
    lu_vec3 vdir = lu_v3_scale(to, 1.0f / dist);
    float pv;
    lu_vec3 f = vertex_eval(v, lu_v3_neg(vdir), &pv);
    if (lu_v3_maxc(f) <= 0.0f) return lu_v3s(0.0f);
    lu_vec3 sy = beam_scatter(st, y, b->u, vdir, b->mask);
    if (lu_v3_maxc(sy) <= 0.0f) return lu_v3s(0.0f);
    lu_vec3 tb = media_transmittance(st, b->o, b->u, s, b->mask, rng);
    if (lu_v3_maxc(tb) <= 0.0f) return lu_v3s(0.0f);
    lu_vec3 txy = transmit(st, v->x, lu_v3_neg(vdir), dist, v->mask, rng);
    if (lu_v3_maxc(txy) <= 0.0f) return lu_v3s(0.0f);
    lu_vec3 c = lu_v3_mul(lu_v3_mul(f, b->flux), lu_v3_mul(lu_v3_mul(tb, sy), txy));
    return lu_v3_scale(c, 1.0f / (d2 * pdf));
}

/* Connects vertex v to every light beam. */
static lu_vec3 connect_beams(const pt_state *st, const pt_vertex *v, const pt_beam *beams, int nbeams, lu_k_rng *rng) {
    lu_vec3 sum = lu_v3s(0.0f);
    for (int i = 0; i < nbeams; i++) sum = lu_v3_add(sum, beam_contrib(st, v, &beams[i], rng));
    return sum;
}

/* Light subpaths from every point, spot and directional light through
 * refracting boundaries; appends the beams (segments after the first specular
 * event that pass through some medium) and returns their count. */
static int trace_light_paths(const pt_state *st, lu_k_rng *rng, pt_beam *beams, int cap) {
    const lu_scene *s = st->scene;
    int nb = 0;
    for (int l = 0; l < s->light_count; l++) {
        const lu_light *light = &s->lights[l];
        if (light->type == LU_LIGHT_ENVIRONMENT) continue;
        const lu_k_light kl = st->klights[l];
        for (int rep = 0; rep < st->light_paths; rep++) {
            lu_vec3 o, d, flux;
            uint64_t mask = st->light_mask[l];
            float u1 = rnd(rng), u2 = rnd(rng);
            if (light->type == LU_LIGHT_DIRECTIONAL) {
                lu_vec3 t, bb;
                lu_k_basis(kl.direction, &t, &bb);
                float r = st->refract_radius * sqrtf(u1), phi = 2.0f * LU_PI * u2;
                float back =
                    lu_v3_len(lu_v3_sub(st->refract_center, st->scene_center)) + st->scene_radius + st->refract_radius;
                o = lu_v3_madd(lu_v3_madd(lu_v3_madd(st->refract_center, kl.direction, back), t, r * cosf(phi)), bb,
                               r * sinf(phi));
                d = lu_v3_neg(kl.direction);
                flux = lu_v3_scale(kl.intensity, LU_PI * st->refract_radius * st->refract_radius);
            } else {
                o = kl.position;
                lu_vec3 to = lu_v3_sub(st->refract_center, o);
                float dist = lu_v3_len(to);
                float pdf;
                if (dist <= st->refract_radius * 1.0001f) {
                    d = lu_k_sample_sphere(u1, u2);
                    pdf = 1.0f / (4.0f * LU_PI);
                } else {
                    float sin2 = st->refract_radius * st->refract_radius / (dist * dist);
                    float cos_max = sqrtf(fmaxf(0.0f, 1.0f - sin2));
                    d = lu_k_sample_cone(lu_v3_scale(to, 1.0f / dist), cos_max, u1, u2);
                    pdf = lu_k_cone_pdf(cos_max);
                }
                float fall = 1.0f;
                if (kl.type == LU_K_LIGHT_SPOT)
                    fall = lu_smoothstep(kl.cos_outer, kl.cos_inner, lu_v3_dot(d, kl.direction));
                flux = lu_v3_scale(kl.intensity, fall / pdf);
            }
            bool specular = false;
            /* The segment right after refracting into a medium as the first
             * specular event: its points are reached by mnee from the
             * camera's vertices, so it is no beam (nothing counted twice). */
            bool mnee_owned = false;
            for (int seg = 0; seg < PT_MAX_LIGHT_SEGMENTS && lu_v3_maxc(flux) > 0.0f; seg++) {
                lu_hit hit;
                bool has = st->surf && lu_accel_closest(st->surf, o, d, 0.0f, LU_K_FAR, &hit);
                float t_end = has ? hit.t : LU_K_FAR;
                if (specular && !mnee_owned && nb < cap) { /* cap: every segment of every subpath fits */
                    /* Clip to the media present along the segment. */
                    float a0 = INFINITY, b0 = -INFINITY, lambda = 0.0f;
                    for (int m = 0; m < st->medium_count; m++) {
                        const pt_medium *pm = &st->media[m];
                        float a, b;
                        if (!medium_active(pm, mask) || !medium_span(pm, o, d, t_end, &a, &b)) continue;
                        a0 = fminf(a0, a);
                        b0 = fmaxf(b0, b);
                        lambda = fmaxf(lambda, pm->lambda);
                    }
                    if (b0 > a0) {
                        pt_beam *bm = &beams[nb++];
                        bm->o = lu_v3_madd(o, d, a0);
                        bm->u = d;
                        bm->len = b0 - a0;
                        bm->flux = flux; /* nothing attenuates before a0 */
                        bm->mask = mask;
                        bm->lambda = lambda;
                    }
                }
                mnee_owned = false;
                flux = lu_v3_mul(flux, media_transmittance(st, o, d, t_end, mask, rng));
                if (!has) break;
                const pt_surf *sf = &st->surf_info[hit.mesh_id];
                if (sf->kind == SURF_OPAQUE) break;
                const pt_medium *pm = &st->media[sf->index];
                if (pm->diffuse) break; /* a diffuse interface ends the specular chain */
                lu_vec3 p = lu_v3_madd(o, d, hit.t);
                if (!pm->refract) {
                    float c = lu_v3_dot(hit.ng, d);
                    flux = lu_v3_scale(flux, lu_k_fresnel_transmittance(c, pm->eta));
                    mask = mask_set(mask, pm->bit, c < 0.0f);
                    o = offset_point(p, hit.ng, d, st->eps);
                    continue;
                }
                bool entering = lu_v3_dot(hit.ng, d) < 0.0f;
                lu_k_dielectric_sample ds = lu_k_sample_dielectric(d, hit.ng, pm->eta, rnd(rng));
                if (ds.refracted) mask = mask_set(mask, pm->bit, entering);
                mnee_owned = !specular && ds.refracted && entering;
                d = ds.wi;
                o = offset_point(p, hit.ng, d, st->eps);
                specular = true;
            }
        }
    }
    /* Several subpaths per light: each carries 1 / light_paths of the flux. */
    float inv = 1.0f / (float)(st->light_paths > 0 ? st->light_paths : 1);
    for (int i = 0; i < nb; i++) beams[i].flux = lu_v3_scale(beams[i].flux, inv);
    return nb;
}

/* beta / avg(r): the spectral-MIS weight of a contribution (r = 1 under
 * spectral tracking). */
static lu_vec3 spectral_weight(lu_vec3 beta, lu_vec3 r) { return lu_v3_scale(beta, 1.0f / lu_v3_avg(r)); }

/* ---- one camera path ---------------------------------------------------------------------- */

/* hero: the channel whose coefficients choose free-flight events (spectral
 * MIS), or -1 for spectral tracking. */
static lu_vec3 trace_path(const pt_state *st, lu_vec3 o, lu_vec3 d, int hero, pt_beam *beams, pt_stats *cs,
                          lu_k_rng *rng) {
    const lu_scene *s = st->scene;
    lu_vec3 L = lu_v3s(0.0f), beta = lu_v3s(1.0f);
    lu_vec3 r = lu_v3s(1.0f); /* spectral MIS: p_c / p_hero of the free-flight decisions so far */
    float rr_scale = 1.0f;    /* product of dielectric radiance factors: RR looks at beta / rr_scale */
    uint64_t mask = st->camera_mask;
    int depth = 0, specular_events = 0;
    bool primary = true;    /* still on the camera ray: straight boundaries apply no F_t (reference) */
    bool scattered = false; /* any scattering vertex yet (the background is a backdrop only) */
    bool prev_delta = true; /* last direction chosen by the camera or a dielectric: no MIS */
    float prev_pdf = 0.0f;

    /* guide=dwivedi: the outward normal at the last boundary point of a
     * sealed medium, and the pending guided step's strategy and phase. */
    lu_vec3 guide_n = lu_v3s(0.0f);
    bool have_guide_n = false, guide_pending = false, guide_pick = false;
    int guide_m = -1;
    float guide_phase = 0.0f;

    int nbeams = 0;
    bool beams_on = st->have_refract && st->have_delta_lights && st->max_depth >= 2;
    if (beams_on && st->light_paths > 0) nbeams = trace_light_paths(st, rng, beams, st->beam_cap);

    PT_COUNT(cs, paths);
    for (int guard = 0; guard < (1 << 24); guard++) {
        PT_COUNT(cs, segments);
        lu_hit hit;
        bool has;
        pt_flight fl;
        /* segment_nee needs t_end first unless it has nothing to do here;
         * then the ray cast can be fused with the free flight. */
        if (guide_pending) { /* lu_pt_guide_applies held at the vertex: no other medium, no segment NEE */
            guide_pending = false;
            fl = lu_pt_guided_step(st, guide_m, o, d, guide_n, guide_pick, guide_phase, hero, &beta, &r, rng, &hit, &has);
        } else if (!segment_nee_idle(st, mask, depth) ||
                   !lu_pt_free_flight_to_surface(st, o, d, mask, &beta, &r, hero, rng, &fl, &hit, &has)) {
            has = st->surf && lu_accel_closest(st->surf, o, d, 0.0f, LU_K_FAR, &hit);
            float t_end = has ? hit.t : LU_K_FAR;
            if (!segment_nee_idle(st, mask, depth))
                L = lu_v3_add(L, lu_v3_mul(spectral_weight(beta, r), segment_nee(st, o, d, t_end, mask, rng)));
            fl = lu_pt_free_flight(st, o, d, t_end, mask, &beta, &r, hero, rng);
        }
        L = lu_v3_add(L, fl.le);
        if (fl.event == LU_K_EVENT_ABSORB || lu_v3_maxc(beta) <= 0.0f) break;

        if (fl.event == LU_K_EVENT_SCATTER) {
            if (++depth > st->max_depth) break;
            PT_COUNT(cs, vertices);
            if (mask & st->sealed_bits) PT_COUNT(cs, sealed_vertices);
            pt_vertex v = {0};
            v.has_seed_n = have_guide_n;
            v.seed_n = guide_n;
            v.surface = false;
            v.x = lu_v3_madd(o, d, fl.t);
            v.d = d;
            v.g = s->media[fl.medium].phase_g;
            v.mask = mask;
            L = lu_v3_add(L, lu_v3_mul(spectral_weight(beta, r), nee(st, &v, depth < st->max_depth, rng)));
            if (beams_on && depth + 1 <= st->max_depth) {
                PT_COUNT(cs, beam_vertices);
                L = lu_v3_add(
                    L,
                    lu_v3_mul(spectral_weight(beta, r),
                              connect_beams(st, &v, beams, nbeams, rng)));
            }
            if (depth >= st->max_depth) break;
            lu_vec3 wi;
            if (st->guide && hero >= 0 && have_guide_n && lu_pt_guide_applies(st, fl.medium, mask) &&
                segment_nee_idle(st, mask, depth)) {
                /* One-sample mixture of the classical and the guided walk;
                 * lu_pt_guided_step weights the direction and distance together. */
                float us = rnd(rng), u1 = rnd(rng), u2 = rnd(rng);
                const pt_medium *gm = &st->media[fl.medium];
                guide_pick = us < gm->guide_prob;
                if (guide_pick) {
                    float mu0 = lu_pt_dwivedi_sample(gm->v0[hero], gm->vlog[hero], u1);
                    wi = lu_k_dir_about(guide_n, mu0, 2.0f * LU_PI * u2);
                } else {
                    wi = lu_k_sample_hg(d, v.g, u1, u2);
                }
                guide_phase = lu_k_phase_hg(lu_v3_dot(d, wi), v.g);
                guide_m = fl.medium;
                guide_pending = true;
            } else {
                float u1 = rnd(rng), u2 = rnd(rng);
                wi = lu_k_sample_hg(d, v.g, u1, u2);
            }
            prev_pdf = lu_k_phase_hg(lu_v3_dot(d, wi), v.g);
            prev_delta = false;
            primary = false;
            scattered = true;
            o = v.x;
            d = wi;
        } else if (!has) {
            /* Escaped: the environment (and, for unscattered paths, the backdrop). */
            lu_vec3 le = scattered ? lu_v3s(0.0f) : s->background;
            int env_i = 0;
            for (int l = 0; l < s->light_count; l++) {
                if (s->lights[l].type != LU_LIGHT_ENVIRONMENT) continue;
                const pt_env *e = &st->envs[env_i++];
                float w = prev_delta ? 1.0f : env_hit_weight(st, e, d, prev_pdf);
                le = lu_v3_madd(le, env_radiance(&s->lights[l], d), w);
            }
            L = lu_v3_add(L, lu_v3_mul(spectral_weight(beta, r), le));
            break;
        } else {
            lu_vec3 p = lu_v3_madd(o, d, hit.t);
            const pt_surf *sf = &st->surf_info[hit.mesh_id];
            if (sf->kind == SURF_BOUNDARY) {
                const pt_medium *pm = &st->media[sf->index];
                const lu_medium *med = &s->media[sf->index];
                float c = lu_v3_dot(hit.ng, d);
                bool entering = c < 0.0f;
                if (pm->diffuse || pm->refract) {
                    guide_n = hit.ng;
                    have_guide_n = true;
                }
                if (cs && (pm->diffuse || pm->refract)) {
                    if (entering) cs->entries++;
                    else cs->inside_hits++;
                    if (specular_events >= PT_MAX_SPECULAR) cs->capped++;
                }
                if (pm->diffuse) {
                    /* Chiang, Kutz and Burley 2016: the interface transmits
                     * every ray, in a cosine-distributed direction about the
                     * normal of the side it leaves towards (a white Lambertian
                     * transmitter, f cos / pdf = 1, no Fresnel); a walk ends
                     * at its first boundary hit. Not a scattering vertex for
                     * max_depth (as dielectric events), but it is diffuse, so
                     * it takes next-event estimation and MIS. */
                    if (++specular_events > PT_MAX_SPECULAR) break;
                    if (cs && !entering) cs->exits++;
                    lu_vec3 n = entering ? lu_v3_neg(hit.ng) : hit.ng;
                    mask = mask_set(mask, pm->bit, entering);
                    pt_vertex v = {0};
                    v.has_seed_n = have_guide_n;
                    v.seed_n = guide_n;
                    v.surface = true;
                    v.lambert_t = true;
                    v.x = lu_v3_madd(p, n, st->eps);
                    v.n = n;
                    v.wo = lu_v3_neg(d);
                    v.mask = mask;
                    L = lu_v3_add(L, lu_v3_mul(spectral_weight(beta, r), nee(st, &v, true, rng)));
                    if (beams_on && depth + 1 <= st->max_depth)
                        L = lu_v3_add(L, lu_v3_mul(spectral_weight(beta, r),
                                                   connect_beams(st, &v, beams, nbeams, rng)));
                    float u1 = rnd(rng), u2 = rnd(rng);
                    d = lu_k_sample_cosine(n, u1, u2);
                    prev_pdf = fmaxf(lu_v3_dot(n, d), 0.0f) * LU_K_INV_PI;
                    if (!(prev_pdf > 0.0f)) break;
                    prev_delta = false;
                    primary = false;
                    scattered = true;
                    o = v.x;
                    continue;
                }
                if (!pm->refract) {
                    /* The seed model: light passes straight, weighted by F_t
                     * (not on the camera ray), and the coat reflects direct
                     * light weighted by F_r at every entry. */
                    if (entering && depth + 1 <= st->max_depth) {
                        pt_vertex v = {0};
                        v.has_seed_n = have_guide_n;
                        v.seed_n = guide_n;
                        v.surface = true;
                        v.x = lu_v3_madd(p, hit.ng, st->eps);
                        v.n = hit.ng;
                        v.wo = lu_v3_neg(d);
                        v.mat = &med->surface;
                        v.mask = mask;
                        float fr = lu_k_fresnel_reflectance(c, pm->eta);
                        if (fr > 0.0f)
                            L = lu_v3_add(
                                L, lu_v3_scale(lu_v3_mul(spectral_weight(beta, r), nee(st, &v, false, rng)), fr));
                    }
                    if (!primary) beta = lu_v3_scale(beta, lu_k_fresnel_transmittance(c, pm->eta));
                    mask = mask_set(mask, pm->bit, entering);
                    o = offset_point(p, hit.ng, d, st->eps);
                } else {
                    if (++specular_events > PT_MAX_SPECULAR) break;
                    lu_k_dielectric_sample ds = lu_k_sample_dielectric(d, hit.ng, pm->eta, rnd(rng));
                    if (cs && !entering) {
                        if (ds.refracted) {
                            cs->exits++;
                        } else {
                            cs->reflected++;
                            lu_vec3 t_unused;
                            if (!lu_k_refract(d, lu_v3_neg(hit.ng), 1.0f / pm->eta, &t_unused)) cs->tir++;
                        }
                    }
                    if (ds.refracted) {
                        mask = mask_set(mask, pm->bit, entering);
                        beta = lu_v3_scale(beta, ds.weight);
                        rr_scale *= ds.weight;
                    }
                    d = ds.wi;
                    o = offset_point(p, hit.ng, d, st->eps);
                    prev_delta = true;
                    primary = false;
                }
                continue;
            }
            /* Opaque surface: Lambert + Blinn-Phong. */
            if (++depth > st->max_depth) break;
            const lu_object *ob = &s->objects[sf->index];
            const uint32_t *tri = &ob->mesh.indices[3u * hit.prim_id];
            float w0 = 1.0f - hit.u - hit.v;
            lu_vec3 n = lu_v3_norm(lu_v3_add(
                lu_v3_add(lu_v3_scale(ob->mesh.normals[tri[0]], w0), lu_v3_scale(ob->mesh.normals[tri[1]], hit.u)),
                lu_v3_scale(ob->mesh.normals[tri[2]], hit.v)));
            lu_vec3 ng = hit.ng;
            if (lu_v3_dot(ng, d) > 0.0f) ng = lu_v3_neg(ng);
            if (lu_v3_dot(n, ng) < 0.0f) n = lu_v3_neg(n);
            pt_vertex v = {0};
            v.has_seed_n = have_guide_n;
            v.seed_n = guide_n;
            v.surface = true;
            v.x = lu_v3_madd(p, ng, st->eps);
            v.n = n;
            v.wo = lu_v3_neg(d);
            v.mat = &ob->material;
            v.mask = mask;
            L = lu_v3_add(L, lu_v3_mul(spectral_weight(beta, r), nee(st, &v, depth < st->max_depth, rng)));
            if (beams_on && depth + 1 <= st->max_depth)
                L = lu_v3_add(
                    L,
                    lu_v3_mul(spectral_weight(beta, r),
                              connect_beams(st, &v, beams, nbeams, rng)));
            if (depth >= st->max_depth) break;
            float ul = rnd(rng), u1 = rnd(rng), u2 = rnd(rng), pdf;
            const lu_material *mat = &ob->material;
            lu_vec3 wi = lu_k_sample_blinn_phong(mat->albedo, mat->specular, mat->shininess, n, v.wo, ul, u1, u2, &pdf);
            if (!(pdf > 0.0f) || lu_v3_dot(wi, ng) <= 0.0f) break;
            lu_vec3 f = lu_k_blinn_phong(mat->albedo, mat->specular, mat->shininess, n, v.wo, wi);
            beta = lu_v3_mul(beta, lu_v3_scale(f, 1.0f / pdf));
            prev_pdf = pdf;
            prev_delta = false;
            primary = false;
            scattered = true;
            o = v.x;
            d = wi;
        }
        if (st->rr && depth >= st->rr_depth) {
            float q = fminf(1.0f, lu_v3_maxc(spectral_weight(beta, r)) / rr_scale);
            if (!(q > 0.0f)) break;
            if (q < 1.0f) {
                if (rnd(rng) >= q) break;
                beta = lu_v3_scale(beta, 1.0f / q);
            }
        }
    }
    /* A non-finite sample would poison the pixel's running mean forever. */
    return lu_v3_finite(L) ? L : lu_v3s(0.0f);
}

/* ---- the render loop ------------------------------------------------------------------------- */

static void render_rows(void *ctx, int64_t begin, int64_t end, int thread) {
    pt_state *st = ctx;
    const lu_camera *cam = &st->scene->camera;
    for (int64_t y = begin; y < end; y++) {
        for (int x = 0; x < cam->width; x++) {
            uint32_t pixel = (uint32_t)(y * cam->width + x);
            double *acc = &st->accum[3 * (size_t)pixel];
            /* Hero channels cycle through a pixel's samples from a hashed
             * offset: every three samples are one multi-sample balance-MIS
             * estimate over the channels (no binomial colour noise), and the
             * random offset keeps any sample count unbiased. */
            uint32_t hero0 = lu_k_hash_u32(pixel ^ (st->seed * 0x85EBCA6Bu)) % 3u;
            for (int k = st->pass_begin; k < st->pass_end; k++) {
                lu_k_rng rng = lu_k_rng_make(st->seed, pixel, (uint32_t)k);
                float ox = 0.5f, oy = 0.5f;
                if (st->jitter) {
                    ox = rnd(&rng);
                    oy = rnd(&rng);
                }
                lu_vec3 d = lu_k_camera_dir(st->cam, (float)x + ox, (float)y + oy);
                int hero = st->spectral == SPECTRAL_HERO ? (int)((hero0 + (uint32_t)k) % 3u) : -1;
                lu_vec3 c = trace_path(st, cam->position, d, hero, st->beam_buf + (size_t)thread * st->beam_cap,
                                       st->stats_buf ? &st->stats_buf[thread] : NULL, &rng);
                acc[0] += c.x;
                acc[1] += c.y;
                acc[2] += c.z;
            }
        }
        long long done = atomic_fetch_add(&st->rows_done, 1) + 1;
        if (thread == 0) lu_progress_update(&st->progress, done);
    }
}

static void print_stats(const pt_stats *per_thread, int threads) {
    pt_stats t = {0};
    for (int i = 0; i < threads; i++) {
        const pt_stats *c = &per_thread[i];
        t.paths += c->paths;
        t.segments += c->segments;
        t.vertices += c->vertices;
        t.sealed_vertices += c->sealed_vertices;
        t.entries += c->entries;
        t.inside_hits += c->inside_hits;
        t.reflected += c->reflected;
        t.tir += c->tir;
        t.exits += c->exits;
        t.capped += c->capped;
        t.beam_vertices += c->beam_vertices;
    }
    double p = t.paths ? (double)t.paths : 1.0, e = t.entries ? (double)t.entries : 1.0;
    lu_log_msg(LU_LOG_INFO,
            "pathtrace stats: %llu paths; per path: %.2f segments, %.2f volume vertices (%.2f in sealed media), "
            "%.3f entries, %.2f boundary hits from inside, %.2f internal reflections (%.2f total), %.3f exits, "
            "%.2f beam-connected vertices; per entry: %.1f sealed vertices, %.2f internal reflections; "
            "interface cap reached %llu times\n",
            (unsigned long long)t.paths, (double)t.segments / p, (double)t.vertices / p, (double)t.sealed_vertices / p,
            (double)t.entries / p, (double)t.inside_hits / p, (double)t.reflected / p, (double)t.tir / p,
            (double)t.exits / p, (double)t.beam_vertices / p, (double)t.sealed_vertices / e, (double)t.reflected / e,
            (unsigned long long)t.capped);
}

static void resolve(pt_state *st, int passes) {
    size_t n = (size_t)st->out->width * st->out->height * 3;
    double inv = 1.0 / (double)passes;
    for (size_t i = 0; i < n; i++) st->out->rgb[i] = (float)(st->accum[i] * inv);
}

static void pt_destroy(void *state) {
    pt_state *st = state;
    if (!st) return;
    if (st->surf) lu_accel_destroy(st->surf);
    for (int m = 0; st->media && m < st->medium_count; m++) {
        lu_pt_majorant_destroy(&st->media[m].maj);
        if (st->media[m].inside) lu_accel_destroy(st->media[m].inside);
        lu_free(st->media[m].neighbours);
    }
    for (int i = 0; st->envs && i < st->env_count; i++) env_destroy(&st->envs[i]);
    lu_free(st->envs);
    lu_free(st->media);
    lu_free(st->surf_info);
    lu_free(st->light_mask);
    lu_free(st->beam_buf);
    lu_free(st->stats_buf);
    lu_free(st);
}

static lu_result pt_prepare(const lu_scene *scene, const double *params, lu_backend backend, void **out,
                            lu_error *err) {
    (void)backend;
    pt_state *st = lu_calloc(1, sizeof *st);
    if (!st) return lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory");
    st->spp = (int)params[P_SPP];
    st->max_depth = (int)params[P_MAX_DEPTH];
    st->rr = params[P_RR] != 0.0;
    st->rr_depth = (int)params[P_RR_DEPTH];
    st->seed = (uint32_t)params[P_SEED];
    st->boundary_mode = (int)params[P_BOUNDARY];
    st->block = (float)params[P_BLOCK];
    st->jitter = params[P_JITTER] != 0.0;
    st->light_paths = (int)params[P_LIGHT_PATHS];
    st->spectral = (int)params[P_SPECTRAL];
    st->equiangular = params[P_EQUIANGULAR] != 0.0;
    st->transmittance = (int)params[P_TRANSMITTANCE];
    st->stats = params[P_STATS] != 0.0;
    st->guide = params[P_GUIDE] != 0.0;
    lu_result r = LU_OK;

    st->eps = lu_scene_ray_epsilon(scene);
    lu_aabb bounds = lu_scene_bounds(scene);
    if (lu_aabb_valid(bounds)) {
        st->scene_center = lu_v3_scale(lu_v3_add(bounds.lo, bounds.hi), 0.5f);
        st->scene_radius = 0.5f * lu_v3_len(lu_v3_sub(bounds.hi, bounds.lo));
    }

    if (scene->medium_count > PT_MAX_MEDIA) {
        lu_free(st);
        return lu_fail(err, LU_ERR_LIMIT, "pathtrace: %d media (at most %d)", scene->medium_count, PT_MAX_MEDIA);
    }
    st->medium_count = scene->medium_count;
    st->media = lu_calloc((size_t)(scene->medium_count ? scene->medium_count : 1), sizeof *st->media);
    int surf_cap = scene->object_count + scene->medium_count;
    st->surf_info = lu_calloc((size_t)(surf_cap ? surf_cap : 1), sizeof *st->surf_info);
    if (!st->media || !st->surf_info) r = lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory");
    if (r == LU_OK && surf_cap) r = lu_accel_create(&st->surf, err);

    int bits = 0;
    lu_aabb rbox = lu_aabb_empty();
    for (int m = 0; m < scene->medium_count && r == LU_OK; m++) {
        const lu_medium *med = &scene->media[m];
        pt_medium *pm = &st->media[m];
        pm->sigma_t = lu_v3_add(med->sigma_a, med->sigma_s);
        pm->sigma_max = lu_v3_maxc(pm->sigma_t);
        pm->constant = med->kind == LU_DENSITY_CONSTANT;
        pm->cdens = med->constant;
        pm->eta = med->eta;
        pm->box = med->bounds;
        pm->bit = -1;
        if (pm->constant) {
            pm->lambda = lu_v3_avg(pm->sigma_t) * pm->cdens;
            for (int c = 0; c < 3; c++) {
                /* similarity-reduced albedo for anisotropic media */
                double ss = lu_v3_get(med->sigma_s, c) * (1.0 - med->phase_g), sa = lu_v3_get(med->sigma_a, c);
                pm->v0[c] = (float)lu_pt_dwivedi_v0(ss + sa > 0.0 ? ss / (ss + sa) : 0.0);
                pm->vlog[c] = lu_pt_dwivedi_log(pm->v0[c]);
            }
            /* The guide ignores the phase function, so each step's weight
             * phase / mixture strays from 1 the more anisotropic the medium,
             * and over a long walk the product of those weights has a heavy
             * tail: the guided share falls with |g|, 1 - max(1/2, |g|^(1/8)),
             * the rule of Blender's Cycles random walk (0.5 at g = 0, 0.14 at
             * 0.3, 0.03 at 0.8). */
            pm->guide_prob = 1.0f - fmaxf(0.5f, powf(fabsf(med->phase_g), 0.125f));
            if (pm->guide_prob < 0.01f) pm->guide_prob = 0.0f;
        } else {
            r = lu_pt_majorant_build(&med->grid, (int)st->block, &pm->maj, err);
            pm->max_pieces = med->grid.nx + med->grid.ny + med->grid.nz + 8;
            pm->lambda = lu_v3_avg(pm->sigma_t) * 0.5f * med->grid.max_value;
        }
        if (r != LU_OK || !med->has_boundary) continue;
        if (bits >= PT_MAX_BOUNDED) {
            r = lu_fail(err, LU_ERR_LIMIT, "pathtrace: more than %d bounded media", PT_MAX_BOUNDED);
            break;
        }
        pm->bit = bits++;
        st->bit_medium[pm->bit] = m;
        pm->refract =
            st->boundary_mode == BOUNDARY_REFRACT || (st->boundary_mode == BOUNDARY_AUTO && med->from_object >= 0);
        pm->diffuse = st->boundary_mode == BOUNDARY_DIFFUSE;
        if (pm->diffuse) st->sealed_bits = mask_set(st->sealed_bits, pm->bit, true);
        uint32_t id;
        r = lu_accel_add_mesh(st->surf, &med->boundary, &id, err);
        if (r == LU_OK) {
            st->surf_info[id].kind = SURF_BOUNDARY;
            st->surf_info[id].index = m;
            r = lu_accel_create(&pm->inside, err);
        }
        if (r == LU_OK) r = lu_accel_add_mesh(pm->inside, &med->boundary, &id, err);
        if (r == LU_OK) r = lu_accel_commit(pm->inside, err);
        if (r == LU_OK && pm->refract) r = lu_mesh_edge_neighbours(&med->boundary, &pm->neighbours, err);
        if (pm->refract) {
            st->have_refract = true;
            st->refract_bits = mask_set(st->refract_bits, pm->bit, true);
            st->sealed_bits = mask_set(st->sealed_bits, pm->bit, true);
            lu_aabb mb = lu_mesh_bounds(&med->boundary);
            lu_aabb_grow(&rbox, mb.lo);
            lu_aabb_grow(&rbox, mb.hi);
        }
    }
    if (st->have_refract) {
        st->refract_center = lu_v3_scale(lu_v3_add(rbox.lo, rbox.hi), 0.5f);
        st->refract_radius = 0.5f * lu_v3_len(lu_v3_sub(rbox.hi, rbox.lo)) * 1.001f + st->eps;
    }
    for (int i = 0; i < scene->object_count && r == LU_OK; i++) {
        if (scene->objects[i].material.type != LU_MATERIAL_DIFFUSE) continue; /* translucent: its medium's boundary */
        uint32_t id;
        r = lu_accel_add_mesh(st->surf, &scene->objects[i].mesh, &id, err);
        if (r == LU_OK) {
            st->surf_info[id].kind = SURF_OPAQUE;
            st->surf_info[id].index = i;
        }
    }
    if (r == LU_OK && st->surf) r = lu_accel_commit(st->surf, err);

    for (int l = 0; l < scene->light_count; l++) st->env_count += scene->lights[l].type == LU_LIGHT_ENVIRONMENT;
    if (r == LU_OK && st->env_count) {
        st->envs = lu_calloc((size_t)st->env_count, sizeof *st->envs);
        if (!st->envs) r = lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory");
        int k = 0;
        for (int l = 0; l < scene->light_count && r == LU_OK; l++)
            if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) r = env_build(&scene->lights[l], l, &st->envs[k++], err);
    }
    if (r != LU_OK) {
        pt_destroy(st);
        return r;
    }
    *out = st;
    return LU_OK;
}

static uint64_t inside_mask_at(const pt_state *st, lu_vec3 p) {
    uint64_t mask = 0;
    for (int m = 0; m < st->medium_count; m++) {
        const pt_medium *pm = &st->media[m];
        if (pm->bit >= 0 && lu_accel_inside(pm->inside, p)) mask = mask_set(mask, pm->bit, true);
    }
    return mask;
}

static lu_result pt_render_impl(void *state, const lu_frame *frame, lu_image *out, const lu_progressive *prog,
                                lu_error *err) {
    const lu_scene *scene = frame->scene;
    pt_state *st = state;
    if (scene->medium_count != st->medium_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "pathtrace: the scene's media changed since prepare");
    int envs = 0;
    for (int l = 0; l < scene->light_count; l++) envs += scene->lights[l].type == LU_LIGHT_ENVIRONMENT;
    if (envs != st->env_count)
        return lu_fail(err, LU_ERR_INVALID_ARG, "pathtrace: the scene's environment lights changed since prepare");
    st->scene = scene;
    st->kctx.st = st;
    st->out = out;
    const lu_camera *c = &scene->camera;
    st->cam = frame->rec->cam;
    st->klights = frame->rec->scene_lights;
    lu_free(st->light_mask);
    size_t nl = (size_t)(scene->light_count ? scene->light_count : 1);
    st->light_mask = lu_calloc(nl, sizeof *st->light_mask);
    st->accum = lu_calloc((size_t)c->width * c->height * 3, sizeof *st->accum);
    if (!st->light_mask || !st->accum) {
        lu_free(st->accum);
        st->accum = NULL;
        return lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory");
    }
    st->have_delta_lights = false;
    st->have_point_lights = false;
    st->delta_light_count = 0;
    for (int l = 0; l < scene->light_count; l++) {
        if (scene->lights[l].type == LU_LIGHT_ENVIRONMENT) continue;
        st->have_delta_lights = true;
        st->have_point_lights |= scene->lights[l].type != LU_LIGHT_DIRECTIONAL;
        st->delta_light_count++;
        if (scene->lights[l].type != LU_LIGHT_DIRECTIONAL)
            st->light_mask[l] = inside_mask_at(st, scene->lights[l].position);
    }
    st->camera_mask = inside_mask_at(st, c->position);
    st->beam_cap = st->delta_light_count * st->light_paths * PT_MAX_LIGHT_SEGMENTS;
    lu_free(st->beam_buf);
    st->beam_buf = st->beam_cap ? lu_calloc((size_t)st->beam_cap * lu_thread_count(), sizeof *st->beam_buf) : NULL;
    if (st->beam_cap && !st->beam_buf) {
        lu_free(st->accum);
        st->accum = NULL;
        return lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory");
    }

    lu_free(st->stats_buf);
    st->stats_buf = NULL;
    if (st->stats) {
        st->stats_buf = lu_calloc((size_t)lu_thread_count(), sizeof *st->stats_buf);
        if (!st->stats_buf) {
            lu_free(st->accum);
            st->accum = NULL;
            return lu_fail(err, LU_ERR_NOMEM, "pathtrace: out of memory");
        }
    }

    /* Bands of rows (lu_renderer_render_rows) run every pass at once: each
     * pixel still sums its passes in pass order, so its value is the same. */
    int every = prog && prog->fn && prog->every > 0 && !frame->rows ? prog->every : st->spp;
    atomic_store(&st->rows_done, 0);
    lu_progress_begin(&st->progress, "pathtrace", (int64_t)c->height * ((st->spp + every - 1) / every));
    for (int p0 = 0; p0 < st->spp; p0 += every) {
        st->pass_begin = p0;
        st->pass_end = p0 + every < st->spp ? p0 + every : st->spp;
        lu_frame_for_rows(frame, 1, render_rows, st, NULL);
        if (prog && prog->fn && st->pass_end < st->spp) {
            resolve(st, st->pass_end);
            prog->fn(prog->user, out, st->pass_end, st->spp);
        }
    }
    lu_progress_end(&st->progress);
    if (st->stats_buf) print_stats(st->stats_buf, lu_thread_count());
    resolve(st, st->spp);
    lu_free(st->accum);
    st->accum = NULL;
    return LU_OK;
}

static lu_result pt_render(void *state, const lu_frame *frame, lu_image *out, lu_error *err) {
    return pt_render_impl(state, frame, out, NULL, err);
}

const lu_method lu_method_pathtrace = {
    .name = "pathtrace",
    .summary =
        "unbiased progressive volumetric path tracer (spectral/ratio tracking, NEE + MIS, dielectric boundaries)",
    .backends = LU_BACKEND_CPU,
    .params = k_params,
    .param_count = P_COUNT,
    /* media coefficients and densities are read at prepare (majorants, sigma_t) */
    .prepare_deps = LU_CHANGE_MEDIA,
    .prepare = pt_prepare,
    .render = pt_render,
    .render_progressive = pt_render_impl,
    .destroy = pt_destroy,
};
