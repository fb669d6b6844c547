/* The corrector's private state, shared by the files of src/iterate (not installed). */
#ifndef RTHS_ITERATE_CORRECTOR_INTERNAL_H
#define RTHS_ITERATE_CORRECTOR_INTERNAL_H

#include "rths/iterate.h"

#include <complex.h>
#include <math.h>

enum {
    LD = RTHS_MAX_UNKNOWNS,
    HISTORY_WIDTH = 2 * RTHS_MAX_HARMONICS,
    DOF_MAX = RTHS_MAX_INTERFACE_DOFS,
    LTI_TERMS = 2 /* each gain and offset of the local LTI model is a line in omega */
};

/* What the corrector learns and carries from one correction (and continuation point) to the
 * next; save() writes exactly this. */
typedef struct corrector_memory {
    int have_jacobian;
    /* 1: the last finite-difference Jacobians (natural sweep) were of a linear time-invariant
     * rig's form, one complex gain per harmonic (an n x n complex matrix with n interface DoFs)
     * and no coupling between harmonics, within 5 %
     * plus what their noise explains. The gains are then refitted to the evaluation history after
     * every step (or, while the history cannot determine them, fixed by each secant pair), and
     * the Jacobians always keep that form. */
    int lti;
    /* dPhi/d(u, omega) in scaled variables: n rows, n + 1 columns (last: d/d omega) */
    double jacobian[LD * LD];
    /* d(response)/d(u, omega), same layout, estimated alongside */
    double response_jacobian[LD * LD];
    /* Per-sample variance of each residual entry's two sides (response, reference) pooled over
     * evaluations: the noise is additive, so every evaluation estimates the same variance, and
     * 4 periods alone give a standard error good to only +-40 %. Sums of squared deviations and
     * their degrees of freedom; each correction halves the weight of the earlier ones. */
    double noise_ss[2][LD];
    double noise_dof;
    /* Natural sweep: the latest evaluations (ring), from which an LTI rig's local model
     * Phi_k = g_k(w) z_k - f_k(w), x_k = r_k(w) z_k + e_k(w) (z_k = A*_k + i B*_k, g, f, r, e
     * linear in w) is fitted by least squares: every evaluation informs the gains, not only
     * secant pairs. Metres and rad/s; cos terms then sin terms. */
    int history_count, history_next;
    struct {
        double omega_rad_s;
        double target[HISTORY_WIDTH], phi[HISTORY_WIDTH], response[HISTORY_WIDTH];
    } history[RTHS_LTI_HISTORY];
} corrector_memory;

/* One iterate: scaled unknowns (and omega), the scaled residual (with the arclength row) and
 * response, the extended residual norm, its record and the solution view of it. */
typedef struct corrector_point {
    double u[LD], phi[LD], resp[LD], ext;
    int within; /* every interface DoF's mismatch below its tolerance (evaluate.c, describe) */
    rths_residual rec;
    rths_solution sol;
} corrector_point;

struct rths_corrector {
    rths_zero_problem problem;
    rths_newton_options opt;
    int n;         /* unknowns */
    int harmonics; /* problem->harmonics (0: no Fourier structure): Fourier pairs, N per DoF */
    int dofs;      /* interface DoFs sharing the pairs (1: one) */
    int m;         /* n, or n + 1 with the arclength row */
    double default_amp_scale, default_omega_scale;
    double scale[LD];
    rths_arclength arc;
    corrector_memory mem;
    /* the current correction */
    int evaluations, iterations;
    double rig_time_s;
    int jacobian_here; /* the Jacobians were measured or secant-updated at this point */
    int fresh;         /* the Jacobians were just measured */
    int repaired;      /* a failed full step's secant updated the Jacobians (secant_repair) */
    rths_corrector_outcome status;
    int refused;        /* the last evaluation failed as refused (rths_evaluation.refused) */
    int refused_trials; /* line-search trials set aside this correction for being refused */
    /* this correction's evaluations' integrity counts, summed (rths_corrector_integrity) */
    long late_samples, clipped_samples, saturated_samples, samples_read;
    int remeasured, refused_evaluations;
    corrector_point cur;
    /* trust region of the targets: the anchor (m), this correction's radius (scaled units,
     * INFINITY without an anchor) and how often it acted */
    double trust_anchor_m, trust_radius;
    int trust_actions;
    /* the reported amplitude's standard error of every interface DoF split in two (matched.c,
     * corrector_finish): the noise, and the step to zero mismatch (the mismatch times the
     * sensitivity's uncertainty, a frequency move's effect), m; iteration.target_rel_se acts on
     * the larger (docs/method.md, "Accuracy on demand") */
    double se_noise_m[DOF_MAX], se_step_m[DOF_MAX];
};

/* evaluate.c */
/* role and damping (a step's fraction of the Newton step, 0 for the other roles) say what the
 * evaluation was for, as rths_newton_options.on_evaluation reports it */
int corrector_evaluate(rths_corrector *c, const double *u, corrector_point *p,
                       rths_evaluation_role role, double damping, rths_error *err);

/* lti.c: the LTI rig's complex-gain form and its local model (one interface DoF: P = N pairs) */
void lti_pair_block(double *J, int P, int p, int q, double complex g);
void lti_block(double *J, int N, int k, double complex g);
/* the complex gain of the (p, q) block of J, its LTI-form projection */
double complex lti_gain(const double *J, int P, int p, int q);
int lti_like(const double *J, int P, int dofs, double noise_entry);
void lti_project(double *J, int P, int dofs);
int lti_history_usable(const corrector_memory *mem, double omega, int unknowns, double *spread);
int lti_fit(const corrector_memory *mem, int N, double omega, double complex *g, double complex *r,
            double complex *z_pred, double *var_ratio, double *var_matched);
void lti_update(double *J, int N, const double *s, const double *y, const double *noise);
void lti_secant_noise(const rths_residual *r0, const rths_residual *r1, int N, double scale,
                      double *noise_phi, double *noise_resp);

/* lti_model.c: the LTI rig's local model for any number n of interface DoFs. Per harmonic k the
 * residual and the physical response are Phi_k = G_k(w) z_k - f_k(w), x_k = R_k(w) z_k + e_k(w),
 * z_k the n targets of harmonic k (complex), G_k and R_k complex n x n matrices (entry (d, e):
 * DoF d's response to DoF e's target), each entry a line in w fitted to the evaluation history.
 * One DoF: lti_fit's scalar gains. */
typedef struct lti_model {
    int harmonics, dofs; /* N per DoF, n */
    /* G_k, R_k column-major n x n; the prediction z_k = G_k^-1 f_k */
    double complex g[RTHS_MAX_HARMONICS][DOF_MAX * DOF_MAX],
        r[RTHS_MAX_HARMONICS][DOF_MAX * DOF_MAX];
    double complex z[RTHS_MAX_HARMONICS][DOF_MAX];
    /* given a residual: per DoF, the variance of its fundamental amplitude's matched estimate
     * x - R G^-1 Phi from the fitted ratio's uncertainty times the residual (model_var), and the
     * evaluations' scatter about the model (scatter_var), m^2 */
    double model_var[DOF_MAX], scatter_var[DOF_MAX];
} lti_model;

/* Fits the model at omega to the history (P pairs, dofs DoFs); phi (metres, P cos then P sin
 * terms, or NULL) asks for the variances. Returns 0, or -1 when the history does not determine
 * the model (too few evaluations or frequencies, an ill-conditioned fit, a singular gain). */
int lti_model_fit(const corrector_memory *mem, int P, int dofs, double omega, const double *phi,
                  lti_model *out);
/* Writes the model's gains into the target blocks of J and R (scaled units = metres here). */
void lti_model_apply(const lti_model *m, double *J, double *R);
/* Secant update in the LTI form: one DoF, lti_update; several, Broyden's update of each
 * harmonic's complex gain matrix, for each harmonic whose change stands above 3 noise. */
void lti_model_secant(double *J, int P, int dofs, const double *s, const double *y,
                      const double *noise);

/* jacobian.c */
int corrector_fd_jacobian(rths_corrector *c, rths_error *err);
void corrector_secant_update(rths_corrector *c, const corrector_point *trial);
int solve_small(int m, double *a, int lda, double *b);

/* matched.c: the converged point's report; on a natural sweep of an LTI rig it may evaluate
 * once more (the fundamental's local gain), so it can return a rig error */
int corrector_finish(rths_corrector *c, rths_error *err);
/* The signal-to-noise floor of the current point (rths_newton_options.min_snr): fills the
 * solution's snr fields; returns 1 when some interface DoF's response lies below the floor. */
int corrector_below_noise_floor(rths_corrector *c);

/* both parts finite */
static inline int finite_complex(double complex z) {
    return isfinite(creal(z)) && isfinite(cimag(z));
}

#endif
