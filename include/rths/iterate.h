/* rths iterate: the zero problem and its Newton-Broyden corrector (docs/method.md, "Iteration and
 * continuation").
 *
 * The zero problem (rths_zero_problem) maps n unknowns at a parameter omega to one residual record
 * per evaluation. On a rig (rths_rig_problem) the unknowns u = (A*_1..A*_N, B*_1..B*_N) are the
 * control target's Fourier coefficients, metres, the parameter is the forcing frequency (itself
 * an unknown for pseudo-arclength continuation), and the residual is the interface mismatch
 * Phi = (A_k - alpha_k, B_k - beta_k), k = 1..N, of the physical (A, B) and numerical (alpha,
 * beta) interface displacements' coefficients measured in steady state; static terms are
 * discarded. The corrector (rths_corrector) solves it; analytic problems serve its tests. */
#ifndef RTHS_ITERATE_H
#define RTHS_ITERATE_H

#include "rths/config.h"
#include "rths/rig.h"

#include <complex.h>

#define RTHS_MAX_UNKNOWNS (2 * RTHS_MAX_HARMONICS + 1)
/* Harmonics a test matches at the interface (iteration.harmonics, --harmonics): 1..3, the ones
 * frf.csv reports (interface_error_h2_m, _h3_m, amplitude_h2_m, _h3_m). */
#define RTHS_MAX_MATCHED_HARMONICS 3
#define RTHS_LTI_HISTORY 12

/* What the evaluations did since the caller last cleared it (rths_settle_options.tally): a
 * caller that clears it at the start of every point (rths frf) learns how the point's
 * evaluations reached steady state, and its max_rig_s_per_point then bounds the point. */
#define RTHS_SETTLE_REASON_LEN 256
typedef struct rths_settle_tally {
    int evaluations;
    int fitted;           /* the steady state from the transient fit (RTHS_SETTLE_FIT) */
    int fit_fallbacks;    /* the fit not trusted: the evaluation waited instead */
    int se_target_missed; /* stopped above target_rel_se: the rig time ran out */
    double rig_time_s;    /* their rig time, failed evaluations included */
    char fallback_reason[RTHS_SETTLE_REASON_LEN]; /* the last fallback's reason ("": none) */
} rths_settle_tally;

/* How one evaluation waits for steady state and averages (docs/method.md, "Iteration and
 * continuation"). */
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
    /* Integrity (docs/method.md, "One evaluation"): the share of an evaluation's controller
     * samples that may be late (0, the default: none). The caller that reads the controller's
     * configuration fills it from controller.max_overrun_share (rths_iterate_config_read does
     * not read controller keys: with --rig the controller process owns them). Any clipped demand or
     * saturated converter sample, or late samples beyond this share, make the evaluation
     * re-measure once; if the re-measurement is corrupted too, the evaluation fails. */
    double max_late_share;
    /* The periods a change of target or forcing spends in the controller's smooth transition
     * (controller.transition_periods, rounded up; filled like max_late_share by the caller that
     * reads the controller's configuration; 0: changes are at once). Those periods are no free
     * decay: the fit skips them, and the wait does not judge steady state within them. */
    int transition_periods;
    /* How an evaluation reaches the steady state (docs/method.md, "The fitted evaluation";
     * iteration.settle.strategy): RTHS_SETTLE_WAIT (0, the default) waits for the transient to
     * decay and averages; RTHS_SETTLE_FIT fits the periods since the change as steady state plus
     * decaying terms with shared poles and stops once the steady state's standard error is
     * within its goal, falling back to waiting when the fit is not trustworthy. */
    int strategy;
    int fit_max_periods; /* fit: periods fitted at most before falling back to waiting */
    /* fit: the least record fitted, in periods after the skipped first ones (0: 8); from 4 (the
     * plain mean's n + 3 residual degrees of freedom) the record's length is left to the fit's
     * standard error and its window check (iteration.settle.fit_min_periods) */
    int fit_min_periods;
    /* fit: the residual degrees of freedom each coefficient's series keeps beyond its decaying
     * terms, which bounds the order a record can fit (iteration.settle.fit_residual_margin,
     * 1..3; 0: the default 3) */
    int fit_residual_margin;
    /* fit: 1 lets a record too short for the window check (under 13 periods read) be compared
     * instead with a fit of the same record with the last trusted fit's poles held
     * (rths_noise_model.fit_seed_*; iteration.settle.fit_seed_poles, off by default) */
    int fit_seed_poles;
    /* Accuracy on demand (iteration.target_rel_se, iteration.max_rig_s_per_point): > 0, the
     * relative standard error of every interface DoF's fundamental amplitude, physical and
     * numerical side (the reported amplitude carries both), an
     * evaluation extends its averaging (wait) or its fitted record (fit) to reach, within at
     * most max_rig_s_per_point rig seconds; when the time runs out first the evaluation is
     * flagged (rths_evaluation.se_target_missed) and noted. With a tally (below) the seconds
     * are the point's: those the tally's evaluations spent count against it, so an evaluation
     * that starts with the point's budget spent waits for steady state only, and is flagged
     * when that does not meet the target; without one they are the evaluation's. 0: off. */
    double target_rel_se;
    double max_rig_s_per_point;
    /* Optional: receives one line per fallback or missed accuracy target (for run.log). */
    void (*note)(void *user, const char *line);
    void *note_user;
    /* Optional: every evaluation adds itself here (the caller clears it per point). */
    rths_settle_tally *tally;
} rths_settle_options;

enum { RTHS_SETTLE_WAIT = 0, RTHS_SETTLE_FIT = 1 };
/* Defaults where the options leave 0 (rths_settle_defaults zeroes them): the fit falls back to
 * waiting after 60 periods it cannot trust; accuracy on demand costs at most 120 rig s an
 * evaluation. */
#define RTHS_SETTLE_FIT_MAX_PERIODS 60
#define RTHS_SETTLE_FIT_MIN_PERIODS 8
#define RTHS_SETTLE_FIT_RESIDUAL_MARGIN 3
#define RTHS_SETTLE_MAX_RIG_S_PER_POINT 120.0

/* The host's noise model (docs/method.md, "One evaluation"): the period-to-period scatter of
 * every coefficient the steady-state test compares (physical and numerical, per interface DoF and
 * matched harmonic, in that order), measured from the averaged periods of the evaluations so far,
 * never from what the configuration or the rig declares. Stored as each coefficient's per-period
 * variance times the samples in the period (white noise scales as 1 / samples, so the model
 * carries across frequencies), pooled with its degrees of freedom. Zeroed: nothing measured yet. */
#define RTHS_NOISE_COEFFICIENTS (4 * RTHS_MAX_HARMONICS * RTHS_MAX_INTERFACE_DOFS)
typedef struct rths_noise_model {
    int coefficients; /* entries in use; 0: nothing measured yet */
    double variance_x_samples[RTHS_NOISE_COEFFICIENTS]; /* m^2 x samples per period */
    double dof; /* degrees of freedom of the pooled estimate */
    /* The last trusted fit's decaying terms (docs/method.md, "The fitted evaluation"): poles per
     * period at fit_seed_hz, fit_seed_order of them (0: none yet). A fitted evaluation whose
     * record is still too short for the window check compares its fit with one of the same
     * record with these poles held (rescaled to its own period). */
    int fit_seed_order;
    double fit_seed_hz;
    double fit_seed_z_re[8], fit_seed_z_im[8];
} rths_noise_model;

typedef struct rths_evaluation {
    int harmonics;
    double frequency_hz;
    rths_fourier phys, num;       /* period-averaged coefficients, m */
    rths_fourier phys_se, num_se; /* standard errors of those means, m */
    double rig_time_s;            /* rig time this evaluation used (wait + average) */
    int wait_periods, average_periods;
    int steady; /* 1 when the steady-state test passed (or the fixed wait elapsed) */
    /* every interface DoF of a rig that drives several (interface_dofs > 1; d = 0 repeats phys,
       num and their standard errors); 0 or 1: phys and num alone */
    int interface_dofs;
    rths_fourier phys_dof[RTHS_MAX_INTERFACE_DOFS], num_dof[RTHS_MAX_INTERFACE_DOFS];
    rths_fourier phys_dof_se[RTHS_MAX_INTERFACE_DOFS], num_dof_se[RTHS_MAX_INTERFACE_DOFS];
    /* output.dofs (rths_period.output_dof): every listed DoF's period-averaged coefficients and
       their standard errors, m (rad for a rotation), in the list's order; 0: none */
    int output_dofs;
    rths_fourier output_dof[RTHS_MAX_OUTPUT_DOFS], output_dof_se[RTHS_MAX_OUTPUT_DOFS];
    /* the periods' integrity counts (rths_period) summed over every period this evaluation
     * read, waiting and averaging, and the controller samples those periods held */
    long late_samples, clipped_demand_samples, saturated_sensor_samples, samples_read;
    /* 1: the first measurement held clipped, saturated or too many late samples, so the
     * evaluation waited for steady state again and measured again (the counts above hold both) */
    int remeasured;
    /* 1: the re-measurement was corrupted too and the evaluation failed (its error names the
     * counts); the corrector then stops with RTHS_CORRECTOR_REFUSED */
    int refused;
    /* the fitted evaluation (rths_settle_options.strategy RTHS_SETTLE_FIT): 1 when the steady
     * state is the fit's (average_periods then holds the periods' worth of averaging its standard
     * error equals, wait_periods the rest); fit_fallback 1 when the fit was not trustworthy and
     * the evaluation waited instead; the fit's order (decaying terms) and largest pole modulus
     * per period */
    int fitted, fit_fallback, fit_order;
    double fit_max_pole;
    /* accuracy on demand: the largest relative standard error of an interface DoF's
     * fundamental amplitude (either side), and 1 when it stayed above target_rel_se within
     * max_rig_s_per_point. In a converged solution of a problem with settle options and a
     * target (rths_zero_problem.settle), both are the REPORTED amplitude's instead: its largest
     * relative standard error over the interface DoFs, and 1 when that stayed above the target
     * within the point's budget (docs/method.md, "Accuracy on demand") */
    double amplitude_rel_se;
    int se_target_missed;
} rths_evaluation;

/* Sets the forcing frequency (if it changed) and target, waits for steady state, averages. */
int rths_evaluate(rths_rig *rig, const rths_settle_options *opt, int harmonics, double frequency_hz,
                  double amplitude_n, const double *target_a, const double *target_b,
                  rths_evaluation *out, rths_error *err);

/* The same for `dofs` interface DoFs (the rig's rths_rig_interface_dofs), DoF d's target at
 * target_a[d * harmonics + k - 1], target_b[...]; dofs 1 is rths_evaluate. Without a noise model
 * carried in (these two), the steady-state test knows no noise until it has averaged: noise
 * larger than the relative tolerance then makes it wait up to max_wait_periods. */
int rths_evaluate_dofs(rths_rig *rig, const rths_settle_options *opt, int harmonics, int dofs,
                       double frequency_hz, double amplitude_n, const double *target_a,
                       const double *target_b, rths_evaluation *out, rths_error *err);
/* The same with the caller's noise model (may be NULL): the steady-state test judges changes
 * against it, and a clean evaluation's averaged periods join it. The rig-backed zero problem
 * carries one across its evaluations. */
int rths_evaluate_noise(rths_rig *rig, const rths_settle_options *opt, rths_noise_model *noise,
                        int harmonics, int dofs, double frequency_hz, double amplitude_n,
                        const double *target_a, const double *target_b, rths_evaluation *out,
                        rths_error *err);

/* Residual Phi (length 2N: cos terms then sin terms) and its standard error per entry. With
 * several interface DoFs, one such block of 2N per DoF in the interface order. */
void rths_evaluation_residual(const rths_evaluation *ev, double *phi, double *phi_se);

struct rths_evaluation_event; /* below */

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
    /* rig safety: a step never exceeds step_limit times the larger of the current unknowns and
     * the reference (the numerical response) in scaled units; 0: no limit */
    double step_limit;
    /* Trust region of the targets along a branch (docs/method.md, "Iteration and continuation"):
     * once the continuation has set an anchor (the last accepted point's size times its last
     * growth, rths_corrector_set_trust_anchor), no target sent to the rig exceeds trust_growth
     * times it; a corrector step that would is shortened onto the boundary, and the radius
     * doubles only after such a step reduced the residual as its model said. 0: no trust region */
    double trust_growth;
    /* 1: the caller knows the rig to be linear time-invariant (a linear structure on the virtual
     * rig), so the LTI form and its fitted model (see the corrector) also serve pseudo-arclength
     * runs, whose frequency unknown otherwise keeps the corrector from looking for it; 0: only
     * natural sweeps test for it */
    int rig_lti;
    /* The signal-to-noise floor (docs/method.md, "One evaluation"): a converged point is accepted
     * only if some interface DoF's fundamental response amplitude is at least min_snr times the
     * measured standard error of its mismatch (per coefficient); 0: no floor. Below it the
     * corrector stops with RTHS_CORRECTOR_BELOW_NOISE, unless accept_below_noise (--force), which
     * accepts the point and flags it (rths_solution.below_noise_floor). */
    double min_snr;
    int accept_below_noise;
    /* 1: a pseudo-arclength run predicts the next point on the quadratic through the last three
     * points (chord-length parametrised) instead of the secant (docs/method.md, "The fitted
     * evaluation": fewer corrector steps per point); iteration.quadratic_predictor, off by
     * default */
    int quadratic_predictor;
    /* 1: when the full Newton step from a carried (secant-updated or modelled) Jacobian makes the
     * residual worse at a point within 50 tolerances of the solution, its trial updates the
     * Jacobian along the step (Broyden, as an accepted step does) and the step is computed again,
     * once per correction, instead of halving it and then measuring a fresh finite-difference
     * Jacobian (docs/method.md, "The corrector"). 6-16 % less rig time on the bilinear and
     * Duffing examples, but on the Duffing fewer points within 3 standard errors (the carried
     * Jacobian the reported amplitudes are extrapolated through is no longer refreshed), so
     * iteration.secant_repair is off by default */
    int secant_repair;
    /* Optional: called after every evaluation the corrector makes (failed corrections, line-search
     * trials and finite-difference columns included) with what it was for and what it measured;
     * rths frf writes each to evaluations.csv (docs/method.md, "Outputs"). NULL: none. */
    void (*on_evaluation)(void *user, const struct rths_evaluation_event *event);
    void *on_evaluation_user;
} rths_newton_options;

/* What an evaluation was for, in the corrector's order of business. */
typedef enum rths_evaluation_role {
    RTHS_EVALUATION_PREDICTION = 0,   /* a correction's first evaluation: the predicted point */
    RTHS_EVALUATION_JACOBIAN = 1,     /* a finite-difference column of the Jacobian */
    RTHS_EVALUATION_STEP = 2,         /* a full Newton step */
    RTHS_EVALUATION_DAMPED_STEP = 3,  /* a line search's shortened step */
    RTHS_EVALUATION_GAIN_PROBE = 4,   /* the matched estimate's measurement of the local gain */
    RTHS_EVALUATION_ACCURACY_STEP = 5 /* a further step for iteration.target_rel_se */
} rths_evaluation_role;

/* "prediction", "jacobian", "step", "damped_step", "gain_probe", "accuracy_step" */
const char *rths_evaluation_role_name(rths_evaluation_role role);

/* One evaluation as rths_newton_options.on_evaluation reports it. */
typedef struct rths_evaluation_event {
    rths_evaluation_role role;
    int iteration;  /* the correction's Newton iterations so far */
    double damping; /* the line search's step fraction (1: the full step); 0 for other roles */
    double frequency_hz;
    /* 1: the rig's measurement was corrupted twice and refused (rths_evaluation.refused): the
     * mismatch fields are NaN */
    int refused;
    double mismatch_m;            /* ||Phi|| over every entry, m (rad for a rotation) */
    double tolerance_m;           /* the corrector's tolerance of it, m */
    double mismatch_to_tolerance; /* the largest ratio over the interface DoFs */
    int within_tolerance;         /* every interface DoF's mismatch below its tolerance */
    double rig_time_s;            /* the rig time it used, as the corrector counts it */
    /* how the evaluation reached steady state: periods waited and averaged, the steady-state
     * test passed, a fitted steady state, a fit that fell back to waiting */
    const rths_evaluation *evaluation;
} rths_evaluation_event;

/* ---- the zero problem: Phi(u; omega) = 0 ----
 *
 * n unknowns u (metres: for a hybrid test the target's Fourier coefficients, cos terms then sin
 * terms) at a parameter omega (rad/s, the forcing frequency). One evaluation gives one residual
 * record, computed once and handed on: the corrector, the continuation and the report all read
 * Phi, the response and their standard errors from it. */
typedef struct rths_residual {
    int n;
    double phi[RTHS_MAX_UNKNOWNS], phi_se[RTHS_MAX_UNKNOWNS]; /* Phi and its standard error, m */
    /* Phi = response - reference: the physical interface response (what the report shows) and
     * the numerical side it must match, with their standard errors, m */
    double response[RTHS_MAX_UNKNOWNS], response_se[RTHS_MAX_UNKNOWNS];
    double reference[RTHS_MAX_UNKNOWNS], reference_se[RTHS_MAX_UNKNOWNS];
    double rig_time_s; /* rig time the evaluation used (also when it failed) */
    /* independent samples averaged into each mean (periods); > 1: the standard errors are
     * sample estimates the corrector may pool across evaluations */
    int samples;
    rths_evaluation eval; /* the measurement behind the record (rig-backed problems; else zero) */
} rths_residual;

/* Evaluates Phi at u (n entries, metres) and omega into *out (all of it). Returns RTHS_OK, or an
 * error code with err set (a rig fault, a non-physical request). */
typedef int (*rths_zero_eval_fn)(void *ctx, const double *u, double omega_rad_s, rths_residual *out,
                                 rths_error *err);

typedef struct rths_zero_problem {
    int n; /* unknowns = residual entries, 1..2 * RTHS_MAX_HARMONICS */
    /* > 0: n = 2 * harmonics Fourier coefficients (cos terms, then sin terms), which lets the
     * corrector recognise a linear time-invariant map; 0: unknowns without that structure */
    int harmonics;
    rths_zero_eval_fn eval;
    void *ctx;
    /* 1: the Fourier pairs are coupled in ways the corrector cannot model, so the LTI form never
       applies: it keeps finite-difference and Broyden Jacobians */
    int coupled;
    /* > 1: the pairs belong to this many interface DoFs, N = harmonics / interface_dofs each,
       pair d N + k for DoF d's harmonic k + 1 (rths_rig_problem_init_dofs). On a linear rig the
       gain of harmonic k is then a complex n x n matrix (every DoF's response to every DoF's
       target), which the LTI form and the residual-model predictor fit; the solution reports
       every DoF's amplitude and standard error. 0 or 1: one DoF */
    int interface_dofs;
    /* Accuracy on demand (docs/method.md, "Accuracy on demand"): the settle options the
     * evaluations use (rig-backed problems; NULL: none). With their target_rel_se > 0 a converged
     * point whose REPORTED amplitude's relative standard error (any interface DoF) is above it
     * takes further corrector steps (the mismatch's term) or longer records (the noise's) while
     * the point's max_rig_s_per_point (their tally's rig time) lasts, and is flagged
     * (rths_evaluation.se_target_missed of its solution) when it still is. */
    const rths_settle_options *settle;
    /* Where the corrector tightens the evaluations' own target_rel_se for the noise's term (the
     * rig problem's override; NULL: it cannot, and only steps) */
    double *evaluation_target_rel_se;
} rths_zero_problem;

/* The rig-backed zero problem of a hybrid test: set the forcing and the target, wait for steady
 * state, average (rths_evaluate); Phi = physical - numerical interface coefficients. */
typedef struct rths_rig_problem {
    rths_rig *rig;
    const rths_settle_options *settle;
    int harmonics;
    double amplitude_n;
    int interface_dofs;     /* 1, or several: 2 N unknowns per DoF, DoF by DoF */
    rths_noise_model noise; /* measured by its evaluations, carried across them */
    /* > 0: the evaluations' target_rel_se instead of settle's (the corrector sets it while a
     * point's reported amplitude needs a smaller noise; docs/method.md, "Accuracy on demand") */
    double target_rel_se;
} rths_rig_problem;

/* Fills *problem to evaluate through *ctx (which must outlive it). */
void rths_rig_problem_init(rths_zero_problem *problem, rths_rig_problem *ctx, rths_rig *rig,
                           const rths_settle_options *settle, int harmonics, double amplitude_n);
/* The same over every interface DoF of the rig (rths_rig_interface_dofs = n): 2 N n unknowns,
 * the cos terms of every (DoF d, harmonic k) pair at j = d N + k - 1, then the sin terms at
 * N n + j, and the residual, response and reference likewise; the problem's harmonics is N n
 * (so a solution's target_a[j], matched_a[j] carry every DoF, its amplitude the first DoF's
 * fundamental, dof_amplitude_m[d] DoF d's) and interface_dofs is n: on a linear rig the LTI form
 * holds n x n complex gains per harmonic. RTHS_EINPUT when 2 N n exceeds 2 RTHS_MAX_HARMONICS. */
int rths_rig_problem_init_dofs(rths_zero_problem *problem, rths_rig_problem *ctx, rths_rig *rig,
                               const rths_settle_options *settle, int harmonics, double amplitude_n,
                               rths_error *err);

/* The host-side numerical substructure (split.numerical_solver: frequency; docs/method.md,
 * "Numerical substructure integration"): the controller drives the physical interface to the
 * target and its `num` channel carries the force F on the numerical substructure's interface
 * (N); the host turns that force's harmonics into the numerical interface displacement through
 * the linear substructure's dynamic stiffness, exactly, at any size:
 *     alpha_k - i beta_k = H(k w) (Fa_k - i Fb_k) + [k = 1] X_forced(w) amplitude,
 * with H the interface receptance (m/N) and X_forced the interface displacement under the forcing
 * on the numerical side per newton of forcing amplitude (0 when the forcing is physical). The
 * residual is the interface mismatch as on the real-time form. */
typedef int (*rths_receptance_fn)(void *ctx, double omega_rad_s, double complex *receptance_m_per_n,
                                  double complex *forced_m_per_n, rths_error *err);

typedef struct rths_frequency_problem {
    rths_rig *rig;          /* the hybrid rig: its `num` channel carries the interface force, N */
    rths_rig *view;         /* the same rig with every period's `num` turned into displacement, m */
    rths_rig_problem inner; /* the rig-backed problem on the view: settling, averaging and
                               standard errors all in metres, as on the real-time form */
    double amplitude_n;
    rths_receptance_fn receptance;
    void *receptance_ctx;
} rths_frequency_problem;

/* Fills *problem to evaluate through *ctx (which must outlive it); release with
 * rths_frequency_problem_release. RTHS_EFAIL when out of memory. */
int rths_frequency_problem_init(rths_zero_problem *problem, rths_frequency_problem *ctx,
                                rths_rig *rig, const rths_settle_options *settle, int harmonics,
                                double amplitude_n, rths_receptance_fn receptance,
                                void *receptance_ctx, rths_error *err);
void rths_frequency_problem_release(rths_frequency_problem *ctx);
/* The conversion above on an averaged evaluation: `num` (force coefficients, N, and their
 * standard errors) becomes the numerical interface displacement, m; the static term follows the
 * physical side's. */
int rths_frequency_evaluation_convert(rths_evaluation *ev, double amplitude_n,
                                      rths_receptance_fn receptance, void *receptance_ctx,
                                      rths_error *err);
/* The same on one record's coefficients at frequency_hz (num_se and phys_se may be NULL). */
int rths_frequency_convert(rths_fourier *num, rths_fourier *num_se, const rths_fourier *phys,
                           const rths_fourier *phys_se, double frequency_hz, double amplitude_n,
                           rths_receptance_fn receptance, void *receptance_ctx, rths_error *err);

/* The residual record of a measurement (Phi, response and reference in the corrector's order). */
void rths_residual_from_evaluation(const rths_evaluation *ev, rths_residual *out);

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
    /* Euclidean norm of Phi over every entry, m (it adds radians to metres when an interface DoF
     * is a rotation: residual_rel and residual_to_tolerance are the unit-consistent measures) */
    double residual_norm_m;
    /* sqrt of the sum over interface DoFs of each DoF's tolerance squared, each
     * max(rel_tolerance x its numerical response, abs_tolerance_m, noise_factor x its mismatch's
     * standard error) in the DoF's own unit (m, or rad for a rotation); one DoF: its tolerance */
    double tolerance_m;
    /* the largest over interface DoFs of ||Phi_d|| / ||numerical response_d|| (dimensionless) */
    double residual_rel;
    /* the largest over interface DoFs of ||Phi_d|| / tolerance_d: < 1 for every accepted point */
    double residual_to_tolerance;
    int converged;
    /* Signal-to-noise floor (rths_newton_options.min_snr), set once within tolerance: the
     * largest over interface DoFs of the fundamental response amplitude over its mismatch's
     * measured standard error (INFINITY without noise), that DoF (0-based), its amplitude and
     * min_snr times the error (the floor), in its own unit; below_noise_floor = 1 when the point
     * was accepted below the floor (accept_below_noise). */
    double snr;
    int snr_dof;
    double snr_amplitude_m, noise_floor_m;
    int below_noise_floor;
    /* The physical interface response at zero mismatch, estimated by one linearised Newton step
     * from the accepted measurement: x* = x - R J^-1 Phi, with J = dPhi/d(target) and
     * R = d(physical coefficients)/d(target) from the corrector (on an arclength run the step
     * includes the frequency and the arclength row, so it runs normal to the branch and is well
     * posed at folds; with a fitted LTI model it stays at the measured frequency unless that step
     * is three times longer). matched_amplitude_se_m holds every known source: the noise (the
     * periods' scatter, or the evaluations' scatter about a fitted LTI model if larger), the
     * uncertainty of the sensitivity times the mismatch (a fitted model's scatter, else the whole
     * step), and a frequency move's effect at the point's frequency (branch slope times the
     * move). have_matched = 0 when no Jacobian exists, or without a fitted LTI model when the
     * step would exceed 50 times the mismatch. */
    int have_matched;
    double matched_a[RTHS_MAX_HARMONICS], matched_b[RTHS_MAX_HARMONICS]; /* m, harmonics 1..N */
    double matched_omega_rad_s;
    double matched_amplitude_m, matched_amplitude_se_m; /* fundamental */
    /* What a report shows: matched_* when the options ask for it and it exists, else the
     * measurement (frequency, fundamental amplitude and its averaging standard error). */
    double frequency_hz, amplitude_m, amplitude_se_m;
    /* 1: amplitude_se_m includes every known source (noise, the remaining mismatch times the
     * response's sensitivity to it, the uncertainty of that sensitivity); 0: no trusted Jacobian
     * gave the sensitivity, and amplitude_se_m covers the noise alone (a lower bound) */
    int amplitude_se_honest;
    /* Several interface DoFs (rths_zero_problem.interface_dofs = n > 1; else 0): DoF d's reported
     * fundamental amplitude and its standard error, as amplitude_m and amplitude_se_m are the
     * first DoF's (d = 0 repeats them): the matched estimate with every known source when the
     * options ask for it and it exists, else the measurement. */
    int interface_dofs;
    double dof_amplitude_m[RTHS_MAX_INTERFACE_DOFS], dof_amplitude_se_m[RTHS_MAX_INTERFACE_DOFS];
} rths_solution;

/* ---- the corrector: Newton-Broyden with line search, an opaque object ----
 *
 * Life cycle (as GSL's gsl_multiroot_fsolver or KINSOL): create for a zero problem, set() at an
 * initial guess (one evaluation, perhaps a finite-difference Jacobian), iterate() one Newton step
 * (with its line search) while status() is RTHS_CORRECTOR_CONTINUE, read solution(); save() and
 * load() carry what it learnt (Jacobians, pooled noise, evaluation history) across processes; the
 * same object carries it from one continuation point to the next. */
typedef struct rths_corrector rths_corrector;

typedef enum {
    RTHS_CORRECTOR_CONTINUE = 0,  /* not converged yet: iterate again */
    RTHS_CORRECTOR_CONVERGED = 1, /* ||Phi|| below tolerance (and the arclength row satisfied) */
    RTHS_CORRECTOR_STUCK = 2,     /* a fresh Jacobian's step could not reduce the residual */
    RTHS_CORRECTOR_MAX_ITER = 3,  /* max_iterations used up */
    RTHS_CORRECTOR_SINGULAR = 4,  /* a freshly measured Jacobian is singular */
    /* the converged point's response is not clearly above the measured noise (min_snr): the
       run must stop (exit 1) with rths_corrector_solve's message, which names both numbers */
    RTHS_CORRECTOR_BELOW_NOISE = 5,
    /* an evaluation was corrupted twice (clipped demand, saturated converter, late samples;
       rths_evaluation.refused): the run must stop with the evaluation's message */
    RTHS_CORRECTOR_REFUSED = 6
} rths_corrector_outcome;

/* What save() gives: a versioned flat record (layout in docs/journal.md, "Corrector state").
 * Callers store it and hand it back to load(); they need not know the layout. length 0: nothing
 * learnt yet (a zeroed record is valid). */
#define RTHS_CORRECTOR_SAVED_FORMAT 1
#define RTHS_CORRECTOR_SAVED_MAX                                                                   \
    (4 + 2 * RTHS_MAX_UNKNOWNS * RTHS_MAX_UNKNOWNS + 2 * RTHS_MAX_UNKNOWNS + 3 +                   \
     RTHS_LTI_HISTORY * (1 + 6 * RTHS_MAX_HARMONICS))
typedef struct rths_corrector_saved {
    int format; /* RTHS_CORRECTOR_SAVED_FORMAT */
    int length; /* entries of data in use */
    double data[RTHS_CORRECTOR_SAVED_MAX];
} rths_corrector_saved;

int rths_corrector_create(const rths_zero_problem *problem, const rths_newton_options *opt,
                          rths_corrector **out, rths_error *err);
void rths_corrector_destroy(rths_corrector *c);

/* Scaling of the unknowns when no arclength constraint gives one (defaults 1e-4 m, 1 rad/s): the
 * finite-difference steps, the step limit and the line search work in u / amplitude_scale_m. */
void rths_corrector_set_scales(rths_corrector *c, double amplitude_scale_m,
                               double omega_scale_rad_s);
/* The amplitude scale changes from old to new: the carried Jacobians' frequency columns follow. */
void rths_corrector_rescale_amplitude(rths_corrector *c, double old_scale_m, double new_scale_m);

/* Starts a correction at u0 (n entries, m) and omega (with the arclength row when arc->active;
 * arc's positive scales override the corrector's). Resets the per-correction counters, evaluates
 * once, measures a Jacobian when none is carried (or opt->fresh_jacobian). Returns RTHS_OK or the
 * problem's error. */
int rths_corrector_set(rths_corrector *c, const double *u0, double omega_rad_s,
                       const rths_arclength *arc, rths_error *err);
/* One Newton step: solve, limit, line search, Broyden (or LTI) update. Returns RTHS_OK (see
 * status) or the problem's error. */
int rths_corrector_iterate(rths_corrector *c, rths_error *err);
rths_corrector_outcome rths_corrector_status(const rths_corrector *c);
/* The last accepted iterate: targets, omega, its measurement, residual and tolerance; once
 * converged also the matched estimate and the reported amplitude (see rths_solution). */
const rths_solution *rths_corrector_solution(const rths_corrector *c);
/* The last accepted iterate's unknowns (n entries, m) and its residual record. */
void rths_corrector_unknowns(const rths_corrector *c, double *u);
const rths_residual *rths_corrector_residual(const rths_corrector *c);
/* Evaluations, iterations and rig time of the current correction. */
void rths_corrector_counters(const rths_corrector *c, int *evaluations, int *iterations,
                             double *rig_time_s);
/* Set + iterate until done. RTHS_OK when converged; RTHS_EFAIL with the reason otherwise. */
int rths_corrector_solve(rths_corrector *c, const double *u0, double omega_rad_s,
                         const rths_arclength *arc, rths_error *err);
/* The integrity counts of every evaluation of the current correction summed (rths_evaluation:
 * late, clipped-demand and saturated-sensor samples, samples read, evaluations that were
 * re-measured and that were refused), refused ones and line-search trials included: what a run
 * log and summary report per point. Any pointer may be NULL. */
void rths_corrector_integrity(const rths_corrector *c, long *late_samples,
                              long *clipped_demand_samples, long *saturated_sensor_samples,
                              long *samples_read, int *remeasured, int *refused);
/* Drops the carried Jacobians: the next set() measures fresh ones. */
void rths_corrector_forget_jacobian(rths_corrector *c);

/* The trust region's anchor for the next corrections, metres: on a continuation run the Euclidean
 * size of the last accepted point's target coefficients (or of its measured physical response if
 * larger), times its growth from the point before when it grew; 0 (the default) lifts the trust
 * region (the first point of a branch has nothing to anchor it). */
void rths_corrector_set_trust_anchor(rths_corrector *c, double anchor_m);
/* 1 when targets u (metres, n unknowns) lie inside the trust region a new correction starts with
 * (trust_growth times the anchor), else 0. */
int rths_corrector_trust_allows(const rths_corrector *c, const double *u_m);
/* 1 when the corrector's options ask for the quadratic arclength predictor
 * (rths_newton_options.quadratic_predictor). */
int rths_corrector_quadratic_predictor(const rths_corrector *c);
/* How often the trust region acted during the last correction: a starting target shrunk onto it,
 * or a corrector step shortened onto it. */
int rths_corrector_trust_actions(const rths_corrector *c);

void rths_corrector_save(const rths_corrector *c, rths_corrector_saved *out);
/* Restores what save() gave (same problem size); RTHS_EINPUT naming the formats otherwise. */
int rths_corrector_load(rths_corrector *c, const rths_corrector_saved *in, rths_error *err);
/* The Jacobians inside a saved record (n x n target block, leading dimension RTHS_MAX_UNKNOWNS):
 * 1 when it holds some, else 0. */
int rths_corrector_saved_jacobians(const rths_corrector_saved *in, double *jacobian,
                                   double *response_jacobian);

/* Residual-model predictor on an LTI rig (natural sweep): the target at omega from the local
 * model fitted to the recorded evaluations, z_k = f_k / g_k (with n interface DoFs z_k = G_k^-1
 * f_k, G_k the complex n x n gain of harmonic k), with the model's Jacobians seeding the corrector.
 * Returns 0, or -1 when the evaluations do not determine the model (fewer than two frequencies or
 * 2 n + 4 evaluations, or an ill-conditioned fit) or the rig is not LTI-like; -2 when the
 * predicted target lies outside the trust region (rths_corrector_trust_allows). u and the
 * Jacobians are left as they were unless it returns 0. */
int rths_corrector_lti_predict(rths_corrector *c, double omega_rad_s, double *u);

/* Replaces the target columns of the carried Jacobians (n x n, leading dimension
 * RTHS_MAX_UNKNOWNS) with a predictor's, projected onto the LTI form when the rig is LTI-like;
 * ignored while no Jacobian is carried. */
void rths_corrector_seed_jacobians(rths_corrector *c, const double *jacobian,
                                   const double *response_jacobian);

/* Convenience for one correction on a rig (the older interface): state is a saved record (zeroed
 * on first use) carried between calls; *sol holds the initial guess (harmonics, targets, omega)
 * and receives the solution. Returns RTHS_OK when converged, RTHS_EFAIL otherwise. */
typedef rths_corrector_saved rths_corrector_state;
int rths_correct(rths_rig *rig, const rths_settle_options *settle, const rths_newton_options *opt,
                 double amplitude_n, const rths_arclength *arc, rths_corrector_state *state,
                 rths_solution *sol, rths_error *err);

/* Defaults: the project's best ("default") and the seed's flowchart ("paper"). */
void rths_settle_defaults(rths_settle_options *opt, int paper);
void rths_newton_defaults(rths_newton_options *opt, int paper);

/* Reads `iteration.*` keys over the defaults already in the structs. */
int rths_iterate_config_read(rths_config *cfg, rths_settle_options *settle,
                             rths_newton_options *newton, int *harmonics, rths_error *err);

#endif
