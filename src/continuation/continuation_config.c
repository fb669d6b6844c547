/* `continuation` section of the test configuration. */
#include "rths/continuation.h"

int rths_continuation_config_read(rths_config *cfg, rths_continuation_options *opt,
                                  rths_error *err) {
    int rc;
    static const char *const methods[] = {"natural", "arclength", NULL};
    static const char *const predictors[] = {"secant", "model", NULL};
    int method = (int)opt->method, predictor = opt->model_predictor ? 1 : 0;
    long v;
    if ((rc = rths_config_get_double(cfg, "continuation.start_hz", 0, opt->start_hz, 1e-3, 1e5,
                                     &opt->start_hz, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.end_hz", 0, opt->end_hz, 1e-3, 1e5,
                                     &opt->end_hz, err)) ||
        (rc = rths_config_get_choice(cfg, "continuation.method", 0, method, methods, &method,
                                     err)) ||
        (rc = rths_config_get_choice(cfg, "continuation.predictor", 0, predictor, predictors,
                                     &predictor, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.initial_step_hz", 0, opt->initial_step_hz,
                                     1e-6, 1e3, &opt->initial_step_hz, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.max_step_hz", 0, opt->max_step_hz, 1e-6,
                                     1e3, &opt->max_step_hz, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.min_step", 0, opt->min_step, 1e-12, 1.0,
                                     &opt->min_step, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.max_step", 0, opt->max_step, 1e-9, 10.0,
                                     &opt->max_step, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.grow", 0, opt->grow, 1.0, 10.0, &opt->grow,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "continuation.shrink", 0, opt->shrink, 0.01, 0.99,
                                     &opt->shrink, err)) ||
        (rc = rths_config_get_double(cfg, "continuation.amplitude_scale_m", 0,
                                     opt->amplitude_scale_m, 0.0, 1.0, &opt->amplitude_scale_m,
                                     err)))
        return rc;
    opt->method = (rths_cont_method)method;
    opt->model_predictor = predictor;
    if ((rc = rths_config_get_int(cfg, "continuation.max_points", 0, opt->max_points, 2, 100000, &v,
                                  err)))
        return rc;
    opt->max_points = (int)v;
    if ((rc = rths_config_get_int(cfg, "continuation.max_failures", 0, opt->max_failures, 0, 1000,
                                  &v, err)))
        return rc;
    opt->max_failures = (int)v;
    if (opt->start_hz == opt->end_hz)
        return rths_config_error_at(cfg, "continuation.end_hz", err,
                                    "must differ from continuation.start_hz (%g Hz)",
                                    opt->start_hz);
    if (opt->min_step > opt->max_step)
        return rths_config_error_at(cfg, "continuation.min_step", err,
                                    "must not exceed continuation.max_step (%g)", opt->max_step);
    return RTHS_OK;
}
