/* The virtual laboratory's options read from the configuration (rig.shaker, rig.actuator,
 * rig.sensors, rig.noise; docs/config.md). */
#include "plant/plant_internal.h"

#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* A list of at most RTHS_ACTUATOR_MAX_ORDER + 1 coefficients into a fixed array. */
static int coefficients_read(rths_config *cfg, const char *key, int required, double *out,
                             int *count, rths_error *err) {
    double *v = NULL;
    int n = 0, rc = rths_config_get_double_list(cfg, key, required, &v, &n, err);
    if (!rc && n > RTHS_ACTUATOR_MAX_ORDER + 1)
        rc = rths_config_error_at(cfg, key, err, "%d coefficients; at most %d (order %d)", n,
                                  RTHS_ACTUATOR_MAX_ORDER + 1, RTHS_ACTUATOR_MAX_ORDER);
    if (!rc && rths_config_has(cfg, key) && n == 0)
        rc = rths_config_error_at(cfg, key, err, "needs at least one coefficient");
    for (int i = 0; !rc && i < n; i++)
        out[i] = v[i];
    if (!rc && n > 0) *count = n;
    free(v);
    return rc;
}

/* rig.sensors.NAME.adc_bits, adc_range_v, units_per_v, noise_v */
static int adc_config_read(rths_config *cfg, const char *name, rths_adc_spec *adc,
                           rths_error *err) {
    char k_bits[96], k_range[96], k_units[96], k_noise[96];
    snprintf(k_bits, sizeof k_bits, "rig.sensors.%s.adc_bits", name);
    snprintf(k_range, sizeof k_range, "rig.sensors.%s.adc_range_v", name);
    snprintf(k_units, sizeof k_units, "rig.sensors.%s.units_per_v", name);
    snprintf(k_noise, sizeof k_noise, "rig.sensors.%s.noise_v", name);
    long bits = adc->bits;
    int rc;
    if ((rc = rths_config_get_int(cfg, k_bits, 0, bits, 0, 32, &bits, err)) ||
        (rc = rths_config_get_double_ex(cfg, k_range, 0, adc->range_v, 0, 1e4, RTHS_CONFIG_LO_OPEN,
                                        &adc->range_v, err)) ||
        (rc = rths_config_get_double_ex(cfg, k_units, 0, adc->units_per_v, 0, 1e9,
                                        RTHS_CONFIG_LO_OPEN, &adc->units_per_v, err)) ||
        (rc = rths_config_get_double(cfg, k_noise, 0, adc->noise_v, 0, 1e3, &adc->noise_v, err)))
        return rc;
    adc->bits = (int)bits;
    return RTHS_OK;
}

/* rig.actuator.limits and rig.actuator.dac: for either model. */
static int actuator_limits_read(rths_config *cfg, rths_actuator_options *a, rths_error *err) {
    static const char *const clip[] = {"fault", "clip", NULL}, *const flag[] = {"fault", "flag",
                                                                                NULL};
    long bits = a->dac_bits;
    int rc;
    if ((rc = rths_config_get_double(cfg, "rig.actuator.limits.force_n", 0, a->force_limit_n, 0,
                                     1e9, &a->force_limit_n, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.limits.force_action", 0, a->force_clip,
                                     clip, &a->force_clip, err)) ||
        (rc = rths_config_get_double(cfg, "rig.actuator.limits.stroke_m", 0, a->stroke_limit_m, 0,
                                     100, &a->stroke_limit_m, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.limits.stroke_action", 0, a->stroke_flag,
                                     flag, &a->stroke_flag, err)) ||
        (rc = rths_config_get_double(cfg, "rig.actuator.limits.velocity_m_per_s", 0,
                                     a->velocity_limit_m_per_s, 0, 1e3, &a->velocity_limit_m_per_s,
                                     err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.limits.velocity_action", 0,
                                     a->velocity_flag, flag, &a->velocity_flag, err)) ||
        (rc = rths_config_get_int(cfg, "rig.actuator.dac.bits", 0, bits, 0, 32, &bits, err)) ||
        (rc = rths_config_get_double_ex(cfg, "rig.actuator.dac.range_v", 0, a->dac_range_v, 0, 1e4,
                                        RTHS_CONFIG_LO_OPEN, &a->dac_range_v, err)))
        return rc;
    a->dac_bits = (int)bits;
    return RTHS_OK;
}

/* rig.actuator.velocity_feedback: a number k_v (V(s) = k_v) or a list, V(s) in descending
 * powers of s (plant.h), each coefficient within +-1e15. */
static int velocity_feedback_read(rths_config *cfg, rths_actuator_options *a, rths_error *err) {
    static const char *const key = "rig.actuator.velocity_feedback";
    double *list = NULL;
    int count = 0;
    rths_error local;
    int rc = rths_config_get_double_list(cfg, key, 0, &list, &count, &local);
    if (rc != RTHS_OK || count == 0) {
        free(list);
        /* a list with a bad entry: its own message, not the scalar reader's "got a list" */
        if (rc != RTHS_OK && !strstr(local.msg, "expected a list")) {
            *err = local;
            return rc;
        }
        a->velocity_feedback_count = 0;
        return rths_config_get_double(cfg, key, 0, 0, -1e15, 1e15, &a->velocity_feedback, err);
    }
    if (count > RTHS_ACTUATOR_MAX_ORDER) rc = RTHS_EINPUT;
    for (int i = 0; !rc && i < count; i++)
        if (!(fabs(list[i]) <= 1e15)) {
            rc = rths_config_error_at(cfg, key, err,
                                      "entry %d: must be a finite number within +-1e15 (got %g)",
                                      i + 1, list[i]);
            free(list);
            return rc;
        }
    if (rc) {
        free(list);
        return rths_config_error_at(cfg, key, err,
                                    "%d coefficients; at most %d (degree below the denominator's, "
                                    "at most %d)",
                                    count, RTHS_ACTUATOR_MAX_ORDER, RTHS_ACTUATOR_MAX_ORDER);
    }
    for (int i = 0; i < count; i++)
        a->velocity_feedback_poly[i] = list[i];
    a->velocity_feedback_count = count;
    a->velocity_feedback = 0;
    free(list);
    return RTHS_OK;
}

/* rig.actuator: the model and, for transfer_function, its coefficients, delay and hold. */
static int actuator_config_read(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    static const char *const models[] = {"shaker", "transfer_function", NULL};
    static const char *const outputs[] = {"force", "displacement", NULL};
    static const char *const holds[] = {"linear", "step", NULL};
    rths_actuator_options *a = &opt->actuator;
    int model = (int)a->model, output = 0, rc;
    if ((rc = rths_config_get_choice(cfg, "rig.actuator.model", 0, model, models, &model, err)) ||
        (rc = actuator_limits_read(cfg, a, err)))
        return rc;
    a->model = (rths_actuator_model)model;
    int tf = a->model == RTHS_ACTUATOR_TRANSFER_FUNCTION;
    static const char *const tf_keys[] = {
        "numerator", "denominator", "velocity_feedback",           "output",
        "delay_s",   "hold",        "connection_stiffness_n_per_m"};
    for (int i = 0; !tf && i < 7; i++) {
        char key[64];
        snprintf(key, sizeof key, "rig.actuator.%s", tf_keys[i]);
        if (rths_config_has(cfg, key))
            return rths_config_error_at(cfg, key, err,
                                        "applies to rig.actuator.model: transfer_function only");
    }
    if (!tf) return RTHS_OK;
    /* a transfer function's demand goes through a DAC (held as a step) with no delay unless
     * told: the shaker's defaults do not carry over */
    int hold = 1;
    opt->delay_s = 0;
    if ((rc = coefficients_read(cfg, "rig.actuator.numerator", 1, a->numerator, &a->numerator_count,
                                err)) ||
        (rc = coefficients_read(cfg, "rig.actuator.denominator", 1, a->denominator,
                                &a->denominator_count, err)) ||
        (rc = velocity_feedback_read(cfg, a, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.output", 0, 0, outputs, &output, err)) ||
        (rc = rths_config_get_double(cfg, "rig.actuator.delay_s", 0, 0, 0, 0.1, &opt->delay_s,
                                     err)) ||
        (rc = rths_config_get_choice(cfg, "rig.actuator.hold", 0, hold, holds, &hold, err)))
        return rc;
    opt->linear_hold = hold == 0;
    a->displacement_output = output == 1;
    if (a->displacement_output &&
        (rc = rths_config_get_double_ex(cfg, "rig.actuator.connection_stiffness_n_per_m", 1, 0, 0,
                                        1e12, RTHS_CONFIG_LO_OPEN, &a->connection_stiffness_n_per_m,
                                        err)))
        return rc;
    if (!a->displacement_output &&
        rths_config_has(cfg, "rig.actuator.connection_stiffness_n_per_m"))
        return rths_config_error_at(cfg, "rig.actuator.connection_stiffness_n_per_m", err,
                                    "applies to rig.actuator.output: displacement only");
    if (a->displacement_output && a->force_clip)
        return rths_config_error_at(cfg, "rig.actuator.limits.force_action", err,
                                    "clip needs rig.actuator.output: force (a displacement-output "
                                    "actuator can trip on its force: fault)");
    if (a->numerator_count > a->denominator_count)
        return rths_config_error_at(cfg, "rig.actuator.numerator", err,
                                    "degree %d above the denominator's %d: the actuator must be "
                                    "proper",
                                    a->numerator_count - 1, a->denominator_count - 1);
    if (a->denominator[0] == 0)
        return rths_config_error_at(cfg, "rig.actuator.denominator", err,
                                    "the leading coefficient must be nonzero");
    if (a->velocity_feedback_count >= a->denominator_count)
        return rths_config_error_at(
            cfg, "rig.actuator.velocity_feedback", err,
            "degree %d; over the denominator's degree %d it must be at most "
            "%d (V(s) x' / D(s) strictly proper)",
            a->velocity_feedback_count - 1, a->denominator_count - 1, a->denominator_count - 2);
    return RTHS_OK;
}

static int read_noise(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    const char *text = NULL;
    int rc = rths_config_get_string(cfg, "rig.noise", 0, NULL, &text, err);
    if (rc || !text) return rc;
    if (strcmp(text, "lab")) {
        rths_error bool_err;
        if (rths_config_get_bool(cfg, "rig.noise", 0, opt->noise, &opt->noise, &bool_err))
            return rths_config_error_at(cfg, "rig.noise", err,
                                        "expected true, false or lab, got '%s'", text);
        return RTHS_OK;
    }
    opt->noise = PLANT_NOISE_LAB;
    opt->laser.noise_std = 1e-6;
    opt->accelerometer.noise_std = 0.1;
    opt->load_cell.noise_std = 0.1;
    return RTHS_OK;
}

int rths_plant_config_read(rths_config *cfg, rths_plant_options *opt, rths_error *err) {
    /* substeps_per_sample 0 is the exact integrator; rk4 takes 8 substeps unless told */
    long seed = (long)opt->seed,
         substeps = opt->substeps_per_sample > 0 ? opt->substeps_per_sample : 8;
    static const char *const holds[] = {"linear", "step", NULL};
    static const char *const integrators[] = {"exact", "rk4", NULL};
    int hold = 0, integrator = 0;
    int rc;
    if ((rc = read_noise(cfg, opt, err)) ||
        (rc = rths_config_get_int(cfg, "rig.seed", 0, seed, 0, 2147483647L, &seed, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.plant_integrator", 0,
                                     opt->substeps_per_sample > 0 ? 1 : 0, integrators, &integrator,
                                     err)) ||
        (rc = rths_config_get_int(cfg, "rig.substeps_per_sample", 0, substeps, 1, 1000, &substeps,
                                  err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.gain_n_per_v", 0, opt->gain_n_per_v, 1e-6,
                                     1e6, &opt->gain_n_per_v, err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.delay_s", 0, opt->delay_s, 0, 0.1,
                                     &opt->delay_s, err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.lag_cutoff_hz", 0, opt->lag_cutoff_hz, 0, 1e6,
                                     &opt->lag_cutoff_hz, err)) ||
        (rc = rths_config_get_choice(cfg, "rig.shaker.hold", 0, opt->linear_hold ? 0 : 1, holds,
                                     &hold, err)) ||
        (rc = rths_config_get_double(cfg, "rig.shaker.armature_mass_kg", 0, opt->armature_mass_kg,
                                     0, 1e3, &opt->armature_mass_kg, err)))
        return rc;
    opt->seed = (uint64_t)seed;
    if (integrator == 0 && rths_config_has(cfg, "rig.substeps_per_sample"))
        return rths_config_error_at(cfg, "rig.substeps_per_sample", err,
                                    "applies to rig.plant_integrator: rk4 only (the exact "
                                    "integrator has no substeps)");
    opt->substeps_per_sample = integrator == 1 ? (int)substeps : 0;
    opt->linear_hold = hold == 0;
    struct {
        const char *name;
        rths_sensor_spec *spec;
    } sensors[3] = {{"laser", &opt->laser},
                    {"accelerometer", &opt->accelerometer},
                    {"load_cell", &opt->load_cell}};
    static const char *const fields[4] = {"gain_error", "offset", "noise_std", "quantum"};
    rths_adc_spec *adcs[3] = {&opt->laser_adc, &opt->accelerometer_adc, &opt->load_cell_adc};
    for (int s = 0; s < 3; s++) {
        if ((rc = adc_config_read(cfg, sensors[s].name, adcs[s], err))) return rc;
        double *values[4] = {&sensors[s].spec->gain_error, &sensors[s].spec->offset,
                             &sensors[s].spec->noise_std, &sensors[s].spec->quantum};
        for (int f = 0; f < 4; f++) {
            char key[96];
            snprintf(key, sizeof key, "rig.sensors.%s.%s", sensors[s].name, fields[f]);
            double lo = f == 0 ? -0.5 : f == 1 ? -1e6 : 0, hi = f == 0 ? 0.5 : 1e6;
            if ((rc = rths_config_get_double(cfg, key, 0, *values[f], lo, hi, values[f], err)))
                return rc;
        }
    }
    return actuator_config_read(cfg, opt, err);
}
