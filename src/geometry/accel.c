/* Ray queries against triangle meshes through Embree 3.
 *
 * One RTCDevice and one RTCScene per accel; each lu_mesh becomes one triangle
 * geometry whose geomID is its insertion index. The index buffer is shared
 * with the lu_mesh. The vertex buffer is a padded copy: Embree loads the last
 * vertex with a 16-byte SSE read, so a packed 12-byte-stride array needs one
 * spare float after it, which an lu_mesh allocation does not promise.
 *
 * The scene is built with RTC_SCENE_FLAG_ROBUST (watertight Pluecker triangle
 * test: a ray through a shared edge or vertex hits at least one of the
 * triangles there, which parity counting depends on) and high build quality
 * (spatial splits; a primitive may then be reported more than once per ray,
 * which lu_accel_all_hits removes).
 *
 * Embree's geometric normal Ng points along (p1 - p0) x (p2 - p0), i.e.
 * outward for counter-clockwise triangles, which is lucent's convention; the
 * tests check it against analytic boxes and spheres. */
#include "geometry_internal.h"
#include "core/memory.h"

#include <embree3/rtcore.h>
#include <float.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#define LU_ACCEL_MAX_MESHES (1u << 20)
/* Embree drops primitives with coordinates beyond ~1.8e18; reject them. */
#define LU_ACCEL_MAX_COORD 1.0e18f

typedef struct accel_mesh {
    const lu_mesh *mesh;
    float *verts;   /* 3 * vertex_count + 1 floats (see the padding note above) */
} accel_mesh;

struct lu_accel {
    RTCDevice device;
    RTCScene scene;
    accel_mesh *meshes;
    uint32_t count, capacity;
    lu_aabb bounds;
    bool committed;
    /* First error reported by Embree's callback since the last check; the
     * callback may run on TBB build threads, hence the atomic claim. */
    atomic_int has_error;
    enum RTCError error_code;
    char error_text[256];
    /* Embree's memory, charged to the account in use when the device was
     * made (the monitor may run on Embree's build threads). */
    lu_mem_account *account;
};

bool lu_accel_is_committed(const lu_accel *a) { return a && a->committed; }

static const char *rtc_error_name(enum RTCError code) {
    switch (code) {
    case RTC_ERROR_NONE: return "RTC_ERROR_NONE";
    case RTC_ERROR_UNKNOWN: return "RTC_ERROR_UNKNOWN";
    case RTC_ERROR_INVALID_ARGUMENT: return "RTC_ERROR_INVALID_ARGUMENT";
    case RTC_ERROR_INVALID_OPERATION: return "RTC_ERROR_INVALID_OPERATION";
    case RTC_ERROR_OUT_OF_MEMORY: return "RTC_ERROR_OUT_OF_MEMORY";
    case RTC_ERROR_UNSUPPORTED_CPU: return "RTC_ERROR_UNSUPPORTED_CPU";
    case RTC_ERROR_CANCELLED: return "RTC_ERROR_CANCELLED";
    }
    return "RTC_ERROR_?";
}

static void on_embree_error(void *user, enum RTCError code, const char *str) {
    lu_accel *a = user;
    int expected = 0;
    if (!atomic_compare_exchange_strong(&a->has_error, &expected, 1)) return;
    a->error_code = code;
    snprintf(a->error_text, sizeof a->error_text, "%s", str ? str : "");
}

/* Turns a pending Embree error (code or callback message) into an lu_error. */
static lu_result embree_check(lu_accel *a, const char *what, lu_error *err) {
    enum RTCError code = rtcGetDeviceError(a->device);
    bool called_back = atomic_load(&a->has_error) != 0;
    if (code == RTC_ERROR_NONE && !called_back) return LU_OK;
    if (code == RTC_ERROR_NONE) code = a->error_code;
    lu_result r = lu_fail(err, code == RTC_ERROR_OUT_OF_MEMORY ? LU_ERR_NOMEM : LU_ERR_BACKEND,
                          "embree: %s failed: %s%s%s", what, rtc_error_name(code),
                          called_back && a->error_text[0] ? ": " : "", called_back ? a->error_text : "");
    atomic_store(&a->has_error, 0);
    return r;
}

lu_result lu_accel_create(lu_accel **out, lu_error *err) {
    if (!out) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_accel_create: out is NULL");
    *out = NULL;
    lu_accel *a = lu_calloc(1, sizeof *a);
    if (!a) return lu_fail(err, LU_ERR_NOMEM, "lu_accel_create: out of memory");
    atomic_init(&a->has_error, 0);
    a->bounds = lu_aabb_empty();
    *out = a;
    return LU_OK;
}

static bool on_embree_memory(void *user, ssize_t bytes, bool post) {
    (void)post;
    lu_mem_add(((lu_accel *)user)->account, LU_MEM_ACCEL, (long long)bytes);
    return true;
}

/* Device and scene are made on first use, so creating an accel is cheap and
 * cannot fail for Embree reasons. */
static lu_result ensure_scene(lu_accel *a, lu_error *err) {
    if (a->scene) return LU_OK;
    if (!a->device) {
        a->device = rtcNewDevice(NULL);
        if (!a->device)
            return lu_fail(err, LU_ERR_BACKEND, "embree: device creation failed: %s",
                           rtc_error_name(rtcGetDeviceError(NULL)));
        rtcSetDeviceErrorFunction(a->device, on_embree_error, a);
        a->account = lu_mem_account_hold();
        rtcSetDeviceMemoryMonitorFunction(a->device, on_embree_memory, a);
        /* all_hits needs filter callbacks, and parity needs back faces. */
        if (rtcGetDeviceProperty(a->device, RTC_DEVICE_PROPERTY_FILTER_FUNCTION_SUPPORTED) != 1)
            return lu_fail(err, LU_ERR_UNSUPPORTED, "embree: this build lacks filter function support");
        if (rtcGetDeviceProperty(a->device, RTC_DEVICE_PROPERTY_BACKFACE_CULLING_ENABLED) != 0)
            return lu_fail(err, LU_ERR_UNSUPPORTED, "embree: this build culls back faces");
    }
    a->scene = rtcNewScene(a->device);
    if (!a->scene) return embree_check(a, "scene creation", err);
    rtcSetSceneFlags(a->scene, RTC_SCENE_FLAG_ROBUST | RTC_SCENE_FLAG_CONTEXT_FILTER_FUNCTION);
    rtcSetSceneBuildQuality(a->scene, RTC_BUILD_QUALITY_HIGH);
    return embree_check(a, "scene set-up", err);
}

lu_result lu_accel_add_mesh(lu_accel *a, const lu_mesh *mesh, uint32_t *mesh_id, lu_error *err) {
    if (!a || !mesh) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_accel_add_mesh: NULL accel or mesh");
    const uint32_t id = a->count, nv = mesh->vertex_count, nt = mesh->triangle_count;
    if (id >= LU_ACCEL_MAX_MESHES)
        return lu_fail(err, LU_ERR_LIMIT, "accel: more than %u meshes", LU_ACCEL_MAX_MESHES);
    if (nt > LU_MAX_TRIANGLES)
        return lu_fail(err, LU_ERR_LIMIT, "accel mesh %u: %u triangles exceed the limit %u", id, nt,
                       LU_MAX_TRIANGLES);
    if (nv > LU_MAX_VERTICES)
        return lu_fail(err, LU_ERR_LIMIT, "accel mesh %u: %u vertices exceed the limit %u", id, nv,
                       LU_MAX_VERTICES);
    if ((nv && !mesh->positions) || (nt && !mesh->indices))
        return lu_fail(err, LU_ERR_INVALID_ARG, "accel mesh %u: NULL positions or indices", id);
    /* Embree reads indices unchecked, so a bad one would read out of bounds. */
    for (size_t i = 0; i < 3 * (size_t)nt; i++)
        if (mesh->indices[i] >= nv)
            return lu_fail(err, LU_ERR_RANGE, "accel mesh %u: triangle %zu references vertex %u of %u", id,
                           i / 3, mesh->indices[i], nv);
    for (uint32_t i = 0; i < nv; i++) {
        lu_vec3 p = mesh->positions[i];
        if (!lu_v3_finite(p))
            return lu_fail(err, LU_ERR_NONFINITE, "accel mesh %u: vertex %u is not finite", id, i);
        if (fabsf(p.x) > LU_ACCEL_MAX_COORD || fabsf(p.y) > LU_ACCEL_MAX_COORD || fabsf(p.z) > LU_ACCEL_MAX_COORD)
            return lu_fail(err, LU_ERR_RANGE, "accel mesh %u: vertex %u has a coordinate beyond %g", id, i,
                           (double)LU_ACCEL_MAX_COORD);
    }
    lu_result r = ensure_scene(a, err);
    if (r != LU_OK) return r;

    if (a->count == a->capacity) {
        uint32_t cap = a->capacity ? 2 * a->capacity : 4;
        accel_mesh *m = lu_realloc(a->meshes, cap * sizeof *m);
        if (!m) return lu_fail(err, LU_ERR_NOMEM, "accel: out of memory for the mesh table");
        a->meshes = m;
        a->capacity = cap;
    }
    float *verts = lu_malloc((3 * (size_t)nv + 1) * sizeof(float));
    if (!verts) return lu_fail(err, LU_ERR_NOMEM, "accel mesh %u: out of memory copying %u vertices", id, nv);
    if (nv) memcpy(verts, mesh->positions, 3 * (size_t)nv * sizeof(float));
    verts[3 * (size_t)nv] = 0.0f;

    RTCGeometry g = rtcNewGeometry(a->device, RTC_GEOMETRY_TYPE_TRIANGLE);
    if (!g) {
        lu_free(verts);
        return embree_check(a, "geometry creation", err);
    }
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_VERTEX, 0, RTC_FORMAT_FLOAT3, verts, 0, 3 * sizeof(float), nv);
    rtcSetSharedGeometryBuffer(g, RTC_BUFFER_TYPE_INDEX, 0, RTC_FORMAT_UINT3, mesh->indices, 0,
                               3 * sizeof(uint32_t), nt);
    rtcCommitGeometry(g);
    r = embree_check(a, "geometry set-up", err);
    if (r == LU_OK) {
        rtcAttachGeometryByID(a->scene, g, id);
        r = embree_check(a, "geometry attach", err);
    }
    rtcReleaseGeometry(g);   /* the scene holds its own reference */
    if (r != LU_OK) {
        lu_free(verts);
        return r;
    }
    a->meshes[id].mesh = mesh;
    a->meshes[id].verts = verts;
    a->count++;
    for (size_t i = 0; i < 3 * (size_t)nt; i++) lu_aabb_grow(&a->bounds, mesh->positions[mesh->indices[i]]);
    a->committed = false;
    if (mesh_id) *mesh_id = id;
    return LU_OK;
}

lu_result lu_accel_commit(lu_accel *a, lu_error *err) {
    if (!a) return lu_fail(err, LU_ERR_INVALID_ARG, "lu_accel_commit: NULL accel");
    lu_result r = ensure_scene(a, err);
    if (r != LU_OK) return r;
    rtcCommitScene(a->scene);
    r = embree_check(a, "scene commit", err);
    a->committed = r == LU_OK;
    return r;
}

void lu_accel_destroy(lu_accel *a) {
    if (!a) return;
    /* The scene holds the geometries, and every object holds the device:
     * release in this order so the device (and its TBB arena) really goes. */
    if (a->scene) rtcReleaseScene(a->scene);
    if (a->device) rtcReleaseDevice(a->device);
    lu_mem_account_release(a->account);
    for (uint32_t i = 0; i < a->count; i++) lu_free(a->meshes[i].verts);
    lu_free(a->meshes);
    lu_free(a);
}

lu_aabb lu_accel_bounds(const lu_accel *a) { return a ? a->bounds : lu_aabb_empty(); }

/* ---- queries ------------------------------------------------------------ */

static float max_abs3(lu_vec3 v) { return fmaxf(fabsf(v.x), fmaxf(fabsf(v.y), fabsf(v.z))); }

/* Fills an Embree ray for the interval (tmin, tmax). Embree wants
 * 0 <= tnear, so a negative tmin moves the origin back to o + off d (off is
 * added to every reported t); -inf is replaced by a parameter before the
 * accel's bounds, since nothing exists earlier. */
static bool setup_ray(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax, struct RTCRay *ray,
                      float *off) {
    if (!a || !a->committed || !lu_aabb_valid(a->bounds)) return false;
    if (!lu_v3_finite(o) || !lu_v3_finite(d) || isnan(tmin) || isnan(tmax) || !(tmax > tmin)) return false;
    float dlen = lu_v3_len(d);
    if (!(dlen > 0.0f) || !isfinite(dlen)) return false;
    *off = 0.0f;
    if (tmin < 0.0f) {
        /* Farthest corner distance bounds how far back any geometry can be. */
        lu_vec3 far = lu_v3_max(lu_v3_sub(a->bounds.hi, o), lu_v3_sub(o, a->bounds.lo));
        float reach = -(lu_v3_len(far) / dlen) * 1.001f - 1e-30f;
        *off = tmin > reach ? tmin : reach;
        if (!isfinite(*off)) return false;
        o = lu_v3_madd(o, d, *off);
        tmin = 0.0f;
        tmax -= *off;
    }
    memset(ray, 0, sizeof *ray);
    ray->org_x = o.x;
    ray->org_y = o.y;
    ray->org_z = o.z;
    ray->dir_x = d.x;
    ray->dir_y = d.y;
    ray->dir_z = d.z;
    ray->tnear = tmin;
    ray->tfar = tmax;
    ray->mask = 0xFFFFFFFFu;
    return true;
}

static lu_vec3 unit_normal(float x, float y, float z) { return lu_v3_norm(lu_v3(x, y, z)); }

bool lu_accel_closest(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax, lu_hit *hit) {
    struct RTCRayHit rh;
    float off;
    if (!setup_ray(a, o, d, tmin, tmax, &rh.ray, &off)) return false;
    memset(&rh.hit, 0, sizeof rh.hit);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcIntersect1(a->scene, &ctx, &rh);
    if (rh.hit.geomID == RTC_INVALID_GEOMETRY_ID) return false;
    if (hit) {
        hit->t = rh.ray.tfar + off;
        hit->mesh_id = rh.hit.geomID;
        hit->prim_id = rh.hit.primID;
        hit->u = rh.hit.u;
        hit->v = rh.hit.v;
        hit->ng = unit_normal(rh.hit.Ng_x, rh.hit.Ng_y, rh.hit.Ng_z);
    }
    return true;
}

bool lu_accel_occluded(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax) {
    struct RTCRay ray;
    float off;
    if (!setup_ray(a, o, d, tmin, tmax, &ray, &off)) return false;
    struct RTCIntersectContext ctx;
    rtcInitIntersectContext(&ctx);
    rtcOccluded1(a->scene, &ctx, &ray);
    return ray.tfar == -INFINITY;
}

/* ---- all hits: one traversal, every candidate recorded and rejected ------- */

typedef struct hit_rec {
    float t, u, v, ng[3];
    uint32_t geom, prim;
    bool dead;
} hit_rec;

typedef struct collector {
    struct RTCIntersectContext ctx;   /* first: Embree hands this pointer to the filter */
    float tlo, thi;                   /* the exact open interval, in shifted ray units */
    hit_rec *recs;
    int n, cap;
    bool oom;
    hit_rec local[64];
} collector;

static bool collector_grow(collector *c) {
    int cap = 2 * c->cap;
    hit_rec *r;
    if (c->recs == c->local) {
        r = lu_malloc((size_t)cap * sizeof *r);
        if (r) memcpy(r, c->local, (size_t)c->n * sizeof *r);
    } else {
        r = lu_realloc(c->recs, (size_t)cap * sizeof *r);
    }
    if (!r) return false;
    c->recs = r;
    c->cap = cap;
    return true;
}

/* Embree passes N rays in SOA layout: RTCRayN floats are org xyz, tnear,
 * dir xyz, time, tfar (N each); RTCHitN is Ng xyz, u, v, primID, geomID. The
 * C API has no accessors (rtcore_ray.h's are C++), so index by hand. */
static void collect_filter(const struct RTCFilterFunctionNArguments *args) {
    collector *c = (collector *)args->context;
    const unsigned N = args->N;
    const float *ray = (const float *)args->ray;
    const float *hf = (const float *)args->hit;
    const unsigned *hu = (const unsigned *)args->hit;
    for (unsigned i = 0; i < N; i++) {
        if (args->valid[i] == 0) continue;
        args->valid[i] = 0;   /* reject: traversal goes on, tfar stays where it was */
        float t = ray[8 * N + i];
        if (!(t > c->tlo && t < c->thi)) continue;
        if (c->n == c->cap && !collector_grow(c)) {
            c->oom = true;
            continue;
        }
        hit_rec *r = &c->recs[c->n++];
        r->t = t;
        r->ng[0] = hf[0 * N + i];
        r->ng[1] = hf[1 * N + i];
        r->ng[2] = hf[2 * N + i];
        r->u = hf[3 * N + i];
        r->v = hf[4 * N + i];
        r->prim = hu[5 * N + i];
        r->geom = hu[6 * N + i];
        r->dead = false;
    }
}

static bool rec_less(const hit_rec *a, const hit_rec *b) {
    if (a->t != b->t) return a->t < b->t;
    if (a->geom != b->geom) return a->geom < b->geom;
    return a->prim < b->prim;
}

static int rec_cmp(const void *pa, const void *pb) {
    const hit_rec *a = pa, *b = pb;
    return rec_less(a, b) ? -1 : (rec_less(b, a) ? 1 : 0);
}

/* Two triangles touch when they have a vertex position in common. Positions,
 * not indices: flat-shaded meshes duplicate vertices along creases, and the
 * crossing at a box edge must still merge. */
static bool triangles_touch(const lu_accel *a, uint32_t geom, uint32_t p, uint32_t q) {
    const uint32_t *idx = a->meshes[geom].mesh->indices;
    const float *v = a->meshes[geom].verts;
    for (int i = 0; i < 3; i++) {
        const float *pi = v + 3 * (size_t)idx[3 * (size_t)p + i];
        for (int j = 0; j < 3; j++) {
            const float *qj = v + 3 * (size_t)idx[3 * (size_t)q + j];
            if (pi[0] == qj[0] && pi[1] == qj[1] && pi[2] == qj[2]) return true;
        }
    }
    return false;
}

/* Sorts the candidates and merges reports of one surface crossing:
 *  - the same primitive twice (spatial splits put it in several leaves);
 *  - a ray through a shared edge or vertex, which the watertight test reports
 *    for every triangle there: hits at the same t (within a few float ulps of
 *    the hit point's magnitude), on the same mesh, whose triangles share a
 *    vertex position and which cross in the same direction (sign of ng.d).
 * A ray grazing a silhouette edge meets a front- and a back-facing triangle
 * at the same t; those stay two crossings (in and out), so parity holds. */
static int merge_hits(const lu_accel *a, hit_rec *r, int n, lu_vec3 o, lu_vec3 d) {
    if (n <= 32) {
        for (int i = 1; i < n; i++) {
            hit_rec x = r[i];
            int j = i - 1;
            while (j >= 0 && rec_less(&x, &r[j])) {
                r[j + 1] = r[j];
                j--;
            }
            r[j + 1] = x;
        }
    } else {
        qsort(r, (size_t)n, sizeof *r, rec_cmp);
    }
    const float omax = max_abs3(o), dmax = max_abs3(d);
    int kept = 0;
    for (int i = 0; i < n; i++) {
        if (r[i].dead) continue;
        const float tol = 32.0f * FLT_EPSILON * (omax + fabsf(r[i].t) * dmax) / dmax + FLT_MIN;
        const bool front_i = r[i].ng[0] * d.x + r[i].ng[1] * d.y + r[i].ng[2] * d.z < 0.0f;
        for (int j = i + 1; j < n && r[j].t - r[i].t <= tol; j++) {
            if (r[j].dead || r[j].geom != r[i].geom) continue;
            if (r[j].prim == r[i].prim) {
                r[j].dead = true;
                continue;
            }
            const bool front_j = r[j].ng[0] * d.x + r[j].ng[1] * d.y + r[j].ng[2] * d.z < 0.0f;
            if (front_j == front_i && triangles_touch(a, r[i].geom, r[i].prim, r[j].prim)) r[j].dead = true;
        }
        r[kept++] = r[i];
    }
    return kept;
}

int lu_accel_all_hits(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax, lu_hit *hits,
                      int max_hits) {
    struct RTCRayHit rh;
    float off;
    if (!setup_ray(a, o, d, tmin, tmax, &rh.ray, &off)) return 0;
    collector c;
    rtcInitIntersectContext(&c.ctx);
    c.ctx.filter = collect_filter;
    c.recs = c.local;
    c.n = 0;
    c.cap = (int)(sizeof c.local / sizeof c.local[0]);
    c.oom = false;
    /* Embree does not promise hits within an ulp of tnear/tfar either way, so
     * it gets a slightly wider interval and the filter applies the exact one. */
    c.tlo = rh.ray.tnear;
    c.thi = rh.ray.tfar;
    rh.ray.tnear = fmaxf(0.0f, c.tlo - 1e-6f * fabsf(c.tlo));
    rh.ray.tfar = c.thi + 1e-6f * fabsf(c.thi);
    memset(&rh.hit, 0, sizeof rh.hit);
    rh.hit.geomID = RTC_INVALID_GEOMETRY_ID;
    rh.hit.instID[0] = RTC_INVALID_GEOMETRY_ID;
    rtcIntersect1(a->scene, &c.ctx, &rh);

    int n = -1;
    if (!c.oom) {
        lu_vec3 os = lu_v3(rh.ray.org_x, rh.ray.org_y, rh.ray.org_z);
        n = merge_hits(a, c.recs, c.n, os, d);
        if (max_hits < 0 || !hits) max_hits = 0;
        for (int i = 0; i < n && i < max_hits; i++) {
            const hit_rec *r = &c.recs[i];
            hits[i].t = r->t + off;
            hits[i].mesh_id = r->geom;
            hits[i].prim_id = r->prim;
            hits[i].u = r->u;
            hits[i].v = r->v;
            hits[i].ng = unit_normal(r->ng[0], r->ng[1], r->ng[2]);
        }
    }
    if (c.recs != c.local) lu_free(c.recs);
    return n;
}

/* Three fixed, non-axis-aligned, mutually non-coplanar directions: a point
 * whose ray grazes an edge or a coplanar face along one of them is still
 * classified by the other two. */
static const lu_vec3 k_inside_dirs[3] = {
    {0.5381f, 0.7131f, 0.4494f},
    {-0.6523f, 0.2747f, 0.7064f},
    {0.3169f, -0.8438f, -0.4331f},
};

bool lu_accel_inside(const lu_accel *a, lu_vec3 p) {
    if (!a || !a->committed || !lu_v3_finite(p)) return false;
    lu_aabb b = a->bounds;
    if (!lu_aabb_valid(b) || p.x < b.lo.x || p.y < b.lo.y || p.z < b.lo.z || p.x > b.hi.x || p.y > b.hi.y ||
        p.z > b.hi.z)
        return false;
    int votes = 0;
    for (int k = 0; k < 3; k++) {
        int n = lu_accel_all_hits(a, p, k_inside_dirs[k], 0.0f, INFINITY, NULL, 0);
        if (n > 0 && (n & 1)) votes++;
        /* Stop once the majority is decided. */
        if (votes == 2) return true;
        if (votes + (2 - k) < 2) return false;
    }
    return votes >= 2;
}
