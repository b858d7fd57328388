/* The frame stage (src/methods/frame.h): one renderer driven through a
 * scripted sequence of scene changes must, after every frame, give exactly
 * the image a fresh renderer gives for the same scene (bit for bit), and its
 * rebuild counters must show that each cached product was rebuilt exactly
 * when one of its declared inputs changed. The expected dependencies below
 * are the specification, written independently of the code that tracks them. */
#include <lucent/lucent.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "backends/gpu.h"
#include "lu_test.h"

/* ---- scripted changes ---- */

static lu_vec3 rotate_about_y(lu_vec3 p, lu_vec3 centre, float deg) {
    float a = deg * (float)M_PI / 180.0f, c = cosf(a), s = sinf(a);
    lu_vec3 d = lu_v3_sub(p, centre);
    return lu_v3_add(centre, lu_v3(c * d.x + s * d.z, d.y, -s * d.x + c * d.z));
}

static float blob(void *ctx, int x, int y, int z, float v) {
    const float *c = ctx;
    float dx = (float)x - c[0], dy = (float)y - c[1], dz = (float)z - c[2];
    return v + 0.5f * expf(-(dx * dx + dy * dy + dz * dz) / 8.0f);
}

enum { S_FIRST, S_STILL, S_CAMERA, S_LIGHT0, S_LIGHT1, S_DENSITY, S_COEFS, S_CAMERA_LIGHT, S_OBJECT, S_AFTER, S_COUNT };
static const char *const k_step_names[S_COUNT] = {"first", "still", "camera", "light 0", "light 1", "density edit",
                                                   "coefficients", "camera + light 0", "object moved",
                                                   "camera after the move"};

/* Applies step s; returns the lu_change bits it made and sets *lights to the
 * scene lights it changed (bit per light). */
static unsigned apply_step(lu_scene *sc, int s, uint64_t *lights) {
    *lights = 0;
    lu_error err = {0};
    switch (s) {
    case S_FIRST:
        *lights = ~0ull;
        return LU_CHANGE_ALL;
    case S_STILL:
        return 0;
    case S_CAMERA:
    case S_CAMERA_LIGHT:
        sc->camera.position = rotate_about_y(sc->camera.position, sc->camera.look_at, 4.0f);
        if (s == S_CAMERA) return LU_CHANGE_CAMERA;
        /* fall through */
    case S_LIGHT0:
    case S_LIGHT1: {
        int l = s == S_LIGHT1 ? 1 : 0;
        if (l >= sc->light_count) return s == S_CAMERA_LIGHT ? LU_CHANGE_CAMERA : 0;
        lu_light *li = &sc->lights[l];
        if (li->type == LU_LIGHT_DIRECTIONAL) li->direction = lu_v3_norm(rotate_about_y(li->direction, lu_v3s(0), 4.0f));
        else if (li->type == LU_LIGHT_ENVIRONMENT) li->env_scale *= 1.1f;
        else {
            li->position = rotate_about_y(li->position, sc->camera.look_at, 4.0f);
            li->direction = lu_v3_norm(rotate_about_y(li->direction, lu_v3s(0), 4.0f));
        }
        *lights = 1ull << l;
        return LU_CHANGE_LIGHTS | (s == S_CAMERA_LIGHT ? LU_CHANGE_CAMERA : 0u);
    }
    case S_DENSITY: {
        lu_grid *g = NULL;
        if (sc->medium_count == 0 || lu_scene_medium_grid(sc, 0, &g, &err) != LU_OK) return 0;
        int lo[3] = {0, 0, 0}, hi[3] = {g->nx, g->ny, g->nz};
        float c[3] = {0.5f * (float)g->nx, 0.4f * (float)g->ny, 0.5f * (float)g->nz};
        CHECK_OK(lu_grid_apply(g, lo, hi, blob, c, &err), &err);
        return LU_CHANGE_MEDIA;
    }
    case S_COEFS:
        if (sc->medium_count == 0) return 0;
        sc->media[0].sigma_s = lu_v3_scale(sc->media[0].sigma_s, 1.05f);
        return LU_CHANGE_MEDIA;
    case S_OBJECT:
        /* Objects are baked to world space: a moved object is a new mesh. */
        for (int o = 0; o < sc->object_count; o++) {
            lu_mesh *m = &sc->objects[o].mesh, n;
            if (sc->objects[o].material.type != LU_MATERIAL_DIFFUSE) continue;
            CHECK_OK(lu_mesh_alloc(&n, m->vertex_count, m->triangle_count, &err), &err);
            for (uint32_t v = 0; v < m->vertex_count; v++) {
                n.positions[v] = lu_v3_add(m->positions[v], lu_v3(0.02f, 0.0f, 0.01f));
                n.normals[v] = m->normals[v];
            }
            memcpy(n.indices, m->indices, (size_t)m->triangle_count * 3 * sizeof *m->indices);
            lu_mesh_destroy(m);
            *m = n;
            *lights = ~0ull;
            return LU_CHANGE_GEOMETRY;
        }
        return 0;
    case S_AFTER:
        sc->camera.position = rotate_about_y(sc->camera.position, sc->camera.look_at, -4.0f);
        return LU_CHANGE_CAMERA;
    }
    return 0;
}

/* ---- the products and what they depend on ---- */

typedef struct product {
    const char *name;
    unsigned deps;      /* rebuilt once when any of these changed */
    bool per_light;     /* also rebuilt, once per kernel light, when that light alone changed */
} product;

/* In deps: the camera, where the phase is anisotropic (the source radiance is
 * scattered towards the camera), or where the method's light-side work reads
 * it in any way (view_dependent). */
#define CAMERA_IF_ANISOTROPIC (1u << 16)
#define CAMERA_IF_VIEW (1u << 17)

static const product k_products[] = {
    {"media_rays.camera", LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY, false},
    {"media_rays.maps", LU_CHANGE_LIGHTS | LU_CHANGE_GEOMETRY, false},
    {"media_rays.boundary_maps", LU_CHANGE_LIGHTS | LU_CHANGE_GEOMETRY, false},
    {"media_rays.surface_vis", LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY, true},
    /* bssrdf: the light-space maps and the splats made from them are the
     * light's; the camera's hits and the splats' screen tiles are the camera's */
    {"bssrdf.maps", LU_CHANGE_GEOMETRY, true},
    {"bssrdf.splats", LU_CHANGE_GEOMETRY, true},
    {"bssrdf.gbuffer", LU_CHANGE_CAMERA | LU_CHANGE_GEOMETRY, false},
    {"bssrdf.bins", LU_CHANGE_CAMERA | LU_CHANGE_LIGHTS | LU_CHANGE_GEOMETRY, false},
    /* ddod: the precomputation reads the media and the geometry; psi towards
     * the camera and each light also the camera's or that light's position */
    {"ddod.set", LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, false},
    {"ddod.view_psi", LU_CHANGE_CAMERA | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, false},
    {"ddod.light_psi", LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, true},
    {"ddod.pixels", LU_CHANGE_ALL, false},
    {"ddod.bins", LU_CHANGE_CAMERA | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, false},
    /* afm: a light's views frame the media's box from the light, and its
     * light-ray spans are where those rays cross the boundary meshes */
    {"afm.views", LU_CHANGE_GEOMETRY, true},
    /* a light's attenuation maps: the transmittance along its views' rays
     * through the media (density, coefficients, boundary Fresnel) */
    {"afm.maps", LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, true},
    /* the Gaussians fitted to the density and their reconstruction */
    {"gradient.fit", LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, false},
    /* source radiance at the samples, its gradient and shading error
     * (traced towards the lights through the media and the shadow maps) */
    {"gradient.samples", LU_CHANGE_LIGHTS | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY | CAMERA_IF_ANISOTROPIC, false},
    /* the splitting, which weighs that error by the transmittance to the
     * camera, and the radiance grid interpolated from the final samples */
    {"gradient.radiance_grid", LU_CHANGE_LIGHTS | LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY | CAMERA_IF_VIEW, false},
    /* the majorant grid of each medium's density (empty-space skipping) */
    {"view_march.occupancy", LU_CHANGE_MEDIA | LU_CHANGE_GEOMETRY, false},
};
#define PRODUCTS ((int)(sizeof k_products / sizeof k_products[0]))

_Static_assert(sizeof k_products / sizeof k_products[0] <= 32, "run_sequence keeps 32 counters");

/* Whether a method's light-side work reads the camera: the source radiance
 * is scattered towards the camera, so it depends on the view direction
 * unless the phase is isotropic, and gradient's dynamic sampling weighs each
 * sample's error by its transmittance to the camera (Ren et al. 2008, Eq. 5;
 * its splitting is on at these settings: 64^3 grids allow two levels). */
static bool anisotropic(const lu_scene *sc) { return sc->medium_count > 0 && sc->media[0].phase_g != 0.0f; }
static bool view_dependent(const char *method, const lu_scene *sc) {
    return anisotropic(sc) || strcmp(method, "gradient") == 0;
}

static int kernel_lights(const lu_scene *sc) {
    int n = 0;
    for (int l = 0; l < sc->light_count; l++) n += sc->lights[l].type != LU_LIGHT_ENVIRONMENT;
    return n;
}

static uint64_t expected_rebuilds(const product *p, const char *method, unsigned changes, uint64_t lights,
                                  const lu_scene *sc) {
    unsigned deps = p->deps & LU_CHANGE_ALL;
    if ((p->deps & CAMERA_IF_VIEW) && view_dependent(method, sc)) deps |= LU_CHANGE_CAMERA;
    if ((p->deps & CAMERA_IF_ANISOTROPIC) && anisotropic(sc)) deps |= LU_CHANGE_CAMERA;
    if (p->per_light) {
        if (changes & deps) return (uint64_t)kernel_lights(sc);
        uint64_t n = 0;
        for (int l = 0; l < sc->light_count && l < 63; l++)
            n += ((lights >> l) & 1u) && sc->lights[l].type != LU_LIGHT_ENVIRONMENT;
        return n;
    }
    return (changes & deps) ? 1u : 0u;
}

static bool same_pixels(const lu_image *a, const lu_image *b) {
    return a->width == b->width && a->height == b->height &&
           memcmp(a->rgb, b->rgb, (size_t)a->width * a->height * 3 * sizeof(float)) == 0;
}

static void run_sequence(const char *scene_file, const char *method, lu_backend backend, const char *settings) {
    char path[1024];
    snprintf(path, sizeof path, "%s/scenes/%s", LU_SOURCE_DIR, scene_file);
    lu_scene sc;
    lu_error err = {0};
    CHECK_OK(lu_scene_load(path, &sc, &err), &err);
    sc.camera.width = 40;
    sc.camera.height = 24;
    lu_kvlist kv = {0};
    lu_test_settings(&kv, settings);
    lu_renderer *r = NULL;
    CHECK_OK(lu_renderer_create(method, &sc, &kv, backend, &r, &err), &err);
    if (!r) {
        lu_scene_destroy(&sc);
        lu_kv_free(&kv);
        return;
    }
    int np = PRODUCTS;
    uint64_t before[PRODUCTS] = {0};
    bool uses[PRODUCTS] = {false};
    int identical = 0;
    uint64_t prepares_before = 0;
    for (int s = 0; s < S_COUNT; s++) {
        uint64_t lights;
        unsigned changes = apply_step(&sc, s, &lights);
        lu_image kept = {0}, fresh = {0};
        CHECK_OK(lu_renderer_render(r, &sc, &kept, &err), &err);
        lu_renderer *f = NULL;
        CHECK_OK(lu_renderer_create(method, &sc, &kv, backend, &f, &err), &err);
        if (f) CHECK_OK(lu_renderer_render(f, &sc, &fresh, &err), &err);
        bool same = kept.rgb && fresh.rgb && same_pixels(&kept, &fresh);
        identical += same;
        CHECK_MSG(same, "%s %s on %s, step \"%s\": the kept renderer's frame differs from a fresh renderer's "
                  "(rel-L2 %g)", method, lu_backend_name(backend), scene_file, k_step_names[s],
                  kept.rgb && fresh.rgb ? lu_test_rel_l2(&kept, &fresh) : -1.0);
        for (int i = 0; i < np; i++) {
            uint64_t now = lu_renderer_rebuilds(r, k_products[i].name);
            if (s == S_FIRST) uses[i] = now > 0;
            if (!uses[i]) continue;
            uint64_t want = expected_rebuilds(&k_products[i], method, changes, lights, &sc);
            CHECK_MSG(now - before[i] == want, "%s %s on %s, step \"%s\": %s rebuilt %llu times, expected %llu",
                      method, lu_backend_name(backend), scene_file, k_step_names[s], k_products[i].name,
                      (unsigned long long)(now - before[i]), (unsigned long long)want);
            before[i] = now;
        }
        /* New geometry makes the renderer prepare again (method.c). */
        uint64_t prepares = lu_renderer_rebuilds(r, "renderer.prepare");
        const lu_method *lm = lu_method_find(method);
        uint64_t want_prepares = s != S_FIRST && (changes & (LU_CHANGE_GEOMETRY | lm->prepare_deps)) ? 1u : 0u;
        CHECK_MSG(prepares - prepares_before == want_prepares, "%s %s on %s, step \"%s\": prepared %llu times, expected %llu",
                  method, lu_backend_name(backend), scene_file, k_step_names[s],
                  (unsigned long long)(prepares - prepares_before), (unsigned long long)want_prepares);
        prepares_before = prepares;
        lu_renderer_destroy(f);
        lu_image_destroy(&kept);
        lu_image_destroy(&fresh);
    }
    int used = 0;
    for (int i = 0; i < np; i++) used += uses[i];
    fprintf(stderr, "  %-9s %-3s %-22s %d/%d frames identical to a fresh renderer's, %d tracked products\n", method,
            lu_backend_name(backend), scene_file, identical, S_COUNT, used);
    lu_renderer_destroy(r);
    lu_scene_destroy(&sc);
    lu_kv_free(&kv);
}

static const char *const k_cheap =
    "raymarch.steps=48 raymarch.shadow_res=64 afm.steps=48 afm.map_res=32 afm.shadow_res=64 "
    "gradient.steps=48 gradient.shadow_res=64 gradient.gaussians=64 rbf.steps=48 rbf.shadow_res=64 "
    "rbf.gaussians=64 pervoxel.steps=48 pervoxel.shadow_res=64";

static void test_view_march_methods_cpu(void) {
    static const char *const methods[] = {"raymarch", "afm", "gradient", "rbf", "pervoxel"};
    static const char *const scenes[] = {"demo.json", "smoke_box.json"};
    for (int s = 0; s < 2; s++)
        for (int m = 0; m < 5; m++) run_sequence(scenes[s], methods[m], LU_BACKEND_CPU, k_cheap);
    /* a bounded medium (afm's light-ray spans and boundary crossings) lit by
     * a point light (six views) and a directional light (one) */
    run_sequence("layered_cube.json", "afm", LU_BACKEND_CPU, k_cheap);
    run_sequence("layered_cube.json", "raymarch", LU_BACKEND_CPU, k_cheap);
    /* the truths read the media at prepare: a media change prepares them again */
    run_sequence("smoke_box.json", "reference", LU_BACKEND_CPU, "reference.tolerance=0.05 reference.max_depth=2");
    run_sequence("smoke_box.json", "pathtrace", LU_BACKEND_CPU, "pathtrace.spp=1 pathtrace.max_depth=2");
}

static void test_view_march_methods_gpu(void) {
    lu_gpu_context *ctx = NULL;
    lu_error err = {0};
    if (!lu_gpu_compiled_in() || lu_gpu_context_create(&ctx, LU_GPU_AUTO, &err) != LU_OK) {
        fprintf(stderr, "  skipped: no GPU context (%s)\n", err.message);
        return;
    }
    lu_gpu_context_destroy(ctx);
    static const char *const methods[] = {"raymarch", "afm", "gradient"};
    for (int m = 0; m < 3; m++) run_sequence("demo.json", methods[m], LU_BACKEND_GPU, k_cheap);
    run_sequence("layered_cube.json", "afm", LU_BACKEND_GPU, k_cheap);
}

/* Translucent objects: bssrdf on its spheres (no media: the density and
 * coefficient steps change nothing it reads), ddod on the cube with the
 * torus (a grid medium: both steps redo its precomputation). */
static const char *const k_cheap_translucent =
    "bssrdf.splats=256 bssrdf.map_res=48 bssrdf.table_size=64 bssrdf.prefilter=2 "
    "ddod.res=12 ddod.dirs=16 ddod.samples=300 ddod.fit=2";

static void test_translucent_methods_cpu(void) {
    run_sequence("bssrdf_spheres.json", "bssrdf", LU_BACKEND_CPU, k_cheap_translucent);
    /* an environment light (its SH and the environment splats' flux follow it) */
    run_sequence("dragon_env.json", "bssrdf", LU_BACKEND_CPU,
                 "bssrdf.map_res=48 bssrdf.table_size=64 bssrdf.prefilter=2 bssrdf.env_samples=300 "
                 "bssrdf.relax_iters=2");
    run_sequence("cube_torus.json", "ddod", LU_BACKEND_CPU, k_cheap_translucent);
}

static void test_translucent_methods_gpu(void) {
    lu_gpu_context *ctx = NULL;
    lu_error err = {0};
    if (!lu_gpu_compiled_in() || lu_gpu_context_create(&ctx, LU_GPU_AUTO, &err) != LU_OK) {
        fprintf(stderr, "  skipped: no GPU context (%s)\n", err.message);
        return;
    }
    lu_gpu_context_destroy(ctx);
    run_sequence("bssrdf_spheres.json", "bssrdf", LU_BACKEND_GPU, k_cheap_translucent);
    run_sequence("cube_torus.json", "ddod", LU_BACKEND_GPU, k_cheap_translucent);
}

int main(void) {
    /* ddod's precomputation cache: a folder of this run's own */
    char cache[] = "/tmp/lucent-test-frame-XXXXXX";
    CHECK(mkdtemp(cache) != NULL);
    lu_set_cache_dir(cache, NULL);
    RUN_TEST(test_view_march_methods_cpu);
    RUN_TEST(test_view_march_methods_gpu);
    RUN_TEST(test_translucent_methods_cpu);
    RUN_TEST(test_translucent_methods_gpu);
    lu_test_remove_dir(cache);
    TEST_EXIT();
}
