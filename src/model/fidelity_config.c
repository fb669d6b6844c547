/* The fidelity section of the configuration (docs/config/fidelity.md) and the sweep it asks for. */
#include "rths/fidelity.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int rths_fidelity_config_read(rths_config *cfg, const rths_assembly *a, rths_fidelity_options *o,
                              rths_error *err) {
    rths_modes modes;
    int rc = rths_modal_analysis(a, &modes, err);
    if (rc) return rc;
    /* the second mode is where the seed's hybrid test is hardest (docs/method.md, "Numerical
     * substructure integration"); fall back to the first for a one-DoF structure */
    double f_mode = modes.frequency_hz[modes.n >= 2 ? 1 : 0];
    rths_modes_free(&modes);
    return rths_fidelity_config_read_band(cfg, 0.9 * f_mode, 1.1 * f_mode, 1001, o, err);
}

int rths_fidelity_config_read_band(rths_config *cfg, double start_hz, double end_hz, int points,
                                   rths_fidelity_options *o, rths_error *err) {
    long n_points;
    int rc;
    if ((rc = rths_config_get_double(cfg, "fidelity.start_hz", 0, start_hz, 1e-6, 1e6, &o->start_hz,
                                     err)) ||
        (rc = rths_config_get_double(cfg, "fidelity.end_hz", 0, fmax(end_hz, 1.1 * o->start_hz),
                                     1e-6, 1e6, &o->end_hz, err)) ||
        (rc = rths_config_get_int(cfg, "fidelity.points", 0, points, 3, 1000000, &n_points, err)))
        return rc;
    if (!(o->end_hz > o->start_hz))
        return rths_config_error_at(cfg, "fidelity.end_hz", err,
                                    "must be above fidelity.start_hz (%g Hz), got %g Hz",
                                    o->start_hz, o->end_hz);
    o->points = (int)n_points;
    long nonlinear_points;
    if ((rc =
             rths_config_get_int(cfg, "fidelity.nonlinear_points", 0, 11 < n_points ? 11 : n_points,
                                 2, n_points, &nonlinear_points, err)))
        return rc;
    o->nonlinear_points = (int)nonlinear_points;
    return RTHS_OK;
}

static int compare_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return (x > y) - (x < y);
}

int rths_fidelity_frequencies(const rths_fidelity_options *o, const double *extra, int n_extra,
                              double **freqs, int *count, rths_error *err) {
    int total = o->points + n_extra;
    double *f = malloc((size_t)total * sizeof *f);
    *freqs = NULL;
    *count = 0;
    if (!f) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    for (int i = 0; i < o->points; i++)
        f[i] = o->start_hz + (o->end_hz - o->start_hz) * i / (o->points - 1);
    if (n_extra > 0) memcpy(f + o->points, extra, (size_t)n_extra * sizeof *f);
    qsort(f, (size_t)total, sizeof *f, compare_double);
    int unique = 0;
    for (int i = 0; i < total; i++)
        if (unique == 0 || f[i] != f[unique - 1]) f[unique++] = f[i];
    *freqs = f;
    *count = unique;
    return RTHS_OK;
}
