/* Soak (docs/reliability.md, "Soak"): one renderer per CPU method renders
 * many frames while the camera swings about its look-at point and the
 * first light the other way, every frame a change the frame stage must act
 * on. The swing is periodic (PERIOD frames, the same angles bit for bit
 * each period), so a method's working set, which may depend on the view
 * (bssrdf's splats), is the same from one period to the next. Two figures:
 *   - the bytes the library holds through the host allocator (lu_host),
 *     counted exactly by this allocator: from the second period on, frame
 *     f must hold exactly what frame f - PERIOD held (a buffer not reused,
 *     or a cache that grows, shows at once);
 *   - the process's resident memory (/proc/self/statm), which also sees
 *     Embree, FFTW and the C library: its peak over the last period may
 *     exceed the second period's by at most 5 % (not under ASan, whose
 *     quarantine keeps freed memory resident).
 * Default (the suite): 3 periods, 48 frames per method at 64x36. `make soak` runs
 * `test_soak --frames 1000 --size 160x90 --csv FILE` (a row per frame and
 * method: method,frame,lib_bytes,rss_kb), which docs/reliability.md plots. */
#include "lu_test.h"

#include <time.h>

#include "lu_test_alloc.h"

#define PERIOD 16

static void quiet_log(lu_log_level level, const char *message, void *user) {
    (void)level, (void)message, (void)user;
}

/* Rodrigues' turn of v about the unit axis u. */
static lu_vec3 turn(lu_vec3 v, lu_vec3 u, float a) {
    float c = cosf(a), s = sinf(a), d = lu_v3_dot(u, v);
    return lu_v3_add(lu_v3_add(lu_v3_scale(v, c), lu_v3_scale(lu_v3_cross(u, v), s)), lu_v3_scale(u, d * (1 - c)));
}

typedef struct job {
    const char *method, *scene, *settings;
} job;

static void soak(const job *j, int frames, int w, int h, FILE *csv) {
    char path[512];
    snprintf(path, sizeof path, LU_SOURCE_DIR "/scenes/%s.json", j->scene);
    lu_error err = {0};
    lu_scene s;
    if (lu_scene_load(path, &s, &err) != LU_OK) {
        CHECK_MSG(false, "%s: %s", path, err.message);
        return;
    }
    s.camera.width = w;
    s.camera.height = h;
    lu_kvlist kv = {0};
    char buf[256];
    snprintf(buf, sizeof buf, "%s", j->settings);
    lu_result res = LU_OK;
    for (char *tok = strtok(buf, " "); tok && res == LU_OK; tok = strtok(NULL, " "))
        res = lu_kv_parse_assignment(&kv, tok, &err);
    lu_renderer *r = NULL;
    if (res == LU_OK) res = lu_renderer_create(j->method, &s, &kv, LU_BACKEND_CPU, &r, &err);
    lu_camera cam0 = s.camera;
    lu_light light0 = s.light_count ? s.lights[0] : (lu_light){0};
    lu_vec3 up = lu_v3_norm(cam0.up);
    long long *bytes = calloc((size_t)frames, sizeof *bytes);
    long *rss = calloc((size_t)frames, sizeof *rss);
    lu_image img = {0};
    int done = 0;
    struct timespec t0, t1;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    for (int f = 0; f < frames && res == LU_OK && bytes && rss; f++, done++) {
        float a = 0.4f * sinf(6.2831853f * (float)(f % PERIOD) / (float)PERIOD);
        s.camera.position = lu_v3_add(cam0.look_at, turn(lu_v3_sub(cam0.position, cam0.look_at), up, a));
        if (s.light_count && s.lights[0].type != LU_LIGHT_ENVIRONMENT) {
            s.lights[0].position = lu_v3_add(cam0.look_at, turn(lu_v3_sub(light0.position, cam0.look_at), up, -a));
            s.lights[0].direction = turn(light0.direction, up, -a);
        }
        res = lu_renderer_render(r, &s, &img, &err);
        bytes[f] = atomic_load(&g_bytes);
        rss[f] = lu_resident_kb();
        if (csv) fprintf(csv, "%s,%d,%lld,%ld\n", j->method, f, bytes[f], rss[f]);
    }
    clock_gettime(CLOCK_MONOTONIC, &t1);
    double secs = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
    CHECK_MSG(res == LU_OK, "%s: %s", j->method, err.message);
    if (res == LU_OK && done == frames) {
        int bad = 0;
        for (int f = 2 * PERIOD; f < frames; f++)
            if (bytes[f] != bytes[f - PERIOD] && bad++ < 3)
                CHECK_MSG(false, "%s: frame %d holds %lld library bytes, frame %d (the same view) %lld", j->method, f,
                          bytes[f], f - PERIOD, bytes[f - PERIOD]);
        long peak2 = 0, peak_last = 0;
        for (int f = PERIOD; f < 2 * PERIOD; f++) peak2 = rss[f] > peak2 ? rss[f] : peak2;
        for (int f = frames - PERIOD; f < frames; f++) peak_last = rss[f] > peak_last ? rss[f] : peak_last;
#if defined(__SANITIZE_ADDRESS__)
        /* ASan's quarantine keeps freed blocks resident (up to 256 MB), so
         * resident memory says nothing here; the exact byte count above
         * still holds. */
        (void)peak_last;
#else
        CHECK_MSG(peak_last <= peak2 + peak2 / 20, "%s: resident peak %ld kB in the last period, %ld in the second",
                  j->method, peak_last, peak2);
#endif
        fprintf(stderr, "  %-10s %4d frames: library %lld bytes at the end (%d frames off their period's), resident"
                        " peak %ld kB second period, %ld last (%+.2f %%), %.0f s\n",
                j->method, frames, bytes[frames - 1], bad, peak2, peak_last,
                100.0 * (double)(peak_last - peak2) / (double)(peak2 ? peak2 : 1), secs);
    }
    free(bytes);
    free(rss);
    lu_image_destroy(&img);
    lu_renderer_destroy(r);
    lu_kv_free(&kv);
    lu_scene_destroy(&s);
}

int main(int argc, char **argv) {
    int frames = 3 * PERIOD, w = 64, h = 36;
    const char *csv_path = NULL, *only = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--frames") == 0 && i + 1 < argc) frames = atoi(argv[++i]);
        else if (strcmp(argv[i], "--size") == 0 && i + 1 < argc) {
            if (sscanf(argv[++i], "%dx%d", &w, &h) != 2) return 2;
        } else if (strcmp(argv[i], "--csv") == 0 && i + 1 < argc) csv_path = argv[++i];
        else if (strcmp(argv[i], "--method") == 0 && i + 1 < argc) only = argv[++i];
        else {
            fprintf(stderr, "usage: test_soak [--frames N] [--size WxH] [--csv FILE] [--method NAME]\n");
            return 2;
        }
    }
    if (frames < 3 * PERIOD || w < 1 || h < 1) {
        fprintf(stderr, "test_soak: --frames must be at least %d and --size positive\n", 3 * PERIOD);
        return 2;
    }
    lu_host host = k_test_alloc_host;
    host.log = quiet_log;
    lu_error err = {0};
    CHECK(lu_host_set(&host, &err) == LU_OK);
    FILE *csv = csv_path ? fopen(csv_path, "w") : NULL;
    if (csv_path && !csv) {
        fprintf(stderr, "test_soak: cannot write %s\n", csv_path);
        return 2;
    }
    if (csv) fprintf(csv, "method,frame,lib_bytes,rss_kb\n");
    const job jobs[] = {
        {"reference", "demo", ""},
        {"raymarch", "demo", ""},
        {"afm", "demo", "afm.map_res=64"},
        {"gradient", "demo", ""},
        {"pervoxel", "demo", "pervoxel.grid=32"},   /* its per-voxel tracing at full grid is 3.5x the frame: 1,000 frames must fit make soak */
        {"rbf", "demo", ""},
        {"ddod", "bssrdf_spheres", "ddod.res=32 ddod.dirs=32 ddod.samples=2000 ddod.cache=0"},
        {"pathtrace", "demo", "pathtrace.spp=1"},
        {"bssrdf", "bssrdf_spheres", "bssrdf.splats=1024"},
    };
    int ran = 0;
    for (size_t i = 0; i < sizeof jobs / sizeof jobs[0]; i++)
        if (!only || strcmp(only, jobs[i].method) == 0) soak(&jobs[i], frames, w, h, csv), ran++;
    CHECK_MSG(ran > 0, "no soak job for method %s", only ? only : "");
    if (csv) fclose(csv);
    TEST_EXIT();
}
