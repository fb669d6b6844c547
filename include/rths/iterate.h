/* rths iterate: the zero problem over a rig and its Newton-Broyden corrector.
 *
 * Unknowns u = (A*_1..A*_N, B*_1..B*_N) — the control target's Fourier coefficients, metres — and,
 * for pseudo-arclength continuation, the forcing frequency. The residual is the interface mismatch
 * Phi = (A_k - alpha_k, B_k - beta_k), k = 1..N, of the physical (A, B) and numerical (alpha, beta)
 * interface displacements' coefficients measured in steady state. Static terms are discarded. */
#ifndef RTHS_ITERATE_H
#define RTHS_ITERATE_H

#include "rths/config.h"
#include "rths/rig.h"

#define RTHS_MAX_UNKNOWNS (2 * RTHS_MAX_HARMONICS + 1)
#define RTHS_LTI_HISTORY 12

/* How one evaluation waits for steady state and averages (SPEC §6). */
typedef struct rths_settle_options {
    int fixed_wait_periods; /* > 0: wait exactly this many periods (the seed's fixed wait) */
    int min_wait_periods;   /* adaptive: never judge steady before this many periods */
    int max_wait_periods;   /* adaptive: give up waiting (evaluation flagged not steady) */
    int average_periods;    /* whole periods averaged once steady */
    /* Adaptive steady state: the change of every coefficient between consecutive periods is below
     * max(abs_tolerance_m, rel_tolerance * coefficient scale, noise_factor * per-period noise). */
    double abs_tolerance_m;
    double rel_tolerance;
    double noise_factor;
} rths_settle_options;

typedef struct rths_evaluation {
    int harmonics;
    double frequency_hz;
    rths_fourier phys, num;       /* period-averaged coefficients, m */
    rths_fourier phys_se, num_se; /* standard errors of those means, m */
    double rig_time_s;            /* rig time this evaluation used (wait + average) */
    int wait_periods, average_periods;
    int steady; /* 1 when the steady-state test passed (or the fixed wait elapsed) */
} rths_evaluation;

/* Sets the forcing frequency (if it changed) and target, waits for steady state, averages. */
int rths_evaluate(rths_rig *rig, const rths_settle_options *opt, int harmonics, double frequency_hz,
                  double amplitude_n, const double *target_a, const double *target_b,
                  rths_evaluation *out, rths_error *err);

/* Residual Phi (length 2N: cos terms then sin terms) and its standard error per entry. */
void rths_evaluation_residual(const rths_evaluation *ev, double *phi, double *phi_se);

typedef struct rths_newton_options {
    int max_iterations;   /* corrector iterations (each: one evaluation + line search) */
    double rel_tolerance; /* ||Phi|| < max(rel * ||numerical coefficients||, abs, noise floor) */
    double abs_tolerance_m;
    double noise_factor;      /* tolerance floor = noise_factor * ||standard error of Phi|| */
    double fd_step_rel;       /* finite-difference step, relative to the coefficient scale */
    double fd_step_min_m;     /* ... but never below this (above the noise) */
    double fd_step_omega_rel; /* FD step of the frequency (pseudo-arclength), relative */
    double min_damping;       /* line search halves the step down to this factor */
    int fresh_jacobian;       /* 1: FD Jacobian at every corrector start (the seed's flowchart) */
    /* 1: report the physical interface response extrapolated to zero mismatch (see
     * rths_solution.matched_*); 0: report the last measurement, as the seed does */
    int report_matched;
} rths_newton_options;

/* The state the corrector carries between continuation points. */
typedef struct rths_corrector_state {
    int harmonics;
    int n; /* 2N unknown target coefficients */
    int have_jacobian;
    /* 1: the last finite-difference Jacobians (natural sweep) were of a linear time-invariant
     * rig's form, one complex gain per harmonic and no coupling between harmonics, within 5 %
     * plus what their noise explains. The gains are then refitted to the evaluation history after
     * every step (or, while the history cannot determine them, fixed by each secant pair), and
     * the Jacobians always keep that form. */
    int lti;
    /* dPhi/d(target, omega): 2N rows, 2N + 1 columns (last column: d/d omega, rad/s) */
    double jacobian[RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS];
    /* d(physical interface coefficients)/d(target, omega), same layout, estimated alongside */
    double response_jacobian[RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS];
    /* Per-period variance of each matched coefficient (physical, numerical side) pooled over
     * evaluations: the noise is additive, so every evaluation estimates the same variance, and
     * 4 periods alone give a standard error good to only +-40 %. Sums of squared deviations and
     * their degrees of freedom; each correction attempt halves the weight of the earlier ones. */
    double noise_ss[2][RTHS_MAX_UNKNOWNS];
    double noise_dof;
    /* Natural sweep: the latest evaluations (ring), from which an LTI rig's local model
     * Phi_k = g_k(w) z_k - f_k(w), x_k = r_k(w) z_k + e_k(w) (z_k = A*_k + i B*_k, g, f, r, e
     * linear in w) is fitted by least squares: every evaluation informs the gains, not only
     * secant pairs. Metres and rad/s; cos terms then sin terms. */
    int history_count, history_next;
    struct {
        double omega_rad_s;
        double target[2 * RTHS_MAX_HARMONICS], phi[2 * RTHS_MAX_HARMONICS],
            response[2 * RTHS_MAX_HARMONICS];
    } history[RTHS_LTI_HISTORY];
    int evaluations; /* counters for the current point */
    int iterations;
    double rig_time_s;
} rths_corrector_state;

/* Optional pseudo-arclength constraint: tangent . (scaled(u) - scaled(u_pred)) = 0 with
 * scaled(u) = (targets / amplitude_scale_m, omega / omega_scale_rad_s). */
typedef struct rths_arclength {
    int active;
    double tangent[RTHS_MAX_UNKNOWNS]; /* 2N + 1, in scaled variables */
    double predicted[RTHS_MAX_UNKNOWNS];
    double amplitude_scale_m;
    double omega_scale_rad_s;
} rths_arclength;

typedef struct rths_solution {
    int harmonics;
    double target_a[RTHS_MAX_HARMONICS], target_b[RTHS_MAX_HARMONICS]; /* m */
    double omega_rad_s;
    rths_evaluation eval; /* the measurement at the solution */
    double residual_norm_m;
    double tolerance_m;
    int converged;
    /* The physical interface response at zero mismatch, estimated by one linearised Newton step
     * from the accepted measurement: x* = x - R J^-1 Phi, with J = dPhi/d(target) and
     * R = d(physical coefficients)/d(target) from the corrector (on an arclength run the step
     * includes the frequency and the arclength row, so it runs normal to the branch and is well
     * posed at folds). The step is within tolerance, so its linearisation error is second order;
     * what remains is the measurement noise of x and Phi, propagated into
     * matched_amplitude_se_m. have_matched = 0 when no Jacobian exists, when without a fitted
     * LTI model the Jacobians were only carried from earlier points (not measured or updated at
     * this one), or when the step would exceed 50 times the mismatch. */
    int have_matched;
    double matched_a[RTHS_MAX_HARMONICS], matched_b[RTHS_MAX_HARMONICS]; /* m, harmonics 1..N */
    double matched_omega_rad_s;
    double matched_amplitude_m, matched_amplitude_se_m; /* fundamental */
    /* What a report shows: matched_* when the options ask for it and it exists, else the
     * measurement (frequency, fundamental amplitude and its averaging standard error). */
    double frequency_hz, amplitude_m, amplitude_se_m;
} rths_solution;

/* Solves Phi = 0 (with the arclength row when arc->active, else at fixed omega) from the initial
 * guess in *sol (targets and omega). On success sol holds the solution; state keeps the Jacobian
 * and the per-point counters (reset at entry). Returns RTHS_OK when converged, RTHS_EFAIL when not
 * (sol->converged = 0) or on a rig fault (err says which). */
int rths_correct(rths_rig *rig, const rths_settle_options *settle, const rths_newton_options *opt,
                 double amplitude_n, const rths_arclength *arc, rths_corrector_state *state,
                 rths_solution *sol, rths_error *err);

/* LTI rig on a natural sweep (state->lti): the target at omega predicted by the local model fitted
 * to the recorded evaluations, z_k = f_k / g_k, with the model's Jacobians written into the state
 * to seed the corrector. Returns 0, or -1 when the evaluations do not determine the model (fewer
 * than two frequencies or six evaluations, or a singular fit). */
int rths_corrector_lti_predict(rths_corrector_state *state, int harmonics, double omega_rad_s,
                               double *target_a, double *target_b);

/* Replaces the target columns of the state's Jacobians (2N x 2N, leading dimension
 * RTHS_MAX_UNKNOWNS) with a predictor's, projected onto the LTI form when the state is LTI. */
void rths_corrector_seed_jacobians(rths_corrector_state *state, const double *jacobian,
                                   const double *response_jacobian);

/* Defaults: the project's best ("default") and the seed's flowchart ("paper"). */
void rths_settle_defaults(rths_settle_options *opt, int paper);
void rths_newton_defaults(rths_newton_options *opt, int paper);

/* Reads `iteration.*` keys over the defaults already in the structs. */
int rths_iterate_config_read(rths_config *cfg, rths_settle_options *settle,
                             rths_newton_options *newton, int *harmonics, rths_error *err);

#endif
