/* rths tune: PD and grounding gains from the model, checked stable with a stated margin against
 * the sampled loop, the actuator and the delay (docs/method.md, "Tuning the gains").
 *
 * The physical loop: the physical substructure as the virtual rig models it (plant.h: the
 * interface mass the rig carries, the shaker's gain, lag and armature or the transfer-function
 * actuator with its velocity path, the transport delay (whole samples as the virtual rig holds
 * it, or any delay with its fraction of a sample), the linear or step hold of the demand),
 * discretised exactly over one controller sample, closed by the controller's own
 * discrete PD (backward difference through its first-order low-pass at velocity_cutoff_hz).
 * Stability is the closed loop's spectral radius < 1; the margins come from the discrete loop's
 * frequency response L(e^{i w h}) = K(e^{i w h}) P(e^{i w h}), the loop broken at the demand.
 *
 * The grounding loop: the numerical substructure as the controller integrates it (its scheme),
 * with the grounding force computed from the previous sample (the same equations as
 * src/controller/step.c's check at create). */
#ifndef RTHS_TUNE_H
#define RTHS_TUNE_H

#include "rths/controller.h"
#include "rths/core.h"
#include "rths/plant.h"
#include "rths/setup.h"

#include <complex.h>

/* The physical loop of ni interface DoFs, the interface the last ni of the n DoFs, each closed by
 * its own PD on its own effort channel. The controller's demands go to the actuators through the
 * inverse actuator transform and its displacements come from the lasers through the inverse
 * sensor transform (src/controller/step.c), and the actuators' gain, lag, delay and hold are
 * equal: in the linear loop both transforms cancel, and only the armatures' mass at the
 * actuators' points, T diag(m_a) T^T, remains of them. */
typedef struct rths_pd_loop_spec {
    int n;                   /* physical DoFs (internal ones first, the interface last) */
    int ni;                  /* interface DoFs (0: 1), at most RTHS_MAX_INTERFACE_DOFS */
    const double *mass;      /* n x n, kg: the interface block is the rig's mass */
    const double *damping;   /* n x n, N s/m */
    const double *stiffness; /* n x n, N/m (may be singular: a free mass) */
    double sample_rate_hz;
    double velocity_cutoff_hz;        /* the PD's differentiator low-pass; 0: raw difference */
    const rths_plant_options *rig;    /* actuator, delay, lag, armature, hold */
    const double *actuator_transform; /* ni x ni (setup.h); NULL: one actuator on each DoF */
} rths_pd_loop_spec;

typedef struct rths_pd_loop rths_pd_loop;

/* What the margins of one pair of gains are (with several interface DoFs: of one loop broken at
 * its effort demand, the others closed; the spectral radius is the whole coupled loop's). */
typedef struct rths_loop_margins {
    double spectral_radius;  /* of the closed sampled loop: stable below 1 */
    int stable;              /* spectral_radius < 1 */
    double gain_margin_db;   /* 20 log10 of the smallest factor on both gains that reaches -1;
                                INFINITY: the phase never crosses -180 deg inside |L| < 1 */
    double gain_margin_hz;   /* where (the phase crossover), NAN without */
    double phase_margin_deg; /* 180 deg + arg L where |L| = 1, the smallest; INFINITY: none */
    double crossover_hz;     /* where, NAN without */
    double bandwidth_hz;     /* |S| = |1 / (1 + L)| <= 1/sqrt(2) at every frequency below */
} rths_loop_margins;

int rths_pd_loop_create(const rths_pd_loop_spec *spec, rths_pd_loop **out, rths_error *err);
/* The loop of a setup's physical substructure (every interface DoF, the actuator transform's
 * armature mass) on the configured rig and controller. delay_s < 0: the rig's delay as the virtual
 * rig holds it (rounded to whole samples); otherwise this delay, s, with its fraction of a
 * sample (a lab's measured delay). */
int rths_pd_loop_from_setup(const rths_setup *setup, const rths_controller_options *copt,
                            const rths_plant_options *popt, double delay_s, rths_pd_loop **out,
                            rths_error *err);
void rths_pd_loop_destroy(rths_pd_loop *loop);
/* The transport delay the loop holds: whole samples, and the fraction of a sample beyond them
 * (spec->rig->delay_s as given: [0, 1)). */
int rths_pd_loop_delay_samples(const rths_pd_loop *loop);
double rths_pd_loop_delay_fraction(const rths_pd_loop *loop);
int rths_pd_loop_dofs(const rths_pd_loop *loop);
/* Spectral radius of the closed loop with gains kp (V/m) and kd (V s/m) on every DoF; -1 on
 * failure. */
double rths_pd_loop_radius(const rths_pd_loop *loop, double kp, double kd);
/* The same with gains per interface DoF (V/m or V m/rad, V s/m or V s m/rad): every loop closed
 * at once, the coupled sampled loop. */
double rths_pd_loop_radius_dofs(const rths_pd_loop *loop, const double *kp, const double *kd);
/* Margins of DoF 0's loop with these gains on every DoF. */
int rths_pd_loop_margins(const rths_pd_loop *loop, double kp, double kd, rths_loop_margins *out,
                         rths_error *err);
/* Margins of interface DoF d's loop broken at its effort demand, the other loops closed by their
 * gains (L_d = K_d (P_dd - P_do K_o (I + P_oo K_o)^-1 P_od)); the spectral radius the coupled
 * loop's. */
int rths_pd_loop_margins_dof(const rths_pd_loop *loop, int d, const double *kp, const double *kd,
                             rths_loop_margins *out, rths_error *err);
/* The frequencies the margins are read on (log-spaced up to Nyquist): their count, and the
 * loop L = K P at each, broken at the demand, for gains kp and kd (frequency_hz and l hold
 * rths_pd_loop_points() entries). */
int rths_pd_loop_points(void);
void rths_pd_loop_response(const rths_pd_loop *loop, double kp, double kd, double *frequency_hz,
                           double complex *l);
/* L_d of DoF d, the others closed (as rths_pd_loop_margins_dof); -1 when it cannot be formed. */
int rths_pd_loop_response_dof(const rths_pd_loop *loop, int d, const double *kp, const double *kd,
                              double *frequency_hz, double complex *l);

/* Spectral radius per sample of the numerical substructure under grounding control with gains
 * gkp, gkd per interface DoF (N/m, N s/m), the controller's scheme and sample rate. -1 with err
 * set on failure. Same equations as the check in rths_controller_create. */
double rths_grounding_radius(const rths_setup *setup, const rths_controller_options *copt,
                             const double *gkp, const double *gkd, rths_error *err);

/* The rule (docs/method.md, "Tuning the gains"). */
typedef struct rths_tune_rule {
    double min_gain_margin_db;       /* 6 */
    double min_phase_margin_deg;     /* 45 */
    double grounding_gain_factor;    /* 2: the grounding gains times this must still be stable */
    double grounding_max_radius;     /* 0.99 at those gains */
    double grounding_decay_fraction; /* 0.9: of the fastest decay of the numerical side found */
    double pd_decay_fraction; /* 0.9, several interface DoFs: of the fastest decay of the coupled
                                 physical loop's slowest transient found for a loop's gains */
    double delay_s; /* < 0 (default): the rig's delay as the virtual rig holds it, whole samples;
                       else the physical loop's transport delay, s (fraction of a sample kept) */
} rths_tune_rule;

void rths_tune_rule_defaults(rths_tune_rule *rule);

typedef struct rths_tune_result {
    double kp_v_per_m, kd_v_s_per_m;  /* interface DoF 1's (all of them: below) */
    rths_loop_margins tuned, current; /* current: the configured gains'; DoF 1's loop */
    double current_kp_v_per_m, current_kd_v_s_per_m;
    /* per interface DoF (n_int of them; V/m or V m/rad, V s/m or V s m/rad): the gains, and the
     * margins of each loop broken with the others closed */
    double kp[RTHS_MAX_INTERFACE_DOFS], kd[RTHS_MAX_INTERFACE_DOFS];
    double current_kp[RTHS_MAX_INTERFACE_DOFS], current_kd[RTHS_MAX_INTERFACE_DOFS];
    rths_loop_margins tuned_dof[RTHS_MAX_INTERFACE_DOFS], current_dof[RTHS_MAX_INTERFACE_DOFS];
    /* the coupled loop (every DoF closed): the largest factor on all PD gains together that keeps
     * it stable (bisected to 0.1 %, capped at 1e3), in dB; the tuned gains need rule's
     * min_gain_margin_db; its spectral radius at the tuned gains times that margin's factor */
    double coupled_gain_margin_db, current_coupled_gain_margin_db;
    double coupled_radius_at_margin;
    int sweeps; /* passes of loop-at-a-time tuning (1 with one DoF) */
    int delay_samples;
    double delay_fraction; /* of a sample, beyond delay_samples */
    int n_int;
    double grounding_kp[RTHS_MAX_INTERFACE_DOFS], grounding_kd[RTHS_MAX_INTERFACE_DOFS];
    double grounding_frequency_hz;     /* sqrt(kp^ / m) of the chosen gains */
    double grounding_damping_ratio;    /* kd^ / (2 sqrt(kp^ m)) */
    double grounding_decay_per_s;      /* -ln(radius) / h of the chosen gains */
    double grounding_best_decay_per_s; /* the fastest found */
    double grounding_radius;           /* at the chosen gains */
    double grounding_radius_margin;    /* at grounding_gain_factor times them */
    double grounding_radius_current;   /* at the configured gains */
    double lowest_mode_hz;             /* of the assembly */
} rths_tune_result;

/* Tunes both loops of a setup, every interface DoF. RTHS_EINPUT when the setup is outside what
 * the analysis models (gain matrices, a transfer-function actuator on several DoFs, host-side
 * numerical solver); RTHS_EFAIL when no gains meet the rule (named in err). */
int rths_tune(const rths_setup *setup, const rths_controller_options *copt,
              const rths_plant_options *popt, const rths_tune_rule *rule, rths_tune_result *out,
              rths_error *err);

#endif
