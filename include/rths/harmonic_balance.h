/* rths harmonic balance (model module): the periodic response of M q'' + C q' + K q +
 * sum_e g_e b_e = static_force + force cos(w t) with nonlinear elements (nonlinear.h) as a
 * truncated Fourier series, the elements' forces by alternating frequency-time evaluation (AFT:
 * the series sampled at `samples` points per period, the forces evaluated there, transformed
 * back), Newton with the exact Jacobian of the truncated system (docs/method.md, "Harmonic
 * balance"). It is a truth at one frequency (its truncation checked by doubling the harmonics)
 * and, condensed onto the interface and the elements' DoFs, the frequency form's numerical
 * substructure (rths_hb_substructure below). */
#ifndef RTHS_HARMONIC_BALANCE_H
#define RTHS_HARMONIC_BALANCE_H

#include "rths/nonlinear.h"
#include "rths/signals.h"

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

/* ---- the frequency form's nonlinear numerical substructure (docs/method.md, "Nonlinear
 * elements in the frequency form") ----
 *
 * The numerical substructure of a split (1 to RTHS_MAX_INTERFACE_DOFS interface DoFs, order
 * (interface, numerical)) with its nonlinear elements, solved per call by harmonic balance with
 * AFT:
 *     M q'' + C q' + K q + sum_e g_e b_e = e_int F(t) + f amplitude cos(w t) + static_force,
 * F(t) the interface force whose harmonics 1..n_harmonics are given (above them 0). The DoFs no
 * element touches are condensed out exactly per harmonic (their dynamic stiffness' Schur
 * complement), so the Newton system holds the interface and the elements' DoFs only, with the
 * exact Jacobian of the condensed system (rths_hb_substructure_solve, _force and _eval take the
 * one-interface case; rths_hb_substructure_solve_dofs any). The interface's mean is prescribed (the
 * physical side's, as the grounding control makes the real-time form's follow it); the other DoFs'
 * means come from the static balance with static_force (an element's preload). Every solve starts
 * from the previous solution. */
typedef struct rths_hb_substructure rths_hb_substructure;

/* s: the split; count/el: every element of the setup in assembly DoFs, those
 * with numerical = 1 are taken (both DoFs on the numerical side or the ground); static_force (n,
 * assembly order, may be NULL): the preloads, taken on the numerical internal DoFs; forcing_dof:
 * the forcing's assembly DoF (taken when on the numerical side or the interface, as
 * rths_numerical_receptance does). opt: harmonics and AFT samples (NULL: rths_hb_defaults with
 * the harmonics raised to RTHS_HB_SUBSTRUCTURE_HARMONICS). RTHS_EINPUT for a split or element the
 * form cannot take, naming it. */
#define RTHS_HB_SUBSTRUCTURE_HARMONICS 25
#define RTHS_HB_SUBSTRUCTURE_SAMPLES 512
int rths_hb_substructure_create(const rths_split *s, int count, const rths_nl_element *el,
                                const double *static_force, int forcing_dof,
                                const rths_hb_options *opt, rths_hb_substructure **out,
                                rths_error *err);
void rths_hb_substructure_destroy(rths_hb_substructure *h);

/* The interface displacement's harmonics disp_a/disp_b[k], k = 1..n_harmonics (m; index 0 set to
 * mean_m), for the interface force's force_a/force_b[k] (N), the forcing's amplitude_n at
 * omega_rad_s and the interface mean mean_m. sensitivity (may be NULL): 2 n_harmonics x
 * 2 n_harmonics column-major, d(disp) / d(force) over (a_1..a_n, b_1..b_n), from the converged
 * Jacobian (to carry standard errors). RTHS_EFAIL when Newton does not converge. */
int rths_hb_substructure_solve(rths_hb_substructure *h, double omega_rad_s, double amplitude_n,
                               int n_harmonics, const double *force_a, const double *force_b,
                               double mean_m, double *disp_a, double *disp_b, double *sensitivity,
                               rths_error *err);

/* The other way round: the interface force harmonics force_a/force_b[k], k = 0..n_harmonics
 * (N; index 0 the mean force), the substructure needs to move its interface with the mean
 * disp_a[0] and the harmonics disp_a/disp_b[k], k = 1..n_harmonics (<= the object's harmonics),
 * free of force above them. This direction stays well posed where the force-driven one folds (a
 * resonance of the free substructure met by a harmonic: the bilinear example near its folds). */
int rths_hb_substructure_force(rths_hb_substructure *h, double omega_rad_s, double amplitude_n,
                               int n_harmonics, const double *disp_a, const double *disp_b,
                               double *force_a, double *force_b, rths_error *err);

/* The grounding control of the real-time form (docs/method.md, "Nonlinear elements in the
 * frequency form"): a spring kp_n_per_m[d] and a damper kd_n_s_per_m[d] from each interface DoF d
 * to a moving base, the physical interface's motion given to rths_hb_substructure_solve_dofs.
 * Replaces earlier gains; 0 removes them. */
int rths_hb_substructure_set_grounding(rths_hb_substructure *h, const double *kp_n_per_m,
                                       const double *kd_n_s_per_m, rths_error *err);

/* The numerical substructure as the real-time form runs it, on 1..RTHS_MAX_INTERFACE_DOFS
 * interface DoFs (the split's interface order): driven by the measured interface forces
 * force[d] (harmonics 1..RTHS_MAX_HARMONICS, N) and the grounding toward the physical interface
 * motion base[d] (m), its interfaces' means prescribed as base[d].a[0]; disp[d] its interface
 * motion (harmonics 0..RTHS_MAX_HARMONICS). Starts from the previous solution. RTHS_EFAIL when
 * Newton does not converge. */
int rths_hb_substructure_solve_dofs(rths_hb_substructure *h, double omega_rad_s, double amplitude_n,
                                    const rths_fourier *force, const rths_fourier *base,
                                    rths_fourier *disp, rths_error *err);

/* An rths_receptance_fn (iterate.h) with ctx the object: the receptance of the substructure's
 * linear part alone (elements removed). Passed to rths_frequency_problem_init, it tells the
 * frequency problem to convert every period through rths_hb_substructure_solve instead, with
 * all harmonics at once. */
int rths_hb_substructure_eval(void *ctx, double omega_rad_s, double complex *receptance_m_per_n,
                              double complex *forced_m_per_n, rths_error *err);

/* For run.log: "harmonic balance: H harmonics, N time samples per period, R DoFs kept
 * (interface + elements), C condensed" */
void rths_hb_substructure_describe(const rths_hb_substructure *h, char *buf, size_t size);
/* Newton steps of the last solve and in all. */
void rths_hb_substructure_counts(const rths_hb_substructure *h, int *last_newton, long *solves);

#endif
