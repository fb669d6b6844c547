/* The experimental Floquet estimate at a converged point (run.h; docs/method.md, "Experimental
 * Floquet multipliers"): configuration, the perturbed record, the phase grid, the fit. */
#include "rths/model.h"
#include "rths/run.h"
#include "rths/stability.h"
#include "run/frf_internal.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>

void rths_floquet_measure_defaults(rths_floquet_measure_options *o) {
    *o = (rths_floquet_measure_options){.periods = 120,
                                        .perturbation_v = 0.02,
                                        .cutoff_hz = 5.0,
                                        .samples_per_period = 16,
                                        .sample_rate_hz = 10000.0,
                                        .seed = 1};
    rths_floquet_defaults(&o->fit);
    o->fit.max_order = 24;
}

int rths_floquet_measure_config_read(rths_config *cfg, rths_floquet_measure_options *o,
                                     rths_error *err) {
    long periods = o->periods, grid = o->samples_per_period, order = o->fit.max_order,
         harmonics = o->fit.phase_harmonics, varying = o->fit.varying_lags,
         bins = o->fit.phase_bins;
    int rc;
    if ((rc = rths_config_get_bool(cfg, "stability.experimental_floquet", 0, o->enabled,
                                   &o->enabled, err)) ||
        (rc = rths_config_get_int(cfg, "stability.floquet_periods", 0, periods, 8, 100000, &periods,
                                  err)) ||
        (rc = rths_config_get_double(cfg, "stability.floquet_perturbation_v", 0, o->perturbation_v,
                                     1e-9, 10, &o->perturbation_v, err)) ||
        (rc = rths_config_get_double(cfg, "stability.floquet_cutoff_hz", 0, o->cutoff_hz, 0, 1e5,
                                     &o->cutoff_hz, err)) ||
        (rc = rths_config_get_int(cfg, "stability.floquet_samples_per_period", 0, grid, 8, 400,
                                  &grid, err)) ||
        (rc = rths_config_get_int(cfg, "stability.floquet_max_order", 0, order, 2,
                                  RTHS_FLOQUET_MAX_ORDER, &order, err)) ||
        (rc = rths_config_get_int(cfg, "stability.floquet_phase_harmonics", 0, harmonics, 0,
                                  RTHS_FLOQUET_MAX_PHASE_HARMONICS, &harmonics, err)) ||
        (rc = rths_config_get_int(cfg, "stability.floquet_phase_bins", 0, bins, 0, 400, &bins,
                                  err)) ||
        (rc = rths_config_get_int(cfg, "stability.floquet_varying_lags", 0, varying, 0,
                                  RTHS_FLOQUET_MAX_ORDER, &varying, err)))
        return rc;
    /* only when on (virtual rig only): with --rig the controller section is the process's, and
     * reading one of its keys here would make the host judge the rest of it */
    if (o->enabled &&
        (rc = rths_config_get_double(cfg, "controller.sample_rate_hz", 0, o->sample_rate_hz, 100,
                                     1e6, &o->sample_rate_hz, err)))
        return rc;
    if (2 * harmonics >= grid)
        return rths_config_error_at(cfg, "stability.floquet_phase_harmonics", err,
                                    "%ld phase harmonics need more than %ld samples per period "
                                    "(stability.floquet_samples_per_period)",
                                    harmonics, 2 * harmonics);
    o->periods = (int)periods;
    o->samples_per_period = (int)grid;
    o->fit.max_order = (int)order;
    o->fit.phase_harmonics = (int)harmonics;
    o->fit.varying_lags = (int)(varying < order ? varying : order);
    if (bins > grid)
        return rths_config_error_at(cfg, "stability.floquet_phase_bins", err,
                                    "%ld bins on %ld samples per period "
                                    "(stability.floquet_samples_per_period): at most one bin "
                                    "per sample",
                                    bins, grid);
    o->fit.phase_bins = (int)bins;
    rths_chart_options chart;
    return rths_chart_config_read(cfg, &chart, err);
}

int rths_floquet_measure(rths_rig *rig, double frequency_hz, const rths_floquet_measure_options *o,
                         uint64_t seed, rths_floquet_estimate *est, double *rig_time_s,
                         rths_error *err) {
    *rig_time_s = 0;
    if (!(frequency_hz > 0))
        return rths_error_set(err, RTHS_EINPUT, "Floquet estimate at %g Hz", frequency_hz);
    long max_samples = (long)((o->periods + 3) * o->sample_rate_hz / frequency_hz * 1.05) + 1000;
    rths_perturbed_sample *rec = malloc((size_t)max_samples * sizeof *rec);
    size_t grid_n = (size_t)o->periods * (size_t)o->samples_per_period;
    double *buf = malloc(3 * (size_t)max_samples * sizeof *buf);
    double *u = malloc(grid_n * sizeof *u), *y = malloc(grid_n * sizeof *y);
    int rc = RTHS_OK, n = 0, periods = 0;
    if (!rec || !buf || !u || !y) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    rths_perturbation p = {.rms_v = o->perturbation_v, .cutoff_hz = o->cutoff_hz, .seed = seed};
    double t0 = rths_rig_time_s(rig);
    if (!rc) rc = rths_rig_record_perturbed(rig, &p, o->periods, (int)max_samples, rec, &n, err);
    *rig_time_s = rths_rig_time_s(rig) - t0;
    if (!rc) {
        double *phase = buf, *xp = buf + max_samples, *xn = buf + 2 * max_samples;
        for (int i = 0; i < n; i++) {
            phase[i] = rec[i].phase_rad;
            xp[i] = rec[i].x_phys_m;
            xn[i] = rec[i].x_num_m;
        }
        rc = rths_floquet_phase_grid(phase, xp, xn, n, o->samples_per_period, o->periods, u, y,
                                     &periods, err);
    }
    if (!rc) {
        rths_floquet_remove_periodic_mean(u, o->samples_per_period, periods);
        rths_floquet_remove_periodic_mean(y, o->samples_per_period, periods);
        rc = rths_floquet_estimate_series(u, y, o->samples_per_period, periods, &o->fit, est, err);
    }
    free(rec), free(buf), free(u), free(y);
    return rc;
}

/* The least damped eigenvalue's real part of the linear assembly, 1/s. */
static int linear_decay_rate(const rths_setup *s, double *sigma, rths_error *err) {
    const rths_assembly *a = &s->assembly;
    double *sa = NULL, *sb = NULL;
    int n2 = 2 * a->n,
        rc = rths_state_space(a->n, a->mass, a->damping, a->stiffness, 1, s->force, &sa, &sb, err);
    double *wr = malloc((size_t)n2 * sizeof *wr), *wi = malloc((size_t)n2 * sizeof *wi), vl, vr;
    if (!rc && (!wr || !wi)) rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    if (!rc && LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', n2, sa, n2, wr, wi, &vl, 1, &vr, 1))
        rc = rths_error_set(err, RTHS_EFAIL, "LAPACK dgeev failed on the assembly");
    *sigma = -INFINITY;
    for (int i = 0; i < n2 && !rc; i++)
        *sigma = fmax(*sigma, wr[i]);
    free(sa), free(sb), free(wr), free(wi);
    return rc;
}

int frf_floquet_truth_compute(const rths_setup *s, frf_floquet_truth *t, rths_error *err) {
    *t = (frf_floquet_truth){.linear = !s->has_bilinear};
    return t->linear ? linear_decay_rate(s, &t->decay_rate_per_s, err) : RTHS_OK;
}

double frf_floquet_truth_at(const frf_state *run, double f_hz, double amp_m) {
    if (run->floquet_truth.linear) return exp(run->floquet_truth.decay_rate_per_s / f_hz);
    return rths_truth_branch_max_floquet(&run->truth, f_hz, amp_m);
}
