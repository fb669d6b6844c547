/* The virtual rig: controller step + virtual plant on a simulated clock (see rig_virtual.h). */
#include "rths/rig_virtual.h"

#include <errno.h>
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

typedef struct {
    rths_sample_loop *loop; /* the per-sample loop, shared with the controller process */
    rths_controller *ctrl;  /* the loop's */
    double sample_rate_hz;
    double min_frequency_hz, displacement_limit_m; /* the controller's options */
    double pace;                 /* rig seconds per wall second; 0: as fast as the CPU allows */
    int64_t pace_anchor_wall_ns; /* monotonic clock when the current rig command began */
    double pace_anchor_rig_s;    /* rig time then */
    rths_rig_integrity closed;   /* every period the controller closed, delivered or not */
} virtual_rig;

/* Takes the controller's next closed period (1) into its integrity totals, or 0 when none. */
static int pop_period(virtual_rig *v, rths_period *p) {
    if (!rths_controller_pop_period(v->ctrl, p)) return 0;
    v->closed.periods++;
    v->closed.samples += p->samples;
    v->closed.late_samples += p->late_samples;
    v->closed.clipped_demand_samples += p->clipped_demand_samples;
    v->closed.saturated_sensor_samples += p->saturated_sensor_samples;
    return 1;
}

static void sample(virtual_rig *v, rths_controller_output *out) {
    rths_sample_loop_run(v->loop, out);
}

static int64_t monotonic_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (int64_t)ts.tv_sec * 1000000000 + ts.tv_nsec;
}

/* Pacing (rig.pace): every command that runs the rig (run_periods, record_trace) starts a new
 * anchor, so the host's own computing between commands is never "caught up" by running faster
 * than the pace afterwards, as a lab rig would not either. */
static void pace_begin(virtual_rig *v) {
    if (!(v->pace > 0)) return;
    v->pace_anchor_wall_ns = monotonic_ns();
    v->pace_anchor_rig_s = rths_controller_time_s(v->ctrl);
}

/* Sleeps until the wall clock reaches the rig time run since pace_begin, divided by the pace:
 * an absolute deadline from the anchor, so sleeping's own overshoot never accumulates (no
 * drift), and the wall time of a command is never below its rig time / pace. */
static void pace_wait(virtual_rig *v) {
    if (!(v->pace > 0)) return;
    double ahead_s = (rths_controller_time_s(v->ctrl) - v->pace_anchor_rig_s) / v->pace;
    int64_t deadline = v->pace_anchor_wall_ns + (int64_t)ceil(ahead_s * 1e9);
    struct timespec ts = {(time_t)(deadline / 1000000000), (long)(deadline % 1000000000)};
    while (clock_nanosleep(CLOCK_MONOTONIC, TIMER_ABSTIME, &ts, NULL) == EINTR) {
    }
}

static int fault_error(virtual_rig *v, rths_error *err) {
    rths_fault_detail detail;
    char text[256];
    rths_controller_fault_detail(v->ctrl, &detail);
    rths_fault_detail_format(&detail, text, sizeof text);
    return rths_error_set(err, RTHS_EFAIL,
                          "virtual rig fault at t = %.4f s: %s (limits in controller.limits "
                          "and rig.actuator.limits); the demand was ramped to zero",
                          rths_controller_time_s(v->ctrl), text);
}

static int v_set_forcing(void *self, double frequency_hz, double amplitude_n, rths_error *err) {
    virtual_rig *v = self;
    if (!(frequency_hz >= v->min_frequency_hz && frequency_hz < 0.25 * v->sample_rate_hz) ||
        !isfinite(amplitude_n))
        return rths_error_set(err, RTHS_EINPUT,
                              "forcing %g Hz, %g N is out of range: the frequency must be in "
                              "[%g, %g) Hz (controller.min_frequency_hz, a quarter of "
                              "controller.sample_rate_hz), the amplitude finite",
                              frequency_hz, amplitude_n, v->min_frequency_hz,
                              0.25 * v->sample_rate_hz);
    rths_controller_set_forcing(v->ctrl, frequency_hz, amplitude_n);
    return RTHS_OK;
}

/* Every DoF's target finite and within the stroke, then set (a[d * harmonics + k]). */
static int v_set_target_dofs(void *self, int dofs, int harmonics, const double *a, const double *b,
                             rths_error *err) {
    virtual_rig *v = self;
    if (harmonics < 0 || harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "%d harmonics: 0..%d supported", harmonics,
                              RTHS_MAX_HARMONICS);
    if (dofs != rths_controller_interface_dofs(v->ctrl))
        return rths_error_set(err, RTHS_EINPUT, "target for %d interface DoFs; the rig drives %d",
                              dofs, rths_controller_interface_dofs(v->ctrl));
    for (int k = 0; k < dofs * harmonics; k++)
        if (!isfinite(a[k]) || !isfinite(b[k]))
            return rths_error_set(err, RTHS_EINPUT, "target coefficient %d is not finite", k + 1);
    for (int d = 0; d < dofs; d++) {
        double peak = rths_target_peak_bound_m(harmonics, a + d * harmonics, b + d * harmonics);
        if (peak > v->displacement_limit_m)
            return rths_error_set(err, RTHS_EINPUT,
                                  "target of up to %g m is beyond the displacement limit %g m "
                                  "(controller.limits.displacement_m)",
                                  peak, v->displacement_limit_m);
    }
    rths_controller_set_target_dofs(v->ctrl, dofs, harmonics, a, b);
    return RTHS_OK;
}

static int v_set_target(void *self, int harmonics, const double *a, const double *b,
                        rths_error *err) {
    return v_set_target_dofs(self, 1, harmonics, a, b, err);
}

static int v_interface_dofs(void *self) {
    return rths_controller_interface_dofs(((virtual_rig *)self)->ctrl);
}

static int v_run_periods(void *self, int count, rths_period *out, rths_error *err) {
    virtual_rig *v = self;
    double f = rths_controller_frequency_hz(v->ctrl);
    if (!(f > 0)) return rths_error_set(err, RTHS_EINPUT, "set the forcing before running");
    rths_period discard;
    while (pop_period(v, &discard)) {
    }
    /* bound: twice the samples of the slowest plausible periods, plus slack */
    long limit = (long)(count + 2) * (long)(2 * v->sample_rate_hz / f) + 100000;
    int got = 0;
    pace_begin(v);
    for (long i = 0; got < count; i++) {
        if (i > limit) return rths_error_set(err, RTHS_EFAIL, "virtual rig: no period completed");
        sample(v, NULL);
        if (rths_controller_fault(v->ctrl)) return fault_error(v, err);
        int before = got;
        while (got < count && pop_period(v, &out[got]))
            got++;
        if (got > before) pace_wait(v); /* a period is delivered when its time has passed */
    }
    return RTHS_OK;
}

/* A trace sample from what the step reported: every interface DoF's signals with several. */
static rths_trace_sample trace_sample(const rths_controller_output *o) {
    rths_trace_sample t = {.time_s = o->time_s,
                           .x_phys_m = o->x_phys_m,
                           .x_num_m = o->x_num_m,
                           .target_m = o->target_m,
                           .force_n = o->force_n,
                           .demand = o->demand_v};
    if (o->dofs > 1) {
        t.dofs = o->dofs;
        for (int d = 0; d < o->dofs; d++) {
            t.x_phys_dof_m[d] = o->x_phys_dof_m[d];
            t.x_num_dof_m[d] = o->x_num_dof_m[d];
            t.target_dof_m[d] = o->target_dof_m[d];
            t.force_dof_n[d] = o->force_dof_n[d];
            t.demand_dof_v[d] = o->demand_dof_v[d];
        }
    }
    return t;
}

static int v_record_trace(void *self, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err) {
    virtual_rig *v = self;
    *n_out = 0;
    if (!(duration_s > 0) || max_samples < 1)
        return rths_error_set(err, RTHS_EINPUT, "trace of %g s with %d samples", duration_s,
                              max_samples);
    long total = (long)ceil(duration_s * v->sample_rate_hz);
    long every = (total + max_samples - 1) / max_samples;
    if (every < 1) every = 1;
    rths_controller_output o;
    /* paced in slices of 10 ms rig time: a trace has no periods to wait at */
    long slice = (long)ceil(0.01 * v->sample_rate_hz);
    pace_begin(v);
    for (long i = 0; i < total; i++) {
        sample(v, &o);
        if (rths_controller_fault(v->ctrl)) return fault_error(v, err);
        if (i % every == 0 && *n_out < max_samples) out[(*n_out)++] = trace_sample(&o);
        if ((i + 1) % slice == 0 || i + 1 == total) {
            /* the periods closed meanwhile are not the trace's, but their integrity counts are
             * the rig's: taken every slice, before the controller's ring could overflow */
            rths_period discard;
            while (pop_period(v, &discard)) {
            }
            pace_wait(v);
        }
    }
    return RTHS_OK;
}

/* The rig keeps running its target; the demand carries the seeded perturbation meanwhile. */
static int v_record_perturbed(void *self, const rths_perturbation *p, int periods, int max_samples,
                              rths_perturbed_sample *out, int *n_out, rths_error *err) {
    virtual_rig *v = self;
    *n_out = 0;
    double f = rths_controller_frequency_hz(v->ctrl);
    if (!(f > 0)) return rths_error_set(err, RTHS_EINPUT, "set the forcing before perturbing");
    if (rths_sample_loop_set_perturbation(v->loop, p->rms_v, p->cutoff_hz, v->sample_rate_hz,
                                          p->seed))
        return rths_error_set(err, RTHS_EINPUT, "perturbation of %g V RMS, cutoff %g Hz", p->rms_v,
                              p->cutoff_hz);
    rths_period discard;
    while (pop_period(v, &discard)) {
    }
    long limit = (long)(periods + 3) * (long)(2 * v->sample_rate_hz / f) + 100000;
    int ends = 0, rc = RTHS_OK;
    rths_controller_output o;
    pace_begin(v);
    for (long i = 0; ends <= periods && !rc; i++) {
        if (i > limit) {
            rc = rths_error_set(err, RTHS_EFAIL, "virtual rig: no period completed");
            break;
        }
        sample(v, &o);
        if (rths_controller_fault(v->ctrl)) {
            rc = fault_error(v, err);
            break;
        }
        if (*n_out < max_samples) {
            double amplitude_n, theta, omega;
            rths_controller_forcing(v->ctrl, &amplitude_n, &theta, &omega);
            out[(*n_out)++] = (rths_perturbed_sample){theta, o.x_phys_m, o.x_num_m,
                                                      rths_sample_loop_perturbation_v(v->loop)};
        }
        int before = ends;
        while (pop_period(v, &discard))
            ends++;
        if (ends > before) pace_wait(v);
    }
    rths_sample_loop_set_perturbation(v->loop, 0, 0, v->sample_rate_hz, 0);
    return rc;
}

static double v_time(void *self) {
    return rths_controller_time_s(((virtual_rig *)self)->ctrl);
}
static rths_rig_fault v_fault(void *self) {
    return rths_controller_fault(((virtual_rig *)self)->ctrl);
}
static int v_reset_fault(void *self, rths_error *err) {
    (void)err;
    virtual_rig *v = self;
    rths_controller_reset_fault(v->ctrl);
    return rths_sample_loop_arm(v->loop);
}
static double v_noise(void *self) {
    return rths_plant_noise_level_m(rths_sample_loop_plant(((virtual_rig *)self)->loop));
}
static void v_destroy(void *self) {
    virtual_rig *v = self;
    rths_sample_loop_destroy(v->loop);
    free(v);
}

static const rths_rig_ops virtual_ops = {
    .set_forcing = v_set_forcing,
    .set_target = v_set_target,
    .run_periods = v_run_periods,
    .record_trace = v_record_trace,
    .time_s = v_time,
    .fault = v_fault,
    .reset_fault = v_reset_fault,
    .noise_level_m = v_noise,
    .destroy = v_destroy,
    .set_target_dofs = v_set_target_dofs,
    .interface_dofs = v_interface_dofs,
    .record_perturbed = v_record_perturbed,
};

int rths_virtual_rig_create_with(const rths_setup *setup, const rths_controller_options *copt,
                                 const rths_plant_options *popt, rths_rig **out, rths_error *err) {
    *out = NULL;
    virtual_rig *v = calloc(1, sizeof *v);
    if (!v) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    v->sample_rate_hz = copt->sample_rate_hz;
    v->min_frequency_hz = copt->min_frequency_hz;
    v->displacement_limit_m = copt->displacement_limit_m;
    int rc = rths_sample_loop_create(setup, copt, popt, &v->loop, err);
    if (!rc) v->ctrl = rths_sample_loop_controller(v->loop);
    char description[200];
    snprintf(description, sizeof description,
             "virtual rig: %s integrator, %g Hz, %s actuator, delay %g s, noise %s",
             rths_scheme_name(copt->scheme), copt->sample_rate_hz,
             rths_actuator_model_name(popt->actuator.model), popt->delay_s,
             popt->noise == 2 ? "lab"
             : popt->noise    ? "on"
                              : "off");
    if (!rc && !(*out = rths_rig_create(&virtual_ops, v, description)))
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (rc) {
        rths_sample_loop_destroy(v->loop);
        free(v);
        return rc;
    }
    return rths_sample_loop_arm(v->loop);
}

int rths_virtual_rig_create(rths_config *cfg, const rths_setup *setup, int has_seed,
                            uint64_t seed_override, rths_rig **out, rths_error *err) {
    rths_controller_options copt;
    rths_plant_options popt;
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    double pace = 0;
    int rc = rths_sample_loop_config_read(cfg, &copt, &popt, err);
    if (!rc) rc = rths_config_get_double(cfg, "rig.pace", 0, 0.0, 0.0, 1e6, &pace, err);
    if (rc) return rc;
    /* a multi-site test's list of sites (docs/method.md, "Multi-site tests"): in one process
     * the virtual rig runs every site's physical part itself */
    rths_config_mark_known(cfg, "rig.sites");
    if (has_seed) popt.seed = seed_override;
    rc = rths_virtual_rig_create_with(setup, &copt, &popt, out, err);
    if (!rc && pace > 0) rc = rths_virtual_rig_set_pace(*out, pace, err);
    return rc;
}

int rths_virtual_rig_set_pace(rths_rig *rig, double factor, rths_error *err) {
    virtual_rig *v = rths_rig_backend(rig, &virtual_ops);
    if (!v) return rths_error_set(err, RTHS_EINPUT, "pacing applies to the virtual rig only");
    if (!(factor >= 0 && factor <= 1e6))
        return rths_error_set(err, RTHS_EINPUT,
                              "pace %g: expected a factor of real time in (0, 1e6] (1: real "
                              "time), or 0 for unpaced",
                              factor);
    v->pace = factor;
    return RTHS_OK;
}

rths_controller *rths_virtual_rig_controller(rths_rig *rig) {
    virtual_rig *v = rths_rig_backend(rig, &virtual_ops);
    return v ? v->ctrl : NULL;
}

int rths_virtual_rig_integrity(rths_rig *rig, rths_rig_integrity *out) {
    virtual_rig *v = rths_rig_backend(rig, &virtual_ops);
    memset(out, 0, sizeof *out);
    if (!v) return RTHS_EINPUT;
    *out = v->closed;
    return RTHS_OK;
}

rths_plant *rths_virtual_rig_plant(rths_rig *rig) {
    virtual_rig *v = rths_rig_backend(rig, &virtual_ops);
    return v ? rths_sample_loop_plant(v->loop) : NULL;
}
