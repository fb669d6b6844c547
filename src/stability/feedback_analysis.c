/* Analysis of a feedback test's time trace (include/rths/stability.h): Fourier coefficients over
 * whole forcing periods, the growth rate of the unforced part, and the divergence verdict. */
#include "rths/stability.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

int rths_whole_period_fourier(const double *t_s, const double *x, int n, double frequency_hz,
                              int harmonics, int max_periods, double *coef, int *samples) {
    if (n < 1 || !(frequency_hz > 0)) return 0;
    double period = 1.0 / frequency_hz, w = 2 * M_PI * frequency_hz;
    int width = 1 + 2 * harmonics;
    /* the samples cover [0, t_last + dt): a period is whole when its end is within that */
    double dt = n > 1 ? (t_s[n - 1] - t_s[0]) / (n - 1) : 0;
    int total = (int)floor((t_s[n - 1] + dt) / period + 1e-9);
    if (total > max_periods) total = max_periods;
    int i = 0, count = 0;
    for (int j = 0; j < total; j++) {
        double *c = coef + (size_t)j * (size_t)width, end = (j + 1) * period;
        memset(c, 0, (size_t)width * sizeof *c);
        int m = 0;
        for (; i < n && t_s[i] < end - 1e-12; i++, m++) {
            double ph = w * t_s[i];
            c[0] += x[i];
            for (int k = 1; k <= harmonics; k++) {
                c[2 * k - 1] += x[i] * cos(k * ph);
                c[2 * k] += x[i] * sin(k * ph);
            }
        }
        if (m == 0) break;
        c[0] /= m;
        for (int k = 1; k < width; k++)
            c[k] *= 2.0 / m;
        if (samples) samples[j] = m;
        count++;
    }
    return count;
}

/* x(t - T) minus x(t) at sample i, x linear between the samples around t - T; *j is the search
 * position (samples are visited in order). */
static double minus_one_period(const double *t_s, const double *x, int i, double period_s, int *j) {
    double tp = t_s[i] - period_s;
    while (*j + 1 < i && t_s[*j + 1] <= tp)
        ++*j;
    double span = t_s[*j + 1] - t_s[*j];
    double u = span > 0 ? (tp - t_s[*j]) / span : 0;
    return x[i] - ((1 - u) * x[*j] + u * x[*j + 1]);
}

double rths_feedback_growth_rate(const double *t_s, const double *x, int n, double period_s,
                                 double slowest_s, double *last_envelope, double *fit_span_s) {
    *last_envelope = NAN;
    *fit_span_s = 0;
    if (n < 8) return NAN;
    double t0 = t_s[0], t1 = t_s[n - 1];
    int use_diff = t1 - t0 > 1.5 * period_s;
    double start = use_diff ? t0 + period_s : t0;
    double window = fmax(period_s, slowest_s);
    if ((t1 - start) / window < 4) window = (t1 - start) / 4;
    if (!(window > 0)) return NAN;
    int w_count = (int)floor((t1 - start) / window);
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    int used = 0, i = 0, j = 0;
    while (i < n && t_s[i] < start)
        i++;
    for (int w = 0; w < w_count; w++) {
        double env = 0, t_end = start + (w + 1) * window;
        for (; i < n && t_s[i] < t_end; i++) {
            double v = use_diff ? minus_one_period(t_s, x, i, period_s, &j) : x[i];
            if (isfinite(v)) env = fmax(env, fabs(v));
        }
        if (!(env > 0)) continue;
        *last_envelope = env;
        if (w < w_count / 2) continue;
        double xc = t_end - 0.5 * window, y = log(env);
        sx += xc, sy += y, sxx += xc * xc, sxy += xc * y, used++;
    }
    if (used < 2) return NAN;
    *fit_span_s = (used - 1) * window;
    return (used * sxy - sx * sy) / (used * sxx - sx * sx);
}

void rths_feedback_assess(const rths_assembly *a, const double *t_s, const double *x_num_m,
                          const double *x_phys_m, int n, double forcing_hz, double requested_s,
                          int limit_tripped, int beyond_bounds, double noise_m,
                          rths_feedback_verdict *out) {
    memset(out, 0, sizeof *out);
    rths_modes modes;
    rths_error err;
    double slowest = 0;
    if (!rths_modal_analysis(a, &modes, &err)) {
        slowest = 1.0 / modes.frequency_hz[0];
        rths_modes_free(&modes);
    }
    double last_env, span;
    double g =
        rths_feedback_growth_rate(t_s, x_num_m, n, 1.0 / forcing_hz, slowest, &last_env, &span);
    int finite = 1;
    for (int i = 0; i < n; i++) {
        if (!isfinite(x_num_m[i]) || !isfinite(x_phys_m[i]))
            finite = 0;
        else
            out->max_abs_x_num_m = fmax(out->max_abs_x_num_m, fabs(x_num_m[i]));
    }
    out->reached_s = n > 0 ? t_s[n - 1] : 0;
    out->growth_rate_per_s = g;
    out->fit_span_s = span;
    if (!finite)
        out->reason = "the response became non-finite";
    else if (limit_tripped)
        out->reason = "a safety limit tripped";
    else if (beyond_bounds || out->reached_s < requested_s - 2.0 / forcing_hz)
        out->reason = "the response grew beyond bounds (1000 x the true steady amplitude)";
    else if (g > 0 && g * span > log(2.0) && last_env > 10 * noise_m)
        out->reason = "the response grows (its unforced part more than doubled over the second "
                      "half)";
    else if (g > 0)
        out->note = "positive growth rate but too little growth over this run to call it "
                    "divergence; run more periods to decide";
    out->diverged = out->reason != NULL;
}
