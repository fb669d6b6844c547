/* rths floquet: an experimental estimate of the Floquet multipliers of a periodic orbit held by
 * a hybrid test, from the rig's response to a small injected perturbation (docs/method.md,
 * "Experimental Floquet multipliers"; after Barton, "Control-based continuation: bifurcation and
 * stability analysis for physical experiments", MSSP 2017).
 *
 * At a converged point the controller holds the orbit x*(t). A small random perturbation of the
 * actuator demand makes the physical interface deviate by u = delta x, and the numerical
 * substructure, driven by the force the physical side exerts, deviates by y = delta xi. The map
 * u -> y ("the series map": physical dynamic stiffness, then the numerical substructure, with
 * the grounding control around it) is linear time-periodic about the orbit. It is identified as a
 * periodic ARX model on a phase-locked grid of P samples per forcing period,
 *
 *   y_k = sum_{i=1..n} a_i(phi_k) y_{k-i} + sum_{j=0..n} b_j(phi_k) u_{k-j} + e_k,
 *
 * the coefficients of the first lags (varying_lags) a Fourier series of order H in the phase
 * phi_k = 2 pi (k mod P) / P, or piecewise constant over phase bins, fitted by linear least squares
 * (one QR factorisation, LAPACK dgeqrf, serves every order). The true assembly is the hybrid system
 * with the interface matched, u = y: substituting gives the closed recurrence (1 - b_0) y_k = sum_i
 * (a_i + b_i) y_{k-i}, whose companion matrices, multiplied over one period, give the monodromy
 * matrix; its eigenvalues (dgeev) estimate the Floquet multipliers. The grounding control drops out
 * on closure (it acts on y - u), and nothing about the numerical model or the actuator needs to be
 * known. The largest modulus gets a standard error (a bootstrap over whole periods plus the
 * change from order n - 2), and the stability label is three-way: stable, unstable, or
 * undetermined where the fit is not trustworthy or the circle lies within 2 standard errors.
 * Not for the per-sample path: it allocates and calls LAPACK. */
#ifndef RTHS_FLOQUET_H
#define RTHS_FLOQUET_H

#include "rths/core.h"

enum { RTHS_FLOQUET_MAX_ORDER = 40, RTHS_FLOQUET_MAX_PHASE_HARMONICS = 12 };

/* The three-way experimental stability label (rths_floquet_estimate.label; frf.csv's
 * stable_experimental): undetermined when the fit is not trustworthy or the largest modulus lies
 * within determined_se standard errors of 1 at the chosen order or a neighbouring one. */
enum { RTHS_FLOQUET_UNDETERMINED = -1, RTHS_FLOQUET_UNSTABLE = 0, RTHS_FLOQUET_STABLE = 1 };

typedef struct rths_floquet_options {
    int min_order, max_order; /* ARX orders n tried (1..RTHS_FLOQUET_MAX_ORDER); BIC picks one */
    int phase_harmonics;      /* H: Fourier order of the coefficients in phase (0: LTI) */
    /* the coefficients of lags 1..varying_lags (of u and y) vary with phase; b_0 (the interface
     * mass ratio's feedthrough, which the closure divides by) and the later lags are constant:
     * the orbit's time variation sits in the physical substructure's stiffness, felt at once,
     * while the model order that resolves the dynamics is high; a phase basis on every lag would
     * multiply the parameters by the basis' size */
    int varying_lags;
    /* > 0: piecewise-constant coefficients over this many equal phase bins instead of the
     * Fourier series (at most P; a bilinear kink switches the stiffness within a sample) */
    int phase_bins;
    /* trust limits: one-step residual RMS over the output deviation's RMS, and the condition
     * number of the column-scaled regression matrix */
    double max_relative_residual;
    double max_condition;
    /* the standard error of the largest modulus: a bootstrap over whole periods (the regression
     * rows of periods drawn with replacement, refitted at the chosen order) with this many
     * replicates (0: no standard error, the label stays undetermined), seeded by
     * bootstrap_seed so an estimate repeats bit for bit */
    int bootstrap_replicates;
    uint64_t bootstrap_seed;
    /* the label is determined only when |max_abs - 1| exceeds this many standard errors */
    double determined_se;
    /* trust limit on the standard error relative to the modulus: beyond it the record does not
     * resolve the closure, whose replicates then scatter far from normal and "beyond 2 SE" no
     * longer means 97.7 % */
    double max_relative_se;
} rths_floquet_options;

/* min_order 2, max_order 16, phase_harmonics 3, varying_lags 2, max_relative_residual 0.2,
 * max_condition 1e12, bootstrap_replicates 200, bootstrap_seed 1, determined_se 2,
 * max_relative_se 0.05. */
void rths_floquet_defaults(rths_floquet_options *opt);

typedef struct rths_floquet_estimate {
    int order;           /* n chosen by the Bayesian information criterion */
    int phase_harmonics; /* H used (0 with bins) */
    int phase_bins;      /* bins used (0: Fourier) */
    int parameters;      /* 2 v (basis size) + 2 (n - v) + 1, v = min(varying_lags, n) */
    int rows;            /* regression rows (grid samples with a full history) */
    int n_multipliers;   /* n */
    double multiplier_re[RTHS_FLOQUET_MAX_ORDER], multiplier_im[RTHS_FLOQUET_MAX_ORDER];
    double max_abs; /* largest multiplier modulus (sorted: multiplier 0) */
    /* its standard error (dimensionless), two parts added in quadrature: the noise's, the
     * standard deviation of the largest modulus over the bootstrap replicates (NaN without a
     * bootstrap, INFINITY when more than a tenth of the replicates could not be refitted or
     * closed), and the finite order's, the change of the largest modulus from order n - 2 to
     * the chosen n (0 where n - 2 is below the orders tried): a sampled ARX model only
     * approximates the continuous-time map, and the bootstrap does not see that bias */
    double max_abs_se;
    double max_abs_se_bootstrap, max_abs_se_order;
    double max_abs_half[2];   /* the same order fitted to the first and the second half of the
                                 periods: they differ by more than 3 times their difference's
                                 standard error, 2 max_abs_se, only when the bootstrap
                                 understates the scatter (a record that drifts) */
    double max_abs_order[2];  /* the same record fitted at orders n - 2 and n + 2 (NaN where
                                 outside the orders tried) */
    int orders_agree;         /* both within 3 max_abs_se of order n's largest modulus */
    double relative_residual; /* RMS one-step residual / RMS of y */
    double condition; /* of the column-scaled regression matrix (1-norm estimate of its QR factor,
                         dtrcon) */
    double closure_gain; /* min over phase of |1 - b_0|: the closure's well-posedness */
    int stable;          /* max_abs < 1 (whatever the standard error) */
    int trustworthy;     /* residual, condition, closure and relative standard error within
                            limits, the neighbouring orders on the same side of the unit circle
                            and the halves consistent with the standard error */
    int label;           /* RTHS_FLOQUET_STABLE / _UNSTABLE when trustworthy and |max_abs - 1|
                            > determined_se max_abs_se, else RTHS_FLOQUET_UNDETERMINED */
    char note[200];      /* why not trustworthy ("" when it is) */
} rths_floquet_estimate;

/* Per-sample records (phase_rad in [0, 2 pi) at each sample, advancing by less than pi per sample
 * at a constant frequency; u and y the two signals) to a phase-locked grid of samples_per_period
 * points per period at phases 2 pi j / P, each the mean of the samples whose unwrapped phase lies
 * within half a grid step (a box filter applied alike to u and y, so the map between them is kept
 * while the noise and the content above the grid's Nyquist frequency are reduced). Only whole
 * periods are kept, starting at the first grid point after the record's start; *periods_out of
 * them (at most max_periods), u_grid and y_grid hold P * max_periods values. RTHS_EINPUT when the
 * record holds no whole period or a grid cell holds no sample. */
int rths_floquet_phase_grid(const double *phase_rad, const double *u, const double *y, long n,
                            int samples_per_period, int max_periods, double *u_grid, double *y_grid,
                            int *periods_out, rths_error *err);

/* Subtracts from s (samples_per_period * periods, period after period) its mean over the periods
 * at each grid phase: what is left is the deviation from the periodic orbit. */
void rths_floquet_remove_periodic_mean(double *s, int samples_per_period, int periods);

/* Fits the periodic ARX model of the series map u -> y (deviations on the phase grid, P * periods
 * samples each), closes it with u = y and fills est (see the header comment). RTHS_EINPUT for bad
 * options or too few samples for the smallest model (rows below twice the parameters),
 * RTHS_EFAIL when LAPACK fails. */
int rths_floquet_estimate_series(const double *u, const double *y, int samples_per_period,
                                 int periods, const rths_floquet_options *opt,
                                 rths_floquet_estimate *est, rths_error *err);

#endif
