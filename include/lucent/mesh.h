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

/* By extension: .obj, .ply, .ply.gz (or any .gz holding a PLY; .obj.gz is
 * read as OBJ). A file without triangles is an error (LU_ERR_FORMAT).
 * OBJ: vn lines are per-corner and ignored; normals are recomputed.
 * PLY: vertex nx,ny,nz are used (normalised) when all three exist.
 * Codes: LU_ERR_IO missing/unreadable file, LU_ERR_FORMAT malformed or
 * truncated data, LU_ERR_RANGE bad vertex index (OBJ index 0 included),
 * LU_ERR_NONFINITE NaN/inf coordinates, LU_ERR_LIMIT counts over LU_MAX_*. */
lu_result lu_mesh_load(const char *path, lu_mesh *mesh, lu_error *err);
lu_result lu_mesh_load_obj(const char *path, lu_mesh *mesh, lu_error *err);
lu_result lu_mesh_load_ply(const char *path, lu_mesh *mesh, lu_error *err);
/* Writes binary little-endian PLY (positions, normals, faces), atomically. */
lu_result lu_mesh_save_ply(const lu_mesh *mesh, const char *path, lu_error *err);

/* Procedural shapes, centred at the origin unless a parameter says otherwise:
 *   "sphere"  radius=1 subdivisions=4          (icosphere, 20*4^s triangles, s in 0..8)
 *   "box"     size=[2,2,2]                     (12 triangles, outward normals, flat)
 *   "torus"   major_radius=0.6 minor_radius=0.2 segments=64 sides=32 (axis +Y)
 *   "plane"   size=[10,10]                     (in XZ, normal +Y)
 *   "room"    size=[6,3,6] window=[x0,y0,x1,y1] (inward-facing box, a hole in the +X wall)
 * The window's x runs along Z and its y along Y, in room coordinates (origin
 * at the room centre); default [-size_z/6, -size_y/4, size_z/6, size_y/4].
 * A window of zero width or height means no hole.
 * Unknown names or parameters are errors naming `where` (LU_ERR_SCENE). */
lu_result lu_mesh_procedural(const char *name, const lu_kvlist *params, lu_mesh *mesh, const char *where,
                             lu_error *err);

/* Positions and normals; a mirroring map (negative determinant) also swaps
 * two corners of every triangle so counter-clockwise stays outward. */
void lu_mesh_transform(lu_mesh *mesh, const lu_affine *xf);
/* Area-weighted smooth normals; a vertex no triangle uses gets +Y. */
void lu_mesh_compute_normals(lu_mesh *mesh);
lu_aabb lu_mesh_bounds(const lu_mesh *mesh);
double lu_mesh_area(const lu_mesh *mesh);
/* Signed volume about the origin (positive for a closed, outward-oriented mesh). */
double lu_mesh_volume(const lu_mesh *mesh);
/* Appends src into dst (indices offset). */
lu_result lu_mesh_append(lu_mesh *dst, const lu_mesh *src, lu_error *err);

#ifdef __cplusplus
}
#endif
#endif
