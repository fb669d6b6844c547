/* Before a test: what `rths model` already knows about it. The true assembly's interface
 * response over the requested range against the rig's displacement limit, so a test that must
 * trip is refused before the rig is armed instead of faulting at its first resonance. */
#include "run/frf_internal.h"

#include "rths/controller.h"

#include <math.h>
#include <stdio.h>

/* The truth curve's range: the run's, with a margin (the last step may pass end_hz, the first
 * correction move below start_hz), so every accepted point lies inside the curve it is judged
 * against. */
static void truth_range(const frf_state *st, double *lo, double *hi) {
    *lo = fmin(st->cont.start_hz, st->cont.end_hz);
    *hi = fmax(st->cont.start_hz, st->cont.end_hz);
    double margin = 0.1 * (*hi - *lo);
    *lo = fmax(*lo - margin, 0.5 * *lo);
    *hi += margin;
}

int frf_plan_within_limits(frf_state *st, rths_error *err) {
    double lo, hi;
    truth_range(st, &lo, &hi);
    int rc = rths_truth_compute(st->setup, lo, hi, &st->truth, err);
    if (rc) return rc;
    rths_controller_options copt;
    rths_controller_defaults(&copt);
    if ((rc = rths_controller_config_read(st->opt->cfg, &copt, err))) return rc;
    /* the peak within the run's own range; every harmonic adds to the displacement */
    double f_lo = fmin(st->cont.start_hz, st->cont.end_hz),
           f_hi = fmax(st->cont.start_hz, st->cont.end_hz), peak = 0, peak_hz = 0;
    const rths_truth_curve *t = &st->truth;
    for (int j = 0; j < t->n; j++) {
        if (t->freq_hz[j] < f_lo || t->freq_hz[j] > f_hi) continue;
        double x =
            t->amp_m[j] + (t->amp_h2_m ? t->amp_h2_m[j] : 0) + (t->amp_h3_m ? t->amp_h3_m[j] : 0);
        if (x > peak) peak = x, peak_hz = t->freq_hz[j];
    }
    if (!(peak > copt.displacement_limit_m)) return RTHS_OK;
    char what[512];
    snprintf(what, sizeof what,
             "the true assembly's interface response reaches %.3g m at %.4g Hz in [%g, %g] Hz, "
             "beyond controller.limits.displacement_m = %g m: the test would trip there",
             peak, peak_hz, f_lo, f_hi, copt.displacement_limit_m);
    if (!st->opt->force)
        return rths_error_set(err, RTHS_EINPUT,
                              "%s; narrow continuation.start_hz/end_hz, lower "
                              "forcing.amplitude_n or raise the limit (--force runs it anyway)",
                              what);
    fprintf(stderr, "rths frf: warning: %s (--force)\n", what);
    snprintf(st->limit_warning, sizeof st->limit_warning, "%s (--force)", what);
    return RTHS_OK;
}
