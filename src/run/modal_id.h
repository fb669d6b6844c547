/* Modal identification from a measured receptance (docs/method.md, "Complex FRF and modal
 * identification"): the poles by the rational fraction polynomial method (Richardson & Formenti
 * 1982) in its weighted, iterated form (Sanathanan & Koerner 1963), then the residues by linear
 * least squares with the poles fixed (LSFD) beside real upper and lower residual terms; the
 * standard errors by a parametric bootstrap over the points' standard errors. Pure numerics:
 * no files, no setup. */
#ifndef RTHS_RUN_MODAL_ID_H
#define RTHS_RUN_MODAL_ID_H

#include "rths/core.h"

#include <complex.h>
#include <stdint.h>

enum { FRF_MODAL_MAX_MODES = 8 };

/* One identified mode: H(w) ~ A / (w_n^2 - w^2 + 2 i zeta w_n w) near it (Ewins' modal constant
 * A, real for proportional damping; complex in general). */
typedef struct frf_mode_estimate {
    double frequency_hz, frequency_se_hz;   /* undamped natural frequency |lambda| / 2 pi */
    double damping_ratio, damping_ratio_se; /* -Re(lambda) / |lambda| */
    double complex modal_constant;
    double modal_constant_se_real, modal_constant_se_imag;
} frf_mode_estimate;

typedef struct frf_modal_fit_options {
    int modes;         /* pole pairs fitted, 1..FRF_MODAL_MAX_MODES */
    int bootstrap;     /* replicates for the standard errors; 0: none (SEs NaN) */
    uint64_t seed;     /* the bootstrap's generator (a fixed seed: the same file every run) */
    int sk_iterations; /* Sanathanan-Koerner reweightings; 0: 30 */
} frf_modal_fit_options;

/* Fits h[k] (the receptance at f_hz[k], each part with standard error se[k] > 0; points with a
 * non-finite value or a non-positive SE are left out) with opt->modes modes; out[r] ascending in
 * frequency. *replicates_used gets the bootstrap replicates that fitted (may be NULL). RTHS_EINPUT
 * with fewer points than unknowns, RTHS_EFAIL when the fit finds fewer stable oscillating poles
 * than modes. */
int frf_modal_fit(int n, const double *f_hz, const double complex *h, const double *se,
                  const frf_modal_fit_options *opt, frf_mode_estimate *out, int *replicates_used,
                  rths_error *err);

#endif
