/* lu_lightview.h — light-space views (kernel: C and GLSL): the "virtual
 * camera at the light" of shadow mapping, shared by shadow maps, attenuation
 * function maps and light-space sample maps.
 *
 * A view is perspective (from a point: spot lights, or one face of a point
 * light's cube) or orthographic (directional lights). Projecting a world
 * point gives (u, v) in [0, 1]^2 over the map and a depth: the Euclidean
 * distance from the light for perspective views (distance along the light
 * ray, what attenuation along that ray is a function of), the distance from
 * the view plane along the light direction for orthographic ones. Texel
 * (i, j) of a res x res map covers u in [i/res, (i+1)/res]; its centre ray is
 * lu_k_lightview_ray(view, (i + 0.5) / res, (j + 0.5) / res). */
#ifndef LU_LIGHTVIEW_H
#define LU_LIGHTVIEW_H

#include "kernels/lu_kernel.h"

struct lu_k_lightview {
    vec3 origin;      /* light position (perspective) or the view plane's centre (orthographic) */
    vec3 axis_u, axis_v, axis_w;  /* orthonormal; w is the direction light travels */
    float extent_u, extent_v;     /* perspective: tan of the half-angles; orthographic: half sizes */
    float depth_far;              /* largest depth of interest (for normalisation and clears) */
    int ortho;
};
LU_TYPEDEF(lu_k_lightview)

struct lu_k_lightray {
    vec3 origin, dir;  /* dir is unit; depth along it is the view's depth */
};
LU_TYPEDEF(lu_k_lightray)

/* The light ray through map position (u, v) in [0, 1]^2. */
LU_FN lu_k_lightray lu_k_lightview_ray(lu_k_lightview vw, float u, float v) {
    lu_k_lightray r;
    float su = (2.0f * u - 1.0f) * vw.extent_u, sv = (2.0f * v - 1.0f) * vw.extent_v;
    if (vw.ortho != 0) {
        r.origin = lu_v3_add(vw.origin, lu_v3_add(lu_v3_scale(vw.axis_u, su), lu_v3_scale(vw.axis_v, sv)));
        r.dir = vw.axis_w;
    } else {
        r.origin = vw.origin;
        r.dir = lu_v3_norm(lu_v3_add(vw.axis_w, lu_v3_add(lu_v3_scale(vw.axis_u, su), lu_v3_scale(vw.axis_v, sv))));
    }
    return r;
}

/* (u, v, depth) of world point x; u, v outside [0, 1] or depth <= 0 mean
 * the point is outside the view. */
LU_FN vec3 lu_k_lightview_project(lu_k_lightview vw, vec3 x) {
    vec3 d = lu_v3_sub(x, vw.origin);
    float pu = lu_v3_dot(d, vw.axis_u), pv = lu_v3_dot(d, vw.axis_v), pw = lu_v3_dot(d, vw.axis_w);
    if (vw.ortho != 0) return lu_v3(0.5f + 0.5f * pu / vw.extent_u, 0.5f + 0.5f * pv / vw.extent_v, pw);
    if (pw <= 0.0f) return lu_v3(-1.0f, -1.0f, -1.0f);
    return lu_v3(0.5f + 0.5f * pu / (pw * vw.extent_u), 0.5f + 0.5f * pv / (pw * vw.extent_v), lu_v3_len(d));
}

LU_FN bool lu_k_lightview_inside(vec3 uvd) {
    return uvd.z > 0.0f && uvd.x >= 0.0f && uvd.x <= 1.0f && uvd.y >= 0.0f && uvd.y <= 1.0f;
}

/* Cube face of a point light for direction d from the light: 0..5 = +x, -x,
 * +y, -y, +z, -z (the face whose axis has d's largest component). */
LU_FN int lu_k_cube_face(vec3 d) {
    float ax = lu_abs(d.x), ay = lu_abs(d.y), az = lu_abs(d.z);
    if (ax >= ay && ax >= az) return d.x >= 0.0f ? 0 : 1;
    if (ay >= az) return d.y >= 0.0f ? 2 : 3;
    return d.z >= 0.0f ? 4 : 5;
}

/* An orthonormal (u, v) pair for a view direction w. */
LU_FN vec3 lu_k_basis_u(vec3 w) {
    vec3 ref = lu_abs(w.y) < 0.999f ? lu_v3(0.0f, 1.0f, 0.0f) : lu_v3(0.0f, 0.0f, 1.0f);
    return lu_v3_norm(lu_v3_cross(ref, w));
}

/* Face f of a point light's cube map: a 90-degree perspective view. */
LU_FN lu_k_lightview lu_k_cube_view(vec3 origin, int face, float depth_far) {
    lu_k_lightview vw;
    float sgn = (face & 1) == 1 ? -1.0f : 1.0f;
    int axis = face / 2;
    vw.axis_w = lu_v3(axis == 0 ? sgn : 0.0f, axis == 1 ? sgn : 0.0f, axis == 2 ? sgn : 0.0f);
    vw.axis_u = lu_k_basis_u(vw.axis_w);
    vw.axis_v = lu_v3_cross(vw.axis_w, vw.axis_u);
    vw.origin = origin;
    vw.extent_u = 1.0f;
    vw.extent_v = 1.0f;
    vw.depth_far = depth_far;
    vw.ortho = 0;
    return vw;
}

#endif
