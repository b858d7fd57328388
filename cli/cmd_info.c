/* lucent info FILE — a summary of a scene, mesh, grid or image. */
#include <float.h>
#include <stdio.h>
#include <string.h>

#include "backends/gpu.h"
#include "cli.h"

static void usage(void) {
    printf("usage: lucent info FILE\n"
           "       lucent info --gpu [--software|--hardware]\n"
           "\n"
           "FILE is a scene (.json), a mesh (.obj, .ply, .ply.gz), a NanoVDB grid (.nvdb), an\n"
           "OpenVDB grid (.vdb: its first float grid, read by the converter lucent-vdb-convert;\n"
           "LUCENT_VDB_CONVERTER=PATH names another) or an image (.png, .exr, .pfm). Prints\n"
           "counts, bounds, value ranges and voxel sizes.\n"
           "--gpu makes the GPU backend's OpenGL 4.5 context (headless EGL: hardware devices\n"
           "first, then Mesa's software device, then the surfaceless platform; --software or\n"
           "--hardware insists on one kind) and prints vendor, renderer, version, the EGL\n"
           "devices found and the limits methods depend on. Exits 1 when no context can be made.\n"
           "LUCENT_GPU=auto|hardware|software in the environment does what --hardware and\n"
           "--software do, for every GPU context lucent makes; LUCENT_GPU_DEVICE=N tries only\n"
           "EGL device N of the list printed here.\n");
}

static void print_box(const char *indent, lu_aabb b) {
    printf("%sbounds    [%.4g, %.4g, %.4g] .. [%.4g, %.4g, %.4g]\n", indent, b.lo.x, b.lo.y, b.lo.z, b.hi.x, b.hi.y,
           b.hi.z);
}

static void print_mesh(const char *indent, const lu_mesh *m) {
    printf("%svertices  %u\n%striangles %u\n", indent, m->vertex_count, indent, m->triangle_count);
    print_box(indent, lu_mesh_bounds(m));
    printf("%sarea      %.6g\n%svolume    %.6g (signed; positive when closed and outward)\n", indent, lu_mesh_area(m),
           indent, lu_mesh_volume(m));
}

static void print_grid(const char *indent, const lu_grid *g, const lu_affine *index_to_world) {
    lu_vec3 vx = lu_affine_vector(index_to_world, lu_v3(1, 0, 0));
    lu_vec3 vy = lu_affine_vector(index_to_world, lu_v3(0, 1, 0));
    lu_vec3 vz = lu_affine_vector(index_to_world, lu_v3(0, 0, 1));
    printf("%sgrid      \"%s\" %d x %d x %d voxels\n", indent, g->name, g->nx, g->ny, g->nz);
    printf("%svoxel     %.6g x %.6g x %.6g\n", indent, lu_v3_len(vx), lu_v3_len(vy), lu_v3_len(vz));
    printf("%svalues    [%.6g, %.6g]\n", indent, g->min_value, g->max_value);
    uint64_t dense = (uint64_t)g->nx * (uint64_t)g->ny * (uint64_t)g->nz * sizeof(float);
    if (lu_grid_is_sparse(g))
        printf("%sstorage   sparse: %llu-byte NanoVDB tree (the dense box would take %llu bytes)\n", indent,
               (unsigned long long)lu_grid_storage_bytes(g), (unsigned long long)dense);
    else
        printf("%sstorage   dense: %llu bytes\n", indent, (unsigned long long)dense);
    printf("%sactive    %llu voxels\n", indent, (unsigned long long)lu_grid_active_voxels(g));
    print_box(indent, lu_aabb_transform(index_to_world, lu_grid_index_support(g)));
}

static const char *light_name(lu_light_type t) {
    switch (t) {
    case LU_LIGHT_POINT: return "point";
    case LU_LIGHT_SPOT: return "spot";
    case LU_LIGHT_DIRECTIONAL: return "directional";
    default: return "environment";
    }
}

static void print_scene(const lu_scene *s) {
    const lu_camera *c = &s->camera;
    printf("camera    %dx%d, fov_y %.4g deg, at [%.4g, %.4g, %.4g] looking at [%.4g, %.4g, %.4g]\n", c->width,
           c->height, c->fov_y_deg, c->position.x, c->position.y, c->position.z, c->look_at.x, c->look_at.y,
           c->look_at.z);
    printf("lights    %d\n", s->light_count);
    for (int i = 0; i < s->light_count; i++) {
        const lu_light *l = &s->lights[i];
        printf("  [%d] %-11s", i, light_name(l->type));
        if (l->type == LU_LIGHT_ENVIRONMENT)
            printf(" %dx%d map, scale %.4g\n", l->env.width, l->env.height, l->env_scale);
        else
            printf(" %s [%.4g, %.4g, %.4g]\n", l->type == LU_LIGHT_DIRECTIONAL ? "irradiance" : "intensity",
                   l->intensity.x, l->intensity.y, l->intensity.z);
    }
    if (lu_scene_animated(s)) {
        int f0, f1;
        printf("time      %.6g s at %.6g fps (frame %d)", s->time, s->fps > 0 ? s->fps : 24.0, lu_scene_frame_at(s, s->time));
        if (lu_scene_frame_range(s, &f0, &f1)) printf(", sequences over frames %d-%d", f0, f1);
        printf("\n");
    }
    printf("media     %d\n", s->medium_count);
    for (int i = 0; i < s->medium_count; i++) {
        const lu_medium *m = &s->media[i];
        printf("  [%d] sigma_s [%.4g, %.4g, %.4g] sigma_a [%.4g, %.4g, %.4g] g %.3g%s\n", i, m->sigma_s.x, m->sigma_s.y,
               m->sigma_s.z, m->sigma_a.x, m->sigma_a.y, m->sigma_a.z, m->phase_g,
               m->from_object >= 0 ? " (translucent object)" : "");
        if (m->kind == LU_DENSITY_GRID) print_grid("      ", &m->grid, &m->index_to_world);
        else printf("      density   constant %.4g\n", m->constant);
        if (m->density_anim || m->emission_anim)
            printf("      follows   the time (%s%s%s)\n", m->density_anim ? "density" : "",
                   m->density_anim && m->emission_anim ? ", " : "", m->emission_anim ? "emission" : "");
        if (m->has_boundary) {
            printf("      boundary  eta %.3g, %u triangles\n", m->eta, m->boundary.triangle_count);
        }
        if (m->emission != LU_EMISSION_NONE) {
            lu_vec3 le = lu_medium_emission_max(m);
            static const char *const kinds[] = {"none", "constant", "grid", "temperature"};
            printf("      emission  %s, Le up to [%.4g, %.4g, %.4g]", kinds[m->emission], le.x, le.y, le.z);
            if (m->emission == LU_EMISSION_BLACKBODY)
                printf(", T' = (T - %g) * %g in [%.4g, %.4g] K", m->temp_offset, m->temp_scale,
                       (m->emission_grid.min_value - m->temp_offset) * m->temp_scale,
                       (m->emission_grid.max_value - m->temp_offset) * m->temp_scale);
            printf("\n");
        }
        print_box("      ", m->bounds);
    }
    printf("objects   %d\n", s->object_count);
    for (int i = 0; i < s->object_count; i++) {
        const lu_object *o = &s->objects[i];
        printf("  [%d] %s%s%s, %u triangles\n", i, o->material.type == LU_MATERIAL_DIFFUSE ? "diffuse" : "translucent",
               o->material.preset[0] ? " " : "", o->material.preset, o->mesh.triangle_count);
    }
}

static void print_image(const lu_image *im) {
    double lo = DBL_MAX, hi = -DBL_MAX, sum = 0;
    size_t n = (size_t)im->width * im->height * 3;
    for (size_t i = 0; i < n; i++) {
        lo = im->rgb[i] < lo ? im->rgb[i] : lo;
        hi = im->rgb[i] > hi ? im->rgb[i] : hi;
        sum += im->rgb[i];
    }
    printf("image     %d x %d, RGB\nvalues    [%.6g, %.6g], mean %.6g\n", im->width, im->height, lo, hi, sum / (double)n);
}

static int print_gpu(lu_gpu_device_pref pref) {
    lu_error err = {0};
    lu_gpu_context *ctx = NULL;
    if (lu_gpu_context_create(&ctx, pref, &err) != LU_OK) return lu_cli_error("info", &err);
    lu_gpu_info in;
    lu_gpu_info_get(ctx, &in);
    printf("vendor        %s\nrenderer      %s%s\nversion       %s\nGLSL          %s\n", in.vendor, in.renderer,
           in.is_software ? " (software)" : "", in.version, in.glsl_version);
    printf("EGL path      %s\ndevice        %s\nEGL devices   %s\n", in.egl_path, in.device,
           in.device_list[0] ? in.device_list : "(none enumerated)");
    printf("max 3D texture        %d\n", in.max_3d_texture_size);
    printf("max SSBO size         %lld bytes\n", (long long)in.max_ssbo_size);
    printf("max SSBO bindings     %d\n", in.max_ssbo_bindings);
    printf("max texture units     %d\n", in.max_texture_units);
    printf("max image units       %d\n", in.max_image_units);
    printf("max work groups       %d x %d x %d\n", in.max_work_group_count[0], in.max_work_group_count[1],
           in.max_work_group_count[2]);
    printf("max work group size   %d x %d x %d (%d invocations)\n", in.max_work_group_size[0],
           in.max_work_group_size[1], in.max_work_group_size[2], in.max_work_group_invocations);
    printf("max shared memory     %d bytes\n", in.max_shared_memory);
    printf("context creation      %.3f s\n", in.create_seconds);
    const char *why;
    lu_backend b = lu_backend_auto(&why);
    printf("backend auto          %s (%s)\n", lu_backend_name(b), b == LU_BACKEND_GPU ? why : "no hardware GPU");
    if (b != LU_BACKEND_GPU) printf("                      %s\n", why);
    lu_gpu_context_destroy(ctx);
    return LU_EXIT_OK;
}

int lu_cmd_info(int argc, char **argv) {
    const char *path = NULL;
    bool gpu = false;
    lu_gpu_device_pref pref = LU_GPU_AUTO;
    for (int i = 1; i < argc; i++) {
        if (lu_cli_is_help(argv[i])) {
            usage();
            return LU_EXIT_OK;
        } else if (strcmp(argv[i], "--gpu") == 0) {
            gpu = true;
        } else if (strcmp(argv[i], "--software") == 0) {
            pref = LU_GPU_SOFTWARE;
        } else if (strcmp(argv[i], "--hardware") == 0) {
            pref = LU_GPU_HARDWARE;
        } else if (argv[i][0] == '-') {
            return lu_cli_usage("info", "unknown option \"%s\"", argv[i]);
        } else if (!path) {
            path = argv[i];
        } else {
            return lu_cli_usage("info", "unexpected argument \"%s\"", argv[i]);
        }
    }
    if (gpu && path) return lu_cli_usage("info", "--gpu takes no FILE");
    if (gpu) return print_gpu(pref);
    if (pref != LU_GPU_AUTO) return lu_cli_usage("info", "--software and --hardware go with --gpu");
    if (!path) return lu_cli_usage("info", "missing FILE");
    lu_error err = {0};
    const char *ext = lu_path_ext(path);
    if (strcmp(ext, "json") == 0) {
        lu_scene s;
        if (lu_scene_load(path, &s, &err) != LU_OK) return lu_cli_error("info", &err);
        print_scene(&s);
        lu_scene_destroy(&s);
    } else if (strcmp(ext, "obj") == 0 || strcmp(ext, "ply") == 0 || strcmp(ext, "gz") == 0) {
        lu_mesh m = {0};
        if (lu_mesh_load(path, &m, &err) != LU_OK) return lu_cli_error("info", &err);
        print_mesh("", &m);
        lu_mesh_destroy(&m);
    } else if (strcmp(ext, "nvdb") == 0 || strcmp(ext, "vdb") == 0) {
        lu_grid g = {0};
        lu_result r = ext[0] == 'v' ? lu_grid_load_vdb(path, NULL, &g, &err) : lu_grid_load_nvdb(path, NULL, &g, &err);
        if (r != LU_OK) return lu_cli_error("info", &err);
        print_grid("", &g, &g.index_to_world);
        lu_grid_destroy(&g);
    } else if (lu_image_format_from_path(path) != LU_IMAGE_AUTO) {
        lu_image im = {0};
        if (lu_image_load(path, &im, &err) != LU_OK) return lu_cli_error("info", &err);
        print_image(&im);
        lu_image_destroy(&im);
    } else {
        return lu_cli_usage("info", "cannot tell what kind of file \"%s\" is from its extension", path);
    }
    return LU_EXIT_OK;
}
