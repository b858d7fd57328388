/* lucent export-grid SCENE.json [--medium N] [--time T] -o OUT.nvdb — a scene medium's
 * density grid, as the scene loaded it, written as NanoVDB. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "cli.h"

static void usage(void) {
    printf("usage: lucent export-grid SCENE.json [--medium N] [--time T] -o OUT.nvdb\n"
           "\n"
           "Writes the density grid of medium N (default 0) of the scene, as the scene\n"
           "loader made it (files, procedural grids and voxelised meshes alike), as a\n"
           "NanoVDB float grid named \"density\". The grid's map is the medium's index-to-\n"
           "world transform, the scene's transform included, so voxel positions are world\n"
           "positions. Densities are stored as they are: sigma_s and sigma_a (per world\n"
           "unit at density 1) stay in the scene and are printed, with the voxel size.\n"
           "\n"
           "options:\n"
           "  --medium N          which medium (0-based index into \"media\")\n"
           "  --time T            the grid at time T seconds (media that follow time: a sequence,\n"
           "                      an animated plume), so that a loop over frame times bakes a\n"
           "                      procedural into a numbered sequence\n"
           "  -o, --output FILE   the .nvdb file, written under a temporary name and renamed\n");
}

int lu_cmd_export_grid(int argc, char **argv) {
    const char *scene_path = NULL, *out = NULL;
    long medium = 0;
    bool time_given = false;
    double time = 0.0;
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i];
        bool has_next = i + 1 < argc;
        if (lu_cli_is_help(a)) {
            usage();
            return LU_EXIT_OK;
        } else if ((strcmp(a, "-o") == 0 || strcmp(a, "--output") == 0) && has_next) {
            out = argv[++i];
        } else if (strcmp(a, "--medium") == 0 && has_next) {
            char *end = NULL;
            medium = strtol(argv[++i], &end, 10);
            if (*end || end == argv[i] || medium < 0 || medium > 1000000)
                return lu_cli_usage("export-grid", "--medium takes an index >= 0");
        } else if (strcmp(a, "--time") == 0 && has_next) {
            char *end = NULL;
            time = strtod(argv[++i], &end);
            time_given = true;
            if (*end || end == argv[i] || !isfinite(time) || fabs(time) > 1e6)
                return lu_cli_usage("export-grid", "--time takes seconds in [-1e6, 1e6]");
        } else if (a[0] == '-') {
            return lu_cli_usage("export-grid", "unknown or incomplete option \"%s\"", a);
        } else if (!scene_path) {
            scene_path = a;
        } else {
            return lu_cli_usage("export-grid", "unexpected argument \"%s\"", a);
        }
    }
    if (!scene_path) return lu_cli_usage("export-grid", "missing SCENE.json");
    if (!out) return lu_cli_usage("export-grid", "missing -o OUT.nvdb");
    if (strcmp(lu_path_ext(out), "nvdb") != 0)
        return lu_cli_usage("export-grid", "the output \"%s\" must end in .nvdb", out);
    if (lu_cli_check_output("export-grid", out) != LU_EXIT_OK) return LU_EXIT_FAIL;

    lu_scene scene;
    int rc = lu_cli_load_scene("export-grid", scene_path, 0, 0, &scene);
    if (rc != LU_EXIT_OK) return rc;
    lu_error err = {0};
    if (time_given && lu_scene_set_time(&scene, time, &err) != LU_OK) {
        rc = lu_cli_error("export-grid", &err);
    } else if (medium >= scene.medium_count) {
        fprintf(stderr, "lucent export-grid: error: %s has %d media; there is no medium %ld\n", scene_path,
                scene.medium_count, medium);
        rc = LU_EXIT_FAIL;
    } else if (scene.media[medium].kind != LU_DENSITY_GRID) {
        fprintf(stderr, "lucent export-grid: error: %s: medium %ld has a constant density, not a grid\n", scene_path,
                medium);
        rc = LU_EXIT_FAIL;
    } else {
        const lu_medium *m = &scene.media[medium];
        /* A shallow copy: the same voxels under the world map (the grid's own
         * map is the file's, before the scene transform). */
        lu_grid g = m->grid;
        g.index_to_world = m->index_to_world;
        snprintf(g.name, sizeof g.name, "density");
        if (lu_grid_save_nvdb(&g, out, &err) != LU_OK) {
            rc = lu_cli_error("export-grid", &err);
        } else {
            const lu_affine *w = &m->index_to_world;
            lu_vec3 h =
                lu_v3(lu_v3_len(lu_affine_vector(w, lu_v3(1, 0, 0))), lu_v3_len(lu_affine_vector(w, lu_v3(0, 1, 0))),
                      lu_v3_len(lu_affine_vector(w, lu_v3(0, 0, 1))));
            printf("wrote %s: %d x %d x %d voxels, voxel %g x %g x %g, values [%g, %g], sigma_s %g %g %g, "
                   "sigma_a %g %g %g, g %g\n",
                   out, g.nx, g.ny, g.nz, h.x, h.y, h.z, g.min_value, g.max_value, m->sigma_s.x, m->sigma_s.y,
                   m->sigma_s.z, m->sigma_a.x, m->sigma_a.y, m->sigma_a.z, m->phase_g);
        }
    }
    lu_scene_destroy(&scene);
    return rc;
}
