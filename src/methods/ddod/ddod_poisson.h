/* Internal: ddod's weighted Poisson-disk sampling (step 3 of ddod.h): darts
 * drawn once per field, thrown at a radius scale that the caller searches
 * for (ddod_precompute.c), and lu_ddod_poisson, both in one call. */
#ifndef LU_METHODS_DDOD_POISSON_H
#define LU_METHODS_DDOD_POISSON_H

#include "methods/ddod/ddod.h"

/* Where a sample may go (NULL fn: anywhere). */
typedef struct lu_ddod_valid {
    bool (*fn)(void *user, lu_vec3 p);
    void *user;
} lu_ddod_valid;

/* The darts of one sampling run. They do not depend on the radius scale,
 * so the passes that search for the scale share them: voxel v drawn with
 * probability ~ 1 / radius^3 (the density a Poisson-disk set of local radius
 * r ends up with, so darts go where points can land), a uniform point in it. */
typedef struct lu_ddod_darts {
    int n;
    float *p;              /* xyz per dart */
    float *r;              /* the radius of its voxel (unscaled) */
    signed char *valid;    /* cached lu_ddod_valid answer: 0 not asked yet, 1 yes, -1 no */
    float rmax;            /* largest radius of the field */
} lu_ddod_darts;


/* Draws candidates darts from the field (seeded). */
lu_result lu_ddod_darts_draw(const lu_ddod_field *f, int candidates, uint32_t seed, lu_ddod_darts *d, lu_error *err);
/* Dart throwing at radius scale `scale`: a dart is kept when no kept point q
 * has |p - q| < max(r_p, r_q) and `valid` accepts it. */
lu_result lu_ddod_darts_throw(const lu_ddod_field *f, lu_ddod_darts *d, float scale, const lu_ddod_valid *valid,
                              float **points_out, float **radii_out, int *count_out, lu_error *err);
void lu_ddod_darts_free(lu_ddod_darts *d);

#endif
