/* lucent/mesh.h — indexed triangle meshes: OBJ, PLY (ascii / binary LE / BE,
 * optionally .gz), procedural shapes.
 *
 * Loaders triangulate polygons as fans, drop degenerate-index faces, and
 * compute smooth per-vertex normals (area-weighted) when the file has none.
 * Errors name the file and the line (ascii) or byte offset (binary). */
#ifndef LUCENT_MESH_H
#define LUCENT_MESH_H

#include "core.h"
#include "math.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct lu_mesh {
    uint32_t vertex_count;
    uint32_t triangle_count;
    lu_vec3 *positions;     /* vertex_count */
    lu_vec3 *normals;       /* vertex_count, unit length */
    uint32_t *indices;      /* 3 * triangle_count, counter-clockwise = outward */
} lu_mesh;

void lu_mesh_destroy(lu_mesh *mesh);
/* Allocates zeroed arrays for the given counts (checks LU_MAX_*). */
lu_result lu_mesh_alloc(lu_mesh *mesh, uint32_t vertex_count, uint32_t triangle_count, lu_error *err);

/* By extension: .obj, .ply, .ply.gz (or any .gz holding a PLY). */
lu_result lu_mesh_load(const char *path, lu_mesh *mesh, lu_error *err);
lu_result lu_mesh_load_obj(const char *path, lu_mesh *mesh, lu_error *err);
lu_result lu_mesh_load_ply(const char *path, lu_mesh *mesh, lu_error *err);
/* Writes binary little-endian PLY (positions, normals, faces), atomically. */
lu_result lu_mesh_save_ply(const lu_mesh *mesh, const char *path, lu_error *err);

/* Procedural shapes, centred at the origin unless a parameter says otherwise:
 *   "sphere"  radius=1 subdivisions=4          (icosphere)
 *   "box"     size=[2,2,2]                     (12 triangles, outward normals, flat)
 *   "torus"   major_radius=0.6 minor_radius=0.2 segments=64 sides=32 (axis +Y)
 *   "plane"   size=[10,10]                     (in XZ, normal +Y)
 *   "room"    size=[6,3,6] window=[x0,y0,x1,y1] (inward-facing box, a hole in the +X wall)
 * Unknown names or parameters are errors naming `where`. */
lu_result lu_mesh_procedural(const char *name, const lu_kvlist *params, lu_mesh *mesh, const char *where,
                             lu_error *err);

void lu_mesh_transform(lu_mesh *mesh, const lu_affine *xf);   /* positions and normals */
void lu_mesh_compute_normals(lu_mesh *mesh);                  /* area-weighted smooth normals */
lu_aabb lu_mesh_bounds(const lu_mesh *mesh);
double lu_mesh_area(const lu_mesh *mesh);
/* Signed volume (positive for a closed, outward-oriented mesh). */
double lu_mesh_volume(const lu_mesh *mesh);
/* Appends src into dst (indices offset). */
lu_result lu_mesh_append(lu_mesh *dst, const lu_mesh *src, lu_error *err);

#ifdef __cplusplus
}
#endif
#endif
