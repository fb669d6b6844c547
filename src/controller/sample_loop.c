/* The per-sample loop (see controller.h): the controller step and a device (io.h: the reference
 * plug-in over the simulated plant, or a lab's plug-in) joined at the per-sample I/O seam, once,
 * for every user. */
#include "rths/controller.h"

#include <math.h>
#include <stdlib.h>

/* A seeded random perturbation added to the first actuator's demand (the experimental Floquet
 * estimate, docs/method.md, "Experimental Floquet multipliers"): white normal numbers held per
 * sample, through two cascaded first-order low-passes (band-limited: less content above what the
 * host's phase grid resolves), scaled so the output has the requested RMS. Fixed-size state:
 * the per-sample path stays allocation- and library-free. */
typedef struct {
    int on;
    rths_rng rng;
    double alpha;   /* low-pass pole per sample (0: white) */
    double gain;    /* white input scale giving the requested output RMS */
    double s1, s2;  /* the two filter states */
    double value_v; /* the perturbation added at the last sample */
} demand_perturbation;

struct rths_sample_loop {
    rths_controller *ctl;
    rths_io *io;
    rths_sensor_sample sensors; /* preallocated: read into every sample */
    rths_io_demand demand;      /* preallocated: written every sample */
    demand_perturbation perturb;
    int next_late;      /* rths_sample_loop_mark_late: the next sample is late */
    int watchdog_armed; /* the device's hardware watchdog is kicked every sample */
};

/* Declared in rig_virtual.h (the virtual rig is its user). */
int rths_sample_loop_set_perturbation(rths_sample_loop *l, double rms_v, double cutoff_hz,
                                      double sample_rate_hz, uint64_t seed);
double rths_sample_loop_perturbation_v(const rths_sample_loop *l);

int rths_sample_loop_set_perturbation(rths_sample_loop *l, double rms_v, double cutoff_hz,
                                      double sample_rate_hz, uint64_t seed) {
    demand_perturbation *p = &l->perturb;
    if (!(rms_v >= 0 && rms_v < 1e3) || !(cutoff_hz >= 0) || !(sample_rate_hz > 0))
        return RTHS_EINPUT;
    *p = (demand_perturbation){.on = rms_v > 0};
    if (!p->on) return RTHS_OK;
    rths_rng_seed(&p->rng, seed);
    /* the cascade ((1 - a) / (1 - a z^-1))^2 driven by unit white noise has the variance
     * (1 - a)^4 sum_k (k + 1)^2 a^2k = (1 - a)^4 (1 + a^2) / (1 - a^2)^3 */
    double a = cutoff_hz > 0 ? exp(-2 * M_PI * cutoff_hz / sample_rate_hz) : 0.0;
    double var = pow(1 - a, 4) * (1 + a * a) / pow(1 - a * a, 3);
    p->alpha = a;
    p->gain = rms_v / sqrt(var);
    return RTHS_OK;
}

double rths_sample_loop_perturbation_v(const rths_sample_loop *l) {
    return l->perturb.value_v;
}

static double next_perturbation(demand_perturbation *p) {
    if (!p->on) return 0.0;
    double w = p->gain * rths_rng_normal(&p->rng);
    p->s1 = p->alpha * p->s1 + (1 - p->alpha) * w;
    p->s2 = p->alpha * p->s2 + (1 - p->alpha) * p->s1;
    return p->value_v = p->s2;
}

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

int rths_sample_loop_create_io(const rths_setup *setup, const rths_controller_options *copt,
                               rths_io *io, rths_sample_loop **out, rths_error *err) {
    *out = NULL;
    rths_sample_loop *l = calloc(1, sizeof *l);
    if (!l) {
        rths_io_destroy(io);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    l->io = io;
    /* forcing on an internal physical DoF: the device applies it (the simulated plant does, in
     * continuous time), or the setup is refused */
    rths_controller_options co = *copt;
    co.plant_applies_forcing = rths_io_info(io)->applies_internal_forcing;
    int rc = rths_controller_create(setup, &co, &l->ctl, err);
    if (rc) {
        rths_sample_loop_destroy(l);
        return rc;
    }
    rths_controller_arm(l->ctl, 0);
    *out = l;
    return RTHS_OK;
}

int rths_sample_loop_create(const rths_setup *setup, const rths_controller_options *copt,
                            const rths_plant_options *popt, rths_sample_loop **out,
                            rths_error *err) {
    *out = NULL;
    rths_io *io = NULL;
    int rc = rths_io_open_virtual(setup, popt, copt->sample_rate_hz, &io, err);
    return rc ? rc : rths_sample_loop_create_io(setup, copt, io, out, err);
}

int rths_sample_loop_create_configured(rths_config *cfg, const rths_setup *setup,
                                       const rths_controller_options *copt, rths_sample_loop **out,
                                       rths_error *err) {
    *out = NULL;
    /* before any device opens: a sensor sample carries at most RTHS_MAX_SENSED_DOFS */
    int rc = rths_controller_check_sensed_dofs(&setup->split, err);
    if (rc) return rc;
    const char *path = NULL;
    rc = rths_config_get_string(cfg, "io.plugin", 0, NULL, &path, err);
    if (rc) return rc;
    rths_io_open_args args = {.abi_version = RTHS_IO_ABI_VERSION,
                              .sample_rate_hz = copt->sample_rate_hz,
                              .physical_dofs = setup->split.np,
                              .config = cfg,
                              .section = "io"};
    rths_io *io = NULL;
    /* an empty io.plugin (an unset variable in a lab's script) must not run the simulated plant */
    if (path && !path[0])
        return rths_config_error_at(cfg, "io.plugin", err,
                                    "is empty; give the plug-in's shared object by a path "
                                    "(e.g. ./lab_daq.so), or leave the key out for the simulated "
                                    "plant");
    if (path)
        rc = rths_io_load(path, &args, &io, err);
    else
        rc = rths_io_open_table(&rths_io_virtual_plugin, "virtual plant", &args, &io, err);
    return rc ? rc : rths_sample_loop_create_io(setup, copt, io, out, err);
}

void rths_sample_loop_destroy(rths_sample_loop *l) {
    if (!l) return;
    rths_io_destroy(l->io); /* safe state, then close */
    rths_controller_destroy(l->ctl);
    free(l);
}

double rths_sample_loop_run(rths_sample_loop *l, rths_controller_output *out) {
    /* a failed read leaves NaN in the sample: the step latches the non-finite fault; a device's
     * own limit (the actuator's stroke, velocity, force) latches like the controller's */
    int device = rths_io_read(l->io, &l->sensors);
    if (device > 0) {
        rths_fault_detail why = {.fault = device <= RTHS_RIG_FAULT_WATCHDOG ? device
                                                                            : RTHS_RIG_FAULT_LINK,
                                 .cause = RTHS_FAULT_CAUSE_DEVICE};
        rths_controller_trip_detail(l->ctl, &why);
    }
    /* Integrity counts of the open period (signals.h): the sample's lateness and its readings
     * before the step, which may close the period they belong to; the demand's clipping after
     * the write, in the period over which the demand acts. */
    rths_controller_count_sample(l->ctl, l->next_late, 0,
                                 (rths_io_read_flags(l->io) & RTHS_IO_SAMPLE_SENSOR_SATURATED));
    l->next_late = 0;
    double demand = rths_controller_step(l->ctl, &l->sensors, out);
    l->demand.n_demands = rths_controller_interface_dofs(l->ctl);
    rths_controller_demands(l->ctl, l->demand.demand_dof_v);
    /* the perturbation goes to the actuator only, past the controller's own limit check; never
     * once a fault is latched (the ramp to zero must reach zero) */
    if (l->perturb.on && rths_controller_fault(l->ctl) == RTHS_RIG_OK) {
        double dv = next_perturbation(&l->perturb);
        demand += dv;
        l->demand.demand_dof_v[0] += dv;
    }
    l->demand.demand_v = demand;
    rths_controller_forcing(l->ctl, &l->demand.forcing_amplitude_n, &l->demand.forcing_theta_rad,
                            &l->demand.forcing_omega_rad_s);
    rths_io_write(l->io, &l->demand);
    if (rths_io_write_flags(l->io) & RTHS_IO_SAMPLE_DEMAND_CLIPPED)
        rths_controller_count_sample(l->ctl, 0, 1, 0);
    if (l->watchdog_armed) rths_io_watchdog_kick(l->io);
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

void rths_sample_loop_mark_late(rths_sample_loop *l) {
    l->next_late = 1;
}

void rths_sample_loop_safe_state(rths_sample_loop *l) {
    rths_io_safe_state(l->io);
}

int rths_sample_loop_watchdog_arm(rths_sample_loop *l, double timeout_s, rths_error *err) {
    int rc = rths_io_watchdog_arm(l->io, timeout_s, err);
    if (!rc) l->watchdog_armed = 1;
    return rc;
}

rths_controller *rths_sample_loop_controller(rths_sample_loop *l) {
    return l->ctl;
}

rths_plant *rths_sample_loop_plant(rths_sample_loop *l) {
    return rths_io_virtual_plant(l->io);
}

const rths_io_device_info *rths_sample_loop_device(const rths_sample_loop *l) {
    return rths_io_info(l->io);
}
