/* lu_diffusion.h — diffusion profiles of a homogeneous, highly scattering
 * medium (kernel: C and GLSL). Everything is per colour channel and in one
 * length unit (the coefficients' inverse); r is the distance between where
 * light enters and where it leaves, d a slab's thickness.
 *
 * Dipole (Jensen, Marschner, Levoy, Hanrahan 2001): a real source at depth
 * z_r = l = 1/sigma_t' and a negative image at height z_v = l + 4 A D above
 * the surface (the extrapolated boundary sits at z_b = 2 A D), so
 *   R_d(r) = alpha'/(4 pi) [ z_r (1 + s d_r) e^{-s d_r} / d_r^3
 *                          + z_v (1 + s d_v) e^{-s d_v} / d_v^3 ],
 *   s = sigma_tr = sqrt(3 sigma_a sigma_t'), D = 1/(3 sigma_t'),
 *   A = (1 + F_dr)/(1 - F_dr) (Groenhuis), F_dr the Egan-Hilgeman fit.
 * Each term integrates over the plane to (1/2) e^{-s z} (with rho^2 = r^2 +
 * z^2: z/2 * int_z^inf (1 + s rho) e^{-s rho} / rho^2 d rho), which gives the
 * closed-form total  R_d = (alpha'/2) (1 + e^{-(4/3) A sqrt(3(1-alpha'))})
 * e^{-sqrt(3(1-alpha'))}: the check every table is held to.
 * (The thesis prints A inverted in its section 4.2.2 and drops a factor 2 from
 * the multipole period; these are the original papers' forms.)
 *
 * Multipole (Donner and Jensen 2005): a slab of thickness d with extrapolated
 * boundaries z_b0 = 2 A(0) D above and z_bd = 2 A(d) D below, mirrored
 * repeatedly with period 2 (d + z_b0 + z_bd):
 *   z_r,i = 2 i (d + z_b0 + z_bd) + l,  z_v,i = 2 i (d + z_b0 + z_bd) - l - 2 z_b0,
 *   R(r) = alpha'/(4 pi) sum_i [ z_r,i (1 + s d_r,i) e^{-s d_r,i}/d_r,i^3 - (same for z_v,i) ],
 *   T(r) = alpha'/(4 pi) sum_i [ (d - z_r,i)(...)/d'_r,i^3 - (same for z_v,i) ],
 * with d_x,i = sqrt(r^2 + z_x,i^2) for R and d'_x,i = sqrt(r^2 + (d - z_x,i)^2)
 * for T (the thesis writes z_x,i in both, which would make T a copy of R).
 * i = 0 alone with d -> infinity is the dipole.
 *
 * Normalised diffusion (Christensen and Burley 2015): R(r) = A (e^{-r/h} +
 * e^{-r/(3h)}) / (8 pi h r), which integrates to the albedo A over the plane;
 * h = ell / s(A). Their fits pair s with a length: for light entering
 * perpendicularly (the searchlight set-up, the one the BSSRDF's pencil beam
 * is), s = 1.85 - A + 7 |A - 0.8|^3 with ell the volume mean free path
 * 1/sigma_t' (published mean error 5.5 % against Monte Carlo), and
 * s = 3.5 + 100 (A - 0.33)^4 with ell the diffuse mean free path 1/sigma_tr
 * (7.7 %). The volume pairing is used: it is the more accurate, and it stays
 * finite for a non-absorbing medium, where 1/sigma_tr is infinite. */
#ifndef LU_DIFFUSION_H
#define LU_DIFFUSION_H

#include "kernels/lu_kernel.h"

/* Egan and Hilgeman's fit of the diffuse Fresnel reflectance for relative
 * index eta = n_inside / n_outside (as in Jensen et al. 2001). */
LU_FN float lu_k_fdr(float eta) {
    if (eta < 1.0f) return -0.4399f + 0.7099f / eta - 0.3319f / (eta * eta) + 0.0636f / (eta * eta * eta);
    return -1.4399f / (eta * eta) + 0.7099f / eta + 0.6681f + 0.0636f * eta;
}

/* Groenhuis' boundary mismatch factor A = (1 + F_dr) / (1 - F_dr). */
LU_FN float lu_k_diffusion_a(float eta) {
    float f = lu_k_fdr(eta);
    return (1.0f + f) / (1.0f - f);
}

/* Per-channel constants of one homogeneous layer. */
struct lu_k_diffusion {
    vec3 sigma_tr;   /* effective transport coefficient sqrt(3 sigma_a sigma_t') */
    vec3 alpha_p;    /* reduced albedo sigma_s' / sigma_t' */
    vec3 l;          /* depth of the real source, 1 / sigma_t' */
    vec3 zb_top;     /* extrapolation distance 2 A(top) D above the top surface */
    vec3 zb_bottom;  /* and below the bottom surface (multipole) */
};
LU_TYPEDEF(lu_k_diffusion)

/* sigma_sp: reduced scattering sigma_s' = (1 - g) sigma_s; eta_top and
 * eta_bottom: relative indices (this layer over what lies beyond) at each face. */
LU_FN lu_k_diffusion lu_k_diffusion_make(vec3 sigma_sp, vec3 sigma_a, float eta_top, float eta_bottom) {
    lu_k_diffusion k;
    vec3 st = lu_v3_add(sigma_sp, sigma_a);
    k.l = lu_v3(1.0f / st.x, 1.0f / st.y, 1.0f / st.z);
    k.alpha_p = lu_v3_mul(sigma_sp, k.l);
    k.sigma_tr = lu_v3(lu_sqrt(3.0f * sigma_a.x * st.x), lu_sqrt(3.0f * sigma_a.y * st.y), lu_sqrt(3.0f * sigma_a.z * st.z));
    /* z_b = 2 A D = 2 A / (3 sigma_t') */
    k.zb_top = lu_v3_scale(k.l, 2.0f * lu_k_diffusion_a(eta_top) / 3.0f);
    k.zb_bottom = lu_v3_scale(k.l, 2.0f * lu_k_diffusion_a(eta_bottom) / 3.0f);
    return k;
}

/* One source's flux through a plane at distance z from it, at lateral
 * distance r: z (1 + s d) e^{-s d} / (4 pi d^3), d = sqrt(r^2 + z^2). Signed by z. */
LU_FN float lu_k_dipole_term(float r, float z, float s) {
    float d = lu_sqrt(r * r + z * z);
    return z * (1.0f + s * d) * lu_exp(-s * d) * LU_K_INV_4PI / (d * d * d);
}

LU_FN float lu_k_dipole1(float r, float s, float alpha_p, float l, float zb) {
    return alpha_p * (lu_k_dipole_term(r, l, s) + lu_k_dipole_term(r, l + 2.0f * zb, s));
}

/* Dipole diffuse reflectance R_d(r) per channel. */
LU_FN vec3 lu_k_dipole(lu_k_diffusion k, float r) {
    return lu_v3(lu_k_dipole1(r, k.sigma_tr.x, k.alpha_p.x, k.l.x, k.zb_top.x),
                 lu_k_dipole1(r, k.sigma_tr.y, k.alpha_p.y, k.l.y, k.zb_top.y),
                 lu_k_dipole1(r, k.sigma_tr.z, k.alpha_p.z, k.l.z, k.zb_top.z));
}

/* Multipole reflectance (transmit = 0) or transmittance (1) of one channel
 * for a slab of thickness d, summing dipole pairs i = -pairs .. pairs. */
LU_FN float lu_k_multipole1(float r, float d, int pairs, int transmit, float s, float alpha_p, float l, float zb0,
                            float zbd) {
    float period = 2.0f * (d + zb0 + zbd);
    float sum = 0.0f;
    for (int i = -pairs; i <= pairs; i++) {
        float zr = lu_float(i) * period + l;
        float zv = lu_float(i) * period - l - 2.0f * zb0;
        if (transmit != 0) sum += lu_k_dipole_term(r, d - zr, s) - lu_k_dipole_term(r, d - zv, s);
        else sum += lu_k_dipole_term(r, zr, s) - lu_k_dipole_term(r, zv, s);
    }
    return alpha_p * sum;
}

LU_FN vec3 lu_k_multipole(lu_k_diffusion k, float r, float d, int pairs, int transmit) {
    return lu_v3(lu_k_multipole1(r, d, pairs, transmit, k.sigma_tr.x, k.alpha_p.x, k.l.x, k.zb_top.x, k.zb_bottom.x),
                 lu_k_multipole1(r, d, pairs, transmit, k.sigma_tr.y, k.alpha_p.y, k.l.y, k.zb_top.y, k.zb_bottom.y),
                 lu_k_multipole1(r, d, pairs, transmit, k.sigma_tr.z, k.alpha_p.z, k.l.z, k.zb_top.z, k.zb_bottom.z));
}

/* Closed-form total diffuse reflectance of the dipole, one channel. */
LU_FN float lu_k_dipole_total1(float s, float alpha_p, float l, float zb) {
    return 0.5f * alpha_p * (lu_exp(-s * l) + lu_exp(-s * (l + 2.0f * zb)));
}

/* Christensen-Burley normalised diffusion, one channel: albedo a, shape
 * length h (the profile is singular like 1/r at r = 0; callers sample r > 0). */
LU_FN float lu_k_burley1(float r, float a, float h) {
    return a * (lu_exp(-r / h) + lu_exp(-r / (3.0f * h))) / (8.0f * LU_K_PI * h * r);
}

/* Christensen and Burley's searchlight shape factor s(A) for the volume mean
 * free path 1/sigma_t' (not for 1/sigma_tr, which has its own fit). */
LU_FN float lu_k_burley_shape(float a) {
    float t = lu_abs(a - 0.8f);
    return 1.85f - a + 7.0f * t * t * t;
}

/* Shape length h of one channel: albedo a, reduced mean free path l = 1/sigma_t'. */
LU_FN float lu_k_burley_h(float a, float l) { return l / lu_k_burley_shape(a); }

#endif
