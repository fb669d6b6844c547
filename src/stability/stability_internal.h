/* Internals shared by the stability module's files. */
#ifndef RTHS_STABILITY_INTERNAL_H
#define RTHS_STABILITY_INTERNAL_H

#include "rths/stability.h"

typedef struct rths_tracker {
    const rths_dde *d;
    double tau;
    int nodes;
    int n; /* roots followed (Im >= 0, one per conjugate pair) */
    double complex *roots;
    int reseeds; /* spectral computations so far */
} rths_tracker;

int rths_tracker_seed(rths_tracker *t, const rths_dde *d, double tau, int nodes, rths_error *err);
int rths_tracker_step(rths_tracker *t, double tau1, rths_error *err);
double rths_tracker_max_real(const rths_tracker *t, double *imag);
void rths_tracker_free(rths_tracker *t);

int rths_refine_crossing(const rths_dde *d, double *tau, double *omega);
int rths_locate_crossing(const rths_dde *d, double tau0, double re0, double tau1, double re1,
                         double omega_guess, double *tau_c, double *omega_c);

/* MDBM over (tau, p, omega): fills the chart's boundary arrays. */
int rths_mdbm_boundaries(rths_dde_family_fn family, void *ctx, const rths_chart_options *o,
                         rths_chart *c, rths_error *err);

#endif
