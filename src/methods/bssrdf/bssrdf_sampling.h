/* Internal: sample points on a triangle mesh for environment lighting
 * (Rohat 2011, section 5.3.1): area-CDF placement, then Turk-style repulsion
 * relaxation that moves points along the surface (across edges, unfolding
 * the motion into each next triangle), neighbours found through a uniform
 * spatial grid. */
#ifndef LU_METHODS_BSSRDF_SAMPLING_H
#define LU_METHODS_BSSRDF_SAMPLING_H

#include <lucent/lucent.h>

typedef struct lu_surface_points {
    int count;
    lu_vec3 *position;
    lu_vec3 *normal;      /* interpolated vertex normal */
    uint32_t *triangle;
} lu_surface_points;

void lu_surface_points_destroy(lu_surface_points *p);

/* `count` points, triangle chosen by binary search in the area CDF, then
 * uniform inside it (u = 1 - sqrt(x1), v = (1 - x2) sqrt(x1), w = x2 sqrt(x1)). */
lu_result lu_surface_sample(const lu_mesh *mesh, int count, uint64_t seed, lu_surface_points *out, lu_error *err);

typedef struct lu_relax_stats {
    int iterations;
    bool converged;          /* uniformity stopped improving and the points settled */
    double seconds;
    double last_rms_move;    /* relative to the radius */
    double nn_mean_before, nn_cv_before;   /* nearest-neighbour distance: mean, std / mean */
    double nn_mean_after, nn_cv_after;
} lu_relax_stats;

/* Repulsion with influence radius `radius` (Turk 1991: 2 sqrt(A / N)): each
 * neighbour closer than radius pushes with (radius - d) along the direction
 * from it, taken in the pivot's tangent plane; all forces are computed, then
 * every point moves by step * force (thesis listing 5.11). Stops after
 * max_iters, or once converged: the nearest-neighbour distances' coefficient
 * of variation improved by less than tol (relative) over 5 iterations and
 * the RMS move is under 1 % of the radius. */
lu_result lu_surface_relax(const lu_mesh *mesh, lu_surface_points *pts, double radius, double step, int max_iters,
                           double tol, lu_relax_stats *stats, lu_error *err);

/* Nearest-neighbour distance statistics (Euclidean), neighbours searched
 * within `search` (points with none inside count as search). */
void lu_surface_nn_stats(const lu_surface_points *pts, double search, double *mean, double *cv);

#endif
