/* The controller process's engine: the per-sample loop (controller.h, rths_sample_loop: the
 * controller step on a device behind the I/O plug-in ABI, io.h: io.plugin's shared object, or the
 * reference plug-in over the virtual plant, the same loop the in-process virtual rig runs) adapted
 * to the protocol's types. */
#include "controller/server_engine.h"

#include "rths/controller.h"
#include "rths/plant.h"
#include "rths/setup.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

_Static_assert(RTHS_PROTO_MAX_DOFS == RTHS_MAX_INTERFACE_DOFS,
               "frames carry every interface DoF the step drives");
_Static_assert(RTHS_PROTO_HARMONICS == RTHS_MAX_HARMONICS,
               "PERIOD frames carry exactly the step's harmonics");

struct rths_engine {
    rths_setup setup;
    int have_setup;
    rths_sample_loop *loop; /* the per-sample loop, shared with the in-process virtual rig */
    rths_controller *ctl;   /* the loop's */
    double h;
    uint32_t period_index; /* network thread only */
    double last_end_s;     /* network thread: end of the last period popped */
    int have_last_end;
};

int rths_engine_create(rths_config *cfg, rths_engine **out, rths_engine_info *info,
                       rths_error *err) {
    *out = NULL;
    if (!cfg) return rths_error_set(err, RTHS_EINPUT, "the controller needs a test configuration");
    rths_engine *e = calloc(1, sizeof *e);
    if (!e) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_controller_options copt;
    rths_plant_options popt;
    rths_controller_defaults(&copt);
    rths_plant_defaults(&popt);
    int rc = rths_setup_read(cfg, &e->setup, err);
    if (!rc) e->have_setup = 1;
    if (!rc) rc = rths_sample_loop_config_read(cfg, &copt, &popt, err);
    /* the protocol (version 2 on) carries every interface DoF's target and records, up to its
     * maximum */
    if (!rc && e->setup.split.n_int > RTHS_PROTO_MAX_DOFS)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "this split has %d interface DoFs; the controller link carries at "
                            "most %d",
                            e->setup.split.n_int, RTHS_PROTO_MAX_DOFS);
    /* the device is loaded, checked and opened here, before the server can arm anything; the
     * loop starts disarmed: nothing is excited until the host arms it */
    if (!rc) rc = rths_sample_loop_create_configured(cfg, &e->setup, &copt, &e->loop, err);
    if (rc) {
        rths_engine_destroy(e);
        return rc;
    }
    e->ctl = rths_sample_loop_controller(e->loop);
    e->h = 1.0 / copt.sample_rate_hz;
    info->sample_period_s = e->h;
    const rths_io_device_info *device = rths_sample_loop_device(e->loop);
    info->noise_level_m = device->displacement_noise_m;
    info->max_harmonics = RTHS_MAX_HARMONICS;
    info->interface_dofs = rths_controller_interface_dofs(e->ctl);
    info->ramp_time_s = copt.ramp_time_s;
    info->min_frequency_hz = copt.min_frequency_hz;
    info->displacement_limit_m = copt.displacement_limit_m;
    /* the plug-in's own words reach the host's console: printable text only */
    char device_text[120 + 4];
    rths_proto_printable(device->description, 120, device_text, sizeof device_text);
    snprintf(info->description, sizeof info->description,
             "rths controller: %d DoF assembly, %d interface DoF(s), %.0f Hz; %s",
             e->setup.assembly.n, info->interface_dofs, copt.sample_rate_hz, device_text);
    *out = e;
    return RTHS_OK;
}

void rths_engine_destroy(rths_engine *e) {
    if (!e) return;
    rths_sample_loop_destroy(e->loop);
    if (e->have_setup) rths_setup_free(&e->setup);
    free(e);
}

void rths_engine_step(rths_engine *e, rths_proto_trace_sample *sig) {
    rths_controller_output o;
    rths_sample_loop_run(e->loop, &o);
    /* the first interface DoF's signals, then every DoF's (traces carry them all) */
    *sig = (rths_proto_trace_sample){.time_s = o.time_s,
                                     .x_phys_m = o.x_phys_m,
                                     .x_num_m = o.x_num_m,
                                     .target_m = o.target_m,
                                     .force_n = o.force_n,
                                     .demand = o.demand_v};
    for (int d = 0; d < o.dofs && d < RTHS_PROTO_MAX_DOFS; d++) {
        sig->x_phys_dof_m[d] = o.x_phys_dof_m[d];
        sig->x_num_dof_m[d] = o.x_num_dof_m[d];
        sig->target_dof_m[d] = o.target_dof_m[d];
        sig->force_dof_n[d] = o.force_dof_n[d];
        sig->demand_dof[d] = o.demand_dof_v[d];
    }
}

int rths_engine_arm(rths_engine *e) {
    return rths_sample_loop_arm(e->loop) ? RTHS_PROTO_ESTATE : 0;
}

void rths_engine_disarm(rths_engine *e) {
    rths_controller_arm(e->ctl, 0);
}

void rths_engine_trip_watchdog(rths_engine *e, double silence_s, double watchdog_s) {
    rths_fault_detail why = {.fault = RTHS_RIG_FAULT_WATCHDOG,
                             .cause = RTHS_FAULT_CAUSE_HOST_SILENT,
                             .value = silence_s,
                             .limit = watchdog_s};
    rths_engine_trip(e, &why);
}

void rths_engine_trip(rths_engine *e, const rths_fault_detail *detail) {
    rths_controller_trip_detail(e->ctl, detail);
    rths_controller_arm(e->ctl, 0);
}

void rths_engine_fault_detail(const rths_engine *e, rths_fault_detail *out) {
    rths_controller_fault_detail(e->ctl, out);
}

void rths_engine_mark_late(rths_engine *e) {
    rths_sample_loop_mark_late(e->loop);
}

void rths_engine_safe_state(rths_engine *e) {
    rths_sample_loop_safe_state(e->loop);
}

int rths_engine_watchdog_arm(rths_engine *e, double timeout_s, rths_error *err) {
    return rths_sample_loop_watchdog_arm(e->loop, timeout_s, err);
}

void rths_engine_set_forcing(rths_engine *e, double frequency_hz, double amplitude_n) {
    rths_controller_set_forcing(e->ctl, frequency_hz, amplitude_n);
}

double rths_engine_forcing_valid_from_s(const rths_engine *e) {
    return rths_controller_forcing_valid_from_s(e->ctl);
}

void rths_engine_set_target(rths_engine *e, int dofs, int harmonics, const double *a,
                            const double *b) {
    rths_controller_set_target_dofs(e->ctl, dofs, harmonics, a, b);
}

double rths_engine_target_valid_from_s(const rths_engine *e) {
    return rths_controller_target_valid_from_s(e->ctl);
}

void rths_engine_demands(const rths_engine *e, double *demand_v) {
    rths_controller_demands(e->ctl, demand_v);
}

void rths_engine_reset_fault(rths_engine *e) {
    rths_controller_reset_fault(e->ctl);
}
int rths_engine_armed(const rths_engine *e) {
    return rths_controller_armed(e->ctl) && rths_controller_fault(e->ctl) == RTHS_RIG_OK;
}
int rths_engine_fault(const rths_engine *e) {
    return (int)rths_controller_fault(e->ctl);
}
double rths_engine_time_s(const rths_engine *e) {
    return rths_controller_time_s(e->ctl);
}
long rths_engine_dropped_periods(const rths_engine *e) {
    return rths_controller_dropped_periods(e->ctl);
}

static void copy_fourier(const rths_fourier *in, rths_proto_fourier *out) {
    for (int k = 0; k <= RTHS_PROTO_HARMONICS; k++) {
        out->a[k] = in->a[k];
        out->b[k] = in->b[k];
    }
}

int rths_engine_pop_period(rths_engine *e, rths_proto_period *out) {
    rths_period p;
    if (!rths_controller_pop_period(e->ctl, &p)) return 0;
    memset(out, 0, sizeof *out);
    out->index = e->period_index++;
    out->frequency_hz = p.frequency_hz;
    out->end_time_s = p.end_time_s;
    /* Periods are contiguous (each ends where the next starts, interpolated between samples),
     * so the previous end is this start; after a gap (dropped periods, the first one) the
     * estimate errs early, which only makes the host discard the period. */
    double span = p.samples * e->h;
    if (e->have_last_end && fabs(p.end_time_s - e->last_end_s - span) <= 1.5 * e->h)
        out->start_time_s = e->last_end_s;
    else
        out->start_time_s = p.end_time_s - span - e->h;
    e->last_end_s = p.end_time_s;
    e->have_last_end = 1;
    out->samples = (uint32_t)p.samples;
    out->late_samples = (uint32_t)p.late_samples;
    out->clipped_demand_samples = (uint32_t)p.clipped_demand_samples;
    out->saturated_sensor_samples = (uint32_t)p.saturated_sensor_samples;
    copy_fourier(&p.phys, &out->phys);
    copy_fourier(&p.num, &out->num);
    copy_fourier(&p.force, &out->force);
    /* the record carries every interface DoF (a one-DoF step may leave interface_dofs 0) */
    out->interface_dofs = p.interface_dofs > 1 ? p.interface_dofs : 1;
    for (int d = 1; d < out->interface_dofs; d++) {
        copy_fourier(&p.phys_dof[d], &out->phys_dof[d]);
        copy_fourier(&p.num_dof[d], &out->num_dof[d]);
        copy_fourier(&p.force_dof[d], &out->force_dof[d]);
    }
    out->output_dofs = p.output_dofs <= RTHS_PROTO_MAX_OUTPUT_DOFS ? p.output_dofs : 0;
    for (int j = 0; j < out->output_dofs; j++)
        copy_fourier(&p.output_dof[j], &out->output_dof[j]);
    return 1;
}
