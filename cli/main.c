/* lucent — one binary, git-style subcommands. */
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"
#include "mpi_job.h"

static const char k_usage[] =
    "usage: lucent <command> [options]\n"
    "\n"
    "commands:\n"
    "  render SCENE.json --method M -o OUT.{png,exr,pfm}   render a scene\n"
    "  compare A B [-o diff.png]                            error metrics of A against reference B\n"
    "  bench SCENE.json... --methods a,b,...                time methods (sweeps, motions), error vs reference\n"
    "  view SCENE.json [--method M]                         interactive viewer (window)\n"
    "  info FILE                                            summarise a scene, mesh, grid or image\n"
    "  export-grid SCENE.json -o OUT.nvdb                   write a medium's density grid as NanoVDB\n"
    "  methods                                              list methods and their parameters\n"
    "  profile --preset NAME                                diffusion profile of a translucent material\n"
    "\n"
    "Every command takes --help. Exit codes: 0 success, 1 failure (bad input, failed\n"
    "render; one line on stderr says why), 2 usage error (a bad argument, or LUCENT_THREADS\n"
    "not an integer in [1, 256]), 3 a --max-* threshold exceeded.\n";

int lu_cli_error(const char *cmd, const lu_error *err) {
    if (lu_mpi_size() > 1)
        fprintf(stderr, "lucent %s: error (rank %d of %d): %s\n", cmd, lu_mpi_rank(), lu_mpi_size(), err->message);
    else
        fprintf(stderr, "lucent %s: error: %s\n", cmd, err->message);
    return LU_EXIT_FAIL;
}

int lu_cli_usage(const char *cmd, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "lucent %s: ", cmd);
    vfprintf(stderr, fmt, ap);
    fprintf(stderr, " (see lucent %s --help)\n", cmd);
    va_end(ap);
    return LU_EXIT_USAGE;
}

bool lu_cli_is_help(const char *arg) { return strcmp(arg, "--help") == 0 || strcmp(arg, "-h") == 0; }

bool lu_cli_parse_size(const char *s, int *w, int *h) {
    char tail;
    return sscanf(s, "%dx%d%c", w, h, &tail) == 2 && *w >= 1 && *h >= 1 && *w <= LU_MAX_IMAGE_DIM &&
           *h <= LU_MAX_IMAGE_DIM;
}

bool lu_cli_parse_backend(const char *s, lu_backend *b) {
    if (strcmp(s, "cpu") == 0) *b = LU_BACKEND_CPU;
    else if (strcmp(s, "gpu") == 0) *b = LU_BACKEND_GPU;
    else if (strcmp(s, "auto") == 0) *b = LU_BACKEND_AUTO;
    else return false;
    return true;
}

lu_backend lu_cli_resolve_backend(const char *cmd, lu_backend b, const lu_method *m) {
    if (b != LU_BACKEND_AUTO) return b;
    lu_backend got = m ? lu_backend_resolve(b, m) : lu_backend_auto(NULL);
    static bool noted;
    const char *why;
    if (lu_backend_auto(&why) == LU_BACKEND_CPU && (!m || (m->backends & LU_BACKEND_GPU)) && !noted) {
        noted = true;
        fprintf(stderr, "lucent %s: note: --backend auto: no hardware GPU (%s); running on the CPU\n", cmd, why);
    }
    return got;
}

int lu_cli_load_scene(const char *cmd, const char *path, int width, int height, lu_scene *scene) {
    lu_error err = {0};
    if (lu_scene_load(path, scene, &err) != LU_OK) return lu_cli_error(cmd, &err);
    if (width > 0) {
        scene->camera.width = width;
        scene->camera.height = height;
    }
    return LU_EXIT_OK;
}

void lu_cli_print_methods(FILE *out) {
    int n;
    const lu_method *const *all = lu_methods(&n);
    for (int i = 0; i < n; i++) {
        const lu_method *m = all[i];
        fprintf(out, "%s [%s%s%s]\n  %s\n", m->name, (m->backends & LU_BACKEND_CPU) ? "cpu" : "",
                (m->backends & LU_BACKEND_CPU) && (m->backends & LU_BACKEND_GPU) ? "," : "",
                (m->backends & LU_BACKEND_GPU) ? "gpu" : "", m->summary);
        for (int j = 0; j < m->param_count; j++) {
            const lu_param_desc *p = &m->params[j];
            if (p->type == LU_PARAM_CHOICE)
                fprintf(out, "    %s.%s = %s (default choice %d) — %s\n", m->name, p->name, p->choices, (int)p->def,
                        p->help);
            else
                fprintf(out, "    %s.%s = %g in [%g, %g] — %s\n", m->name, p->name, p->def, p->lo, p->hi, p->help);
        }
        for (int j = 0; j < m->preset_count; j++)
            fprintf(out, "    %s.preset = %s — %s: %s\n", m->name, m->presets[j].name, m->presets[j].help,
                    m->presets[j].values);
    }
}

int lu_cmd_methods(int argc, char **argv) {
    if (argc > 1 && lu_cli_is_help(argv[1])) {
        printf("usage: lucent methods\n\nLists every method, the backends it runs on, and its parameters\n"
               "(set them with --set method.param=value on render and bench).\n");
        return LU_EXIT_OK;
    }
    if (argc > 1) return lu_cli_usage("methods", "unexpected argument \"%s\"", argv[1]);
    lu_cli_print_methods(stdout);
    return LU_EXIT_OK;
}

int main(int argc, char **argv) {
    if (argc < 2 || lu_cli_is_help(argv[1])) {
        fputs(k_usage, argc < 2 ? stderr : stdout);
        return argc < 2 ? LU_EXIT_USAGE : LU_EXIT_OK;
    }
    if (strcmp(argv[1], "--version") == 0) {
        printf("lucent %s\n", LU_VERSION_STRING);
        return LU_EXIT_OK;
    }
    int host = lu_cli_host_from_env();
    if (host != LU_EXIT_OK) return host;
    static const struct {
        const char *name;
        int (*fn)(int, char **);
        bool divides;   /* divides its work among the ranks of a job (docs/distributed.md) */
    } cmds[] = {{"render", lu_cmd_render, true},   {"compare", lu_cmd_compare, false},
                {"bench", lu_cmd_bench, true},     {"info", lu_cmd_info, false},
                {"methods", lu_cmd_methods, false}, {"profile", lu_cmd_profile, false},
                {"view", lu_cmd_view, false},      {"export-grid", lu_cmd_export_grid, false}};
    for (size_t i = 0; i < sizeof cmds / sizeof cmds[0]; i++) {
        if (strcmp(argv[1], cmds[i].name) != 0) continue;
        int rc = lu_mpi_begin(&argc, &argv);
        if (rc != LU_EXIT_OK) return rc;
        if (lu_mpi_size() > 1 && !cmds[i].divides)
            rc = lu_cli_usage(argv[1], "divides no work among the %d ranks of a job; run it without mpirun or srun",
                              lu_mpi_size());
        else
            rc = cmds[i].fn(argc - 1, argv + 1);
        return lu_mpi_end(rc);
    }
    fprintf(stderr, "lucent: unknown command \"%s\"\n\n%s", argv[1], k_usage);
    return LU_EXIT_USAGE;
}
