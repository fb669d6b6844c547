/* rths fidelity on a structure with nonlinear elements (docs/method.md, "Integration fidelity
 * with nonlinear elements"): the controller's real-time step, run as a pure simulation of the
 * whole assembly (every DoF and every element on the numerical side, nothing measured), against
 * the harmonic-balance truth, per frequency. */
#ifndef RTHS_API_FIDELITY_NONLINEAR_H
#define RTHS_API_FIDELITY_NONLINEAR_H

#include "rths/controller.h"
#include "rths/setup.h"

/* Harmonics of the truth, and the check of its truncation at half of them. */
#define RTHS_FIDELITY_NL_HARMONICS 48
#define RTHS_FIDELITY_NL_SAMPLES 2048

typedef struct rths_fidelity_nl_point {
    double frequency_hz;
    double true_amplitude_m; /* fundamental of the interface DoF, harmonic balance; nan when
                                it did not converge (near a fold) */
    double truth_truncation; /* |A(H) - A(H/2)| / A(H): the truth's own error bound */
    double step_amplitude_m; /* the same from the step's steady state */
    double error_relative;   /* |step - true| / true */
    double settled_s;        /* simulated time until the step's response was periodic */
    int settled;             /* 0: not periodic within the time limit (error still given) */
} rths_fidelity_nl_point;

/* 1 when the comparison applies: nonlinear elements, no static force on the interface DoF (the
 * all-numerical simulation takes static forces on internal DoFs only), few enough DoFs for a
 * dense harmonic balance. Otherwise 0 and *why says so. */
int rths_fidelity_nl_applies(const rths_setup *setup, const char **why);

/* For each of count ascending frequencies (Hz): the step (controller options copt: its sample
 * rate and scheme; gains, ramp and limits overridden for a pure simulation) swept upwards from
 * rest, each frequency's state carried to the next (so both follow one branch through a
 * hysteresis), against the truth warm-started likewise. */
int rths_fidelity_nl_compute(const rths_setup *setup, const rths_controller_options *copt,
                             const double *freqs_hz, int count, rths_fidelity_nl_point *out,
                             rths_error *err);

#endif
