/* The rig interface: a thin dispatcher over a backend's operations. */
#include "rths/rig.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct rths_rig {
    const rths_rig_ops *ops;
    void *self;
    char description[256];
    rths_rig_integrity integrity; /* sums over every period run_periods delivered */
};

rths_rig *rths_rig_create(const rths_rig_ops *ops, void *self, const char *description) {
    rths_rig *rig = calloc(1, sizeof *rig);
    if (!rig) return NULL;
    rig->ops = ops;
    rig->self = self;
    strncpy(rig->description, description ? description : "", sizeof rig->description - 1);
    return rig;
}

void *rths_rig_backend(rths_rig *rig, const rths_rig_ops *ops) {
    return rig && rig->ops == ops ? rig->self : NULL;
}

void rths_rig_destroy(rths_rig *rig) {
    if (!rig) return;
    if (rig->ops->destroy) rig->ops->destroy(rig->self);
    free(rig);
}

const char *rths_rig_description(const rths_rig *rig) {
    return rig->description;
}

int rths_rig_set_forcing(rths_rig *rig, double frequency_hz, double amplitude_n, rths_error *err) {
    return rig->ops->set_forcing(rig->self, frequency_hz, amplitude_n, err);
}

int rths_rig_set_target(rths_rig *rig, int harmonics, const double *a, const double *b,
                        rths_error *err) {
    if (harmonics < 0 || harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "target has %d harmonics; at most %d supported",
                              harmonics, RTHS_MAX_HARMONICS);
    return rig->ops->set_target(rig->self, harmonics, a, b, err);
}

int rths_rig_interface_dofs(rths_rig *rig) {
    return rig->ops->interface_dofs ? rig->ops->interface_dofs(rig->self) : 1;
}

int rths_rig_set_target_dofs(rths_rig *rig, int dofs, int harmonics, const double *a,
                             const double *b, rths_error *err) {
    int have = rths_rig_interface_dofs(rig);
    if (dofs != have)
        return rths_error_set(err, RTHS_EINPUT, "target for %d interface DoFs; rig '%s' drives %d",
                              dofs, rig->description, have);
    if (dofs == 1) return rths_rig_set_target(rig, harmonics, a, b, err);
    if (harmonics < 0 || harmonics > RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT, "target has %d harmonics; at most %d supported",
                              harmonics, RTHS_MAX_HARMONICS);
    return rig->ops->set_target_dofs(rig->self, dofs, harmonics, a, b, err);
}

int rths_rig_run_periods(rths_rig *rig, int count, rths_period *out, rths_error *err) {
    int rc = rig->ops->run_periods(rig->self, count, out, err);
    if (rc) return rc;
    rths_rig_integrity *t = &rig->integrity;
    for (int i = 0; i < count; i++) {
        t->periods++;
        t->samples += out[i].samples;
        t->late_samples += out[i].late_samples;
        t->clipped_demand_samples += out[i].clipped_demand_samples;
        t->saturated_sensor_samples += out[i].saturated_sensor_samples;
    }
    return RTHS_OK;
}

void rths_rig_integrity_totals(const rths_rig *rig, rths_rig_integrity *out) {
    *out = rig->integrity;
}

int rths_rig_disarm(rths_rig *rig, rths_error *err) {
    if (!rig->ops->disarm) return RTHS_OK;
    return rig->ops->disarm(rig->self, err);
}

int rths_rig_record_trace(rths_rig *rig, double duration_s, int max_samples, rths_trace_sample *out,
                          int *n_out, rths_error *err) {
    if (!rig->ops->record_trace)
        return rths_error_set(err, RTHS_EFAIL, "rig '%s' cannot record time traces",
                              rig->description);
    return rig->ops->record_trace(rig->self, duration_s, max_samples, out, n_out, err);
}

double rths_rig_time_s(rths_rig *rig) {
    return rig->ops->time_s(rig->self);
}

rths_rig_fault rths_rig_get_fault(rths_rig *rig) {
    return rig->ops->fault ? rig->ops->fault(rig->self) : RTHS_RIG_OK;
}

int rths_rig_reset_fault(rths_rig *rig, rths_error *err) {
    if (!rig->ops->reset_fault) return RTHS_OK;
    return rig->ops->reset_fault(rig->self, err);
}

double rths_rig_noise_level_m(rths_rig *rig) {
    return rig->ops->noise_level_m ? rig->ops->noise_level_m(rig->self) : 0.0;
}

int rths_rig_can_record_perturbed(const rths_rig *rig) {
    return rig->ops->record_perturbed != NULL;
}

int rths_rig_record_perturbed(rths_rig *rig, const rths_perturbation *p, int periods,
                              int max_samples, rths_perturbed_sample *out, int *n_out,
                              rths_error *err) {
    *n_out = 0;
    if (!rig->ops->record_perturbed)
        return rths_error_set(err, RTHS_EINPUT,
                              "rig '%s' cannot inject a demand perturbation (the experimental "
                              "Floquet estimate needs the virtual rig)",
                              rig->description);
    if (!(p->rms_v > 0 && p->rms_v < 1e3) || !(p->cutoff_hz >= 0) || periods < 1 || max_samples < 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "perturbation of %g V RMS, cutoff %g Hz, over %d periods into %d "
                              "samples: expected 0 < RMS < 1000 V, cutoff >= 0, at least one "
                              "period and one sample",
                              p->rms_v, p->cutoff_hz, periods, max_samples);
    return rig->ops->record_perturbed(rig->self, p, periods, max_samples, out, n_out, err);
}

int rths_rig_clear_fault(rths_rig *rig, char *note, size_t cap, rths_error *err) {
    rths_rig_fault before = rths_rig_get_fault(rig);
    rths_error why = {0};
    if (rths_rig_reset_fault(rig, &why))
        return rths_error_set(err, RTHS_EFAIL, "RESET_FAULT refused by %s: %s", rig->description,
                              why.msg);
    /* a cause that persists (a reading beyond its limit, a host still silent) latches the fault
     * again within a sample or a watchdog period: look again after a moment */
    struct timespec pause = {0, 200000000};
    nanosleep(&pause, NULL);
    rths_rig_fault after = rths_rig_get_fault(rig);
    if (after != RTHS_RIG_OK)
        return rths_error_set(err, RTHS_EFAIL,
                              "RESET_FAULT refused: %s latched its '%s' fault again right after "
                              "the reset; its cause persists (remove it, then reset again)",
                              rig->description, rths_rig_fault_name(after));
    if (before == RTHS_RIG_OK)
        snprintf(note, cap, "RESET_FAULT sent to %s: no fault was latched", rig->description);
    else
        snprintf(note, cap, "RESET_FAULT sent to %s: its '%s' fault cleared", rig->description,
                 rths_rig_fault_name(before));
    return RTHS_OK;
}
