/* The scene builder: the one place a scene is assembled and checked, for the
 * JSON loader (scene_json.c) and for programs that build scenes in code. */
#include <lucent/lucent.h>

#include <stdlib.h>
#include <string.h>

#include "volume/grid_internal.h"

struct lu_scene_builder {
    lu_scene s;
    int light_cap, medium_cap, object_cap;
    bool has_camera;
};

void lu_material_defaults(lu_material *out) {
    memset(out, 0, sizeof *out);
    out->type = LU_MATERIAL_DIFFUSE;
    out->albedo = lu_v3s(0.8f);
    out->specular = lu_v3s(0.0f);
    out->shininess = 32.0f;
    out->eta = 1.3f;
    out->mm_per_unit = 1.0f;
}

lu_result lu_scene_builder_create(lu_scene_builder **out, lu_error *err) {
    *out = lu_calloc(1, sizeof **out);
    if (!*out) return lu_fail(err, LU_ERR_NOMEM, "scene builder: out of memory");
    return LU_OK;
}

void lu_scene_builder_destroy(lu_scene_builder *b) {
    if (!b) return;
    lu_scene_destroy(&b->s);
    lu_free(b);
}

/* Room for one more element of a growing array. */
static bool grow(void **items, int count, int *cap, size_t size) {
    if (count < *cap) return true;
    int n = *cap ? 2 * *cap : 4;
    void *p = lu_realloc(*items, (size_t)n * size);
    if (!p) return false;
    *items = p;
    *cap = n;
    return true;
}

lu_result lu_scene_builder_set_camera(lu_scene_builder *b, const lu_camera *camera, lu_error *err) {
    lu_camera cam = *camera;
    if (cam.width == 0) cam.width = 512;
    if (cam.height == 0) cam.height = 512;
    if (cam.fov_y_deg == 0.0f) cam.fov_y_deg = 45.0f;
    if (lu_v3_len(cam.up) == 0.0f) cam.up = lu_v3(0, 1, 0);
    if (cam.width < 1 || cam.width > LU_MAX_IMAGE_DIM || cam.height < 1 || cam.height > LU_MAX_IMAGE_DIM)
        return lu_fail(err, LU_ERR_RANGE, "camera size %dx%d outside [1, %d]", cam.width, cam.height, LU_MAX_IMAGE_DIM);
    if (!(cam.fov_y_deg >= 0.01f && cam.fov_y_deg <= 179.0f))
        return lu_fail(err, LU_ERR_RANGE, "fov_y_deg %g outside [0.01, 179]", cam.fov_y_deg);
    lu_vec3 fwd = lu_v3_sub(cam.look_at, cam.position);
    if (lu_v3_len(fwd) <= 0.0f) return lu_fail(err, LU_ERR_SCENE, "position and look_at coincide");
    if (lu_v3_len(lu_v3_cross(lu_v3_norm(fwd), lu_v3_norm(cam.up))) < 1e-6f)
        return lu_fail(err, LU_ERR_SCENE, "up is parallel to the view direction");
    b->s.camera = cam;
    b->has_camera = true;
    return LU_OK;
}

void lu_scene_builder_set_background(lu_scene_builder *b, lu_vec3 radiance) { b->s.background = radiance; }

lu_result lu_scene_builder_add_light(lu_scene_builder *b, lu_light *light, lu_error *err) {
    lu_light l = *light;
    memset(&light->env, 0, sizeof light->env);   /* moved in */
    lu_result r = LU_OK;
    if (l.type != LU_LIGHT_POINT && l.type != LU_LIGHT_SPOT && l.type != LU_LIGHT_DIRECTIONAL &&
        l.type != LU_LIGHT_ENVIRONMENT)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "light type %d is not an lu_light_type", (int)l.type);
    else if (l.type == LU_LIGHT_ENVIRONMENT && !l.env.rgb)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "an environment light needs a map (env)");
    else if (l.type == LU_LIGHT_SPOT && l.inner_deg > l.outer_deg)
        r = lu_fail(err, LU_ERR_RANGE, "inner_deg %g exceeds outer_deg %g", l.inner_deg, l.outer_deg);
    else if ((l.type == LU_LIGHT_SPOT || l.type == LU_LIGHT_DIRECTIONAL) && lu_v3_len(l.direction) <= 0.0f)
        r = lu_fail(err, LU_ERR_SCENE, "direction must be non-zero");
    else if (!grow((void **)&b->s.lights, b->s.light_count, &b->light_cap, sizeof l))
        r = lu_fail(err, LU_ERR_NOMEM, "scene builder: out of memory");
    if (r != LU_OK) {
        lu_image_destroy(&l.env);
        return r;
    }
    if (l.type == LU_LIGHT_SPOT || l.type == LU_LIGHT_DIRECTIONAL) l.direction = lu_v3_norm(l.direction);
    b->s.lights[b->s.light_count++] = l;
    return LU_OK;
}

/* The world box holding all of a medium's non-zero density. */
static void medium_bounds(lu_medium *m) {
    lu_aabb box = lu_aabb_empty();
    if (m->kind == LU_DENSITY_GRID) box = lu_aabb_transform(&m->index_to_world, lu_grid_index_support(&m->grid));
    if (m->has_boundary) {
        lu_aabb mb = lu_mesh_bounds(&m->boundary);
        box = m->kind == LU_DENSITY_GRID ? (lu_aabb){lu_v3_max(box.lo, mb.lo), lu_v3_min(box.hi, mb.hi)} : mb;
    }
    m->bounds = box;
}

lu_result lu_scene_builder_add_medium(lu_scene_builder *b, const lu_medium_desc *d, lu_error *err) {
    lu_medium m;
    memset(&m, 0, sizeof m);
    m.kind = d->kind;
    m.from_object = -1;
    m.eta = 1.0f;
    if (d->kind == LU_DENSITY_GRID && d->grid) {
        m.grid = *d->grid;
        memset(d->grid, 0, sizeof *d->grid);
    }
    if (d->boundary) {
        m.boundary = *d->boundary;
        memset(d->boundary, 0, sizeof *d->boundary);
        m.has_boundary = true;
    }
    bool emission_grid = d->emission == LU_EMISSION_GRID || d->emission == LU_EMISSION_BLACKBODY;
    if (emission_grid && d->emission_grid) {
        m.emission_grid = *d->emission_grid;
        memset(d->emission_grid, 0, sizeof *d->emission_grid);
    }
    lu_affine xf = d->transform ? *d->transform : lu_affine_identity();
    lu_result r = LU_OK;
    if (d->kind != LU_DENSITY_GRID && d->kind != LU_DENSITY_CONSTANT)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "density kind %d is not an lu_density_kind", (int)d->kind);
    else if (d->kind == LU_DENSITY_GRID && !lu_grid_has_values(&m.grid))
        r = lu_fail(err, LU_ERR_INVALID_ARG, "a grid medium needs a grid");
    else if (d->kind == LU_DENSITY_CONSTANT && !m.has_boundary)
        r = lu_fail(err, LU_ERR_SCENE, "a constant density needs a \"boundary\" mesh to bound it");
    else if (!(d->phase_g > -1.0f && d->phase_g < 1.0f))
        r = lu_fail(err, LU_ERR_RANGE, "phase_g %g outside (-1, 1)", d->phase_g);
    else if (m.has_boundary && d->eta != 0.0f && !(d->eta >= 1.0f && d->eta <= 4.0f))
        r = lu_fail(err, LU_ERR_RANGE, "boundary eta %g outside [1, 4]", d->eta);
    else if (m.has_boundary && d->surface && d->surface->type != LU_MATERIAL_DIFFUSE)
        r = lu_fail(err, LU_ERR_SCENE, "a boundary surface must be of type \"diffuse\"");
    else if (d->emission != LU_EMISSION_NONE && d->emission != LU_EMISSION_CONSTANT && !emission_grid)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "emission kind %d is not an lu_emission_kind", (int)d->emission);
    else if (emission_grid && (d->kind != LU_DENSITY_GRID || !m.emission_grid.data))
        r = lu_fail(err, LU_ERR_SCENE, "an emission or temperature grid needs a grid density and a grid of its own");
    else if (emission_grid && (m.emission_grid.nx != m.grid.nx || m.emission_grid.ny != m.grid.ny ||
                               m.emission_grid.nz != m.grid.nz))
        r = lu_fail(err, LU_ERR_SCENE, "the emission grid is %dx%dx%d, the density grid %dx%dx%d: they must share one index space",
                    m.emission_grid.nx, m.emission_grid.ny, m.emission_grid.nz, m.grid.nx, m.grid.ny, m.grid.nz);
    else if (d->le_scale < 0.0f || d->le_color.x < 0.0f || d->le_color.y < 0.0f || d->le_color.z < 0.0f)
        r = lu_fail(err, LU_ERR_RANGE, "emission color and scale must be >= 0");
    if (r == LU_OK) {
        m.constant = d->constant;
        m.sigma_s = d->sigma_s;
        m.sigma_a = d->sigma_a;
        m.phase_g = d->phase_g;
        m.emission = d->emission;
        bool no_color = d->le_color.x == 0.0f && d->le_color.y == 0.0f && d->le_color.z == 0.0f;
        m.le_color = no_color ? lu_v3s(1.0f) : d->le_color;
        m.le_scale = d->le_scale != 0.0f ? d->le_scale : 1.0f;
        m.temp_scale = d->temp_scale != 0.0f ? d->temp_scale : 1.0f;
        m.temp_offset = d->temp_offset;
        if (m.kind == LU_DENSITY_GRID && m.grid.generation == 0) lu_grid_stamp_new(&m.grid);
        m.index_to_world = m.kind == LU_DENSITY_GRID ? lu_affine_mul(&xf, &m.grid.index_to_world) : xf;
        if (!lu_affine_invert(&m.index_to_world, &m.world_to_index))
            r = lu_fail(err, LU_ERR_SCENE, "the grid's index-to-world map is singular");
    }
    if (r == LU_OK && !grow((void **)&b->s.media, b->s.medium_count, &b->medium_cap, sizeof m))
        r = lu_fail(err, LU_ERR_NOMEM, "scene builder: out of memory");
    if (r != LU_OK) {
        lu_grid_destroy(&m.grid);
        lu_grid_destroy(&m.emission_grid);
        lu_mesh_destroy(&m.boundary);
        return r;
    }
    if (m.has_boundary) {
        lu_mesh_transform(&m.boundary, &xf);
        m.eta = d->eta != 0.0f ? d->eta : 1.5f;
        if (d->surface) {
            m.surface = *d->surface;
        } else {
            /* a clear glossy coat, no diffuse layer */
            lu_material_defaults(&m.surface);
            m.surface.albedo = lu_v3s(0.0f);
            m.surface.specular = lu_v3s(1.0f);
            m.surface.shininess = 64.0f;
        }
    }
    medium_bounds(&m);
    b->s.media[b->s.medium_count++] = m;
    return LU_OK;
}

lu_result lu_scene_builder_add_object(lu_scene_builder *b, lu_mesh *mesh, const lu_affine *transform,
                                      const lu_material *material, lu_error *err) {
    lu_object o;
    memset(&o, 0, sizeof o);
    o.mesh = *mesh;
    memset(mesh, 0, sizeof *mesh);
    if (material) o.material = *material;
    else lu_material_defaults(&o.material);
    lu_result r = LU_OK;
    if (o.material.type != LU_MATERIAL_DIFFUSE && o.material.type != LU_MATERIAL_TRANSLUCENT)
        r = lu_fail(err, LU_ERR_INVALID_ARG, "material type %d is not an lu_material_type", (int)o.material.type);
    else if (o.material.coating_count < 0 || o.material.coating_count > LU_MAX_COATINGS)
        r = lu_fail(err, LU_ERR_LIMIT, "%d coatings exceed the limit of %d", o.material.coating_count, LU_MAX_COATINGS);
    else if (!grow((void **)&b->s.objects, b->s.object_count, &b->object_cap, sizeof o))
        r = lu_fail(err, LU_ERR_NOMEM, "scene builder: out of memory");
    if (r != LU_OK) {
        lu_mesh_destroy(&o.mesh);
        return r;
    }
    if (transform) lu_mesh_transform(&o.mesh, transform);
    b->s.objects[b->s.object_count++] = o;
    return LU_OK;
}

/* Each translucent object is also a bounded homogeneous medium (scene.h). */
static lu_result add_object_media(lu_scene *s, lu_error *err) {
    int extra = 0;
    for (int i = 0; i < s->object_count; i++) extra += s->objects[i].material.type == LU_MATERIAL_TRANSLUCENT;
    if (!extra) return LU_OK;
    lu_medium *media = lu_realloc(s->media, (size_t)(s->medium_count + extra) * sizeof *media);
    if (!media) return lu_fail(err, LU_ERR_NOMEM, "scene builder: out of memory");
    s->media = media;
    for (int i = 0; i < s->object_count; i++) {
        const lu_object *obj = &s->objects[i];
        if (obj->material.type != LU_MATERIAL_TRANSLUCENT) continue;
        lu_medium *m = &s->media[s->medium_count];
        memset(m, 0, sizeof *m);
        m->kind = LU_DENSITY_CONSTANT;
        m->constant = 1.0f;
        m->index_to_world = m->world_to_index = lu_affine_identity();
        m->sigma_s = obj->material.sigma_s;
        m->sigma_a = obj->material.sigma_a;
        m->phase_g = obj->material.g;
        m->has_boundary = true;
        m->eta = obj->material.eta;
        m->surface.type = LU_MATERIAL_DIFFUSE;
        m->surface.specular = obj->material.specular;
        m->surface.shininess = obj->material.shininess;
        m->from_object = i;
        s->medium_count++;
        lu_result r = lu_mesh_alloc(&m->boundary, obj->mesh.vertex_count, obj->mesh.triangle_count, err);
        if (r != LU_OK) return r;
        memcpy(m->boundary.positions, obj->mesh.positions, obj->mesh.vertex_count * sizeof(lu_vec3));
        memcpy(m->boundary.normals, obj->mesh.normals, obj->mesh.vertex_count * sizeof(lu_vec3));
        memcpy(m->boundary.indices, obj->mesh.indices, 3u * obj->mesh.triangle_count * sizeof(uint32_t));
        medium_bounds(m);
    }
    return LU_OK;
}

lu_result lu_scene_builder_finish(lu_scene_builder *b, lu_scene *out, lu_error *err) {
    memset(out, 0, sizeof *out);
    lu_result r = b->has_camera ? add_object_media(&b->s, err) : lu_fail(err, LU_ERR_SCENE, "the scene has no camera");
    if (r == LU_OK) {
        *out = b->s;
        memset(&b->s, 0, sizeof b->s);
    }
    lu_scene_builder_destroy(b);
    return r;
}
