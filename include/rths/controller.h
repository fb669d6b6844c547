/* rths controller: the per-sample real-time step of the hybrid test (docs/method.md, "The seed
 * structure", "Errata of the seed paper" and "Numerical substructure integration").
 *
 * Every sample: the numerical substructure is advanced one step (chosen scheme) driven by
 *   F_num = F_comp - F_LC + F_ctrl  on the numerical interface DoF, plus the forcing
 *   Phi cos(theta) on its DoF when that DoF is numerical,
 * (for base excitation, forcing.type base: the inertial load -M 1 a_g cos(theta) on every
 * numerical DoF and the interface's whole share, the plant taking its internal DoFs'),
 * with inertial compensation F_comp = p m_int x''_measured when the rig carries the interface's
 * full mass (rig.interface_mass: full, the seed's lab: docs/method.md, "Errata of the seed paper",
 * erratum 2), none when it carries only its physical share (physical_share: docs/method.md, "The
 * interface mass on the rig"), and grounding control F_ctrl
 * = kp^ (x - xi) + kd^ (x' - xi') (erratum 8); the actuator demand is the PD law U = kp (x* - x) +
 * kd (x*' - x') towards the periodic target x*(theta) (or, in feedback mode, towards the numerical
 * interface itself: the conventional real-time hybrid test); running Fourier sums of the physical
 * and numerical interface displacement and the load-cell force are closed at every whole period and
 * published to a lock-free single-producer/single-consumer ring.
 *
 * rths_controller_step never allocates, locks, prints or calls LAPACK: everything is built by
 * rths_controller_create. The command functions (set_forcing, set_target, arm, ...) must be
 * called from the thread that runs the step; only rths_controller_pop_period may run on another
 * thread. Several interface DoFs (1 to RTHS_MAX_INTERFACE_DOFS) are driven by one actuator each:
 * PD control, grounding control, inertial compensation (the compensated mass block times the
 * measured accelerations) and Fourier sums per DoF. */
#ifndef RTHS_CONTROLLER_H
#define RTHS_CONTROLLER_H

#include "rths/config.h"
#include "rths/io.h"
#include "rths/krylov_reduce.h"
#include "rths/plant.h"
#include "rths/reduce.h"
#include "rths/setup.h"
#include "rths/signals.h"

/* What the step computed this sample (for traces). */
typedef struct rths_controller_output {
    double time_s;
    double demand_v; /* actuator demand, V */
    double target_m; /* x*(t) */
    double x_phys_m; /* measured physical interface displacement */
    double x_num_m;  /* numerical interface displacement */
    double force_n;  /* measured interface force */
    /* every interface DoF's (the fields above are DoF 0's), dofs of them */
    int dofs;
    double x_phys_dof_m[RTHS_MAX_INTERFACE_DOFS], x_num_dof_m[RTHS_MAX_INTERFACE_DOFS];
    double target_dof_m[RTHS_MAX_INTERFACE_DOFS], force_dof_n[RTHS_MAX_INTERFACE_DOFS];
    double demand_dof_v[RTHS_MAX_INTERFACE_DOFS];
} rths_controller_output;

typedef struct rths_controller_options {
    double sample_rate_hz; /* 10000 (seed) */
    rths_scheme scheme;    /* numerical substructure integrator; default exact_foh */
    double kp_v_per_m;     /* physical PD, 100 V/m (seed) */
    double kd_v_s_per_m;   /* 10 V s/m (seed) */
    /* per interface DoF (the split's interface order); 0 (default): kp_v_per_m, kd_v_s_per_m */
    double kp_dof_v_per_m[RTHS_MAX_INTERFACE_DOFS];
    double kd_dof_v_s_per_m[RTHS_MAX_INTERFACE_DOFS];
    /* grounding gains per interface DoF (N/m or N m/rad; N s/m or N m s/rad); 0: the scalars */
    double grounding_kp_dof[RTHS_MAX_INTERFACE_DOFS];
    double grounding_kd_dof[RTHS_MAX_INTERFACE_DOFS];
    /* PD gain matrices (controller.kp_matrix, kd_matrix), gain_matrix_rows actuators x
       gain_matrix_cols interface DoFs, element (a, d) at [a + d * RTHS_MAX_INTERFACE_DOFS]:
       demand of actuator a per unit error of DoF d (V per m or rad; V s per m or rad); rows 0:
       none, the per-DoF gains through the inverse actuator transform (setup.h) */
    int gain_matrix_rows, gain_matrix_cols;
    double kp_matrix[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_INTERFACE_DOFS];
    double kd_matrix[RTHS_MAX_INTERFACE_DOFS * RTHS_MAX_INTERFACE_DOFS];
    double grounding_kp_n_per_m;   /* numerical grounding PD, 50000 N/m (seed) */
    double grounding_kd_n_s_per_m; /* 200 N s/m (seed) */
    double velocity_cutoff_hz;     /* filtered differentiator of the laser signal */
    double demand_limit_v;         /* |U| above this latches a fault */
    double displacement_limit_m;   /* |x| of any physical DoF above this latches a fault */
    double force_limit_n;          /* |F_LC| above this latches a fault */
    double ramp_time_s;            /* demand, forcing and target ramp to zero in this time */
    int track_static;              /* target's static term = the measured mean of the last
                                      period (the actuator carries no static load) */
    /* controller.transition_periods: a new forcing (frequency and amplitude, gliding from the
       period boundary where it takes effect) or target is reached along the smootherstep
       s(u) = u^3 (10 - 15 u + 6 u^2) over this many forcing periods (u by phase), the tracked
       static term over one period, instead of at once, so modes away from the forcing frequency
       are hardly excited (docs/method.md, "Smooth transitions"). 0: at once, as the seed paper.
       Default 3. */
    double transition_periods;
    double min_frequency_hz;   /* forcing below this is refused by the rigs (a period must end
                                  in bounded time); 0.1 Hz */
    double max_pending_s;      /* a forcing change waits for the period boundary at most this
                                  long; then the open period is dropped unpublished and the new
                                  forcing starts at phase 0 at once; 1 s */
    int plant_applies_forcing; /* 1: forcing on an internal physical DoF is accepted and left
                                  to the plant (rths_controller_forcing gives its phase);
                                  0 (default): such a forcing DoF is refused at create */
    /* controller.reduction: a numerical substructure larger than RTHS_REDUCE_FULL_UP_TO DoFs is
       integrated as its Craig-Bampton reduction (reduce.h), at most RTHS_REALTIME_MAX_DOFS */
    rths_reduction_options reduction;
    /* A sparse model's numerical substructure (setup->sparse) is integrated as its band-exact
       Krylov reduction (krylov_reduce.h), never densely: controller.reduction.max_error,
       check_points and fill, and the band: the sweep's (continuation.start_hz, end_hz, widened
       by RTHS_CONTROLLER_KRYLOV_BAND_MARGIN of its width each side); end_hz 0: no sweep given,
       and create refuses a sparse setup naming those keys. */
    rths_krylov_options krylov;
    /* controller.max_overrun_share: the share of an evaluation's samples that may have missed
       their deadline (rths_period.late_samples over samples) before the host refuses the
       evaluation; 0 (default): none may. Read here so the key belongs to the controller's
       section; the step does not use it, the host does (docs/config/controller.md). */
    double max_overrun_share;
    /* output.dofs: assembly DoFs (0-based here, 1-based in the file) whose displacements the step
       sums into every period's output_dof (signals.h); 0 (default): none, and the step does no
       extra work. Read from the output section, which the controller process shares with the
       host's configuration. */
    int output_dofs;
    int output_dof[RTHS_MAX_OUTPUT_DOFS];
} rths_controller_options;

/* What latched a fault: the limit and the channel it was beyond, so that every fault message
 * names the channel, the value and the limit (rths_fault_detail_format). */
typedef enum rths_fault_cause {
    RTHS_FAULT_CAUSE_NONE = 0,
    RTHS_FAULT_CAUSE_DISPLACEMENT_LIMIT,      /* channel: the laser's assembly DoF (1-based) */
    RTHS_FAULT_CAUSE_FORCE_LIMIT,             /* channel: the actuator whose load cell (1-based) */
    RTHS_FAULT_CAUSE_DEMAND_LIMIT,            /* channel: the actuator (1-based) */
    RTHS_FAULT_CAUSE_NONFINITE_LASER,         /* channel: the laser's assembly DoF (0: unknown) */
    RTHS_FAULT_CAUSE_NONFINITE_ACCELEROMETER, /* channel: the actuator */
    RTHS_FAULT_CAUSE_NONFINITE_LOAD_CELL,     /* channel: the actuator */
    RTHS_FAULT_CAUSE_NONFINITE_NUMERICAL,     /* channel: the interface DoF's assembly DoF */
    RTHS_FAULT_CAUSE_NONFINITE_DEMAND,        /* channel: the actuator */
    RTHS_FAULT_CAUSE_DEVICE,                  /* the I/O device's own limit (its read said so) */
    RTHS_FAULT_CAUSE_HOST_SILENT,             /* value: host silence, limit: server.watchdog_s, s */
    RTHS_FAULT_CAUSE_LOOP_STALLED,            /* value: how long the sample ran, limit: its
                                                 deadline plus server.stall_margin_s, s */
    RTHS_FAULT_CAUSE_EXTERNAL,                /* rths_controller_trip without a detail */
} rths_fault_cause;

typedef struct rths_fault_detail {
    int fault;   /* rths_rig_fault (0: none) */
    int cause;   /* rths_fault_cause */
    int channel; /* see the cause */
    double value, limit;
    double time_s; /* controller time of the latch */
} rths_fault_detail;

/* One line, e.g. "demand limit: actuator 1 demand -10.4 V beyond +-10 V" (no newline). Pure:
 * any thread. */
void rths_fault_detail_format(const rths_fault_detail *d, char *out, size_t cap);

void rths_controller_defaults(rths_controller_options *opt);
/* Reads the `controller` section over the defaults. */
int rths_controller_config_read(rths_config *cfg, rths_controller_options *opt, rths_error *err);

typedef struct rths_controller rths_controller;

int rths_controller_create(const rths_setup *setup, const rths_controller_options *opt,
                           rths_controller **out, rths_error *err);
void rths_controller_destroy(rths_controller *c);
/* The Krylov reduction's band is the sweep widened by this share of its width each side: the
 * continuation accepts points up to its range margin (rths_continuation_options.range_margin,
 * 0.05 of the range) beyond it. */
#define RTHS_CONTROLLER_KRYLOV_BAND_MARGIN 0.05
/* 1 when the step integrates a sparse model's Krylov reduction (setup->sparse, real-time form),
 * its report in *rep (the reduced size is n_boundary + rep->basis); 0 otherwise. */
int rths_controller_krylov_report(const rths_controller *c, rths_krylov_report *rep);
/* That report in one line for run.log, e.g. "numerical substructure: sparse, 480 DoFs, reduced
 * in real time to 17 DoFs (Krylov, 3 shift(s)), interface FRF error 2.1e-09 (max 0.001) over 31
 * check points of 0.94-1.18 Hz"; empty when no Krylov reduction is integrated. */
void rths_controller_krylov_text(const rths_controller *c, char *buf, size_t size);
/* DoFs of the numerical model the step integrates: the split's numerical substructure, its
 * reduction, or 0 when the host solves it (split.numerical_solver: frequency). In that mode the
 * step drives the physical interface to the target and its published `num` channel carries the
 * force on the numerical substructure's interface, F = p m_int x''_measured - F_LC, N. */
int rths_controller_numerical_dofs(const rths_controller *c);
/* The most Newton steps one sample has taken for the numerical side's nonlinear elements since
 * create (0 without them; at most a fixed bound, docs/method.md, "Nonlinear elements in the
 * real-time step"): the per-sample worst case rths_bench step_size reports. */
int rths_controller_nonlinear_newton_steps(const rths_controller *c);

/* Commands (step thread). Without a transition (transition_periods 0) forcing changes
 * (frequency and amplitude) take effect at the next period boundary, so every published period
 * has one forcing, and a change that has waited max_pending_s without a boundary drops the open
 * period and starts at phase 0; with one, a forcing change glides from the present forcing,
 * from the next period boundary (at once when the last sample closed a period), and the periods
 * it spans are transitional (published with the frequency at their end).
 * The phase theta is continuous across changes. The first forcing of a controller at rest
 * starts at once. */
void rths_controller_set_forcing(rths_controller *c, double frequency_hz, double amplitude_n);
/* After set_forcing: a controller time t such that every period whose start time is at or after
 * t - h/2 runs (or glides) under that forcing and every earlier one ran under the one before:
 * the start of the open period when the change took it over, else one sample past that start.
 * A controller process answers SET_FORCING's ACK with it (docs/protocol.md). */
double rths_controller_forcing_valid_from_s(const rths_controller *c);
void rths_controller_set_target(rths_controller *c, int harmonics, const double *a,
                                const double *b);
/* Targets of `dofs` interface DoFs: DoF d's coefficients a[d * harmonics + k - 1], b[...] of
 * cos / sin(k w t); DoFs from `dofs` on get none. rths_controller_set_target is its dofs = 1 case.
 */
void rths_controller_set_target_dofs(rths_controller *c, int dofs, int harmonics, const double *a,
                                     const double *b);
/* After set_target: a controller time t such that every period whose start time is at or after
 * t - h/2 runs under that target or its transition. A target that follows a forcing change
 * still waiting for its boundary, or that reaches the first period of that change's glide
 * (transitions on), belongs to the change: t is the forcing's (that glide period's start, where
 * the target's transition began up to a few samples in); otherwise the time it was set. A
 * controller process answers SET_TARGET's ACK with it (docs/protocol.md). */
double rths_controller_target_valid_from_s(const rths_controller *c);
int rths_controller_interface_dofs(const rths_controller *c);
/* The last step's demand of every actuator (rths_controller_interface_dofs of them), V. */
void rths_controller_demands(const rths_controller *c, double *demand_v);
void rths_controller_set_feedback(rths_controller *c, int on);
/* Armed: demand and forcing act. Disarming (or a fault) ramps them to zero over ramp_time_s. */
void rths_controller_arm(rths_controller *c, int armed);
int rths_controller_armed(const rths_controller *c);
rths_rig_fault rths_controller_fault(const rths_controller *c);
/* Latches an external fault (e.g. the watchdog) exactly like a limit trip; _detail with what
 * caused it (its fault field is the code latched). */
void rths_controller_trip(rths_controller *c, rths_rig_fault fault);
void rths_controller_trip_detail(rths_controller *c, const rths_fault_detail *detail);
void rths_controller_reset_fault(rths_controller *c);
/* What latched the fault (cause NONE when none is latched). Step thread. */
void rths_controller_fault_detail(const rths_controller *c, rths_fault_detail *out);
/* Counts one sample into the open period's integrity counts (rths_period: late_samples,
 * clipped_demand_samples, saturated_sensor_samples; each argument 0 or not). The per-sample
 * loop calls it; never allocates. */
void rths_controller_count_sample(rths_controller *c, int late, int clipped_demand,
                                  int saturated_sensor);
double rths_controller_time_s(const rths_controller *c);
double rths_controller_frequency_hz(const rths_controller *c);
/* The forcing as of the last step: amplitude (ramp included), N, the phase theta of that sample
 * and omega, rad/s, so that the force over the next sample is amplitude cos(theta + omega tau),
 * 0 <= tau <= h. For a plant that applies forcing on a physical DoF. */
void rths_controller_forcing(const rths_controller *c, double *amplitude_n, double *theta,
                             double *omega_rad_s);
/* 1 when the forcing phase is at a period boundary (the last step closed a period). */
int rths_controller_at_period_boundary(const rths_controller *c);

/* The per-sample step: sensors in, demand out (V). out may be NULL. */
double rths_controller_step(rths_controller *c, const rths_sensor_sample *in,
                            rths_controller_output *out);

/* An upper bound of the target's peak |x*(t)| = |sum_k a[k] cos k w t + b[k] sin k w t|, m:
 * sum_k hypot(a[k], b[k]) (exact for one harmonic). The rigs refuse a target whose bound is beyond
 * the displacement limit; the step also clamps x* to the limit, so a ramp never overshoots it. */
double rths_target_peak_bound_m(int harmonics, const double *a, const double *b);
/* Refuses a physical substructure with more DoFs than a sensor sample carries
 * (RTHS_MAX_SENSED_DOFS): the controller's and the per-sample loop's check before anything
 * opens. */
int rths_controller_check_sensed_dofs(const rths_split *s, rths_error *err);

/* Any thread (single consumer): the oldest unread whole period; 1 if one was available. Periods
 * that do not fit in the ring (capacity 256) are dropped and counted. */
int rths_controller_pop_period(rths_controller *c, rths_period *out);
long rths_controller_dropped_periods(const rths_controller *c);

/* The per-sample loop: the one place where the step and the rig's plant meet, shared by the
 * in-process virtual rig (rig_virtual.c) and the controller process (server_engine.c). Every
 * sample: read the device's sensors, step the controller, write the demand and the forcing's
 * phase to the device (io.h). The device is an I/O plug-in: the reference one over the simulated
 * plant (forcing on an internal physical DoF applied there, in continuous time; the plant advances
 * one sample with the demand held), or a lab's, loaded from a shared object.
 *
 * Arming rules, the same for both users: the loop starts disarmed; a latched fault disarms it
 * (the step ramps the demand to zero); after rths_controller_reset_fault, excitation needs a new
 * rths_sample_loop_arm. */
typedef struct rths_sample_loop rths_sample_loop;

/* Reads the sections the loop is built from (controller and rig) over the defaults already in
 * copt and popt, and checks them against each other (the shaker delay against the sample rate,
 * located at rig.shaker.delay_s). */
int rths_sample_loop_config_read(rths_config *cfg, rths_controller_options *copt,
                                 rths_plant_options *popt, rths_error *err);
int rths_sample_loop_create(const rths_setup *setup, const rths_controller_options *copt,
                            const rths_plant_options *popt, rths_sample_loop **out,
                            rths_error *err);
/* Over a device already opened (taken over: closed by rths_sample_loop_destroy, also on
 * failure). The device's applies_internal_forcing decides whether a setup forcing an internal
 * physical DoF is accepted. */
int rths_sample_loop_create_io(const rths_setup *setup, const rths_controller_options *copt,
                               rths_io *io, rths_sample_loop **out, rths_error *err);
/* Over the device the configuration names: io.plugin, a shared object (io.h, loaded and checked
 * before anything can be armed), or by default the reference plug-in over the simulated plant,
 * opened through the same ABI from the configuration. */
int rths_sample_loop_create_configured(rths_config *cfg, const rths_setup *setup,
                                       const rths_controller_options *copt, rths_sample_loop **out,
                                       rths_error *err);
/* Safe state and close of the device, then the controller. */
void rths_sample_loop_destroy(rths_sample_loop *loop);
/* One sample; returns the demand (V). out may be NULL. Never allocates, blocks or prints. */
double rths_sample_loop_run(rths_sample_loop *loop, rths_controller_output *out);
/* Arms; RTHS_EFAIL (nothing changed) while a fault is latched. */
int rths_sample_loop_arm(rths_sample_loop *loop);
/* The controller process's pacing: the next sample (the next rths_sample_loop_run) started after
 * its deadline had passed (server.c), and is counted late in its period. The in-process virtual
 * rig runs on a simulated clock and never calls it: its records count 0 late samples. */
void rths_sample_loop_mark_late(rths_sample_loop *loop);
/* The device's safe state, from any thread (the process's supervisor while the loop thread is
 * stuck in the device; see io.h). */
void rths_sample_loop_safe_state(rths_sample_loop *loop);
/* The device's hardware watchdog (io.h): arm once before the loop runs; the loop kicks it every
 * sample once armed. */
int rths_sample_loop_watchdog_arm(rths_sample_loop *loop, double timeout_s, rths_error *err);
rths_controller *rths_sample_loop_controller(rths_sample_loop *loop);
/* The simulated plant behind the reference plug-in in this process; NULL for any other device. */
rths_plant *rths_sample_loop_plant(rths_sample_loop *loop);
const rths_io_device_info *rths_sample_loop_device(const rths_sample_loop *loop);

#endif
