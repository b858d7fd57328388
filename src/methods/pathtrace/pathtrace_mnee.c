/* Manifold next-event estimation through one refraction, for the path tracer
 * (pathtrace.c): from a vertex x inside a refracting medium, the point s on
 * its boundary where a delta light's ray refracts towards x (Hanika, Droske
 * and Fascione 2015, "Manifold Next Event Estimation"), and the factor by
 * which the refraction spreads or concentrates the light's irradiance there.
 * Documented in docs/pathtrace.md ("Lights behind a refracting
 * boundary").
 *
 * The renderer refracts with the triangles' geometric normals, so the
 * boundary is piecewise flat and the manifold walk uses the same normals:
 * on one facet the constraint (Snell's law at s, the refracted ray through
 * x) has at most one solution, found in closed form (directional light) or
 * by a safeguarded one-dimensional Newton iteration in the plane of
 * incidence (point and spot lights). The walk moves from facet to facet: the
 * facet's solution is the next guess, and the boundary triangle the ray from
 * x towards it meets first is the next facet, until that triangle is the
 * facet itself. Flat facets make one solution per facet but several facets
 * per point where their refracted beams overlap (the faceted form of a
 * curved surface's focusing), so from the facet found the search grows
 * across edges through every neighbour that holds a solution too; each is
 * a path of its own. The generalized geometry term of a flat interface is
 * closed form: the ray tube's cross-section at x against its solid angle at
 * the light (or its cross-section, directional). Visibility from x and from
 * the light is the caller's shadow rays. */
#include "methods/pathtrace/pathtrace_state.h"

#include <math.h>

/* Facet hops before the walk gives up; it stops sooner at a cycle between
 * facets (a gap of the refracted light field, or a solution it cannot
 * reach). */
#define PT_MNEE_HOPS 16
/* Facets tried per vertex and light, over every patch (a patch grows only
 * through facets with a solution, a handful where facets are small against
 * the depth of x). */
#define PT_MNEE_TRIED 96
#define PT_MNEE_GAP 1

/* On the plane through p with outward unit normal n: the point s where the
 * light's ray refracts (index eta inside) towards x. false: no solution on
 * this plane (x or the light on the wrong side). */
static bool facet_solve(lu_k_light kl, float eta, lu_vec3 p, lu_vec3 n, lu_vec3 x, pt_mnee_path *out) {
    double h2 = lu_v3_dot(lu_v3_sub(p, x), n);
    if (!(h2 > 0.0)) return false;
    if (kl.type == LU_K_LIGHT_DIRECTIONAL) {
        float ci = lu_v3_dot(kl.direction, n);
        lu_vec3 t;
        if (!(ci > 0.0f) || !lu_k_refract(lu_v3_neg(kl.direction), n, eta, &t)) return false;
        float ct = -lu_v3_dot(t, n);
        if (!(ct > 0.0f)) return false;
        float len = (float)h2 / ct;
        out->s = lu_v3_madd(x, t, -len);
        out->t = t;
        out->dist = len;
        out->cos_i = ci;
        /* Parallel light: cross-section cos_i at the facet becomes cos_t. */
        out->gain = ci / ct;
        return true;
    }
    lu_vec3 lp = kl.position;
    double h1 = lu_v3_dot(lu_v3_sub(lp, p), n);
    if (!(h1 > 0.0)) return false;
    /* The plane of incidence holds the light, x and the normal: s lies on
     * the segment between their feet at distance r from the light's foot,
     * where sin(theta_i) = eta sin(theta_t); that difference rises
     * monotonically in r from the foot of the light to the foot of x, so
     * the root is unique. */
    lu_vec3 lf = lu_v3_madd(lp, n, (float)-h1), xf = lu_v3_madd(x, n, (float)h2);
    lu_vec3 dv = lu_v3_sub(xf, lf);
    double D = lu_v3_len(dv);
    double r = 0.0;
    if (D > 1e-7 * (h1 + h2)) {
        double lo = 0.0, hi = D;
        r = eta * D * h1 / (h2 + eta * h1); /* the paraxial root (sines as tangents) */
        for (int it = 0; it < 64; it++) {
            double a = sqrt(r * r + h1 * h1), b = sqrt((D - r) * (D - r) + h2 * h2);
            double f = r / a - eta * (D - r) / b;
            if (f > 0.0) hi = r;
            else lo = r;
            double fp = h1 * h1 / (a * a * a) + eta * h2 * h2 / (b * b * b);
            double rn = r - f / fp;
            if (!(rn > lo && rn < hi)) rn = 0.5 * (lo + hi);
            bool done = fabs(rn - r) <= 1e-9 * (D + h1 + h2); /* float output */
            r = rn;
            if (done) break;
        }
    }
    lu_vec3 s = D > 0.0 ? lu_v3_madd(lf, dv, (float)(r / D)) : lf;
    lu_vec3 tl = lu_v3_sub(lp, s), tx = lu_v3_sub(x, s);
    double d1 = lu_v3_len(tl), d2 = lu_v3_len(tx);
    if (!(d1 > 0.0) || !(d2 > 0.0)) return false;
    double ci = lu_v3_dot(tl, n) / d1, ct = -lu_v3_dot(tx, n) / d2;
    if (!(ci > 0.0) || !(ct > 0.0)) return false;
    out->s = s;
    out->t = lu_v3_scale(tx, (float)(1.0 / d2));
    out->dist = (float)d2;
    out->cos_i = (float)ci;
    /* The ray tube from the point light: its cross-section at x per unit
     * solid angle is (d1 + d2 / eta) sagittally (as sin(theta_t) = sin(theta_i)
     * / eta) times d1 cos_t / cos_i + d2 cos_i / (eta cos_t) in the plane of
     * incidence; the irradiance at s facing the light is I / d1^2. Normal
     * incidence gives I / (d1 + d2 / eta)^2, the point seen at its apparent
     * depth. */
    out->gain = (float)(d1 * d1 / ((d1 + d2 / eta) * (d1 * ct / ci + d2 * ci / (eta * ct))));
    return true;
}

/* Whether s, on the plane of triangle tri, lies in it (barycentrics). */
static bool in_triangle(const lu_mesh *me, uint32_t tri, lu_vec3 s) {
    lu_vec3 a = me->positions[me->indices[3u * tri]];
    lu_vec3 e1 = lu_v3_sub(me->positions[me->indices[3u * tri + 1]], a);
    lu_vec3 e2 = lu_v3_sub(me->positions[me->indices[3u * tri + 2]], a), w = lu_v3_sub(s, a);
    double d00 = lu_v3_dot(e1, e1), d01 = lu_v3_dot(e1, e2), d11 = lu_v3_dot(e2, e2);
    double d20 = lu_v3_dot(w, e1), d21 = lu_v3_dot(w, e2), den = d00 * d11 - d01 * d01;
    if (!(den > 0.0)) return false;
    double b1 = (d11 * d20 - d01 * d21) / den, b2 = (d00 * d21 - d01 * d20) / den;
    return b1 >= 0.0 && b2 >= 0.0 && b1 + b2 <= 1.0;
}

/* The hop walk from x along `seed`: a facet with a solution, verified by the
 * ray from x towards it meeting that facet first. */
static bool hop_walk(const pt_state *st, int m, lu_k_light kl, lu_vec3 x, lu_vec3 seed, pt_mnee_path *out) {
    const pt_medium *pm = &st->media[m];
    lu_vec3 dir = seed;
    lu_hit hit;
    if (!lu_accel_closest(pm->inside, x, dir, 0.0f, LU_K_FAR, &hit)) return false;
    uint32_t seen[PT_MNEE_HOPS];
    for (int hop = 0; hop < PT_MNEE_HOPS; hop++) {
        /* The walk is deterministic: a facet met again is a cycle. */
        for (int i = 0; i < hop; i++)
            if (seen[i] == hit.prim_id) return false;
        seen[hop] = hit.prim_id;
        /* A facet seen from inside faces away from x (outward normals). */
        if (!(lu_v3_dot(hit.ng, dir) > 0.0f)) return false;
        lu_vec3 p = lu_v3_madd(x, dir, hit.t);
        pt_mnee_path c;
        if (!facet_solve(kl, pm->eta, p, hit.ng, x, &c)) return false;
        dir = lu_v3_neg(c.t);
        lu_hit h2;
        if (!lu_accel_closest(pm->inside, x, dir, 0.0f, LU_K_FAR, &h2)) return false;
        if (h2.prim_id == hit.prim_id) {
            if (fabsf(h2.t - c.dist) > 1e-3f * c.dist + st->eps) return false;
            c.ns = hit.ng;
            c.prim = hit.prim_id;
            *out = c;
            return true;
        }
        hit = h2;
    }
    return false;
}

/* A cheap rejection for point and spot lights: on the plane of triangle
 * tri (unit normal n), the solution lies between the paraxial root (sines
 * taken as tangents, which puts it nearer the light's foot) and the foot of
 * x; false when that segment lies wholly outside one of the triangle's
 * edges. */
static bool point_may_hit(const lu_mesh *me, uint32_t tri, lu_vec3 n, lu_vec3 lp, lu_vec3 x, float eta) {
    const uint32_t *ix = &me->indices[3u * tri];
    lu_vec3 v[3] = {me->positions[ix[0]], me->positions[ix[1]], me->positions[ix[2]]};
    float h1 = lu_v3_dot(lu_v3_sub(lp, v[0]), n), h2 = lu_v3_dot(lu_v3_sub(v[0], x), n);
    if (!(h1 > 0.0f) || !(h2 > 0.0f)) return false;
    lu_vec3 lf = lu_v3_madd(lp, n, -h1), xf = lu_v3_madd(x, n, h2);
    lu_vec3 pp = lu_v3_madd(lf, lu_v3_sub(xf, lf), eta * h1 / (h2 + eta * h1));
    for (int e = 0; e < 3; e++) {
        lu_vec3 ed = lu_v3_sub(v[(e + 1) % 3], v[e]);
        float s0 = lu_v3_dot(lu_v3_cross(ed, lu_v3_sub(pp, v[e])), n);
        float s1 = lu_v3_dot(lu_v3_cross(ed, lu_v3_sub(xf, v[e])), n);
        if (s0 < 0.0f && s1 < 0.0f) return false;
    }
    return true;
}

static bool listed(const uint32_t *list, int n, uint32_t v) {
    for (int i = 0; i < n; i++)
        if (list[i] == v) return true;
    return false;
}

int lu_pt_mnee_solve(const pt_state *st, int m, lu_k_light kl, lu_vec3 x, const lu_vec3 *seeds, int nseeds,
                     pt_mnee_path *out, int cap) {
    const pt_medium *pm = &st->media[m];
    const lu_mesh *me = &st->scene->media[m].boundary;
    uint32_t tried[PT_MNEE_TRIED], queue[PT_MNEE_TRIED];
    int miss[PT_MNEE_TRIED]; /* facets without a solution passed on the way */
    int nt = 0, n = 0;
    /* A later guess only when the earlier ones found nothing: the patch
     * search covers a connected solution set from any facet of it. */
    for (int k = 0; k < nseeds && n == 0 && nt < PT_MNEE_TRIED; k++) {
        pt_mnee_path c;
        if (!hop_walk(st, m, kl, x, seeds[k], &c) || listed(tried, nt, c.prim)) continue;
        /* The facets with a solution form patches (several where the facets'
         * refracted beams overlap, as they do under a convex boundary, which
         * focuses light): grow the patch across edges from the walk's facet,
         * through facets that hold a solution and past at most PT_MNEE_GAP
         * facets in a row that do not. */
        int qh = 0, qt = 0;
        tried[nt++] = c.prim;
        queue[qt] = c.prim;
        miss[qt++] = 0;
        out[n++] = c;
        while (qh < qt && n < cap) {
            uint32_t f = queue[qh];
            int fm = miss[qh++];
            for (int e = 0; e < 3 && n < cap && nt < PT_MNEE_TRIED; e++) {
                uint32_t g = pm->neighbours ? pm->neighbours[3u * f + e] : UINT32_MAX;
                if (g == UINT32_MAX || listed(tried, nt, g)) continue;
                tried[nt++] = g;
                const uint32_t *ix = &me->indices[3u * g];
                lu_vec3 a = me->positions[ix[0]];
                lu_vec3 ng = lu_v3_norm(
                    lu_v3_cross(lu_v3_sub(me->positions[ix[1]], a), lu_v3_sub(me->positions[ix[2]], a)));
                bool hit = (kl.type == LU_K_LIGHT_DIRECTIONAL || point_may_hit(me, g, ng, kl.position, x, pm->eta)) &&
                           facet_solve(kl, pm->eta, a, ng, x, &c) && in_triangle(me, g, c.s);
                if (hit) {
                    c.ns = ng;
                    c.prim = g;
                    out[n++] = c;
                }
                if (hit || fm < PT_MNEE_GAP) {
                    queue[qt] = g;
                    miss[qt++] = hit ? 0 : fm + 1;
                }
            }
        }
    }
    return n;
}
