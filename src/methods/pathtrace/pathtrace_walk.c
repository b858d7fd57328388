/* Free flight through media and the subsurface walk's steps, for the path
 * tracer (pathtrace.c): null-collision walkers per medium (lu_tracking.h),
 * superposed when media overlap; the surface query fused with the free
 * flight in constant media; the Dwivedi-guided step (guide=dwivedi).
 * Documented in docs/pathtrace.md ("Subsurface walk"). */
#include "methods/pathtrace/pathtrace_state.h"

#include <math.h>

/* ---- media along a segment ------------------------------------------------------------ */

typedef struct pt_walker {
    int m;
    float t, t1;
    lu_vec3 oi, di;
    lu_k_walk w;
} pt_walker;

/* Starts medium m's collision process over [a, b]; false if nothing to walk. */
static bool walker_begin(const pt_state *st, int m, lu_vec3 o, lu_vec3 d, float a, float b, lu_k_rng *rng,
                         pt_walker *wk) {
    const pt_medium *pm = &st->media[m];
    const lu_medium *med = &st->scene->media[m];
    wk->m = m;
    wk->t1 = b;
    if (pm->constant) {
        float mu = pm->sigma_max * pm->cdens;
        if (!(mu > 0.0f)) return false;
        wk->t = a - logf(1.0f - rnd(rng)) / mu;
        return true;
    }
    if (!(pm->sigma_max > 0.0f)) return false;
    wk->oi = lu_affine_point(&med->world_to_index, o);
    wk->di = lu_affine_vector(&med->world_to_index, d);
    wk->w = lu_k_walk_begin(wk->oi, wk->di, a, b, st->block);
    wk->t = lu_k_walk_tentative(&st->kctx, m, &wk->w, a, pm->sigma_max, rng);
    return true;
}

static void walker_advance(const pt_state *st, pt_walker *wk, lu_k_rng *rng) {
    const pt_medium *pm = &st->media[wk->m];
    if (pm->constant)
        wk->t -= logf(1.0f - rnd(rng)) / (pm->sigma_max * pm->cdens);
    else
        wk->t = lu_k_walk_tentative(&st->kctx, wk->m, &wk->w, wk->t, pm->sigma_max, rng);
}

static int earliest_walker(const pt_walker *wk, int n);
static bool flight_event(const pt_state *st, pt_walker *w, lu_vec3 *beta, lu_vec3 *r, int hero, lu_k_rng *rng,
                         pt_flight *f);

/* Free flight over (0, t_end) through every medium active under `mask`.
 * hero >= 0: hero-channel sampling (r tracks the spectral MIS ratios);
 * hero < 0: spectral tracking. */
pt_flight lu_pt_free_flight(const pt_state *st, lu_vec3 o, lu_vec3 d, float t_end, uint64_t mask, lu_vec3 *beta,
                             lu_vec3 *r, int hero, lu_k_rng *rng) {
    pt_walker wk[PT_MAX_MEDIA];
    int n = 0;
    pt_flight f = {-1, -1, t_end};
    for (int m = 0; m < st->medium_count; m++) {
        const pt_medium *pm = &st->media[m];
        float a, b;
        if (!medium_active(pm, mask) || !medium_span(pm, o, d, t_end, &a, &b)) continue;
        if (walker_begin(st, m, o, d, a, b, rng, &wk[n])) n++;
    }
    for (int guard = 0; guard < 100000000; guard++) {
        int k = earliest_walker(wk, n);
        if (k < 0) return f;
        if (flight_event(st, &wk[k], beta, r, hero, rng, &f)) return f;
    }
    return f;
}

/* The walker whose tentative collision comes first, or -1 when all are done. */
static int earliest_walker(const pt_walker *wk, int n) {
    int k = -1;
    float tk = INFINITY;
    for (int i = 0; i < n; i++)
        if (wk[i].t < wk[i].t1 && wk[i].t < tk) {
            tk = wk[i].t;
            k = i;
        }
    return k;
}

/* The event at walker w's tentative collision: true when the flight ends
 * there (*f set: a scattering or nothing left to carry), false after a null
 * collision (the walker has moved on). */
static bool flight_event(const pt_state *st, pt_walker *w, lu_vec3 *beta, lu_vec3 *r, int hero, lu_k_rng *rng,
                         pt_flight *f) {
    const pt_medium *pm = &st->media[w->m];
    const lu_medium *med = &st->scene->media[w->m];
    float tk = w->t;
    float dens, mu;
    if (pm->constant) {
        dens = pm->cdens;
        mu = pm->sigma_max * dens;
    } else {
        dens = lu_grid_sample(&med->grid, lu_v3_madd(w->oi, w->di, tk));
        mu = pm->sigma_max * w->w.dmax;
    }
    lu_vec3 sa = lu_v3_scale(med->sigma_a, dens), ss = lu_v3_scale(med->sigma_s, dens);
    int ev = hero >= 0 ? lu_k_hero_event(beta, r, sa, ss, mu, hero, rnd(rng))
                       : lu_k_spectral_event(beta, sa, ss, mu, rnd(rng));
    if (ev == LU_K_EVENT_ABSORB) {
        f->event = LU_K_EVENT_ABSORB;
        return true;
    }
    if (ev == LU_K_EVENT_SCATTER) {
        f->event = LU_K_EVENT_SCATTER;
        f->medium = w->m;
        f->t = tk;
        return true;
    }
    walker_advance(st, w, rng);
    return false;
}

/* The ray cast to the next surface fused with free_flight: the surface is
 * looked for only over each stretch between tentative collisions (a walk's
 * steps are short, and a short ray query is cheap), so a walk never casts to
 * infinity. Draws the same random numbers and returns the same flight and hit
 * as lu_accel_closest to infinity followed by free_flight, provided every
 * medium the ray meets has constant density and contains the origin (then
 * free_flight starts the same walkers whatever t_end is); returns false,
 * having drawn nothing, when that does not hold. */
bool lu_pt_free_flight_to_surface(const pt_state *st, lu_vec3 o, lu_vec3 d, uint64_t mask, lu_vec3 *beta, lu_vec3 *r,
                                   int hero, lu_k_rng *rng, pt_flight *f, lu_hit *hit, bool *has) {
    int ms[PT_MAX_MEDIA];
    float bs[PT_MAX_MEDIA];
    int nm = 0;
    for (int m = 0; m < st->medium_count; m++) {
        const pt_medium *pm = &st->media[m];
        float a, b;
        if (!medium_active(pm, mask) || !medium_span(pm, o, d, LU_K_FAR, &a, &b)) continue;
        if (!pm->constant || a > 0.0f) return false;
        ms[nm] = m;
        bs[nm++] = b;
    }
    pt_walker wk[PT_MAX_MEDIA];
    int n = 0;
    for (int i = 0; i < nm; i++)
        if (walker_begin(st, ms[i], o, d, 0.0f, bs[i], rng, &wk[n])) n++;
    f->event = -1;
    f->medium = -1;
    f->t = LU_K_FAR;
    *has = false;
    float t_lo = 0.0f;
    for (int guard = 0; guard < 100000000; guard++) {
        int k = earliest_walker(wk, n);
        float tq = k < 0 ? LU_K_FAR : wk[k].t;
        /* [0, t_lo] is known to be free of surfaces (closed intervals). */
        if (st->surf && tq > t_lo && lu_accel_closest(st->surf, o, d, t_lo, tq, hit)) {
            *has = true;
            f->event = -1;
            f->t = hit->t;
            return true;
        }
        if (k < 0) return true;
        t_lo = tq;
        if (flight_event(st, &wk[k], beta, r, hero, rng, f)) return true;
    }
    return true;
}

/* ---- the guided walk (pathtrace.guide=dwivedi) ------------------------------------------------ */

/* Whether a vertex in medium m under `mask` takes guided steps: m is a
 * sealed constant medium and the only one present (so a step's free flight
 * is one exponential per channel). */
bool lu_pt_guide_applies(const pt_state *st, int m, uint64_t mask) {
    const pt_medium *pm = &st->media[m];
    if (!pm->constant || pm->bit < 0 || !((st->sealed_bits >> pm->bit) & 1u) || !(pm->guide_prob > 0.0f))
        return false;
    for (int k = 0; k < st->medium_count; k++)
        if (k != m && medium_active(&st->media[k], mask)) return false;
    return true;
}

/* The step from a vertex in medium m along d (already chosen, by the
 * strategy `guided`), whose distance the same strategy now samples:
 * classical, rate sigma_t of the hero channel; guided, the stretched rate
 * sigma_t (1 - mu0 / v0). The step's density under hero channel c is the
 * mixture (1 - P) phase(d) p_c(t) + P dwivedi_c(d) q_c(t | d) (P =
 * the medium's guide_prob; survival probabilities when the step reaches the surface);
 * beta takes f / p_hero and r takes p_c / p_hero, so that, as everywhere
 * else, a contribution is f / avg_c(p_c): the balance heuristic over the
 * channels, each of them a two-technique mixture. The surface is looked for
 * up to the sampled distance only. */
pt_flight lu_pt_guided_step(const pt_state *st, int m, lu_vec3 o, lu_vec3 d, lu_vec3 n_out, bool guided, float phase,
                             int hero, lu_vec3 *beta, lu_vec3 *r, lu_k_rng *rng, lu_hit *hit, bool *has) {
    const pt_medium *pm = &st->media[m];
    const lu_medium *med = &st->scene->media[m];
    pt_flight f = {-1, -1, LU_K_FAR};
    float mu0 = lu_v3_dot(d, n_out), pgd = pm->guide_prob;
    float sh = lu_v3_get(pm->sigma_t, hero) * pm->cdens;
    float rate = guided ? sh * (1.0f - mu0 / pm->v0[hero]) : sh;
    float t = -logf(1.0f - rnd(rng)) / rate;
    float a, b;
    if (!medium_span(pm, o, d, LU_K_FAR, &a, &b)) b = 0.0f;
    *has = st->surf && lu_accel_closest(st->surf, o, d, 0.0f, t, hit);
    bool collide = !*has && t < b;
    float tt = *has ? hit->t : (collide ? t : b);
    float pc[3], fc[3];
    for (int c = 0; c < 3; c++) {
        float sc = lu_v3_get(pm->sigma_t, c) * pm->cdens;
        float rg = sc * (1.0f - mu0 / pm->v0[c]);
        float tc = expf(-sc * tt), tg = expf(-rg * tt);
        float pg = lu_pt_dwivedi_pdf(pm->v0[c], pm->vlog[c], mu0);
        if (collide) {
            pc[c] = (1.0f - pgd) * phase * sc * tc + pgd * pg * rg * tg;
            fc[c] = phase * tc * lu_v3_get(med->sigma_s, c) * pm->cdens;
        } else {
            pc[c] = (1.0f - pgd) * phase * tc + pgd * pg * tg;
            fc[c] = phase * tc;
        }
    }
    float ph = pc[hero];
    if (!(ph > 0.0f)) {
        *beta = lu_v3s(0.0f);
        f.event = LU_K_EVENT_ABSORB;
        return f;
    }
    *beta = lu_v3_mul(*beta, lu_v3_scale(lu_v3(fc[0], fc[1], fc[2]), 1.0f / ph));
    *r = lu_v3_mul(*r, lu_v3_scale(lu_v3(pc[0], pc[1], pc[2]), 1.0f / ph));
    if (collide) {
        f.event = LU_K_EVENT_SCATTER;
        f.medium = m;
        f.t = tt;
    } else if (*has) {
        f.t = hit->t;
    }
    return f;
}

