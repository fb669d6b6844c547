/* rths harmonic balance (model module): the periodic response of M q'' + C q' + K q +
 * sum_e g_e b_e = static_force + force cos(w t) with nonlinear elements (nonlinear.h) as a
 * truncated Fourier series, the elements' forces by alternating frequency-time evaluation (AFT:
 * the series sampled at `samples` points per period, the forces evaluated there, transformed
 * back), Newton with the exact Jacobian of the truncated system (docs/method.md, "Harmonic
 * balance"). The frequency form of the numerical substructure is to be built on it; today it is
 * a truth at one frequency, its truncation checked by doubling the harmonics. */
#ifndef RTHS_HARMONIC_BALANCE_H
#define RTHS_HARMONIC_BALANCE_H

#include "rths/nonlinear.h"

typedef struct rths_hb_options {
    int harmonics;  /* H: harmonics 0..H kept */
    int samples;    /* AFT time samples per period, >= 2 H + 1 (more resolve a kink better) */
    int max_newton; /* Newton steps at most */
    double tol;     /* converged when the residual's largest entry <= tol x the forcing's */
} rths_hb_options;

void rths_hb_defaults(rths_hb_options *opt); /* H 15, 256 samples, 50 steps, 1e-11 */

/* The coefficients' layout: coef[i + n j] for DoF i, j = 0 the mean, j = 2k - 1 the cos(k w t)
 * and j = 2k the sin(k w t) coefficient (m); n (2 H + 1) entries. On entry a first guess (zeros:
 * the linear solution is tried first), on return the solution; *iterations its Newton steps. */
int rths_hb_solve(const rths_assembly *a, int count, const rths_nl_element *el,
                  const double *static_force, const double *force, double omega_rad_s,
                  const rths_hb_options *opt, double *coef, int *iterations, rths_error *err);

#endif
