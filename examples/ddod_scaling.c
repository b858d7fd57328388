/* ddod frame time against the number of lights (the paper's Table 3) and of
 * samples (Table 4), on both backends, measured in one run so the numbers
 * compare as ratios:
 *   build/examples/ddod_scaling scenes/homogeneous_sphere.json [frames] > scaling.csv
 * Lights: the scene's first light copied round the object (1, 2, 4, 8 point
 * lights at the same distance, intensities divided so the total stays).
 * Samples: 25k, 50k, 100k with one scene. Prints CSV: what,n,backend,ms,
 * cpu_ms_samples (pass 1 on the CPU), samples. The precomputation is cached
 * ($LUCENT_CACHE_DIR), so only the first run of each setting pays for it. */
#include <lucent/lucent.h>

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Median frame time (ms) after one warm-up frame; -1 when the backend is missing. */
static double time_frames(const lu_scene *s, const char *samples, lu_backend be, int frames) {
    lu_error err = {0};
    lu_kvlist set = {0};
    char kv[64];
    snprintf(kv, sizeof kv, "ddod.samples=%s", samples);
    lu_kv_parse_assignment(&set, kv, &err);
    lu_renderer *r = NULL;
    lu_image img = {0};
    double ms[64], med = -1.0;
    if (lu_renderer_create("ddod", s, &set, be, &r, &err) == LU_OK && lu_renderer_render(r, s, &img, &err) == LU_OK) {
        int n = frames < 64 ? frames : 64;
        for (int i = 0; i < n; i++) {
            lu_renderer_render(r, s, &img, &err);
            ms[i] = r->last_render_ms;
        }
        qsort(ms, (size_t)n, sizeof ms[0], cmp_double);
        med = ms[n / 2];
    } else {
        fprintf(stderr, "%s backend: %s\n", lu_backend_name(be), err.message);
    }
    lu_renderer_destroy(r);
    lu_image_destroy(&img);
    lu_kv_free(&set);
    return med;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: %s SCENE.json [frames]\n", argv[0]);
        return 2;
    }
    int frames = argc > 2 ? atoi(argv[2]) : 5;
    lu_error err = {0};
    lu_scene scene;
    if (lu_scene_load(argv[1], &scene, &err) != LU_OK || scene.light_count < 1) {
        fprintf(stderr, "%s\n", scene.light_count < 1 ? "the scene needs a light" : err.message);
        return 1;
    }
    lu_light *orig = scene.lights;
    int orig_count = scene.light_count;
    lu_light lights[8];
    printf("what,n,backend,ms\n");
    lu_backend bes[2] = {LU_BACKEND_CPU, LU_BACKEND_GPU};
    for (int b = 0; b < 2; b++) {
        for (int n = 1; n <= 8; n *= 2) {
            for (int i = 0; i < n; i++) {
                lights[i] = orig[0];
                /* rotate the first light's position about the y axis */
                float a = 2.0f * (float)M_PI * (float)i / (float)n, c = cosf(a), sn = sinf(a);
                lu_vec3 p = orig[0].position;
                lights[i].position = lu_v3(c * p.x + sn * p.z, p.y, -sn * p.x + c * p.z);
                lights[i].intensity = lu_v3_scale(orig[0].intensity, 1.0f / (float)n);
            }
            scene.lights = lights;
            scene.light_count = n;
            double ms = time_frames(&scene, "50000", bes[b], frames);
            printf("lights,%d,%s,%.3f\n", n, lu_backend_name(bes[b]), ms);
            fflush(stdout);
        }
        scene.lights = orig;
        scene.light_count = orig_count;
        const char *ns[3] = {"25000", "50000", "100000"};
        for (int k = 0; k < 3; k++) {
            double ms = time_frames(&scene, ns[k], bes[b], frames);
            printf("samples,%s,%s,%.3f\n", ns[k], lu_backend_name(bes[b]), ms);
            fflush(stdout);
        }
    }
    lu_scene_destroy(&scene);
    return 0;
}
