/* lucent/geometry.h — ray queries against triangle meshes (Embree), inside
 * tests, and voxelisation of closed meshes.
 *
 * An lu_accel holds one or more meshes (each gets an id in insertion order).
 * Queries are thread-safe after lu_accel_commit. Rays are o + t d with d of
 * any length; t is in units of d. */
#ifndef LUCENT_GEOMETRY_H
#define LUCENT_GEOMETRY_H

#include "core.h"
#include "grid.h"
#include "math.h"
#include "mesh.h"

#ifdef __cplusplus
extern "C" {
#endif

typedef struct lu_accel lu_accel;

typedef struct lu_hit {
    float t;
    uint32_t mesh_id;      /* order of lu_accel_add_mesh */
    uint32_t prim_id;      /* triangle index within that mesh */
    float u, v;            /* barycentrics of vertices 1 and 2 */
    lu_vec3 ng;            /* unit geometric normal, outward for CCW triangles */
} lu_hit;

lu_result lu_accel_create(lu_accel **out, lu_error *err);
/* The accel keeps a pointer to the mesh: it must outlive the accel. */
lu_result lu_accel_add_mesh(lu_accel *a, const lu_mesh *mesh, uint32_t *mesh_id, lu_error *err);
lu_result lu_accel_commit(lu_accel *a, lu_error *err);
void lu_accel_destroy(lu_accel *a);
lu_aabb lu_accel_bounds(const lu_accel *a);

/* Queries return false / 0 before a successful commit, for non-finite
 * input, and for d = 0. tmin may be negative (even -inf): the ray then
 * starts behind o. Closest and occluded leave hits within an ulp of tmin or
 * tmax to Embree's rounding; all_hits applies the open interval exactly. */

/* Closest hit in (tmin, tmax); false if none. */
bool lu_accel_closest(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax, lu_hit *hit);
/* Any hit in (tmin, tmax). */
bool lu_accel_occluded(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax);
/* All crossings in (tmin, tmax), sorted by t, at most max_hits (returns the
 * total found, which may exceed max_hits). One traversal, no epsilon stepping.
 * A ray through a shared edge or vertex counts once: reports at the same t
 * (to float rounding) from triangles of one mesh that share a vertex
 * position and face the same way are merged; a ray grazing a silhouette
 * edge gives an in and an out crossing at the same t. hits may be NULL with
 * max_hits = 0 to count. Returns -1 if memory for the candidates ran out. */
int lu_accel_all_hits(const lu_accel *a, lu_vec3 o, lu_vec3 d, float tmin, float tmax, lu_hit *hits,
                      int max_hits);
/* Inside a closed mesh set: crossing parity along three fixed directions,
 * majority vote (robust to rays grazing edges). */
bool lu_accel_inside(const lu_accel *a, lu_vec3 p);

/* Voxelises the closed meshes of `a` into g: each voxel holds the fraction of
 * its volume inside (supersampled with ss^3 points per voxel, 1 <= ss <= 32),
 * over the box `bounds` at `resolution` voxels along the longest side. The grid's
 * index_to_world maps voxel centres as the procedural generators do:
 * h = longest side / resolution, ceil(extent / h) voxels per axis (>= 1),
 * voxel i centred at bounds.lo + (i + 0.5) h; 1 <= resolution <= 16384.
 * One +x ray per row of sub-samples; inside-ness is crossing parity (regions
 * inside two overlapping meshes count as outside), and a row with an odd
 * crossing count falls back to lu_accel_inside per sample. g is overwritten
 * (not freed first); its data is malloc'd, released by lu_grid_destroy. */
lu_result lu_voxelize(const lu_accel *a, lu_aabb bounds, int resolution, int ss, lu_grid *g, lu_error *err);

#ifdef __cplusplus
}
#endif
#endif
