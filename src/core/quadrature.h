/* Internal: Gauss-Legendre quadrature, for the smooth integrals the methods
 * tabulate at prepare (Fresnel-weighted angular moments, profile filters). */
#ifndef LU_CORE_QUADRATURE_H
#define LU_CORE_QUADRATURE_H

/* The n nodes x and weights w of Gauss-Legendre quadrature on [-1, 1]
 * (Newton on P_n from Tricomi's initial guesses, to 1e-15). */
void lu_gauss_legendre(int n, double *x, double *w);

#endif
