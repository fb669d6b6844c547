/* The per-sample loop (see controller.h): the controller step and the plant joined at the
 * per-sample I/O seam, once, for every user. */
#include "rths/controller.h"

#include <math.h>
#include <stdlib.h>

struct rths_sample_loop {
    rths_controller *ctl;
    rths_plant *plant;
    rths_sensor_sample sensors; /* preallocated: read into every sample */
};

int rths_sample_loop_config_read(rths_config *cfg, rths_controller_options *copt,
                                 rths_plant_options *popt, rths_error *err) {
    int rc = rths_controller_config_read(cfg, copt, err);
    if (!rc) rc = rths_plant_config_read(cfg, popt, err);
    if (rc) return rc;
    double samples = round(popt->delay_s * copt->sample_rate_hz);
    if (samples > RTHS_PLANT_MAX_DELAY_SAMPLES)
        return rths_config_error_at(cfg, "rig.shaker.delay_s", err,
                                    "%g s is %.0f samples at controller.sample_rate_hz = %g; the "
                                    "shaker's delay line holds at most %d",
                                    popt->delay_s, samples, copt->sample_rate_hz,
                                    RTHS_PLANT_MAX_DELAY_SAMPLES);
    return RTHS_OK;
}

int rths_sample_loop_create(const rths_setup *setup, const rths_controller_options *copt,
                            const rths_plant_options *popt, rths_sample_loop **out,
                            rths_error *err) {
    *out = NULL;
    rths_sample_loop *l = calloc(1, sizeof *l);
    if (!l) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    /* forcing on an internal physical DoF: the plant applies it, in continuous time */
    rths_controller_options co = *copt;
    co.plant_applies_forcing = 1;
    int rc = rths_controller_create(setup, &co, &l->ctl, err);
    if (!rc) rc = rths_plant_create(setup, popt, copt->sample_rate_hz, &l->plant, err);
    if (rc) {
        rths_sample_loop_destroy(l);
        return rc;
    }
    rths_controller_arm(l->ctl, 0);
    *out = l;
    return RTHS_OK;
}

void rths_sample_loop_destroy(rths_sample_loop *l) {
    if (!l) return;
    rths_plant_destroy(l->plant);
    rths_controller_destroy(l->ctl);
    free(l);
}

double rths_sample_loop_run(rths_sample_loop *l, rths_controller_output *out) {
    rths_plant_read(l->plant, &l->sensors);
    double demand = rths_controller_step(l->ctl, &l->sensors, out);
    double amplitude_n, theta, omega_rad_s;
    rths_controller_forcing(l->ctl, &amplitude_n, &theta, &omega_rad_s);
    rths_plant_set_forcing(l->plant, amplitude_n, theta, omega_rad_s);
    rths_plant_advance(l->plant, demand);
    /* A latched fault disarms: after the reset, excitation needs an explicit arm (the step alone
     * only ramps while the fault is latched and would resume on reset). */
    if (rths_controller_fault(l->ctl) != RTHS_RIG_OK && rths_controller_armed(l->ctl))
        rths_controller_arm(l->ctl, 0);
    return demand;
}

int rths_sample_loop_arm(rths_sample_loop *l) {
    if (rths_controller_fault(l->ctl) != RTHS_RIG_OK) return RTHS_EFAIL;
    rths_controller_arm(l->ctl, 1);
    return RTHS_OK;
}

rths_controller *rths_sample_loop_controller(rths_sample_loop *l) {
    return l->ctl;
}

rths_plant *rths_sample_loop_plant(rths_sample_loop *l) {
    return l->plant;
}
