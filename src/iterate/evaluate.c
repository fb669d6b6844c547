/* One evaluation of the rig-backed zero problem: steady state, averaging, the residual record;
 * and the corrector's use of a record (noise pooling, LTI history, tolerance, arclength row). */
#include "iterate/corrector_internal.h"
#include "iterate/transient_fit.h"

#include <complex.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* ---- one evaluation ---- */

static int coefficient_vector(const rths_period *p, int harmonics, double *v) {
    int m = 0;
    for (int k = 1; k <= harmonics; k++) {
        v[m++] = p->phys.a[k];
        v[m++] = p->phys.b[k];
        v[m++] = p->num.a[k];
        v[m++] = p->num.b[k];
    }
    /* the other interface DoFs of a rig that drives several */
    for (int d = 1; d < p->interface_dofs; d++)
        for (int k = 1; k <= harmonics; k++) {
            v[m++] = p->phys_dof[d].a[k];
            v[m++] = p->phys_dof[d].b[k];
            v[m++] = p->num_dof[d].a[k];
            v[m++] = p->num_dof[d].b[k];
        }
    return m;
}

static double vec_norm(const double *v, int n) {
    double s = 0;
    for (int i = 0; i < n; i++)
        s += v[i] * v[i];
    return sqrt(s);
}

/* The integrity counts of the periods one measurement read (rths_period). */
typedef struct integrity_counts {
    long late, clipped, saturated, samples;
} integrity_counts;

static void count_period(integrity_counts *cnt, const rths_period *p) {
    cnt->late += p->late_samples;
    cnt->clipped += p->clipped_demand_samples;
    cnt->saturated += p->saturated_sensor_samples;
    cnt->samples += p->samples;
}

/* Expected norm of the change of the m coefficients between two periods of `samples` samples
 * under the measured noise alone (independent periods: each coefficient's change has twice its
 * per-period variance); 0 while nothing is measured. */
static double noise_change_norm(const rths_noise_model *noise, int m, int samples) {
    if (!noise || noise->coefficients != m || !(noise->dof > 0) || samples <= 0) return 0.0;
    double var = 0;
    for (int i = 0; i < m; i++)
        var += noise->variance_x_samples[i];
    return sqrt(2.0 * var / samples);
}

/* Before the host has measured any noise (the first evaluation of a problem): whether the changes
 * have stopped shrinking, the mean squared change of the last W periods against the W before
 * (sq: a ring of the last 2 W squared changes, newest at index `at` - 1). A geometric transient
 * of ratio r shrinks it to r^(2 W); noise alone keeps it near 1 (with 4 coefficients over 8
 * periods, 32 squared terms a window, the ratio's logarithm scatters by about 0.35). Below 0.7 the
 * stream is still settling: a transient faster than r = 0.7^(1 / 2 W) (0.978 per period for
 * W = 8) is waited out down to the noise, whatever its level, which is what the noise test would
 * do with a known level; a slower one is left to the remaining-transient test as before. */
static const double STATIONARY_RATIO = 0.7;
enum { STATIONARY_MAX_WINDOW = 32 };

static int changes_stationary(const double *sq, int window, int at) {
    double older = 0, newer = 0;
    for (int j = 0; j < window; j++) {
        newer += sq[(at - 1 - j + 2 * window) % (2 * window)];
        older += sq[(at - 1 - window - j + 2 * window) % (2 * window)];
    }
    return older > 0 && newer >= STATIONARY_RATIO * older;
}

/* Runs periods until the coefficient stream is steady (or the fixed wait elapses); *waited and
 * *steady say how it went. The noise the changes are judged against is the host's own model
 * (rths_noise_model), never the rig's declared level; while it has none, the changes' own
 * stationarity (changes_stationary) stands in for the noise test. */
static int wait_steady(rths_rig *rig, const rths_settle_options *opt, const rths_noise_model *noise,
                       int harmonics, int *waited, int *steady, integrity_counts *cnt,
                       rths_error *err) {
    enum { NC = RTHS_NOISE_COEFFICIENTS };
    double prev[NC], cur[NC], change_prev = -1;
    rths_period p;
    int rc, m = 0;
    *waited = 0;
    *steady = 0;
    if (opt->fixed_wait_periods > 0) {
        for (; *waited < opt->fixed_wait_periods; (*waited)++) {
            if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
            count_period(cnt, &p);
        }
        *steady = 1;
        return RTHS_OK;
    }
    int window = opt->min_wait_periods < STATIONARY_MAX_WINDOW ? opt->min_wait_periods
                                                               : STATIONARY_MAX_WINDOW;
    /* steady state is judged from two changes after the controller's transition at the least */
    const int min_wait = opt->min_wait_periods > opt->transition_periods + 3
                             ? opt->min_wait_periods
                             : opt->transition_periods + 3;
    double change_sq[2 * STATIONARY_MAX_WINDOW];
    int changes = 0;
    while (*waited < opt->max_wait_periods + opt->transition_periods) {
        if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        count_period(cnt, &p);
        (*waited)++;
        m = coefficient_vector(&p, harmonics, cur);
        if (*waited > 1) {
            double d[NC];
            for (int i = 0; i < m; i++)
                d[i] = cur[i] - prev[i];
            double change = vec_norm(d, m);
            double noise_change = noise_change_norm(noise, m, p.samples);
            change_sq[changes++ % (2 * window)] = change * change;
            int noise_known = noise_change > 0 || (noise && noise->coefficients == m &&
                                                   noise->dof > 0); /* measured: zero noise */
            int floor_reached =
                noise_known ? change < opt->noise_factor * noise_change
                            : changes >= 2 * window &&
                                  changes_stationary(change_sq, window, changes % (2 * window));
            double threshold = fmax(opt->abs_tolerance_m, opt->rel_tolerance * vec_norm(cur, m));
            /* A geometric transient with ratio r per period still owes change * r / (1 - r);
             * r is estimated from the last two changes (clamped so a noisy estimate near 1
             * keeps us waiting rather than accepting). */
            double remaining;
            if (change == 0.0) {
                remaining = 0.0; /* bit-identical periods: nothing left to settle */
            } else if (change_prev > 0) {
                double r = fmin(change / change_prev, 0.995);
                remaining = change * (1.0 + r / (1.0 - r));
            } else {
                remaining = INFINITY;
            }
            if (*waited >= min_wait && (remaining < threshold || floor_reached)) {
                *steady = 1;
                break;
            }
            change_prev = change;
        }
        memcpy(prev, cur, sizeof cur);
    }
    return RTHS_OK;
}

/* Mean and standard error of the mean of one interface DoF's coefficients over n_avg periods
 * (side 0 physical, 1 numerical). */
static void mean_and_error(int n_avg, double sum[2][2][RTHS_MAX_HARMONICS + 1],
                           double sum2[2][2][RTHS_MAX_HARMONICS + 1], rths_fourier *mean[2],
                           rths_fourier *se[2]) {
    for (int s = 0; s < 2; s++)
        for (int k = 0; k <= RTHS_MAX_HARMONICS; k++)
            for (int c = 0; c < 2; c++) {
                double mu = sum[s][c][k] / n_avg;
                double var = n_avg > 1 ? (sum2[s][c][k] - n_avg * mu * mu) / (n_avg - 1) : 0.0;
                double e = sqrt(fmax(var, 0.0) / n_avg);
                if (c == 0)
                    mean[s]->a[k] = mu, se[s]->a[k] = e;
                else
                    mean[s]->b[k] = mu, se[s]->b[k] = e;
            }
}

/* The noise in an averaging's periods, per coefficient [DoF][harmonic][side][cos, sin]: the sum
 * of each term's estimate of the per-period variance, and the number of terms. The terms are the
 * periods' second differences, (c_{q+1} - 2 c_q + c_{q-1})^2 / 6 (first differences,
 * (c_{q+1} - c_q)^2 / 2, over two periods), not the deviations from the mean: white noise gives
 * each the per-period variance, while a transient left over from the wait, a slow trend across
 * the averaged periods, cancels to (1 - r)^2 of itself (r its ratio per period; 0.5 % for a
 * mode of 1 % damping). Deviations from the mean would count that tail as noise, and the noise
 * test would then accept the next evaluations with ever larger tails (a noise-free cantilever
 * sweep drifted to 2.4 % errors so). */
typedef struct average_scatter {
    int dofs;
    double samples; /* mean samples per period */
    double terms;
    double var_sum[RTHS_MAX_INTERFACE_DOFS][RTHS_MAX_HARMONICS + 1][2][2];
} average_scatter;

/* One period's coefficients into the running differences (last: the previous two periods'). */
static void scatter_add(average_scatter *sc, int q, int n_avg, int d, const rths_fourier *side[2],
                        double last[RTHS_MAX_INTERFACE_DOFS][RTHS_MAX_HARMONICS + 1][2][2][2]) {
    for (int k = 1; k <= RTHS_MAX_HARMONICS; k++)
        for (int s = 0; s < 2; s++)
            for (int c = 0; c < 2; c++) {
                double v = c ? side[s]->b[k] : side[s]->a[k];
                double *l = last[d][k][s][c]; /* l[0]: period q - 1, l[1]: q - 2 */
                if (n_avg >= 3 && q >= 2) {
                    double dd = v - 2 * l[0] + l[1];
                    sc->var_sum[d][k][s][c] += dd * dd / 6.0;
                } else if (n_avg == 2 && q == 1) {
                    double dd = v - l[0];
                    sc->var_sum[d][k][s][c] += dd * dd / 2.0;
                }
                l[1] = l[0];
                l[0] = v;
            }
}

/* The output DoFs' means and standard errors of the mean (out_sum / out_sum2 as mean_and_error's,
 * side 0 used). */
static void average_output_dofs(int n_avg, double out_sum[][2][2][RTHS_MAX_HARMONICS + 1],
                                double out_sum2[][2][2][RTHS_MAX_HARMONICS + 1], int n_out,
                                rths_evaluation *out) {
    out->output_dofs = n_out;
    for (int j = 0; j < n_out; j++) {
        rths_fourier unused_mean, unused_se;
        rths_fourier *mean[2] = {&out->output_dof[j], &unused_mean},
                     *se[2] = {&out->output_dof_se[j], &unused_se};
        mean_and_error(n_avg, out_sum[j], out_sum2[j], mean, se);
    }
}

/* Averages n_avg whole periods: mean and standard error of the mean of every coefficient the rig
 * measures, not only the matched ones (the report shows the higher harmonics' error too), of
 * every interface DoF the periods carry. */
static int average_periods(rths_rig *rig, int n_avg, rths_evaluation *out, integrity_counts *cnt,
                           average_scatter *scatter, rths_error *err) {
    enum { H = RTHS_MAX_HARMONICS + 1, D = RTHS_MAX_INTERFACE_DOFS };
    static const double zero[2][2][H];
    double sum[D][2][2][H], sum2[D][2][2][H];
    for (int d = 0; d < D; d++) {
        memcpy(sum[d], zero, sizeof zero);
        memcpy(sum2[d], zero, sizeof zero);
    }
    double last[D][H][2][2][2] = {{{{{0}}}}}; /* scatter_add's memory of the last two periods */
    memset(scatter, 0, sizeof *scatter);
    rths_period p;
    int rc, dofs = 1, n_out = 0;
    long samples = 0;
    /* output.dofs: one side each (index 0 of the side dimension) */
    double out_sum[RTHS_MAX_OUTPUT_DOFS][2][2][H], out_sum2[RTHS_MAX_OUTPUT_DOFS][2][2][H];
    memset(out_sum, 0, sizeof out_sum);
    memset(out_sum2, 0, sizeof out_sum2);
    for (int q = 0; q < n_avg; q++) {
        if ((rc = rths_rig_run_periods(rig, 1, &p, err))) return rc;
        count_period(cnt, &p);
        samples += p.samples;
        if (q == 0) n_out = p.output_dofs <= RTHS_MAX_OUTPUT_DOFS ? p.output_dofs : 0;
        if (p.output_dofs != n_out)
            return rths_error_set(err, RTHS_EFAIL,
                                  "the rig's periods carry %d output DoFs, then %d (output.dofs)",
                                  n_out, p.output_dofs);
        for (int j = 0; j < n_out; j++)
            for (int k = 0; k < H; k++) {
                const double a = p.output_dof[j].a[k], b = p.output_dof[j].b[k];
                out_sum[j][0][0][k] += a, out_sum[j][0][1][k] += b;
                out_sum2[j][0][0][k] += a * a, out_sum2[j][0][1][k] += b * b;
            }
        dofs = p.interface_dofs > 1 ? p.interface_dofs : 1;
        for (int d = 0; d < dofs; d++) {
            const rths_fourier *sides[2] = {d ? &p.phys_dof[d] : &p.phys,
                                            d ? &p.num_dof[d] : &p.num};
            scatter_add(scatter, q, n_avg, d, sides, last);
        }
        for (int d = 1; d < dofs; d++) {
            const rths_fourier *side[2] = {&p.phys_dof[d], &p.num_dof[d]};
            for (int s = 0; s < 2; s++)
                for (int k = 0; k < H; k++) {
                    sum[d][s][0][k] += side[s]->a[k];
                    sum[d][s][1][k] += side[s]->b[k];
                    sum2[d][s][0][k] += side[s]->a[k] * side[s]->a[k];
                    sum2[d][s][1][k] += side[s]->b[k] * side[s]->b[k];
                }
        }
        const rths_fourier *side[2] = {&p.phys, &p.num};
        for (int s = 0; s < 2; s++)
            for (int k = 0; k < H; k++) {
                sum[0][s][0][k] += side[s]->a[k];
                sum[0][s][1][k] += side[s]->b[k];
                sum2[0][s][0][k] += side[s]->a[k] * side[s]->a[k];
                sum2[0][s][1][k] += side[s]->b[k] * side[s]->b[k];
            }
    }
    rths_fourier *mean[2] = {&out->phys, &out->num}, *se[2] = {&out->phys_se, &out->num_se};
    mean_and_error(n_avg, sum[0], sum2[0], mean, se);
    average_output_dofs(n_avg, out_sum, out_sum2, n_out, out);
    if (dofs > 1) {
        out->interface_dofs = dofs;
        out->phys_dof[0] = out->phys, out->num_dof[0] = out->num;
        out->phys_dof_se[0] = out->phys_se, out->num_dof_se[0] = out->num_se;
    }
    for (int d = 1; d < dofs; d++) {
        rths_fourier *mean_d[2] = {&out->phys_dof[d], &out->num_dof[d]},
                     *se_d[2] = {&out->phys_dof_se[d], &out->num_dof_se[d]};
        mean_and_error(n_avg, sum[d], sum2[d], mean_d, se_d);
    }
    scatter->samples = n_avg > 0 ? (double)samples / n_avg : 0.0;
    scatter->dofs = dofs;
    scatter->terms = n_avg >= 3 ? n_avg - 2 : n_avg == 2 ? 1 : 0;
    return RTHS_OK;
}

int rths_evaluate(rths_rig *rig, const rths_settle_options *opt, int harmonics, double frequency_hz,
                  double amplitude_n, const double *target_a, const double *target_b,
                  rths_evaluation *out, rths_error *err) {
    return rths_evaluate_dofs(rig, opt, harmonics, 1, frequency_hz, amplitude_n, target_a, target_b,
                              out, err);
}

int rths_evaluate_dofs(rths_rig *rig, const rths_settle_options *opt, int harmonics, int dofs,
                       double frequency_hz, double amplitude_n, const double *target_a,
                       const double *target_b, rths_evaluation *out, rths_error *err) {
    return rths_evaluate_noise(rig, opt, NULL, harmonics, dofs, frequency_hz, amplitude_n, target_a,
                               target_b, out, err);
}

/* The noise model's memory: 16 difference terms, 8 evaluations of 4 averaged periods. Its
 * standard deviation is then good to about 20 %, and a noise that changes along a sweep (a
 * resonance's numerical side) is followed within as many evaluations. */
static const double NOISE_MEMORY_TERMS = 16.0;

/* A clean averaging's scatter joins the noise model (restarted if the coefficients changed). */
static void noise_model_add(rths_noise_model *noise, const average_scatter *sc, int harmonics) {
    int m = 4 * harmonics * sc->dofs;
    if (!(sc->terms > 0) || !(sc->samples > 0) || m > RTHS_NOISE_COEFFICIENTS) return;
    if (noise->coefficients != m) memset(noise, 0, sizeof *noise);
    noise->coefficients = m;
    double keep = 1.0;
    if (noise->dof + sc->terms > NOISE_MEMORY_TERMS)
        keep = noise->dof > 0 ? fmax(NOISE_MEMORY_TERMS - sc->terms, 0.0) / noise->dof : 0.0;
    double dof = noise->dof * keep + sc->terms;
    int i = 0;
    for (int d = 0; d < sc->dofs; d++)
        for (int k = 1; k <= harmonics; k++)
            for (int side = 0; side < 2; side++)
                for (int c = 0; c < 2; c++, i++) {
                    double old_sum = noise->variance_x_samples[i] * noise->dof;
                    noise->variance_x_samples[i] =
                        (old_sum * keep + sc->var_sum[d][k][side][c] * sc->samples) / dof;
                }
    noise->dof = dof;
}

/* One line to the caller's log (rths_settle_options.note), if it gave one. */
static void note(const rths_settle_options *opt, const char *fmt, ...) {
    if (!opt->note) return;
    char line[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    opt->note(opt->note_user, line);
}

/* The rig time an evaluation may spend on iteration.target_rel_se: the point's, with a tally
 * (rths_settle_options.tally), else the evaluation's. */
static double max_rig_s(const rths_settle_options *opt) {
    return opt->max_rig_s_per_point > 0 ? opt->max_rig_s_per_point
                                        : RTHS_SETTLE_MAX_RIG_S_PER_POINT;
}

/* The rig time spent against that budget: the tally's evaluations' (the point's so far) and
 * this one's since t0. */
static double rig_s_spent(const rths_settle_options *opt, rths_rig *rig, double t0) {
    return (opt->tally ? opt->tally->rig_time_s : 0.0) + rths_rig_time_s(rig) - t0;
}

/* Whether iteration.target_rel_se is out of the budget's reach for a waiting evaluation: the
 * standard error of an average of steady periods falls as the square root of their number, so
 * meeting the target from rel_se after `periods` periods takes periods ((rel_se / target)^2 - 1)
 * more of period_s each; when those overrun what is left of max_rig_s_per_point the averaging is
 * not extended at all (a zero-target evaluation, whose amplitude is the noise's, would otherwise
 * spend the whole point's budget on a goal it cannot reach, starving the point's other
 * evaluations). Not for a fit: its standard error, the poles' uncertainty in it, falls faster
 * than that while the record is short (measured, the rule cut a cantilever point's fit short). */
static int target_out_of_reach(const rths_settle_options *opt, rths_rig *rig, double t0,
                               double rel_se, int periods, double period_s) {
    if (!(rel_se > opt->target_rel_se)) return 0;
    if (!isfinite(rel_se) || periods < 1) return 1;
    double ratio = rel_se / opt->target_rel_se;
    double more_s = (double)periods * (ratio * ratio - 1.0) * period_s;
    return rig_s_spent(opt, rig, t0) + more_s > max_rig_s(opt);
}

/* The note of a target the budget could not meet. */
static void note_target_missed(const rths_settle_options *opt, double frequency_hz, double rel_se,
                               double spent_s) {
    note(opt,
         "evaluation at %.6g Hz: relative amplitude standard error %.3g above "
         "iteration.target_rel_se %.3g after %.3g rig s%s (iteration.max_rig_s_per_point %.3g): "
         "the rig's noise cannot meet it",
         frequency_hz, rel_se, opt->target_rel_se, spent_s, opt->tally ? " of the point's" : "",
         max_rig_s(opt));
}

/* Relative standard error of interface DoF d's physical fundamental amplitude |x| =
 * hypot(a1, b1): sqrt((a se_a)^2 + (b se_b)^2) / |x| (first order). */
static double amplitude_rel_se(const rths_fourier *x, const rths_fourier *se) {
    double amp = hypot(x->a[1], x->b[1]);
    if (!(amp > 0)) return INFINITY;
    return hypot(x->a[1] * se->a[1], x->b[1] * se->b[1]) / (amp * amp);
}

/* The largest relative amplitude standard error over the evaluation's interface DoFs and both
 * sides: the amplitude a point reports (extrapolated to zero mismatch, docs/method.md, "The
 * matched estimate at zero mismatch") carries the numerical side's noise too, often the larger. */
static double worst_amplitude_rel_se(const rths_evaluation *ev) {
    int dofs = ev->interface_dofs > 1 ? ev->interface_dofs : 1;
    double worst = 0;
    for (int d = 0; d < dofs; d++) {
        const rths_fourier *x = dofs > 1 ? &ev->phys_dof[d] : &ev->phys;
        const rths_fourier *se = dofs > 1 ? &ev->phys_dof_se[d] : &ev->phys_se;
        const rths_fourier *xn = dofs > 1 ? &ev->num_dof[d] : &ev->num;
        const rths_fourier *sen = dofs > 1 ? &ev->num_dof_se[d] : &ev->num_se;
        worst = fmax(worst, fmax(amplitude_rel_se(x, se), amplitude_rel_se(xn, sen)));
    }
    return worst;
}

/* ---- the fitted evaluation (docs/method.md, "The fitted evaluation") ---- */

/* Periods after the change left out of the fit: the change itself falls inside the first. */
enum { FIT_SKIP_PERIODS = 1, FIT_MAX_ORDER = 8 };
/* A pole this close to 1 per period is a transient the record cannot separate from the steady
 * state (its term and the constant are nearly the same column): leave it to waiting. */
static const double FIT_MAX_POLE = 0.99;
/* Residuals whose lag-1 autocorrelation exceeds this are not white: the model misses part of
 * the transient (white noise gives about -(1 + order) / K, 3 / sqrt(m K) either side). */
static const double FIT_MAX_LAG1 = 0.5;
/* ... unless they are this small against the settle tolerance: a fit that extrapolates a slow
 * term can carry its residual's misfit into the steady state many times over, so only a
 * residual far below the tolerance (noise off, rounding) is waived */
static const double FIT_NEGLIGIBLE_RESIDUAL = 0.03;
static const double FIT_SE_FLOOR_OF_TOLERANCE = 0.1;

/* The coefficient of series (d, side, harmonic k, cos/sin) of a period. */
static double period_coefficient(const rths_period *p, int d, int side, int k, int c) {
    const rths_fourier *f =
        d ? (side ? &p->num_dof[d] : &p->phys_dof[d]) : (side ? &p->num : &p->phys);
    return c ? f->b[k] : f->a[k];
}

/* Per interface DoF group of the matched vector (coefficient_vector's order: the first DoF's 4N,
 * then each further DoF's 4N): norms of a and se, and of the change from the previous fit. */
static void group_norms(const double *v, int d, int harmonics, double *out_norm) {
    double s = 0;
    for (int i = 0; i < 4 * harmonics; i++)
        s += v[d * 4 * harmonics + i] * v[d * 4 * harmonics + i];
    *out_norm = sqrt(s);
}

/* Fills out's means and standard errors from the fit of the periods rec[0..K) (every
 * coefficient the evaluation reports: the matched ones from the fit itself, the others with its
 * poles held). */
static void fit_fill(const transient_fit *fit, const rths_period *rec, int K, int dofs,
                     int harmonics, const double *a_matched, const double *se_matched,
                     rths_evaluation *out) {
    enum { H = RTHS_MAX_HARMONICS + 1 };
    double *y = malloc(sizeof(double) * (size_t)K);
    if (!y) return;
    for (int d = 0; d < dofs; d++)
        for (int side = 0; side < 2; side++)
            for (int k = 0; k < H; k++)
                for (int c = 0; c < 2; c++) {
                    double a, e;
                    if (c == 1 && k == 0) {
                        a = 0, e = 0;
                    } else if (k >= 1 && k <= harmonics) {
                        int i = d * 4 * harmonics + (k - 1) * 4 + side * 2 + c;
                        a = a_matched[i], e = se_matched[i];
                    } else {
                        for (int q = 0; q < K; q++)
                            y[q] = period_coefficient(&rec[q], d, side, k, c);
                        transient_fit_apply(fit, y, &a, &e);
                    }
                    rths_fourier *mean = d ? (side ? &out->num_dof[d] : &out->phys_dof[d])
                                           : (side ? &out->num : &out->phys);
                    rths_fourier *se = d ? (side ? &out->num_dof_se[d] : &out->phys_dof_se[d])
                                         : (side ? &out->num_se : &out->phys_se);
                    if (c)
                        mean->b[k] = a, se->b[k] = e;
                    else
                        mean->a[k] = a, se->a[k] = e;
                }
    int n_out = rec[0].output_dofs <= RTHS_MAX_OUTPUT_DOFS ? rec[0].output_dofs : 0;
    out->output_dofs = n_out;
    for (int j = 0; j < n_out; j++)
        for (int k = 0; k < H; k++)
            for (int c = 0; c < 2; c++) {
                double a = 0, e = 0;
                if (!(c == 1 && k == 0)) {
                    for (int q = 0; q < K; q++)
                        y[q] = c ? rec[q].output_dof[j].b[k] : rec[q].output_dof[j].a[k];
                    transient_fit_apply(fit, y, &a, &e);
                }
                if (c)
                    out->output_dof[j].b[k] = a, out->output_dof_se[j].b[k] = e;
                else
                    out->output_dof[j].a[k] = a, out->output_dof_se[j].a[k] = e;
            }
    if (dofs > 1) {
        out->interface_dofs = dofs;
        out->phys_dof[0] = out->phys, out->num_dof[0] = out->num;
        out->phys_dof_se[0] = out->phys_se, out->num_dof_se[0] = out->num_se;
    }
    free(y);
}

/* iteration.settle.fit_seed_poles (off by default: docs/method.md, "The fitted evaluation", has
 * what it measured): the window a record too short for the window check is compared with, the
 * same record fitted with the last trusted fit's poles held (noise->fit_seed_*), rescaled to this
 * period (a pole lambda gives z = exp(lambda T) per period, so log z scales with the period).
 * Returns 0 and fills seed_a, seed_se (the poles taken as exact: a stricter comparison), or -1 when
 * there is no seed, its poles would be too slow here, or the record too short for them. */
static int seeded_window(const rths_noise_model *noise, double frequency_hz, int m, int K,
                         const double *y, double *seed_a, double *seed_se) {
    int n = noise ? noise->fit_seed_order : 0;
    if (n < 1 || n > TRANSIENT_FIT_MAX_ORDER || !(noise->fit_seed_hz > 0) || !(frequency_hz > 0) ||
        K - 1 - n < n + 3)
        return -1;
    double complex c[TRANSIENT_FIT_MAX_ORDER + 1] = {1}; /* monic, highest power first */
    for (int j = 0; j < n; j++) {
        double complex z = cexp(clog(noise->fit_seed_z_re[j] + I * noise->fit_seed_z_im[j]) *
                                (noise->fit_seed_hz / frequency_hz));
        if (!(cabs(z) < FIT_MAX_POLE)) return -1;
        for (int k = j + 1; k > 0; k--)
            c[k] -= z * c[k - 1];
    }
    transient_fit seed = {.order = n, .periods = K, .ok = 1};
    for (int k = 0; k < n; k++)
        seed.alpha[k] = creal(c[k + 1]);
    for (int i = 0; i < m; i++) {
        transient_fit_apply(&seed, y + (size_t)i * K, &seed_a[i], &seed_se[i]);
        if (!isfinite(seed_a[i]) || !isfinite(seed_se[i])) return -1;
    }
    return 0;
}

/* Runs periods from the change and fits them after each (transient_fit_series) until the
 * steady state is trustworthy and its standard error within its goal: per interface DoF,
 *  - every pole of the fit within FIT_MAX_POLE per period,
 *  - the residuals white (lag-1 autocorrelation at most FIT_MAX_LAG1), or too small to matter
 *    (their rms per period within 0.3 times the smallest settle tolerance),
 *  - the steady state stable across windows: the fit of one period fewer within the settle
 *    tolerance max(abs_tolerance_m, rel_tolerance ||a_d||) plus 3 of its standard errors,
 *  - the standard error norm within max(the settle tolerance, what averaging average_periods
 *    periods of the fitted noise would give), or with target_rel_se, the physical amplitude's
 *    relative standard error within it.
 * *accepted 0: the fit was not trustworthy within fit_max_periods (or, with target_rel_se, the
 * rig time ran out before it was); *why names the failed test. */
static int fit_evaluation(rths_rig *rig, const rths_settle_options *opt, rths_noise_model *noise,
                          int harmonics, int dofs, double t0, rths_evaluation *out,
                          integrity_counts *cnt, average_scatter *scatter, int *accepted, char *why,
                          size_t why_size, rths_error *err) {
    enum { NC = RTHS_NOISE_COEFFICIENTS };
    int cap = opt->fit_max_periods > 0 ? opt->fit_max_periods : RTHS_SETTLE_FIT_MAX_PERIODS;
    /* the least record (iteration.settle.fit_min_periods): 4 is the plain mean's n + 3 residual
     * degrees of freedom, below which transient_fit_series fits nothing */
    int min_periods = opt->fit_min_periods > 0 ? opt->fit_min_periods : RTHS_SETTLE_FIT_MIN_PERIODS;
    if (min_periods < 4) min_periods = 4;
    /* the residual degrees of freedom each series keeps beyond its decaying terms
     * (iteration.settle.fit_residual_margin; 0 in the options: the default 3) */
    int margin =
        opt->fit_residual_margin > 0 ? opt->fit_residual_margin : RTHS_SETTLE_FIT_RESIDUAL_MARGIN;
    if (cap < FIT_SKIP_PERIODS + min_periods + 1) cap = FIT_SKIP_PERIODS + min_periods + 1;
    /* the controller's transition is not a free decay: skipped, and not counted against the cap */
    const int transition = opt->transition_periods > 0 ? opt->transition_periods : 0;
    cap += transition;
    rths_period *rec = malloc(sizeof(rths_period) * (size_t)cap);
    int m = 4 * harmonics * dofs, rc = RTHS_OK, have_prev = 0;
    double *y = malloc(sizeof(double) * (size_t)m * cap);
    /* every fit's steady state and standard error by the periods read (0: none) */
    double *hist_a = calloc((size_t)m * (cap + 1), sizeof(double)),
           *hist_se = calloc((size_t)m * (cap + 1), sizeof(double));
    int *hist_ok = calloc((size_t)cap + 1, sizeof(int));
    double a[NC], se[NC], var[NC], prior[NC], seed_a[NC], seed_se[NC];
    const double *prev_a = a, *prev_se = se;
    int n_avg = opt->average_periods > 0 ? opt->average_periods : 1;
    transient_fit fit = {0};
    *accepted = 0;
    snprintf(why, why_size, "no fit within %d periods", cap);
    if (!rec || !y || !hist_a || !hist_se || !hist_ok) {
        free(rec), free(y), free(hist_a), free(hist_se), free(hist_ok);
        return rths_error_set(err, RTHS_EFAIL, "fitted evaluation: out of memory");
    }
    int count = 0;
    long samples = 0;
    while (count < cap) {
        if ((rc = rths_rig_run_periods(rig, 1, &rec[count], err))) break;
        count_period(cnt, &rec[count]);
        count++;
        /* the record fitted: all but the first quarter (at least FIT_SKIP_PERIODS): the fast
         * terms right after the change (the numerical side's own ringing) need many poles and
         * are gone a few periods later, while the slow ones stay in the rest */
        int skip = count / 4 > FIT_SKIP_PERIODS ? count / 4 : FIT_SKIP_PERIODS;
        if (skip < transition) skip = transition;
        int K = count - skip;
        if (K < min_periods) continue;
        const rths_period *first = &rec[skip];
        samples = 0;
        for (int q = 0; q < K; q++) {
            double v[NC];
            coefficient_vector(&first[q], harmonics, v);
            for (int i = 0; i < m; i++)
                y[(size_t)i * K + q] = v[i];
            samples += first[q].samples;
        }
        double mean_samples = (double)samples / K;
        const double *prior_var = NULL;
        double prior_dof = 0;
        if (noise && noise->coefficients == m && noise->dof > 0 && mean_samples > 0) {
            for (int i = 0; i < m; i++)
                prior[i] = noise->variance_x_samples[i] / mean_samples;
            prior_var = prior;
            prior_dof = noise->dof;
        }
        if (transient_fit_series_margin(m, K, y, FIT_MAX_ORDER, margin, prior_var, prior_dof, &fit,
                                        a, se, var))
            continue;
        /* the window compared with: the fit of three quarters of the periods read (a misfit
         * moves the steady state as the record grows, by more than one period shows) */
        int older = (3 * count + 3) / 4;
        while (older > 0 && !hist_ok[older])
            older--;
        have_prev = older > 0 && older < count;
        if (have_prev) {
            prev_a = hist_a + (size_t)older * m;
            prev_se = hist_se + (size_t)older * m;
        } else if (opt->fit_seed_poles &&
                   !seeded_window(noise, out->frequency_hz, m, K, y, seed_a, seed_se)) {
            /* no fit of three quarters of the record yet: the previous fit's poles held give
             * the window instead (a misfit's steady state moves with the model, too) */
            have_prev = 1;
            prev_a = seed_a;
            prev_se = seed_se;
        }
        int ok = 1;
        const char *failed = NULL;
        double min_tol = INFINITY;
        for (int d = 0; d < dofs; d++) {
            double a_norm, se_norm, da_norm, prev_se_norm;
            group_norms(a, d, harmonics, &a_norm);
            group_norms(se, d, harmonics, &se_norm);
            /* the noise the goal allows for is the smaller of the host's model's (measured
             * from earlier evaluations) and the fit's own residual's: a misfit must not widen
             * its own goal, nor a transient the averagings took for noise widen the model's */
            double var_sum = 0, diff[NC];
            for (int i = 0; prior_var && i < 4 * harmonics; i++) /* the smaller: see above */
                var_sum += fmin(prior_var[d * 4 * harmonics + i], var[d * 4 * harmonics + i]);
            for (int i = 0; i < m; i++)
                diff[i] = a[i] - prev_a[i];
            group_norms(diff, d, harmonics, &da_norm);
            group_norms(prev_se, d, harmonics, &prev_se_norm);
            double tol = fmax(opt->abs_tolerance_m, opt->rel_tolerance * a_norm);
            min_tol = fmin(min_tol, tol);
            /* the standard error's own floor is a tenth of the settle tolerance: it enters the
             * corrector's tolerance (noise_factor times it), which near a resonance lets a
             * mismatch of that size through many times amplified; waiting's remaining-transient
             * bound, a bias, does not */
            double goal = fmax(FIT_SE_FLOOR_OF_TOLERANCE * tol, sqrt(var_sum / n_avg));
            if (!have_prev || da_norm > tol + 3 * prev_se_norm) {
                ok = 0;
                if (!failed) failed = "the steady state moved between windows";
            }
            if (opt->target_rel_se > 0) {
                double r = 0;
                for (int side = 0; side < 2; side++) {
                    int i0 = d * 4 * harmonics + 2 * side; /* harmonic 1: cos, sin */
                    rths_fourier x = {0}, xs = {0};
                    x.a[1] = a[i0], x.b[1] = a[i0 + 1], xs.a[1] = se[i0], xs.b[1] = se[i0 + 1];
                    r = fmax(r, amplitude_rel_se(&x, &xs));
                }
                if (r > opt->target_rel_se) {
                    ok = 0;
                    if (!failed) failed = "the standard error above iteration.target_rel_se";
                }
            }
            /* a target tightens the goal, never loosens it */
            if (se_norm > goal) {
                ok = 0;
                if (!failed) failed = "the standard error above its goal";
            }
        }
        int trusted =
            fit.max_abs_z < FIT_MAX_POLE &&
            (fit.lag1 <= FIT_MAX_LAG1 || fit.rms_residual <= FIT_NEGLIGIBLE_RESIDUAL * min_tol);
        if (!trusted) {
            ok = 0;
            failed = fit.max_abs_z >= FIT_MAX_POLE ? "a pole too close to 1 per period"
                                                   : "the residuals not white";
        }
        snprintf(why, why_size,
                 "%s after %d periods (order %d, largest pole %.4f per period, residual lag-1 "
                 "autocorrelation %.2f)",
                 failed ? failed : "accepted", count, fit.order, fit.max_abs_z, fit.lag1);
        int out_of_time = opt->target_rel_se > 0 && rig_s_spent(opt, rig, t0) >= max_rig_s(opt);
        if (ok || (out_of_time && trusted && have_prev && failed &&
                   strcmp(failed, "the standard error above iteration.target_rel_se") == 0)) {
            fit_fill(&fit, first, K, dofs, harmonics, a, se, out);
            /* the averaging the standard error is worth: var / se^2 periods (pooled over the
             * matched coefficients), so a pooling of se^2 n (n - 1) counts the noise right */
            double vs = 0, ss = 0;
            for (int i = 0; i < m; i++)
                vs += var[i], ss += se[i] * se[i];
            int n_eff = ss > 0 ? (int)lround(vs / ss) : K;
            if (n_eff < 2) n_eff = 2;
            if (n_eff > K) n_eff = K;
            out->average_periods = n_eff;
            out->wait_periods += count - n_eff;
            out->fitted = 1;
            out->fit_order = fit.order;
            out->fit_max_pole = fit.max_abs_z;
            out->se_target_missed = !ok;
            if (noise && fit.order > 0) { /* the next evaluation's seeded window */
                noise->fit_seed_order = fit.order;
                noise->fit_seed_hz = out->frequency_hz;
                for (int j = 0; j < fit.order; j++) {
                    noise->fit_seed_z_re[j] = creal(fit.z[j]);
                    noise->fit_seed_z_im[j] = cimag(fit.z[j]);
                }
            }
            /* the fit's residual scatter does not join the noise model: a misfit would pass for
             * noise there and widen the goal of the next fits (the noise is measured by the
             * averagings of waiting evaluations alone) */
            memset(scatter, 0, sizeof *scatter);
            *accepted = 1;
            break;
        }
        /* out of the point's time, a fit that is otherwise trusted was taken above; one that is
         * not goes on to fit_max_periods (the budget bounds the target's extension, not the
         * settling), unless this evaluation alone has spent the budget */
        if (out_of_time && rths_rig_time_s(rig) - t0 >= max_rig_s(opt)) break;
        memcpy(hist_a + (size_t)count * m, a, sizeof(double) * (size_t)m);
        memcpy(hist_se + (size_t)count * m, se, sizeof(double) * (size_t)m);
        hist_ok[count] = 1;
    }
    if (!*accepted) out->wait_periods += count; /* read, then waited on by the fallback */
    free(rec), free(y), free(hist_a), free(hist_se), free(hist_ok);
    return rc;
}

/* Accuracy on demand for the waiting strategy: the averaging extended by average_periods at a
 * time (the blocks' means weighted by their periods, their standard errors combined as
 * independent) until every interface DoF's physical amplitude has relative standard error at
 * most target_rel_se, or the evaluation's rig time reaches max_rig_s_per_point. */
static void combine_fourier(rths_fourier *mean, rths_fourier *se, const rths_fourier *mean2,
                            const rths_fourier *se2, double w1, double w2) {
    for (int k = 0; k <= RTHS_MAX_HARMONICS; k++) {
        mean->a[k] = w1 * mean->a[k] + w2 * mean2->a[k];
        mean->b[k] = w1 * mean->b[k] + w2 * mean2->b[k];
        se->a[k] = hypot(w1 * se->a[k], w2 * se2->a[k]);
        se->b[k] = hypot(w1 * se->b[k], w2 * se2->b[k]);
    }
}

static int extend_average(rths_rig *rig, const rths_settle_options *opt, double t0,
                          rths_evaluation *out, integrity_counts *cnt, average_scatter *scatter,
                          rths_error *err) {
    int block = opt->average_periods > 0 ? opt->average_periods : 1;
    for (double rel; (rel = worst_amplitude_rel_se(out)) > opt->target_rel_se;) {
        /* a spent budget is out of reach too */
        if (target_out_of_reach(opt, rig, t0, rel, out->average_periods, 1.0 / out->frequency_hz))
            return RTHS_OK;
        rths_evaluation more;
        average_scatter sc2;
        memset(&more, 0, sizeof more);
        int rc = average_periods(rig, block, &more, cnt, &sc2, err);
        if (rc) return rc;
        double n1 = out->average_periods, n2 = block, w1 = n1 / (n1 + n2), w2 = n2 / (n1 + n2);
        combine_fourier(&out->phys, &out->phys_se, &more.phys, &more.phys_se, w1, w2);
        combine_fourier(&out->num, &out->num_se, &more.num, &more.num_se, w1, w2);
        int dofs = out->interface_dofs > 1 ? out->interface_dofs : 0;
        for (int d = 0; d < dofs; d++) {
            combine_fourier(&out->phys_dof[d], &out->phys_dof_se[d], &more.phys_dof[d],
                            &more.phys_dof_se[d], w1, w2);
            combine_fourier(&out->num_dof[d], &out->num_dof_se[d], &more.num_dof[d],
                            &more.num_dof_se[d], w1, w2);
        }
        for (int j = 0; j < out->output_dofs && j < more.output_dofs; j++)
            combine_fourier(&out->output_dof[j], &out->output_dof_se[j], &more.output_dof[j],
                            &more.output_dof_se[j], w1, w2);
        if (dofs > 1) {
            out->phys = out->phys_dof[0], out->num = out->num_dof[0];
            out->phys_se = out->phys_dof_se[0], out->num_se = out->num_dof_se[0];
        }
        out->average_periods += block;
        for (int d = 0; d < RTHS_MAX_INTERFACE_DOFS; d++)
            for (int k = 0; k <= RTHS_MAX_HARMONICS; k++)
                for (int s2 = 0; s2 < 2; s2++)
                    for (int c = 0; c < 2; c++)
                        scatter->var_sum[d][k][s2][c] += sc2.var_sum[d][k][s2][c];
        scatter->terms += sc2.terms;
    }
    return RTHS_OK;
}

/* Whether a measurement's samples were all good enough for the coupling to hold. */
static int integrity_ok(const integrity_counts *cnt, const rths_settle_options *opt) {
    return cnt->clipped == 0 && cnt->saturated == 0 &&
           (double)cnt->late <= opt->max_late_share * (double)cnt->samples;
}

static int evaluate_noise(rths_rig *rig, const rths_settle_options *opt, rths_noise_model *noise,
                          int harmonics, int dofs, double frequency_hz, double amplitude_n,
                          const double *target_a, const double *target_b, rths_evaluation *out,
                          rths_error *err) {
    out->harmonics = harmonics;
    out->frequency_hz = frequency_hz;
    if (!(isfinite(frequency_hz) && frequency_hz > 0))
        return rths_error_set(err, RTHS_EFAIL, "corrector asked for a non-physical frequency %g Hz",
                              frequency_hz);
    for (int k = 0; k < harmonics * dofs; k++)
        if (!isfinite(target_a[k]) || !isfinite(target_b[k]))
            return rths_error_set(err, RTHS_EFAIL, "corrector produced a non-finite target");
    double t0 = rths_rig_time_s(rig);
    int rc = rths_rig_set_forcing(rig, frequency_hz, amplitude_n, err);
    if (!rc) rc = rths_rig_set_target_dofs(rig, dofs, harmonics, target_a, target_b, err);
    if (rc) return rc;
    /* without a caller's model, one for this evaluation alone (a re-measurement uses the first
     * measurement's scatter only if that was clean, which it was not: so nothing) */
    rths_noise_model local = {0};
    if (!noise) noise = &local;
    int n_avg = opt->average_periods > 0 ? opt->average_periods : 1;
    integrity_counts cnt = {0};
    /* a corrupted measurement (clipping, saturation, late samples) is measured once more after
     * a new wait for steady state: a transient's brief clip (a large step of the target) is gone
     * by then; one that persists is the rig's state at this target and fails the evaluation */
    for (int attempt = 0; attempt < 2; attempt++) {
        int waited = 0, steady = 0, fitted = 0;
        average_scatter scatter = {0};
        cnt = (integrity_counts){0};
        if (attempt == 0 && opt->strategy == RTHS_SETTLE_FIT) {
            char why[256];
            rc = fit_evaluation(rig, opt, noise, harmonics, dofs, t0, out, &cnt, &scatter, &fitted,
                                why, sizeof why, err);
            if (!rc && fitted) {
                steady = 1;
                if (out->se_target_missed)
                    note_target_missed(opt, frequency_hz, worst_amplitude_rel_se(out),
                                       rig_s_spent(opt, rig, t0));
            } else if (!rc) {
                /* the periods already read count as waiting; the fallback waits on from here */
                out->fit_fallback = 1;
                note(opt, "evaluation at %.6g Hz: transient fit not trusted (%s): waiting instead",
                     frequency_hz, why);
                if (opt->tally)
                    snprintf(opt->tally->fallback_reason, sizeof opt->tally->fallback_reason, "%s",
                             why);
            }
        }
        if (!rc && !fitted) {
            rc = wait_steady(rig, opt, noise, harmonics, &waited, &steady, &cnt, err);
            if (!rc) rc = average_periods(rig, n_avg, out, &cnt, &scatter, err);
            out->average_periods = n_avg;
            if (!rc && opt->target_rel_se > 0) {
                rc = extend_average(rig, opt, t0, out, &cnt, &scatter, err);
                if (!rc && worst_amplitude_rel_se(out) > opt->target_rel_se) {
                    out->se_target_missed = 1;
                    note_target_missed(opt, frequency_hz, worst_amplitude_rel_se(out),
                                       rig_s_spent(opt, rig, t0));
                }
            }
        }
        out->wait_periods += waited;
        out->steady = steady;
        out->amplitude_rel_se = worst_amplitude_rel_se(out);
        out->late_samples += cnt.late;
        out->clipped_demand_samples += cnt.clipped;
        out->saturated_sensor_samples += cnt.saturated;
        out->samples_read += cnt.samples;
        out->rig_time_s = rths_rig_time_s(rig) - t0;
        if (rc) return rc;
        if (rths_rig_get_fault(rig) != RTHS_RIG_OK)
            return rths_error_set(err, RTHS_EFAIL, "rig fault during evaluation at %.6g Hz: %s",
                                  frequency_hz, rths_rig_fault_name(rths_rig_get_fault(rig)));
        if (integrity_ok(&cnt, opt)) {
            noise_model_add(noise, &scatter, harmonics);
            return RTHS_OK;
        }
        if (attempt == 0) out->remeasured = 1;
    }
    out->refused = 1;
    return rths_error_set(
        err, RTHS_EFAIL,
        "evaluation at %.6g Hz refused: measured twice and both times corrupted; in the second, "
        "of %ld controller samples %ld had an actuator demand clipped (demand limit or DAC "
        "range), %ld a converter reading at full scale, %ld were late (share %.3g, "
        "controller.max_overrun_share %.3g): the coupling does not hold there (lower the "
        "forcing, narrow the range, or widen the converter or demand ranges)",
        frequency_hz, cnt.samples, cnt.clipped, cnt.saturated, cnt.late,
        cnt.samples > 0 ? (double)cnt.late / (double)cnt.samples : 0.0, opt->max_late_share);
}

int rths_evaluate_noise(rths_rig *rig, const rths_settle_options *opt, rths_noise_model *noise,
                        int harmonics, int dofs, double frequency_hz, double amplitude_n,
                        const double *target_a, const double *target_b, rths_evaluation *out,
                        rths_error *err) {
    memset(out, 0, sizeof *out);
    int rc = evaluate_noise(rig, opt, noise, harmonics, dofs, frequency_hz, amplitude_n, target_a,
                            target_b, out, err);
    rths_settle_tally *t = opt->tally;
    if (t) { /* failed evaluations too: their rig time is the point's */
        t->evaluations++;
        t->fitted += out->fitted;
        t->fit_fallbacks += out->fit_fallback;
        t->se_target_missed += out->se_target_missed;
        t->rig_time_s += out->rig_time_s;
    }
    return rc;
}

/* Interface DoF d's physical and numerical means and standard errors. */
static void dof_sides(const rths_evaluation *ev, int d, const rths_fourier **phys,
                      const rths_fourier **num, const rths_fourier **phys_se,
                      const rths_fourier **num_se) {
    int several = ev->interface_dofs > 1;
    *phys = several ? &ev->phys_dof[d] : &ev->phys;
    *num = several ? &ev->num_dof[d] : &ev->num;
    *phys_se = several ? &ev->phys_dof_se[d] : &ev->phys_se;
    *num_se = several ? &ev->num_dof_se[d] : &ev->num_se;
}

void rths_evaluation_residual(const rths_evaluation *ev, double *phi, double *phi_se) {
    int N = ev->harmonics, dofs = ev->interface_dofs > 1 ? ev->interface_dofs : 1, M = N * dofs;
    for (int d = 0; d < dofs; d++) {
        const rths_fourier *ph, *nu, *ph_se, *nu_se;
        dof_sides(ev, d, &ph, &nu, &ph_se, &nu_se);
        for (int k = 1; k <= N; k++) {
            int j = d * N + k - 1;
            phi[j] = ph->a[k] - nu->a[k];
            phi[M + j] = ph->b[k] - nu->b[k];
            if (phi_se) {
                phi_se[j] = hypot(ph_se->a[k], nu_se->a[k]);
                phi_se[M + j] = hypot(ph_se->b[k], nu_se->b[k]);
            }
        }
    }
}

void rths_residual_from_evaluation(const rths_evaluation *ev, rths_residual *out) {
    int N = ev->harmonics, dofs = ev->interface_dofs > 1 ? ev->interface_dofs : 1, M = N * dofs;
    out->n = 2 * M;
    rths_evaluation_residual(ev, out->phi, out->phi_se);
    for (int d = 0; d < dofs; d++) {
        const rths_fourier *ph, *nu, *ph_se, *nu_se;
        dof_sides(ev, d, &ph, &nu, &ph_se, &nu_se);
        for (int k = 1; k <= N; k++) {
            int j = d * N + k - 1;
            out->response[j] = ph->a[k];
            out->response[M + j] = ph->b[k];
            out->response_se[j] = ph_se->a[k];
            out->response_se[M + j] = ph_se->b[k];
            out->reference[j] = nu->a[k];
            out->reference[M + j] = nu->b[k];
            out->reference_se[j] = nu_se->a[k];
            out->reference_se[M + j] = nu_se->b[k];
        }
    }
    out->rig_time_s = ev->rig_time_s;
    out->samples = ev->average_periods;
    out->eval = *ev;
}

static int rig_problem_eval(void *ctx, const double *u, double omega_rad_s, rths_residual *out,
                            rths_error *err) {
    rths_rig_problem *rp = ctx;
    int N = rp->harmonics, dofs = rp->interface_dofs > 1 ? rp->interface_dofs : 1, M = N * dofs;
    double a[RTHS_MAX_UNKNOWNS], b[RTHS_MAX_UNKNOWNS];
    for (int j = 0; j < M; j++) { /* pair j = (DoF j / N, harmonic j % N + 1) */
        a[j] = u[j];
        b[j] = u[M + j];
    }
    rths_evaluation ev;
    rths_settle_options tightened;
    const rths_settle_options *settle = rp->settle;
    if (rp->target_rel_se > 0 && settle) {
        tightened = *settle;
        tightened.target_rel_se = rp->target_rel_se;
        settle = &tightened;
    }
    int rc = rths_evaluate_noise(rp->rig, settle, &rp->noise, N, dofs, omega_rad_s / (2 * M_PI),
                                 rp->amplitude_n, a, b, &ev, err);
    memset(out, 0, sizeof *out);
    if (rc) {
        out->rig_time_s = ev.rig_time_s;
        out->eval = ev;
        return rc;
    }
    rths_residual_from_evaluation(&ev, out);
    return RTHS_OK;
}

void rths_rig_problem_init(rths_zero_problem *problem, rths_rig_problem *ctx, rths_rig *rig,
                           const rths_settle_options *settle, int harmonics, double amplitude_n) {
    *ctx = (rths_rig_problem){.rig = rig,
                              .settle = settle,
                              .harmonics = harmonics,
                              .amplitude_n = amplitude_n,
                              .interface_dofs = 1};
    *problem = (rths_zero_problem){.n = 2 * harmonics,
                                   .harmonics = harmonics,
                                   .eval = rig_problem_eval,
                                   .ctx = ctx,
                                   .settle = settle,
                                   .evaluation_target_rel_se = &ctx->target_rel_se};
}

int rths_rig_problem_init_dofs(rths_zero_problem *problem, rths_rig_problem *ctx, rths_rig *rig,
                               const rths_settle_options *settle, int harmonics, double amplitude_n,
                               rths_error *err) {
    rths_rig_problem_init(problem, ctx, rig, settle, harmonics, amplitude_n);
    int dofs = rths_rig_interface_dofs(rig);
    if (dofs == 1) return RTHS_OK;
    if (2 * harmonics * dofs > 2 * RTHS_MAX_HARMONICS)
        return rths_error_set(err, RTHS_EINPUT,
                              "%d harmonics on %d interface DoFs are %d unknowns; the corrector "
                              "takes at most %d (2 RTHS_MAX_HARMONICS)",
                              harmonics, dofs, 2 * harmonics * dofs, 2 * RTHS_MAX_HARMONICS);
    ctx->interface_dofs = dofs;
    problem->n = 2 * harmonics * dofs;
    problem->harmonics = harmonics * dofs;
    problem->interface_dofs = dofs;
    return RTHS_OK;
}

/* ---- the corrector's use of one record ---- */

/* Pools the record's per-sample variances (se^2 n (n - 1) is the sum of squared deviations). */
static void pool_noise(corrector_memory *mem, const rths_residual *r, int n) {
    int s = r->samples;
    if (s <= 1) return;
    int N = n / 2;
    for (int k = 1; k <= N; k++) {
        const double *sd[2] = {r->response_se, r->reference_se};
        for (int side = 0; side < 2; side++) {
            mem->noise_ss[side][k - 1] += sd[side][k - 1] * sd[side][k - 1] * s * (s - 1);
            mem->noise_ss[side][N + k - 1] +=
                sd[side][N + k - 1] * sd[side][N + k - 1] * s * (s - 1);
        }
    }
    if (n % 2)
        for (int side = 0; side < 2; side++) {
            const double *sd = side ? r->reference_se : r->response_se;
            mem->noise_ss[side][n - 1] += sd[n - 1] * sd[n - 1] * s * (s - 1);
        }
    mem->noise_dof += s - 1;
}

/* Natural sweep on Fourier unknowns: the record joins the LTI model's history (ring). */
static void remember_evaluation(corrector_memory *mem, const double *target, double omega,
                                const rths_residual *r, int n) {
    int h = mem->history_next;
    mem->history[h].omega_rad_s = omega;
    memcpy(mem->history[h].target, target, sizeof(double) * (size_t)n);
    memcpy(mem->history[h].phi, r->phi, sizeof(double) * (size_t)n);
    memcpy(mem->history[h].response, r->response, sizeof(double) * (size_t)n);
    mem->history_next = (h + 1) % RTHS_LTI_HISTORY;
    if (mem->history_count < RTHS_LTI_HISTORY) mem->history_count++;
}

/* The solution view of an iterate (its targets were set by corrector_evaluate): per interface DoF
 * d, in its own unit (m, or rad for a rotation), ||Phi_d|| against its tolerance
 * max(rel * ||reference_d||, abs, noise_factor * ||standard error of Phi_d||); the point is within
 * tolerance when every DoF is (p->within). A problem without Fourier structure is one group.
 * Returns ||Phi||^2 over every entry (the line search's measure, in the corrector's scale). */
static double describe(const rths_corrector *c, corrector_point *p) {
    const rths_residual *r = &p->rec;
    int P = c->harmonics, n = c->n, groups = P > 0 ? c->dofs : 1, N = P > 0 ? P / groups : 0;
    p->sol.eval = r->eval;
    double sq = 0, tol_sq = 0, single_tol = 0, worst_rel = 0, worst_ratio = 0;
    int within = 1;
    for (int i = 0; i < n; i++)
        sq += r->phi[i] * r->phi[i];
    for (int d = 0; d < groups; d++) {
        double phi_sq = 0, ref_sq = 0, se_sq = 0;
        /* DoF d's entries: cos terms d N .. d N + N - 1, sin terms P + the same */
        for (int e = 0; e < (P > 0 ? 2 * N : n); e++) {
            int i = P > 0 ? (e < N ? d * N + e : P + d * N + e - N) : e;
            phi_sq += r->phi[i] * r->phi[i];
            ref_sq += r->reference[i] * r->reference[i];
            se_sq += r->phi_se[i] * r->phi_se[i];
        }
        double tol = fmax(fmax(c->opt.rel_tolerance * sqrt(ref_sq), c->opt.abs_tolerance_m),
                          c->opt.noise_factor * sqrt(se_sq));
        double phi_norm = sqrt(phi_sq);
        within = within && phi_norm < tol;
        tol_sq += tol * tol;
        single_tol = tol;
        worst_rel = fmax(worst_rel, ref_sq > 0     ? phi_norm / sqrt(ref_sq)
                                    : phi_norm > 0 ? INFINITY
                                                   : 0.0);
        worst_ratio = fmax(worst_ratio, tol > 0 ? phi_norm / tol : phi_norm > 0 ? INFINITY : 0.0);
    }
    p->within = within;
    p->sol.residual_norm_m = sqrt(sq);
    p->sol.tolerance_m = groups == 1 ? single_tol : sqrt(tol_sq);
    p->sol.residual_rel = worst_rel;
    p->sol.residual_to_tolerance = worst_ratio;
    return sq;
}

/* rths_newton_options.on_evaluation: what the evaluation into *p was for and what it measured;
 * a refused one (its record holds no residual) with NaN mismatches. */
static void report_evaluation(const rths_corrector *c, const corrector_point *p,
                              rths_evaluation_role role, double damping, int refused) {
    if (!c->opt.on_evaluation) return;
    rths_evaluation_event e = {
        .role = role,
        .iteration = c->iterations,
        .damping = damping,
        .frequency_hz = p->sol.omega_rad_s / (2 * M_PI),
        .refused = refused,
        .mismatch_m = refused ? NAN : p->sol.residual_norm_m,
        .tolerance_m = refused ? NAN : p->sol.tolerance_m,
        .mismatch_to_tolerance = refused ? NAN : p->sol.residual_to_tolerance,
        .within_tolerance = !refused && p->within,
        .rig_time_s = p->rec.rig_time_s,
        .evaluation = &p->rec.eval,
    };
    c->opt.on_evaluation(c->opt.on_evaluation_user, &e);
}

/* Evaluates at scaled u into *p: the record, then the scaled residual and response, the
 * arclength row and the extended residual norm. */
int corrector_evaluate(rths_corrector *c, const double *u, corrector_point *p,
                       rths_evaluation_role role, double damping, rths_error *err) {
    int n = c->n;
    double target[LD];
    for (int i = 0; i < n; i++)
        target[i] = u[i] * c->scale[i];
    p->sol.omega_rad_s = u[n] * c->scale[n];
    memcpy(p->u, u, sizeof p->u);
    int rc = c->problem.eval(c->problem.ctx, target, p->sol.omega_rad_s, &p->rec, err);
    /* a measurement corrupted twice (rths_evaluation.refused) is the rig's state at this target,
     * not a numerical failure: the corrector reports it as such (RTHS_CORRECTOR_REFUSED) */
    c->refused = rc != RTHS_OK && p->rec.eval.refused;
    c->evaluations++;
    c->late_samples += p->rec.eval.late_samples;
    c->clipped_samples += p->rec.eval.clipped_demand_samples;
    c->saturated_samples += p->rec.eval.saturated_sensor_samples;
    c->samples_read += p->rec.eval.samples_read;
    c->remeasured += p->rec.eval.remeasured;
    c->refused_evaluations += p->rec.eval.refused;
    c->rig_time_s += p->rec.rig_time_s;
    for (int k = 0; k < c->harmonics; k++) {
        p->sol.target_a[k] = target[k];
        p->sol.target_b[k] = target[c->harmonics + k];
    }
    if (rc) {
        if (c->refused) report_evaluation(c, p, role, damping, 1);
        return rc;
    }
    pool_noise(&c->mem, &p->rec, n);
    if ((c->m == n || c->opt.rig_lti) && c->harmonics > 0)
        remember_evaluation(&c->mem, target, p->sol.omega_rad_s, &p->rec, n);
    double ext = describe(c, p) / (c->scale[0] * c->scale[0]);
    for (int i = 0; i < n; i++) {
        p->phi[i] = p->rec.phi[i] / c->scale[0];
        p->resp[i] = p->rec.response[i] / c->scale[0];
    }
    if (c->m > n) {
        double g = 0;
        for (int j = 0; j < c->m; j++)
            g += c->arc.tangent[j] * (u[j] - c->arc.predicted[j]);
        p->phi[n] = g;
        ext += g * g;
    }
    p->ext = sqrt(ext);
    report_evaluation(c, p, role, damping, 0);
    return RTHS_OK;
}
