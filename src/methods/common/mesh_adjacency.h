/* Triangle adjacency of a mesh across its edges, with vertices welded by
 * exact position (meshes split at normal seams still join there). Shared by
 * bssrdf's surface relaxation (walking points over the surface) and the path
 * tracer's manifold next-event estimation (the facets next to a solution). */
#ifndef LU_METHODS_COMMON_MESH_ADJACENCY_H
#define LU_METHODS_COMMON_MESH_ADJACENCY_H

#include <lucent/lucent.h>

/* *out (3 x triangle_count, lu_free it): neighbour[3 t + e] is the triangle
 * across edge e of t (edge e joins corners e and e+1), or UINT32_MAX on a
 * border or a non-manifold edge. */
lu_result lu_mesh_edge_neighbours(const lu_mesh *m, uint32_t **out, lu_error *err);

#endif
