/* Internal: the method tables and helpers every method driver shares. */
#ifndef LU_METHODS_INTERNAL_H
#define LU_METHODS_INTERNAL_H

#include <lucent/lucent.h>

#include "kernels/lu_optics.h"

extern const lu_method lu_method_reference;
extern const lu_method lu_method_bssrdf;

/* The kernel-side light record (cone angles as cosines). */
static inline lu_k_light lu_light_to_kernel(const lu_light *l) {
    lu_k_light k;
    k.position = l->position;
    k.direction = l->direction;
    k.intensity = l->intensity;
    k.cos_inner = cosf(l->inner_deg * (LU_PI / 180.0f));
    k.cos_outer = cosf(l->outer_deg * (LU_PI / 180.0f));
    k.type = l->type == LU_LIGHT_POINT ? LU_K_LIGHT_POINT
             : l->type == LU_LIGHT_SPOT ? LU_K_LIGHT_SPOT
                                        : LU_K_LIGHT_DIRECTIONAL;
    return k;
}

#endif
