/* Internal: the members a CPU kernel context (`struct lu_k_ctx`) starts
 * with, so that the shared hooks (scene_hooks.h, view_march_hooks.h) find
 * them in every method. Include before defining the struct. */
#ifndef LU_METHODS_KERNEL_CTX_H
#define LU_METHODS_KERNEL_CTX_H

#include "methods/common/view_march.h"
#include "methods/frame.h"

/* The scene part of a CPU kernel context: the media, their kernel records
 * and the kernel lights, all from the frame's records (frame.h). */
#define LU_K_CTX_SCENE_MEMBERS                                                                                        \
    const lu_medium *media;                                                                                            \
    const lu_k_medium *km;                                                                                             \
    int nm;                                                                                                            \
    const lu_k_light *kl;                                                                                              \
    int nl;
/* ... filled from a frame. */
#define LU_K_CTX_SCENE(scene, rec) (scene)->media, (rec)->media, (scene)->medium_count, (rec)->lights, (rec)->light_count

/* The view march's: the scene part, the frame and the light views. */
#define LU_K_CTX_VIEW_MARCH_MEMBERS                                                                                   \
    LU_K_CTX_SCENE_MEMBERS                                                                                             \
    const lu_view_march_frame *f;                                                                                      \
    const lu_k_lightview *views;

#endif
