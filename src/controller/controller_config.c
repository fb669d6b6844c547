/* The `controller` configuration section. */
#include "rths/controller.h"

#include <math.h>
#include <stdlib.h>

/* controller.kp_per_dof, controller.kd_per_dof: a gain per interface DoF (V per m, or per rad
 * for a rotation; V s per m or rad), in the split's interface order; 0 or absent: the scalar. */
static int gains_per_dof(rths_config *cfg, const char *key, double *gains, rths_error *err) {
    double *list = NULL;
    int count = 0, rc = rths_config_get_double_list(cfg, key, 0, &list, &count, err);
    if (!rc && count > RTHS_MAX_INTERFACE_DOFS)
        rc = rths_config_error_at(cfg, key, err, "%d gains; at most %d interface DoFs", count,
                                  RTHS_MAX_INTERFACE_DOFS);
    for (int d = 0; !rc && d < count; d++) {
        if (!(isfinite(list[d]) && list[d] >= 0 && list[d] <= 1e9))
            rc = rths_config_error_at(cfg, key, err, "entry %d is %g; must be in [0, 1e9]", d + 1,
                                      list[d]);
        else
            gains[d] = list[d];
    }
    free(list);
    return rc;
}

/* controller.kp_matrix and kd_matrix: both or neither, the same size, at most 4 x 4, finite
 * (signs free: an actuator behind the cut pushes against a DoF's error). */
static int gain_matrices(rths_config *cfg, rths_controller_options *opt, rths_error *err) {
    static const char *const keys[2] = {"controller.kp_matrix", "controller.kd_matrix"};
    double *m[2] = {NULL, NULL}, *dst[2] = {opt->kp_matrix, opt->kd_matrix};
    int rows[2] = {0, 0}, cols[2] = {0, 0}, rc = RTHS_OK;
    int has[2] = {rths_config_has(cfg, keys[0]), rths_config_has(cfg, keys[1])};
    if (!has[0] && !has[1]) return RTHS_OK;
    for (int k = 0; k < 2 && !rc; k++) {
        if (!has[k]) {
            rc = rths_config_error_at(cfg, keys[!k], err,
                                      "needs %s too (both gain matrices, or "
                                      "neither)",
                                      keys[k]);
            break;
        }
        rc = rths_config_get_matrix(cfg, keys[k], 1, &m[k], &rows[k], &cols[k], err);
        if (!rc && (rows[k] > RTHS_MAX_INTERFACE_DOFS || cols[k] > RTHS_MAX_INTERFACE_DOFS))
            rc = rths_config_error_at(cfg, keys[k], err,
                                      "is %d x %d; at most %d x %d (a row per "
                                      "actuator, a column per interface DoF)",
                                      rows[k], cols[k], RTHS_MAX_INTERFACE_DOFS,
                                      RTHS_MAX_INTERFACE_DOFS);
        if (!rc && k == 1 && (rows[1] != rows[0] || cols[1] != cols[0]))
            rc = rths_config_error_at(cfg, keys[1], err, "is %d x %d but %s is %d x %d", rows[1],
                                      cols[1], keys[0], rows[0], cols[0]);
        for (int i = 0; !rc && i < rows[k] * cols[k]; i++)
            if (!(fabs(m[k][i]) <= 1e9))
                rc = rths_config_error_at(cfg, keys[k], err,
                                          "entry (%d, %d) = %g; must be "
                                          "finite, |gain| <= 1e9",
                                          i % rows[k] + 1, i / rows[k] + 1, m[k][i]);
        for (int i = 0; !rc && i < rows[k]; i++)
            for (int j = 0; j < cols[k]; j++)
                dst[k][i + j * RTHS_MAX_INTERFACE_DOFS] = RTHS_AT(m[k], rows[k], i, j);
    }
    if (!rc) opt->gain_matrix_rows = rows[0], opt->gain_matrix_cols = cols[0];
    free(m[0]), free(m[1]);
    return rc;
}

/* output.dofs: assembly DoFs (1-based) reported beside the interface, each once. The assembly's
 * size is checked at create (rths_controller_create), which knows the setup. */
static int output_dofs_read(rths_config *cfg, rths_controller_options *opt, rths_error *err) {
    int *list = NULL, count = 0;
    int rc = rths_config_get_int_list(cfg, "output.dofs", 0, &list, &count, err);
    if (!rc && count > RTHS_MAX_OUTPUT_DOFS)
        rc = rths_config_error_at(cfg, "output.dofs", err, "%d DoFs; at most %d", count,
                                  RTHS_MAX_OUTPUT_DOFS);
    for (int i = 0; !rc && i < count; i++) {
        if (list[i] < 1)
            rc = rths_config_error_at(cfg, "output.dofs", err,
                                      "entry %d is %d; DoFs are numbered from 1", i + 1, list[i]);
        for (int j = 0; !rc && j < i; j++)
            if (list[j] == list[i])
                rc = rths_config_error_at(cfg, "output.dofs", err,
                                          "DoF %d is listed twice (entries %d and %d)", list[i],
                                          j + 1, i + 1);
        if (!rc) opt->output_dof[i] = list[i] - 1;
    }
    if (!rc) opt->output_dofs = count;
    free(list);
    return rc;
}

/* The Krylov reduction of a sparse model's numerical side (krylov_reduce.h): its keys, and the
 * band it must be exact over, the sweep's (continuation.start_hz, end_hz, either order) widened
 * by RTHS_CONTROLLER_KRYLOV_BAND_MARGIN of its width each side. The continuation reads and checks
 * those keys itself; without them the band stays unset and only a sparse setup needs it
 * (rths_controller_create names the keys then). */
static int krylov_read(rths_config *cfg, rths_krylov_options *opt, rths_error *err) {
    int rc = rths_krylov_config_read(cfg, opt, err);
    if (rc || !rths_config_has(cfg, "continuation.start_hz") ||
        !rths_config_has(cfg, "continuation.end_hz"))
        return rc;
    double f[2];
    rc = rths_config_get_double(cfg, "continuation.start_hz", 0, 0, 1e-3, 1e5, &f[0], err);
    if (!rc) rc = rths_config_get_double(cfg, "continuation.end_hz", 0, 0, 1e-3, 1e5, &f[1], err);
    if (rc) return rc;
    double lo = fmin(f[0], f[1]), hi = fmax(f[0], f[1]);
    double margin = RTHS_CONTROLLER_KRYLOV_BAND_MARGIN * (hi - lo);
    opt->start_hz = fmax(lo - margin, 0.0);
    opt->end_hz = hi + margin;
    return RTHS_OK;
}

int rths_controller_config_read(rths_config *cfg, rths_controller_options *opt, rths_error *err) {
    static const char *const schemes[] = {"implicit_euler", "trapezoidal", "exact_zoh", "exact_foh",
                                          NULL};
    int scheme = (int)opt->scheme, rc;
    if ((rc = rths_config_get_double(cfg, "controller.sample_rate_hz", 0, opt->sample_rate_hz, 100,
                                     1e6, &opt->sample_rate_hz, err)) ||
        (rc = rths_config_get_choice(cfg, "controller.scheme", 0, scheme, schemes, &scheme, err)) ||
        (rc = rths_config_get_double(cfg, "controller.kp_v_per_m", 0, opt->kp_v_per_m, 0, 1e9,
                                     &opt->kp_v_per_m, err)) ||
        (rc = rths_config_get_double(cfg, "controller.kd_v_s_per_m", 0, opt->kd_v_s_per_m, 0, 1e9,
                                     &opt->kd_v_s_per_m, err)) ||
        (rc = rths_config_get_double(cfg, "controller.grounding_kp_n_per_m", 0,
                                     opt->grounding_kp_n_per_m, 0, 1e12, &opt->grounding_kp_n_per_m,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "controller.grounding_kd_n_s_per_m", 0,
                                     opt->grounding_kd_n_s_per_m, 0, 1e12,
                                     &opt->grounding_kd_n_s_per_m, err)) ||
        (rc = rths_config_get_double(cfg, "controller.velocity_cutoff_hz", 0,
                                     opt->velocity_cutoff_hz, 0, 1e6, &opt->velocity_cutoff_hz,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "controller.limits.demand_v", 0, opt->demand_limit_v,
                                     1e-6, 1e6, &opt->demand_limit_v, err)) ||
        (rc = rths_config_get_double(cfg, "controller.limits.displacement_m", 0,
                                     opt->displacement_limit_m, 1e-9, 10,
                                     &opt->displacement_limit_m, err)) ||
        (rc = rths_config_get_double(cfg, "controller.limits.force_n", 0, opt->force_limit_n, 1e-6,
                                     1e9, &opt->force_limit_n, err)) ||
        (rc = rths_config_get_double(cfg, "controller.ramp_time_s", 0, opt->ramp_time_s, 0, 60,
                                     &opt->ramp_time_s, err)) ||
        (rc = rths_config_get_bool(cfg, "controller.track_static", 0, opt->track_static,
                                   &opt->track_static, err)) ||
        (rc = rths_config_get_double(cfg, "controller.min_frequency_hz", 0, opt->min_frequency_hz,
                                     1e-3, 1e3, &opt->min_frequency_hz, err)) ||
        (rc = rths_config_get_double(cfg, "controller.max_pending_s", 0, opt->max_pending_s, 0,
                                     3600, &opt->max_pending_s, err)) ||
        (rc = rths_config_get_double(cfg, "controller.transition_periods", 0,
                                     opt->transition_periods, 0, 100, &opt->transition_periods,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "controller.max_overrun_share", 0, opt->max_overrun_share,
                                     0, 1, &opt->max_overrun_share, err)) ||
        (rc = gains_per_dof(cfg, "controller.kp_per_dof", opt->kp_dof_v_per_m, err)) ||
        (rc = gains_per_dof(cfg, "controller.kd_per_dof", opt->kd_dof_v_s_per_m, err)) ||
        (rc = gains_per_dof(cfg, "controller.grounding_kp_per_dof", opt->grounding_kp_dof, err)) ||
        (rc = gains_per_dof(cfg, "controller.grounding_kd_per_dof", opt->grounding_kd_dof, err)) ||
        (rc = gain_matrices(cfg, opt, err)) ||
        (rc = rths_reduction_config_read(cfg, &opt->reduction, err)) ||
        (rc = krylov_read(cfg, &opt->krylov, err)) || (rc = output_dofs_read(cfg, opt, err)))
        return rc;
    opt->scheme = (rths_scheme)scheme;
    /* the default cutoff (1 kHz, chosen at the seed's 10 kHz) is capped at a quarter of a lower
     * rate, so every rate in range runs with the defaults; a cutoff the user sets is kept */
    if (!rths_config_has(cfg, "controller.velocity_cutoff_hz") &&
        opt->velocity_cutoff_hz > 0.25 * opt->sample_rate_hz)
        opt->velocity_cutoff_hz = 0.25 * opt->sample_rate_hz;
    if (opt->velocity_cutoff_hz >= 0.5 * opt->sample_rate_hz)
        return rths_config_error_at(cfg, "controller.velocity_cutoff_hz", err,
                                    "must be below half the sample rate (%g Hz)",
                                    0.5 * opt->sample_rate_hz);
    return RTHS_OK;
}
