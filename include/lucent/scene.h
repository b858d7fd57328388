/* lucent/scene.h — the scene every method renders (docs/architecture.md §1, §7).
 *
 * A scene is loaded from the JSON contract (docs/scene-format.md) and resolved into
 * world space: meshes are transformed, grids keep their index space plus a
 * composed index->world map, lights carry unit directions.
 *
 * Translucent objects (material "translucent") are not opaque surfaces. The
 * loader also lists each as a bounded homogeneous medium (density 1, the
 * material's coefficients in scene units, its mesh as the boundary) with
 * `from_object` set, so single-scattering methods see it as a medium, while
 * `bssrdf` renders the object itself and skips media with from_object >= 0. */
#ifndef LUCENT_SCENE_H
#define LUCENT_SCENE_H

#include "core.h"
#include "grid.h"
#include "image.h"
#include "math.h"
#include "mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct lu_camera {
    lu_vec3 position, look_at, up;
    float fov_y_deg;
    int width, height;
} lu_camera;

typedef enum lu_light_type {
    LU_LIGHT_POINT = 0,
    LU_LIGHT_SPOT,
    LU_LIGHT_DIRECTIONAL,
    LU_LIGHT_ENVIRONMENT
} lu_light_type;

typedef struct lu_light {
    lu_light_type type;
    lu_vec3 position;       /* point, spot */
    lu_vec3 direction;      /* unit. directional: towards the light; spot: where it shines */
    lu_vec3 intensity;      /* point/spot: W/sr; directional: irradiance W/m^2 */
    float inner_deg, outer_deg;   /* spot cone half-angles; smoothstep falloff between */
    /* environment: equirectangular radiance map times scale. Direction d maps
     * to u = 0.5 + atan2(d.x, -d.z) / (2 pi), v = acos(d.y) / pi (v = 0 top). */
    lu_image env;
    float env_scale;
} lu_light;

typedef enum lu_material_type { LU_MATERIAL_DIFFUSE = 0, LU_MATERIAL_TRANSLUCENT } lu_material_type;

/* A translucent coating over a translucent material (multi-layer profiles,
 * "coatings": [{"preset": "cream", "thickness_mm": 1.5}, ...], top first). */
#define LU_MAX_COATINGS 4
typedef struct lu_coating {
    lu_vec3 sigma_s, sigma_a;   /* scene units, like the material's */
    float eta, g;
    float thickness;            /* scene units */
} lu_coating;

typedef struct lu_material {
    lu_material_type type;
    /* diffuse: Lambert + normalised Blinn-Phong */
    lu_vec3 albedo;         /* default 0.8 */
    lu_vec3 specular;       /* default 0 */
    float shininess;        /* default 32 */
    /* translucent: coefficients in scene units (mm values / mm_per_unit^-1) */
    char preset[32];
    lu_vec3 sigma_s;        /* scattering (reduced, as measured, with g = 0) */
    lu_vec3 sigma_a;
    float eta, g;
    float mm_per_unit;      /* how many millimetres one scene unit is */
    int coating_count;
    lu_coating coatings[LU_MAX_COATINGS];
} lu_material;

/* Measured coefficients of Jensen et al. 2001 (Table 1), per millimetre, and
 * presets authored as surface albedo plus mean free path (albedo[0] > 0),
 * whose coefficients are inverted from those (see "subsurface_albedo"). */
typedef struct lu_material_preset {
    const char *name;
    float sigma_s_prime[3];
    float sigma_a[3];
    float eta;
    float albedo[3];        /* authored presets: total diffuse reflectance of the half-space */
    float mfp_mm[3];        /* and the reduced mean free path 1 / sigma_t' */
} lu_material_preset;
/* sigma_s' and sigma_a per mm of a half-space whose total diffuse
 * reflectance behind relative index eta is albedo (each in (0, 1]) and whose
 * reduced mean free path 1 / sigma_t' is mfp_mm (each > 0). */
void lu_material_from_albedo(const float albedo[3], const float mfp_mm[3], float eta, lu_vec3 *sigma_s_prime,
                             lu_vec3 *sigma_a);
const lu_material_preset *lu_material_presets(int *count);
const lu_material_preset *lu_material_preset_find(const char *name);
/* Absorption from the imaginary part k of a complex index of refraction at
 * wavelength lambda_nm: sigma_a = 4 pi k / lambda, returned per millimetre
 * (Rohat 2011, Table 4.3: marble's k = 1.16979e-7 at 700 nm gives 0.0021). */
float lu_sigma_a_from_ior_imag(float k, float lambda_nm);

typedef enum lu_density_kind { LU_DENSITY_GRID = 0, LU_DENSITY_CONSTANT } lu_density_kind;

/* Emission (docs/volumes.md "Emission"): the medium's source term is
 * sigma_a * density * Le(x) (pbrt-v4's convention: emission enters the
 * radiative transfer equation as absorbed-and-re-emitted radiance), with
 *   CONSTANT   Le = le_scale * le_color
 *   GRID       Le = le_scale * le_color * e(x)       e: a grid in the density's index space
 *   BLACKBODY  Le = le_scale * le_color * B(T')      T' = (T(x) - temp_offset) * temp_scale Kelvin,
 *              T a grid in the density's index space, B lu_blackbody_rgb (0 for T' <= 100 K). */
typedef enum lu_emission_kind {
    LU_EMISSION_NONE = 0,
    LU_EMISSION_CONSTANT,
    LU_EMISSION_GRID,
    LU_EMISSION_BLACKBODY
} lu_emission_kind;

/* A medium's density or emission over time: a numbered sequence of grid
 * files or an animated procedural (see "time" below). Opaque; owned by the scene. */
typedef struct lu_grid_anim lu_grid_anim;

typedef struct lu_medium {
    lu_density_kind kind;
    float constant;             /* LU_DENSITY_CONSTANT: density everywhere inside the boundary */
    lu_grid grid;               /* LU_DENSITY_GRID: data in index space */
    lu_affine index_to_world;   /* scene transform after the grid file's own map */
    lu_affine world_to_index;
    lu_vec3 sigma_a, sigma_s;   /* per scene unit at density 1 */
    float phase_g;              /* Henyey-Greenstein g, 0 = isotropic */
    bool has_boundary;          /* medium exists only inside this closed mesh */
    lu_mesh boundary;           /* world space */
    float eta;                  /* boundary index of refraction */
    lu_material surface;        /* boundary reflection, weighted by (1 - F_t) */
    lu_aabb bounds;             /* world box containing all non-zero density */
    int from_object;            /* index of the translucent object it stands for, or -1 */
    lu_emission_kind emission;  /* LU_EMISSION_NONE: not emissive */
    lu_vec3 le_color;           /* default [1, 1, 1] */
    float le_scale;             /* default 1 */
    float temp_scale, temp_offset; /* BLACKBODY; defaults 1, 0 */
    lu_grid emission_grid;      /* GRID: e(x); BLACKBODY: T(x) in Kelvin before the mapping */
    /* Set when grid / emission_grid follow the scene's time (a sequence or an
     * animated procedural, loaded from JSON); NULL: still. */
    lu_grid_anim *density_anim, *emission_anim;
} lu_medium;

/* Linear sRGB (D65) of the blackbody spectrum at T Kelvin, normalised to
 * 1 at its peak wavelength as pbrt-v4's BlackbodySpectrum is: Planck's law
 * integrated against the CIE 1931 2-degree colour matching functions
 * (Wyman, Sloan and Shirley 2013's multi-lobe fit) over 360-830 nm, divided
 * by the integral of y-bar (a flat spectrum of 1 has Y = 1), then XYZ ->
 * linear sRGB. Tabulated once over log T in [100, 100000] K and interpolated;
 * 0 at or below 100 K, clamped at 100000 K. Channels can be slightly
 * negative (the locus leaves the sRGB gamut below ~1700 K); they are
 * clamped at 0. */
lu_vec3 lu_blackbody_rgb(float kelvin);
/* The same without the table: direct quadrature (slow; tests and the table). */
lu_vec3 lu_blackbody_rgb_exact(double kelvin);
/* Le of medium m at index-space point p (before sigma_a and density):
 * 0 for a non-emissive medium. */
lu_vec3 lu_medium_emission(const lu_medium *m, lu_vec3 p_index);
/* Largest Le anywhere in the medium (an upper bound: grids by their max value). */
lu_vec3 lu_medium_emission_max(const lu_medium *m);

typedef struct lu_object {
    lu_mesh mesh;               /* world space */
    lu_material material;
} lu_object;

typedef struct lu_scene {
    char path[1024];            /* the file it came from ("" for strings) */
    lu_camera camera;
    lu_vec3 background;         /* radiance of rays that hit nothing */
    lu_light *lights;
    int light_count;
    lu_medium *media;
    int medium_count;
    lu_object *objects;
    int object_count;
    double time;                /* seconds (lu_scene_set_time changes it) */
    double fps;                 /* frames per second of sequences; 0: 24 */
} lu_scene;

lu_result lu_scene_load(const char *path, lu_scene *scene, lu_error *err);
/* base_path: file name used in messages and for resolving relative paths. */
lu_result lu_scene_load_string(const char *json, const char *base_path, lu_scene *scene, lu_error *err);
void lu_scene_destroy(lu_scene *scene);

/* The density grid of medium `medium`, for editing (lu_grid_set_values,
 * lu_grid_apply in grid.h). Medium bounds and transforms never change with an
 * edit: the grid's support is the same box. Refuses an index out of range
 * (LU_ERR_INVALID_ARG) and a constant-density medium, translucent objects'
 * media included (LU_ERR_UNSUPPORTED: there is no grid to edit). */
lu_result lu_scene_medium_grid(lu_scene *scene, int medium, lu_grid **grid, lu_error *err);

/* ---- time -----------------------------------------------------------------
 * A scene has one clock: `time` in seconds (scene key "time", default 0) and
 * `fps` (key "fps", default 24). Frame number F starts at time F / fps. A
 * sequence medium ("file": "smoke_####.nvdb", "frames": [A, B]) shows the
 * file numbered lu_scene_frame_at(time) = floor(time * fps + 1e-6) (the
 * 1e-6 keeps time F / fps on frame F despite rounding), holding frame A
 * before the range and B after it ("extend": "loop" wraps instead); an
 * animated procedural is evaluated at the time itself. Still media ignore
 * the time. docs/volumes.md "Time and sequences". */

/* Whether any medium follows the time. */
bool lu_scene_animated(const lu_scene *scene);
/* Puts every animated medium at `time` (finite): a sequence loads the file of
 * its frame (nothing when the frame is the one shown), a procedural is
 * evaluated again; the values go in through lu_grid_set_values, so
 * renderers see a density change (a new grid generation) and nothing else.
 * All or nothing: on failure (a file that fails to load, its message naming
 * it) the scene and its time are as they were. */
lu_result lu_scene_set_time(lu_scene *scene, double time, lu_error *err);
int lu_scene_frame_at(const lu_scene *scene, double time);
double lu_scene_frame_time(const lu_scene *scene, int frame);   /* frame / fps */
/* The smallest range holding every sequence's "frames"; false without sequences. */
bool lu_scene_frame_range(const lu_scene *scene, int *first, int *last);

/* ---- building a scene in code ---------------------------------------------
 * The JSON loader is one user of the builder: every scene, loaded or built,
 * is assembled and checked by the same calls. A builder owns what is added
 * (meshes, grids and environment maps are moved in: the caller's struct is
 * left empty), and lu_scene_builder_finish hands it all to the scene.
 *
 *   lu_scene_builder *b;
 *   lu_scene_builder_create(&b, &err);
 *   lu_scene_builder_set_camera(b, &(lu_camera){.position = {0, 1, 5}, .look_at = {0, 1, 0}}, &err);
 *   lu_scene_builder_add_light(b, &(lu_light){.type = LU_LIGHT_POINT, .position = {0, 4, 0},
 *                                             .intensity = {50, 50, 50}}, &err);
 *   lu_scene_builder_add_medium(b, &(lu_medium_desc){.grid = &grid, .sigma_s = {4, 4, 4}}, &err);
 *   lu_scene_builder_finish(b, &scene, &err);
 *
 * Errors name what is wrong ("position and look_at coincide"); a failed call
 * adds nothing (and frees what it was to take). */
typedef struct lu_scene_builder lu_scene_builder;

/* A medium to add. Zero is the default of every field. */
typedef struct lu_medium_desc {
    lu_density_kind kind;          /* LU_DENSITY_GRID (0): *grid; LU_DENSITY_CONSTANT: constant inside boundary */
    lu_grid *grid;                 /* GRID: moved into the scene */
    float constant;                /* CONSTANT: the density */
    lu_vec3 sigma_s, sigma_a;      /* per scene unit at density 1 */
    float phase_g;                 /* Henyey-Greenstein g in (-1, 1); 0: isotropic */
    const lu_affine *transform;    /* NULL: identity; after the grid's own map, and for the boundary */
    lu_mesh *boundary;             /* NULL: none (grids only); else moved in, transformed by transform */
    float eta;                     /* boundary index of refraction in [1, 4]; 0: 1.5 */
    const lu_material *surface;    /* boundary reflection (diffuse type); NULL: a clear glossy coat */
    lu_emission_kind emission;     /* LU_EMISSION_NONE (0): not emissive; see lu_emission_kind */
    lu_grid *emission_grid;        /* GRID, BLACKBODY: moved in; the density grid's size and index space */
    lu_vec3 le_color;              /* zero: [1, 1, 1] */
    float le_scale;                /* zero: 1 */
    float temp_scale, temp_offset; /* BLACKBODY: temp_scale zero: 1 */
} lu_medium_desc;

/* The default material: diffuse, albedo 0.8, no specular, shininess 32. */
void lu_material_defaults(lu_material *out);

lu_result lu_scene_builder_create(lu_scene_builder **out, lu_error *err);
/* Frees the builder and everything added to it (a builder not finished). */
void lu_scene_builder_destroy(lu_scene_builder *b);
/* Camera: position and look_at distinct, up not along the view, size in
 * [1, LU_MAX_IMAGE_DIM] (0: 512), fov_y_deg in [0.01, 179] (0: 45); up zero: +y. */
lu_result lu_scene_builder_set_camera(lu_scene_builder *b, const lu_camera *camera, lu_error *err);
void lu_scene_builder_set_background(lu_scene_builder *b, lu_vec3 radiance);
/* Spot and directional directions are normalised (zero is an error); a
 * spot needs inner_deg <= outer_deg; an environment light's map is moved in. */
lu_result lu_scene_builder_add_light(lu_scene_builder *b, lu_light *light, lu_error *err);
lu_result lu_scene_builder_add_medium(lu_scene_builder *b, const lu_medium_desc *desc, lu_error *err);
/* mesh is moved in and transformed to world space (transform NULL:
 * identity); material NULL: lu_material_defaults. A translucent object is
 * also listed as a medium at finish (see the top of this file). */
lu_result lu_scene_builder_add_object(lu_scene_builder *b, lu_mesh *mesh, const lu_affine *transform,
                                      const lu_material *material, lu_error *err);
/* Hands everything to *out and frees the builder, whether or not it
 * succeeds (a camera is required). */
lu_result lu_scene_builder_finish(lu_scene_builder *b, lu_scene *out, lu_error *err);

/* World box around all media (empty box if none). */
lu_aabb lu_scene_media_bounds(const lu_scene *scene);
/* World box around everything with geometry: media and objects. */
lu_aabb lu_scene_bounds(const lu_scene *scene);
/* Camera ray through image position (px, py), pixel centres at +0.5. d is unit. */
void lu_camera_ray(const lu_camera *cam, float px, float py, lu_vec3 *o, lu_vec3 *d);

#ifdef __cplusplus
}
#endif
#endif
