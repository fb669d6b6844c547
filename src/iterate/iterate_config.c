/* `iteration` section of the test configuration. */
#include "rths/iterate.h"

#include <math.h>

/* iteration.trust_growth: 0 lifts the trust region; otherwise at least 1 (a region smaller than
 * the last accepted point would refuse the point itself) */
static int trust_growth_read(rths_config *cfg, rths_newton_options *newton, rths_error *err) {
    int rc = rths_config_get_double(cfg, "iteration.trust_growth", 0, newton->trust_growth, 0.0,
                                    1e6, &newton->trust_growth, err);
    if (!rc && newton->trust_growth > 0 && newton->trust_growth < 1)
        return rths_config_error_at(cfg, "iteration.trust_growth", err,
                                    "must be 0 (no trust region) or at least 1, not %g",
                                    newton->trust_growth);
    return rc;
}

/* The fitted evaluation and accuracy on demand (docs/method.md, "The fitted evaluation";
 * docs/config.md, iteration.settle.strategy, iteration.target_rel_se). */
static int settle_strategy_read(rths_config *cfg, rths_settle_options *settle, rths_error *err) {
    static const char *const strategies[] = {"wait", "fit", NULL};
    long v;
    int rc;
    if ((rc = rths_config_get_choice(cfg, "iteration.settle.strategy", 0, settle->strategy,
                                     strategies, &settle->strategy, err)))
        return rc;
    if ((rc = rths_config_get_int(cfg, "iteration.settle.fit_max_periods", 0,
                                  settle->fit_max_periods > 0 ? settle->fit_max_periods
                                                              : RTHS_SETTLE_FIT_MAX_PERIODS,
                                  8, 100000, &v, err)))
        return rc;
    settle->fit_max_periods = (int)v;
    /* docs/method.md, "The fitted evaluation": 4 leaves the record's length to the fit alone */
    if ((rc = rths_config_get_int(cfg, "iteration.settle.fit_min_periods", 0,
                                  settle->fit_min_periods > 0 ? settle->fit_min_periods
                                                              : RTHS_SETTLE_FIT_MIN_PERIODS,
                                  4, settle->fit_max_periods, &v, err)))
        return rc;
    settle->fit_min_periods = (int)v;
    /* docs/method.md, "The fitted evaluation": fewer than 3 lets a short record fit more poles */
    if ((rc = rths_config_get_int(cfg, "iteration.settle.fit_residual_margin", 0,
                                  settle->fit_residual_margin > 0 ? settle->fit_residual_margin
                                                                  : RTHS_SETTLE_FIT_RESIDUAL_MARGIN,
                                  1, 3, &v, err)))
        return rc;
    settle->fit_residual_margin = (int)v;
    if ((rc = rths_config_get_bool(cfg, "iteration.settle.fit_seed_poles", 0,
                                   settle->fit_seed_poles, &settle->fit_seed_poles, err)))
        return rc;
    if ((rc = rths_config_get_double(cfg, "iteration.target_rel_se", 0, settle->target_rel_se, 0.0,
                                     1.0, &settle->target_rel_se, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.max_rig_s_per_point", 0,
                                     settle->max_rig_s_per_point > 0
                                         ? settle->max_rig_s_per_point
                                         : RTHS_SETTLE_MAX_RIG_S_PER_POINT,
                                     1e-3, 1e6, &settle->max_rig_s_per_point, err)))
        return rc;
    return RTHS_OK;
}

int rths_iterate_config_read(rths_config *cfg, rths_settle_options *settle,
                             rths_newton_options *newton, int *harmonics, rths_error *err) {
    long v;
    int rc;
    if ((rc = rths_config_get_int(cfg, "iteration.harmonics", 0, *harmonics, 1,
                                  RTHS_MAX_MATCHED_HARMONICS, &v, err)))
        return rc;
    *harmonics = (int)v;
    if ((rc = rths_config_get_int(cfg, "iteration.max_iterations", 0, newton->max_iterations, 1,
                                  1000, &v, err)))
        return rc;
    newton->max_iterations = (int)v;
    if ((rc = rths_config_get_double(cfg, "iteration.rel_tolerance", 0, newton->rel_tolerance, 1e-9,
                                     1.0, &newton->rel_tolerance, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.abs_tolerance_m", 0, newton->abs_tolerance_m,
                                     0.0, 1.0, &newton->abs_tolerance_m, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.noise_factor", 0, newton->noise_factor, 0.0,
                                     100.0, &newton->noise_factor, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.fd_step_rel", 0, newton->fd_step_rel, 1e-6,
                                     1.0, &newton->fd_step_rel, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.fd_step_min_m", 0, newton->fd_step_min_m, 0.0,
                                     1.0, &newton->fd_step_min_m, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.line_search_min", 0, newton->min_damping, 1e-6,
                                     1.0, &newton->min_damping, err)) ||
        (rc = trust_growth_read(cfg, newton, err)))
        return rc;
    if ((rc = rths_config_get_bool(cfg, "iteration.fresh_jacobian", 0, newton->fresh_jacobian,
                                   &newton->fresh_jacobian, err)) ||
        (rc = rths_config_get_bool(cfg, "iteration.report_matched", 0, newton->report_matched,
                                   &newton->report_matched, err)))
        return rc;
    if ((rc = rths_config_get_int(cfg, "iteration.settle.fixed_wait_periods", 0,
                                  settle->fixed_wait_periods, 0, 100000, &v, err)))
        return rc;
    settle->fixed_wait_periods = (int)v;
    if ((rc = rths_config_get_int(cfg, "iteration.settle.min_wait_periods", 0,
                                  settle->min_wait_periods, 2, 100000, &v, err)))
        return rc;
    settle->min_wait_periods = (int)v;
    if ((rc = rths_config_get_int(cfg, "iteration.settle.max_wait_periods", 0,
                                  settle->max_wait_periods, 2, 1000000, &v, err)))
        return rc;
    settle->max_wait_periods = (int)v;
    if (settle->max_wait_periods < settle->min_wait_periods)
        return rths_config_error_at(cfg, "iteration.settle.max_wait_periods", err,
                                    "must be >= iteration.settle.min_wait_periods (%d)",
                                    settle->min_wait_periods);
    if ((rc = rths_config_get_int(cfg, "iteration.settle.average_periods", 0,
                                  settle->average_periods, 1, 100000, &v, err)))
        return rc;
    settle->average_periods = (int)v;
    if ((rc =
             rths_config_get_double(cfg, "iteration.settle.rel_tolerance", 0, settle->rel_tolerance,
                                    0.0, 1.0, &settle->rel_tolerance, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.settle.abs_tolerance_m", 0,
                                     settle->abs_tolerance_m, 0.0, 1.0, &settle->abs_tolerance_m,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "iteration.settle.noise_factor", 0, settle->noise_factor,
                                     0.0, 100.0, &settle->noise_factor, err)) ||
        (rc = rths_config_get_double(cfg, "iteration.min_snr", 0, newton->min_snr, 0.0, 1e6,
                                     &newton->min_snr, err)))
        return rc;
    if ((rc = settle_strategy_read(cfg, settle, err))) return rc;
    /* docs/method.md, "The fitted evaluation": 10 % less rig time per point on the bilinear
     * with the fit strategy, but its 3-SE coverage fell (99.5 to 97.3 % away from folds), so off
     * by default */
    if ((rc = rths_config_get_bool(cfg, "iteration.quadratic_predictor", 0,
                                   newton->quadratic_predictor, &newton->quadratic_predictor, err)))
        return rc;
    /* docs/method.md, "The corrector": 6-16 % less rig time on the nonlinear examples, but on the
     * Duffing example 93.5 % of the points away from folds within 3 SE (99.4 %), so off */
    return rths_config_get_bool(cfg, "iteration.secant_repair", 0, newton->secant_repair,
                                &newton->secant_repair, err);
}
