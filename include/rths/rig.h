/* rths rig: what a real hybrid-test rig offers the host, and nothing more.
 *
 * The host (iterate/, continuation/, cli/) sees a rig only through this interface. A rig runs the
 * real-time controller (numerical substructure, PD control of the physical interface to a periodic
 * target, grounding control, inertial compensation, forcing, running Fourier sums) and reports,
 * for every whole forcing period it runs, the Fourier coefficients of the physical and numerical
 * interface displacements over that period. Steady-state detection and averaging are the host's
 * job (iterate/), from that per-period stream.
 *
 * Backends: the in-process virtual rig (rths_virtual_rig_create, in rig_virtual.h) and the remote
 * client of the controller process. Units: Hz, N, m, s. */
#ifndef RTHS_RIG_H
#define RTHS_RIG_H

/* The per-period data (rths_fourier, rths_period), fault codes and trace samples: the signals
 * both sides share; the host never sees the controller's or the plant's own headers. */
#include "rths/core.h"
#include "rths/signals.h"

typedef struct rths_rig rths_rig;

/* A seeded random perturbation of the (first) actuator's demand, for the experimental Floquet
 * estimate (floquet.h): normal numbers held per controller sample, band-limited by two cascaded
 * first-order low-passes at cutoff_hz (0: white), RMS rms_v after the filter. */
typedef struct rths_perturbation {
    double rms_v;
    double cutoff_hz;
    uint64_t seed;
} rths_perturbation;

/* One undecimated controller sample of a perturbed record. */
typedef struct rths_perturbed_sample {
    double phase_rad;      /* forcing phase after the sample, [0, 2 pi) */
    double x_phys_m;       /* measured physical interface displacement (the first DoF) */
    double x_num_m;        /* numerical interface displacement */
    double perturbation_v; /* the perturbation added to the demand at this sample */
} rths_perturbed_sample;

/* Backend operations; every call returns RTHS_OK or an error code with err filled. */
typedef struct rths_rig_ops {
    int (*set_forcing)(void *self, double frequency_hz, double amplitude_n, rths_error *err);
    /* Target x*(t) = sum_{k=1..harmonics} a[k-1] cos(k w t) + b[k-1] sin(k w t), metres. */
    int (*set_target)(void *self, int harmonics, const double *a, const double *b, rths_error *err);
    /* Runs `count` whole periods and fills out[0..count-1]. */
    int (*run_periods)(void *self, int count, rths_period *out, rths_error *err);
    /* Runs for duration_s recording a trace decimated to at most max_samples samples. */
    int (*record_trace)(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                        int *n_out, rths_error *err);
    double (*time_s)(void *self);        /* rig time since creation: simulated s or wall s */
    rths_rig_fault (*fault)(void *self); /* latched fault, RTHS_RIG_OK if none */
    int (*reset_fault)(void *self, rths_error *err);
    double (*noise_level_m)(void *self); /* displacement noise standard deviation, m (0: none) */
    void (*destroy)(void *self);
    /* Several interface DoFs (NULL: a one-DoF backend, set_target alone): targets of `dofs`
     * interface DoFs, DoF d's coefficients at a[d * harmonics + k - 1], b[...]. */
    int (*set_target_dofs)(void *self, int dofs, int harmonics, const double *a, const double *b,
                           rths_error *err);
    int (*interface_dofs)(void *self); /* NULL: 1 */
    /* Runs with the perturbation on until `periods` whole forcing periods lie inside the record
     * (one more period end than that), recording every controller sample (at most max_samples),
     * then turns it off. NULL: the rig cannot (the remote rig's protocol
     * has no such command). */
    int (*record_perturbed)(void *self, const rths_perturbation *p, int periods, int max_samples,
                            rths_perturbed_sample *out, int *n_out, rths_error *err);
    /* Ramps excitation and target to zero and leaves the rig disarmed (safe) until the next
     * call that needs it running re-arms it. NULL: nothing to disarm (a rig that is never
     * armed, or one wrapping another that the caller disarms itself). */
    int (*disarm)(void *self, rths_error *err);
} rths_rig_ops;

rths_rig *rths_rig_create(const rths_rig_ops *ops, void *self, const char *description);
void rths_rig_destroy(rths_rig *rig);
const char *rths_rig_description(const rths_rig *rig);
/* The backend object when rig was created with ops, else NULL (for backend-specific calls). */
void *rths_rig_backend(rths_rig *rig, const rths_rig_ops *ops);

int rths_rig_set_forcing(rths_rig *rig, double frequency_hz, double amplitude_n, rths_error *err);
int rths_rig_set_target(rths_rig *rig, int harmonics, const double *a, const double *b,
                        rths_error *err);
/* Targets of every interface DoF (dofs = rths_rig_interface_dofs; a[d * harmonics + k - 1]);
 * rths_rig_set_target is its one-DoF case. */
int rths_rig_set_target_dofs(rths_rig *rig, int dofs, int harmonics, const double *a,
                             const double *b, rths_error *err);
/* Interface DoFs the rig drives, one actuator each (1..RTHS_MAX_INTERFACE_DOFS). */
int rths_rig_interface_dofs(rths_rig *rig);
int rths_rig_run_periods(rths_rig *rig, int count, rths_period *out, rths_error *err);

/* The integrity counts (signals.h, rths_period) summed over every period this rig object
 * delivered through rths_rig_run_periods since it was created, whatever the caller did with them
 * (evaluations refused for them included). */
typedef struct rths_rig_integrity {
    long periods, samples;
    long late_samples, clipped_demand_samples, saturated_sensor_samples;
} rths_rig_integrity;
void rths_rig_integrity_totals(const rths_rig *rig, rths_rig_integrity *out);

/* Brings the rig to its safe state now: excitation and target ramped to zero, disarmed (the
 * remote rig sends DISARM; the virtual rig, on a simulated clock that only runs when asked,
 * has nothing to do). A later call that runs the rig arms it again. */
int rths_rig_disarm(rths_rig *rig, rths_error *err);
int rths_rig_record_trace(rths_rig *rig, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err);
double rths_rig_time_s(rths_rig *rig);
rths_rig_fault rths_rig_get_fault(rths_rig *rig);
int rths_rig_reset_fault(rths_rig *rig, rths_error *err);
/* What `--reset-fault` does: resets the rig's latched fault (RESET_FAULT to a controller), then
 * looks again after 0.2 s; RTHS_EFAIL with the rig's answer when it refused the reset or latched
 * the fault again (its cause persists). note (cap bytes) receives what was done, for run.log. */
int rths_rig_clear_fault(rths_rig *rig, char *note, size_t cap, rths_error *err);
double rths_rig_noise_level_m(rths_rig *rig);
/* The perturbed record above; RTHS_EINPUT naming the rig when it cannot record one. Periods that
 * the record spans are delivered to nobody (the next evaluation waits for steady state anew). */
int rths_rig_record_perturbed(rths_rig *rig, const rths_perturbation *p, int periods,
                              int max_samples, rths_perturbed_sample *out, int *n_out,
                              rths_error *err);
/* Whether this rig object can record one (a wrapping rig answers for itself). */
int rths_rig_can_record_perturbed(const rths_rig *rig);

#endif
