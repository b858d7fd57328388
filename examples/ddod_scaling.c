/* ddod frame time against the number of lights (the paper's Table 3) and of
 * samples (Table 4), on both backends, measured in one run so the numbers
 * compare as ratios:
 *   build/examples/ddod_scaling scenes/homogeneous_sphere.json [frames] [lights] > scaling.csv
 * Lights: the scene's first light copied round the object (1, 2, 4, 8 point
 * lights at the same distance, intensities divided so the total stays),
 * twice: "lights" with the lights and camera still (the traced attenuation
 * table is kept, as in any frame where nothing moves) and "lights_moving"
 * with every light turned a little about the y axis each frame (the table's
 * light entries are retraced every frame). "camera_moving": the scene's own
 * lights, the camera turned a little each frame (the view entries are
 * retraced). "lights_sh": the still lights on the paper's SH path
 * (ddod.view_psi = light_psi = sh), for the cost of the traced default when
 * nothing moves. Samples: 25k, 50k, 100k with one scene. A third argument
 * "lights" keeps only the light rows. Prints CSV: what,n,backend, wall_ms,
 * cpu_ms (medians; cpu_ms is the process's processor time per frame, all
 * threads, llvmpipe's included: the robust number on a shared machine).
 * The precomputation is cached ($LUCENT_CACHE_DIR), so only the first run
 * of each setting pays for it. */
#include <lucent/lucent.h>

#include <math.h>
#include <stdbool.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

static double cpu_ms(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return 1e3 * ((double)ru.ru_utime.tv_sec + ru.ru_utime.tv_usec * 1e-6 + (double)ru.ru_stime.tv_sec +
                  ru.ru_stime.tv_usec * 1e-6);
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

/* Turns what `move` names about the y axis by a small angle (a new
 * position every frame: the traced table cannot be reused). */
enum { MOVE_NONE, MOVE_LIGHTS, MOVE_CAMERA };
static lu_vec3 turn_y(lu_vec3 p, float a) {
    float c = cosf(a), sn = sinf(a);
    return lu_v3(c * p.x + sn * p.z, p.y, -sn * p.x + c * p.z);
}
static void move_scene(lu_scene *s, int move) {
    const float a = 0.01f;
    if (move == MOVE_LIGHTS)
        for (int l = 0; l < s->light_count; l++) s->lights[l].position = turn_y(s->lights[l].position, a);
    if (move == MOVE_CAMERA) s->camera.position = turn_y(s->camera.position, a);
}

/* Median frame wall and processor time (ms) after one warm-up frame; -1 when the backend is missing. */
static double time_frames(lu_scene *s, const char *samples, lu_backend be, int frames, int move, bool paper,
                          double *cpu_out) {
    lu_error err = {0};
    lu_kvlist set = {0};
    char kv[64];
    snprintf(kv, sizeof kv, "ddod.samples=%s", samples);
    lu_kv_parse_assignment(&set, kv, &err);
    if (paper) {
        lu_kv_parse_assignment(&set, "ddod.view_psi=sh", &err);
        lu_kv_parse_assignment(&set, "ddod.light_psi=sh", &err);
    }
    lu_renderer *r = NULL;
    lu_image img = {0};
    double ms[64], cpu[64], med = -1.0;
    *cpu_out = -1.0;
    if (lu_renderer_create("ddod", s, &set, be, &r, &err) == LU_OK && lu_renderer_render(r, s, &img, &err) == LU_OK) {
        int n = frames < 64 ? frames : 64;
        for (int i = 0; i < n; i++) {
            move_scene(s, move);
            double c0 = cpu_ms();
            lu_renderer_render(r, s, &img, &err);
            cpu[i] = cpu_ms() - c0;
            lu_renderer_stats st;
            lu_renderer_get_stats(r, &st, NULL);
            ms[i] = st.frame_ms;
        }
        qsort(ms, (size_t)n, sizeof ms[0], cmp_double);
        qsort(cpu, (size_t)n, sizeof cpu[0], cmp_double);
        med = ms[n / 2];
        *cpu_out = cpu[n / 2];
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
    bool lights_only = argc > 3 && strcmp(argv[3], "lights") == 0;
    lu_error err = {0};
    lu_scene scene;
    if (lu_scene_load(argv[1], &scene, &err) != LU_OK || scene.light_count < 1) {
        fprintf(stderr, "%s\n", scene.light_count < 1 ? "the scene needs a light" : err.message);
        return 1;
    }
    lu_light *orig = scene.lights;
    int orig_count = scene.light_count;
    lu_light lights[8];
    printf("what,n,backend,wall_ms,cpu_ms\n");
    lu_backend bes[2] = {LU_BACKEND_CPU, LU_BACKEND_GPU};
    for (int b = 0; b < 2; b++) {
        const char *rows[3] = {"lights", "lights_moving", "lights_sh"};
        for (int row = 0; row < 3; row++)
            for (int n = 1; n <= 8; n *= 2) {
                for (int i = 0; i < n; i++) {
                    lights[i] = orig[0];
                    lights[i].position = turn_y(orig[0].position, 2.0f * (float)M_PI * (float)i / (float)n);
                    lights[i].intensity = lu_v3_scale(orig[0].intensity, 1.0f / (float)n);
                }
                scene.lights = lights;
                scene.light_count = n;
                double c, ms = time_frames(&scene, "50000", bes[b], frames, row == 1 ? MOVE_LIGHTS : MOVE_NONE, row == 2, &c);
                printf("%s,%d,%s,%.3f,%.3f\n", rows[row], n, lu_backend_name(bes[b]), ms, c);
                fflush(stdout);
            }
        scene.lights = orig;
        scene.light_count = orig_count;
        if (lights_only) continue;
        lu_camera cam = scene.camera;
        double cm, mm = time_frames(&scene, "50000", bes[b], frames, MOVE_CAMERA, false, &cm);
        printf("camera_moving,%d,%s,%.3f,%.3f\n", scene.light_count, lu_backend_name(bes[b]), mm, cm);
        scene.camera = cam;
        const char *ns[3] = {"25000", "50000", "100000"};
        for (int k = 0; k < 3; k++) {
            double c, ms = time_frames(&scene, ns[k], bes[b], frames, MOVE_NONE, false, &c);
            printf("samples,%s,%s,%.3f,%.3f\n", ns[k], lu_backend_name(bes[b]), ms, c);
            fflush(stdout);
        }
    }
    lu_scene_destroy(&scene);
    return 0;
}
