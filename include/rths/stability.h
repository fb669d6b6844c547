/* rths stability: substructurability of the conventional (delayed-feedback) hybrid test
 * (docs/method.md, "Delayed-feedback stability").
 *
 * The delayed-feedback test. The physical substructure (internal DoFs x_p, interface x_i) and the
 * numerical one (interface xi_i, internal xi_n) each obey their own equations (model.h's split:
 * physical matrices P in order (phys, int), numerical N in order (int, num), the interface mass
 * divided as P_ii = (1 - p) M_ii, N_ii = p M_ii, erratum 1 in docs/method.md, "Errata of the seed
 * paper"). The actuator makes the physical interface follow the numerical one with a pure delay,
 * x_i(t) = xi_i(t - tau), and the measured interface force is fed back without delay, F_i^phys =
 * -F_i^num. Eliminating x_i and F_i gives one neutral delay equation in q = the assembly's DoFs
 * (interface DoFs carry the numerical xi_i):
 *
 *   M_tau q''(t-tau) + M_0 q''(t) + C_tau q'(t-tau) + C_0 q'(t) + K_tau q(t-tau) + K_0 q(t) = F(t).
 *
 * How each block arises (X stands for M, C or K; rows/columns are assembly DoFs):
 *  - physical internal rows (the physical substructure's equations for x_p): the columns of
 *    internal physical DoFs act now, X_0 += P_pp; the columns of interface DoFs act on
 *    x_i(t) = xi_i(t - tau), X_tau += P_pi.
 *  - interface rows: the force the physical substructure needs at its interface, P_ip x_p(t) +
 *    P_ii xi_i(t - tau), is moved to the numerical interface equation, so X_0 += P_ip (now),
 *    X_tau += P_ii (the physical interface share, delayed), and the numerical interface equation
 *    itself adds X_0 += N_ii, N_in.
 *  - numerical internal rows: X_0 += N_ni, N_nn (no delay anywhere on the numerical side).
 * So the rule is one line: every physical-substructure entry in an interface COLUMN is delayed,
 * everything else is immediate; X_0 + X_tau = the assembly's X, hence D(0) = det K. For the seed
 * (storeys 1..4, interface 3): M_tau = (1-p) m3 e3 e3^T, C_tau/K_tau hold c3/k3 in column 3 rows 2,
 * 3
 * (-c3, +c3 / -k3, +k3), exactly the paper's eq. (2.10); det(M_0 + z M_tau) = 0 at z = -p/(1-p),
 * so the neutral root chain sits at Re lambda = ln((1-p)/p)/tau: p > 1/2 is necessary.
 *
 * All matrices column-major (core.h), SI units. */
#ifndef RTHS_STABILITY_H
#define RTHS_STABILITY_H

#include "rths/config.h"
#include "rths/core.h"
#include "rths/model.h"
#include "rths/setup.h"

#include <complex.h>

/* ---- the neutral delay equation ---- */

typedef struct rths_dde {
    int n;
    double *m0, *mt, *c0, *ct, *k0, *kt; /* n x n each (owned) */
} rths_dde;

/* Copies six n x n matrices (any may be NULL = zero). With M_0 = M_tau = 0 the equation is
 * first order (C_0 q' + C_tau q'(t-tau) + ...); otherwise a singular M_0 makes it advanced, which
 * the essential-spectrum bound reports as +inf (unstable for every delay). */
int rths_dde_from_matrices(int n, const double *m0, const double *mt, const double *c0,
                           const double *ct, const double *k0, const double *kt, rths_dde *out,
                           rths_error *err);
/* The delayed-feedback test of split s of assembly a (see the header comment). */
int rths_dde_from_split(const rths_assembly *a, const rths_split *s, rths_dde *out,
                        rths_error *err);
/* The delayed-feedback test of a configured setup, honouring rig.interface_mass (setup.h): the
 * rig's interface mass acts on the delayed interface, x_i(t) = xi_i(t - tau), and so does the
 * controller's inertial compensation, which multiplies the measured (physical, hence delayed)
 * acceleration, with the opposite sign: M_tau's interface block is M_rig - M_comp. full:
 * M_II - p M_II; physical_share: (1 - p) M_II - 0. Both are the split's (1 - p) M_II, so the two
 * labs share one chart (docs/method.md, "The interface mass on the rig"); the armature moves
 * inside the actuator, behind the load cell, and is no part of this equation. */
int rths_dde_from_setup(const rths_setup *s, rths_dde *out, rths_error *err);
void rths_dde_free(rths_dde *d);

/* Characteristic matrix A(lambda) = lambda^2 (M_0 + e M_tau) + lambda (C_0 + e C_tau) + K_0 +
 * e K_tau with e = exp(-lambda tau). det_out (may be NULL): D(lambda) = det A. dlog_dlambda and
 * dlog_dtau (may be NULL): D'/D = trace(A^{-1} dA/dlambda) and (dD/dtau)/D, the quantities Newton
 * and root tracking need without overflow. Returns 0, or -1 when A is numerically singular (then
 * *det_out = 0 and the derivatives are not filled). */
int rths_dde_char(const rths_dde *d, double tau, double complex lambda, double complex *det_out,
                  double complex *dlog_dlambda, double complex *dlog_dtau);
/* D(lambda) with row i divided by |lambda|^2 m_i + |lambda| c_i + k_i (m_i, c_i, k_i: row i's
 * 1-norms of M_0 + M_tau etc.): a positive factor, so zeros and the signs of Re and Im are those
 * of D, but the value stays O(1) for any size and frequency (what MDBM compares). */
double complex rths_dde_char_scaled(const rths_dde *d, double tau, double complex lambda);
/* Smallest singular value of the row-scaled A(lambda), estimated as 1/norm_F(A^{-1}) (within a
 * factor sqrt(n)); 0 at an exact root. */
double rths_dde_residual(const rths_dde *d, double tau, double complex lambda);
/* Newton on D(lambda) = 0 from *lambda (in place). 0 when converged (|step| <= 1e-12 (1+|lambda|)
 * within 50 iterations). */
int rths_dde_newton(const rths_dde *d, double tau, double complex *lambda);

/* Essential spectrum: the neutral chains lie on Re lambda = -ln|z| / tau for the finite nonzero
 * roots z of det(M_0 + z M_tau) = 0 (generalised eigenvalues, dggev). *rate_times_tau is
 * max(-ln|z|) over them (the chain bound is rate_times_tau / tau: its sign does not depend on tau);
 * -INFINITY when M_tau = 0 (a retarded equation has no chain), +INFINITY when M_0 is singular.
 * z (may be NULL, n entries) gets the roots, *n_z their number. */
int rths_dde_essential(const rths_dde *d, double *rate_times_tau, double complex *z, int *n_z,
                       rths_error *err);

/* ---- rightmost roots by Chebyshev collocation ---- */

/* Roots of D from the spectral discretisation of the DAE form (docs/method.md, "Delayed-feedback
 * stability") on nodes+1 Chebyshev nodes over [-tau, 0] (generalised eigenproblem, dggev3). A root
 * is accepted only when the relative residual rths_dde_residual of the raw eigenvalue is below
 * accept_tol (<= 0: 1e-6); accepted roots are polished by Newton and returned with Im >= 0 (one of
 * each conjugate pair), sorted by decreasing real part. *roots is malloc'ed. */
int rths_dde_spectral_roots(const rths_dde *d, double tau, int nodes, double accept_tol,
                            double complex **roots, int *n_roots, rths_error *err);

/* Stability at one delay: max_real = max(rightmost accepted root, essential bound); stable iff
 * every accepted root has Re < 0 and the essential bound is < 0. */
typedef struct rths_dde_label {
    double max_real_per_s; /* as above */
    double rightmost_real; /* of the accepted roots (-inf when none) */
    double rightmost_imag;
    double essential_per_s; /* rate_times_tau / tau */
    int stable;
} rths_dde_label;
int rths_dde_label_at(const rths_dde *d, double tau, int nodes, rths_dde_label *out,
                      rths_error *err);

/* Smallest delay in (tau_lo, tau_hi] at which q = 0 loses stability, by root tracking from a
 * spectral labelling at tau_lo (steps: tracking steps, geometric) and Newton on D(i omega) = 0 in
 * (tau, omega) at the crossing. *tau_c = 0 when already unstable at tau_lo and the essential bound
 * is >= 0 (unstable for every delay); NaN when no crossing below tau_hi (or unstable at tau_lo
 * for another reason). *omega_c = crossing frequency (rad/s), NaN when none. */
int rths_dde_critical_delay(const rths_dde *d, double tau_lo, double tau_hi, int steps, int nodes,
                            double *tau_c, double *omega_c, rths_error *err);

/* ---- charts over (tau, p) ---- */

/* Builds the DDE at parameter value p (for a split: the mass ratio). */
typedef int (*rths_dde_family_fn)(void *ctx, double p, rths_dde *out, rths_error *err);

typedef struct rths_chart_options {
    double tau_min_s, tau_max_s;
    int tau_points;
    double p_min, p_max;
    int p_points;
    double omega_min_rad_s, omega_max_rad_s; /* MDBM omega range */
    int omega_points;                        /* MDBM omega grid */
    int mdbm_tau_points, mdbm_p_points;      /* MDBM (tau, p) grid (0: the chart's) */
    int mdbm_refine;                         /* bisection levels per cell */
    int chebyshev_nodes;
    int progress; /* \r progress line on stderr */
} rths_chart_options;

/* The seed's ranges (tau 5e-5..3e-4 s, p 0.01..0.99, omega 1e-4..550 rad/s), 200 x 200 grid. */
void rths_chart_options_default(rths_chart_options *o);

typedef struct rths_chart {
    int nt, np;
    double *tau;                      /* nt */
    double *p;                        /* np */
    double *max_real;                 /* nt x np, [i + j nt] (tau i, p j) */
    int *stable;                      /* nt x np */
    double *essential_rate_times_tau; /* np */
    double *critical_tau;             /* np: rths_dde_critical_delay semantics */
    double *critical_omega;
    int n_boundary; /* MDBM points, ordered along connected curves */
    double *b_tau, *b_p, *b_omega;
    int *b_curve;          /* curve id of each point */
    double b_max_residual; /* max |D_scaled(i omega)| over the polished boundary points */
    /* cross-check: label changes between neighbouring grid points without a boundary point within
     * one cell, and boundary points without a label change within one cell */
    int label_changes, label_changes_unexplained, boundary_unexplained;
} rths_chart;

int rths_chart_compute(rths_dde_family_fn family, void *ctx, const rths_chart_options *o,
                       rths_chart *out, rths_error *err);
void rths_chart_free(rths_chart *c);

/* The family "split of assembly a with roles, mass ratio = p" for rths_chart_compute. */
typedef struct rths_split_family {
    const rths_assembly *assembly;
    const rths_dof_role *roles;
    /* physical shares of the interface damping / stiffness blocks (n_int x n_int), as for
     * rths_split_create; NULL: the coupling rule */
    const double *damping_int_phys, *stiffness_int_phys;
} rths_split_family;
int rths_split_family_build(void *ctx, double p, rths_dde *out, rths_error *err);

/* The family of a configured split s of assembly a: the interface damping and stiffness shares
 * s holds (its physical interface blocks) kept for every p. The shares are malloc'ed into
 * *damping_int, *stiffness_int (n_int x n_int; free both with free()). */
int rths_split_family_of(const rths_assembly *a, const rths_dof_role *roles, const rths_split *s,
                         rths_split_family *out, double **damping_int, double **stiffness_int,
                         rths_error *err);

/* The p where the essential-spectrum bound changes sign along the chart's rows (linear
 * interpolation of rate x tau between neighbouring p), NaN when it keeps its sign. */
double rths_chart_essential_limit(const rths_chart *c);

/* Reads the chart options from the configuration's stability section (docs/config/stability.md):
 * tau_min_s, tau_max_s, tau_points, p_min, p_max, p_points, omega_min_rad_s, omega_max_rad_s,
 * omega_points, mdbm_tau_points, mdbm_p_points, mdbm_refine, chebyshev_nodes; absent keys keep
 * rths_chart_options_default's values. Refuses (located, RTHS_EINPUT) values out of range, an
 * empty tau or omega range, p_max < p_min and an MDBM grid of more than 5e7 cells. */
int rths_chart_config_read(rths_config *cfg, rths_chart_options *o, rths_error *err);

/* ---- time-domain simulation of the delayed-feedback test ---- */

typedef struct rths_delay_sim_result {
    int n;                     /* samples in the decimated trace */
    double *t_s;               /* n */
    double *x_phys_m;          /* physical interface displacement (first interface DoF), n */
    double *x_num_m;           /* numerical interface displacement, n */
    int diverged;              /* |x| > 1e3 x steady amplitude, or non-finite */
    double divergence_time_s;  /* NaN when not diverged */
    double growth_rate_per_s;  /* slope of log(window max |x_num|) over the second half */
    double steady_amplitude_m; /* true assembly's interface amplitude at forcing_hz */
    double end_time_s;         /* simulated time (early stop on divergence) */
} rths_delay_sim_result;

/* Physical substructure with its interface DoFs following the numerical ones delayed by tau_s
 * (ideal delayed actuator), force feedback without delay; force_amplitudes (n, assembly DoFs) *
 * cos(2 pi forcing_hz t), from rest. RK4 at step h_s (<= tau_s / 20; 0: tau_s / 40) with Hermite
 * interpolation of the stored interface history. tau_s > 0. */
int rths_delay_feedback_simulate(const rths_assembly *a, const rths_split *s,
                                 const double *force_amplitudes, double forcing_hz, double tau_s,
                                 double duration_s, double h_s, rths_delay_sim_result *out,
                                 rths_error *err);
void rths_delay_sim_result_free(rths_delay_sim_result *r);

/* ---- analysis of a feedback test's time trace ---- */

/* Fourier coefficients over whole forcing periods of a signal x sampled uniformly from t = 0 (the
 * forcing phase): for period j (samples with j T <= t < (j + 1) T, T = 1 / frequency_hz),
 *   coef[j * (1 + 2 harmonics)] = a0 (the mean), then a_k, b_k for k = 1..harmonics, with
 *   x(t) ~ a0 + sum_k a_k cos(k w t) + b_k sin(k w t)   (a_k = 2/m sum x cos(k w t), m samples).
 * The last period counts only when the samples cover it to its end. coef holds max_periods rows;
 * samples (may be NULL) gets m per period. Returns the number of whole periods. */
int rths_whole_period_fourier(const double *t_s, const double *x, int n, double frequency_hz,
                              int harmonics, int max_periods, double *coef, int *samples);

/* Growth of a feedback test's response, free of the forced part: for a linear test under
 * T-periodic forcing, d(t) = x(t) - x(t - T) solves the unforced equations (the periodic steady
 * state cancels), so the slope of ln max|d| per window, fitted over the second half of the run,
 * is the real part of the dominant characteristic root: negative when the loop is stable,
 * positive when it is not. Windows span at least one period of the slowest mode (slowest_s) so
 * its envelope is seen. A run shorter than 1.5 T uses x itself. NAN when too short;
 * *last_envelope gets the last window's max |d| and *fit_span_s the fitted span. */
double rths_feedback_growth_rate(const double *t_s, const double *x, int n, double period_s,
                                 double slowest_s, double *last_envelope, double *fit_span_s);

typedef struct rths_feedback_verdict {
    int diverged;
    const char *reason;       /* why it diverged (static text), NULL when it did not */
    const char *note;         /* e.g. a positive rate over too short a span (static), or NULL */
    double growth_rate_per_s; /* rths_feedback_growth_rate of x_num */
    double fit_span_s;
    double max_abs_x_num_m; /* over the finite samples */
    double reached_s;       /* time of the last sample */
} rths_feedback_verdict;

/* Whether a feedback test diverged (docs/method.md, "Delayed-feedback stability": growth beyond
 * bounds or a limit trip), from the full-resolution trace (t_s, x_num_m, x_phys_m; n samples from
 * t = 0) of a run of requested_s at forcing_hz on assembly a. In order: a non-finite sample; a
 * safety limit tripped (limit_tripped); beyond_bounds set by the simulation or the run stopped
 * more than two forcing periods early; the unforced part at least doubled over the fitted span
 * and stands clear of the sensor noise (10 noise_m). A positive rate with less growth than that
 * is not called divergence (a short run of a stable test can show a transient rise, mode
 * beating) but gets a note. */
void rths_feedback_assess(const rths_assembly *a, const double *t_s, const double *x_num_m,
                          const double *x_phys_m, int n, double forcing_hz, double requested_s,
                          int limit_tripped, int beyond_bounds, double noise_m,
                          rths_feedback_verdict *out);

#endif
