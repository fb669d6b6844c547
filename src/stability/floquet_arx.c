/* Experimental Floquet multipliers from a periodic ARX fit of the series map (see floquet.h and
 * docs/method.md, "Experimental Floquet multipliers"). */
#include "rths/floquet.h"

#include <lapacke.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void rths_floquet_defaults(rths_floquet_options *opt) {
    opt->min_order = 2;
    opt->max_order = 16;
    opt->phase_harmonics = 3;
    opt->max_relative_residual = 0.2;
    opt->max_condition = 1e12;
}

int rths_floquet_phase_grid(const double *phase_rad, const double *u, const double *y, long n,
                            int samples_per_period, int max_periods, double *u_grid, double *y_grid,
                            int *periods_out, rths_error *err) {
    *periods_out = 0;
    const int p = samples_per_period;
    if (p < 4 || max_periods < 1 || n < 2)
        return rths_error_set(err, RTHS_EINPUT,
                              "phase grid of %d samples per period, %d periods, "
                              "from %ld samples",
                              p, max_periods, n);
    const double step = 2 * M_PI / p;
    /* unwrapped phase at the first and last sample: which whole periods of cells are covered */
    double first = phase_rad[0], last = first;
    for (long i = 1; i < n; i++) {
        double d = phase_rad[i] - phase_rad[i - 1];
        last += d < -M_PI ? d + 2 * M_PI : d;
    }
    long g_min = (long)ceil(first / step + 0.5), g_start = ((g_min + p - 1) / p) * (long)p;
    long g_end = (long)floor(last / step - 0.5); /* last cell wholly inside the record */
    long periods = (g_end - g_start + 1) / p;
    if (periods > max_periods) periods = max_periods;
    if (periods < 1)
        return rths_error_set(err, RTHS_EINPUT,
                              "the record of %ld samples holds no whole period "
                              "of phase cells",
                              n);
    long cells = periods * p;
    int *count = calloc((size_t)cells, sizeof *count);
    if (!count) return rths_error_set(err, RTHS_EFAIL, "out of memory");
    memset(u_grid, 0, (size_t)cells * sizeof *u_grid);
    memset(y_grid, 0, (size_t)cells * sizeof *y_grid);
    double theta = first;
    for (long i = 0; i < n; i++) {
        if (i > 0) {
            double d = phase_rad[i] - phase_rad[i - 1];
            theta += d < -M_PI ? d + 2 * M_PI : d;
        }
        long g = (long)floor(theta / step + 0.5) - g_start;
        if (g < 0 || g >= cells) continue;
        u_grid[g] += u[i];
        y_grid[g] += y[i];
        count[g]++;
    }
    int rc = RTHS_OK;
    for (long g = 0; g < cells && !rc; g++) {
        if (!count[g])
            rc = rths_error_set(err, RTHS_EINPUT,
                                "phase cell %ld holds no sample: %d samples per "
                                "period is finer than the record's sampling",
                                g, p);
        else {
            u_grid[g] /= count[g];
            y_grid[g] /= count[g];
        }
    }
    free(count);
    if (!rc) *periods_out = (int)periods;
    return rc;
}

void rths_floquet_remove_periodic_mean(double *s, int samples_per_period, int periods) {
    for (int j = 0; j < samples_per_period; j++) {
        double mean = 0;
        for (int m = 0; m < periods; m++)
            mean += s[j + m * samples_per_period];
        mean /= periods;
        for (int m = 0; m < periods; m++)
            s[j + m * samples_per_period] -= mean;
    }
}

/* One fit: order n, phase harmonics H, over periods [p0, p1) of the grid. */
typedef struct {
    const double *u, *y;
    int p, n, h;
    const double *basis; /* p x (2H+1): 1, cos q phi, sin q phi */
} arx_model;

static int basis_count(const arx_model *m) {
    return 2 * m->h + 1;
}
static int parameter_count(const arx_model *m) {
    return (2 * m->n + 1) * basis_count(m);
}

/* Regressor r of row k: y_{k-1-r} for r < n, then u_{k-(r-n)}. */
static double regressor(const arx_model *m, long k, int r) {
    return r < m->n ? m->y[k - 1 - r] : m->u[k - (r - m->n)];
}

/* Fills row (length parameters) of the regression at grid sample k. */
static void regression_row(const arx_model *m, long k, double *row) {
    const int nb = basis_count(m);
    const double *b = m->basis + (size_t)(k % m->p) * nb;
    for (int r = 0; r < 2 * m->n + 1; r++) {
        double x = regressor(m, k, r);
        for (int l = 0; l < nb; l++)
            row[r * nb + l] = x * b[l];
    }
}

typedef struct {
    double *theta; /* parameters (caller's buffer of parameter_count) */
    double rss, y_square, condition;
    long rows;
} arx_fit;

/* Least squares over periods [p0, p1): columns scaled to unit norm, dgelsd (SVD), so the
 * condition number is read off the singular values. */
static int fit_arx(const arx_model *m, int p0, int p1, arx_fit *f, rths_error *err) {
    const int np = parameter_count(m);
    long k0 = (long)p0 * m->p + m->n, k1 = (long)p1 * m->p;
    long rows = k1 - k0;
    f->rows = rows;
    if (rows < 2L * np)
        return rths_error_set(err, RTHS_EINPUT,
                              "%ld samples for %d ARX parameters: record more "
                              "periods",
                              rows, np);
    double *a = malloc((size_t)rows * np * sizeof *a), *rhs = malloc((size_t)rows * sizeof *rhs);
    double *scale = calloc((size_t)np, sizeof *scale), *sv = malloc((size_t)np * sizeof *sv);
    double *row = malloc((size_t)np * sizeof *row);
    int rc = RTHS_OK;
    if (!a || !rhs || !scale || !sv || !row) {
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
        goto done;
    }
    for (long k = k0; k < k1; k++) {
        regression_row(m, k, row);
        for (int c = 0; c < np; c++) {
            a[(k - k0) + c * rows] = row[c];
            scale[c] += row[c] * row[c];
        }
        rhs[k - k0] = m->y[k];
    }
    for (int c = 0; c < np; c++) {
        scale[c] = scale[c] > 0 ? sqrt(scale[c]) : 1.0;
        for (long i = 0; i < rows; i++)
            a[i + c * rows] /= scale[c];
    }
    lapack_int rank = 0;
    if (LAPACKE_dgelsd(LAPACK_COL_MAJOR, (lapack_int)rows, np, 1, a, (lapack_int)rows, rhs,
                       (lapack_int)rows, sv, -1.0, &rank)) {
        rc = rths_error_set(err, RTHS_EFAIL, "LAPACK dgelsd failed on the ARX regression");
        goto done;
    }
    f->condition = sv[np - 1] > 0 ? sv[0] / sv[np - 1] : INFINITY;
    for (int c = 0; c < np; c++)
        f->theta[c] = rhs[c] / scale[c];
    f->rss = f->y_square = 0;
    for (long k = k0; k < k1; k++) {
        regression_row(m, k, row);
        double e = m->y[k];
        for (int c = 0; c < np; c++)
            e -= f->theta[c] * row[c];
        f->rss += e * e;
        f->y_square += m->y[k] * m->y[k];
    }
done:
    free(a), free(rhs), free(scale), free(sv), free(row);
    return rc;
}

/* Coefficient of regressor r at grid phase j. */
static double coefficient(const arx_model *m, const double *theta, int r, int j) {
    const int nb = basis_count(m);
    double c = 0;
    for (int l = 0; l < nb; l++)
        c += theta[r * nb + l] * m->basis[(size_t)j * nb + l];
    return c;
}

static int by_modulus_desc(const void *pa, const void *pb) {
    const double *a = pa, *b = pb;
    double ma = hypot(a[0], a[1]), mb = hypot(b[0], b[1]);
    return (ma < mb) - (ma > mb);
}

/* Closes the fitted map with u = y, multiplies the companion matrices over one period and takes
 * the eigenvalues; multipliers sorted by modulus, largest first (re, im pairs in mult). */
static int close_and_multiply(const arx_model *m, const double *theta, double *mult,
                              double *closure_gain, rths_error *err) {
    const int n = m->n;
    double mono[RTHS_FLOQUET_MAX_ORDER * RTHS_FLOQUET_MAX_ORDER] = {0};
    double next[RTHS_FLOQUET_MAX_ORDER * RTHS_FLOQUET_MAX_ORDER], c[RTHS_FLOQUET_MAX_ORDER];
    for (int i = 0; i < n; i++)
        mono[i + i * n] = 1;
    *closure_gain = INFINITY;
    for (int j = 0; j < m->p; j++) {
        double g = 1 - coefficient(m, theta, n, j); /* 1 - b_0 */
        *closure_gain = fmin(*closure_gain, fabs(g));
        for (int i = 1; i <= n; i++)
            c[i - 1] = (coefficient(m, theta, i - 1, j) + coefficient(m, theta, n + i, j)) / g;
        /* companion times mono: the new first row combines the rows, the others shift down */
        for (int col = 0; col < n; col++) {
            double s = 0;
            for (int i = 0; i < n; i++)
                s += c[i] * mono[i + col * n];
            next[col * n] = s;
            for (int i = 1; i < n; i++)
                next[i + col * n] = mono[i - 1 + col * n];
        }
        memcpy(mono, next, sizeof(double) * (size_t)(n * n));
    }
    double wr[RTHS_FLOQUET_MAX_ORDER], wi[RTHS_FLOQUET_MAX_ORDER], vl = 0, vr = 0;
    for (int i = 0; i < n * n; i++)
        if (!isfinite(mono[i]))
            return rths_error_set(err, RTHS_EFAIL,
                                  "the closed ARX model's monodromy matrix is "
                                  "not finite (the closure 1 - b_0 vanished)");
    if (LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', n, mono, n, wr, wi, &vl, 1, &vr, 1))
        return rths_error_set(err, RTHS_EFAIL, "LAPACK dgeev failed on the monodromy matrix");
    for (int i = 0; i < n; i++) {
        mult[2 * i] = wr[i];
        mult[2 * i + 1] = wi[i];
    }
    qsort(mult, (size_t)n, 2 * sizeof *mult, by_modulus_desc);
    return RTHS_OK;
}

static int check_options(const rths_floquet_options *o, int p, int periods, rths_error *err) {
    if (o->min_order < 1 || o->max_order < o->min_order || o->max_order > RTHS_FLOQUET_MAX_ORDER)
        return rths_error_set(err, RTHS_EINPUT, "ARX orders %d..%d: expected 1 <= min <= max <= %d",
                              o->min_order, o->max_order, RTHS_FLOQUET_MAX_ORDER);
    if (o->phase_harmonics < 0 || o->phase_harmonics > RTHS_FLOQUET_MAX_PHASE_HARMONICS ||
        2 * o->phase_harmonics >= p)
        return rths_error_set(err, RTHS_EINPUT,
                              "%d phase harmonics on %d samples per period: "
                              "expected 0..%d and below half the samples",
                              o->phase_harmonics, p, RTHS_FLOQUET_MAX_PHASE_HARMONICS);
    if (periods < 2) return rths_error_set(err, RTHS_EINPUT, "%d period(s): at least 2", periods);
    return RTHS_OK;
}

static double max_abs_of(const arx_model *m, int p0, int p1, double *theta) {
    arx_fit f = {.theta = theta};
    double mult[2 * RTHS_FLOQUET_MAX_ORDER], gain;
    rths_error e;
    if (fit_arx(m, p0, p1, &f, &e) || close_and_multiply(m, theta, mult, &gain, &e)) return NAN;
    return hypot(mult[0], mult[1]);
}

/* The trust verdict: limits, then the halves' labels against the whole record's. */
static void judge(const rths_floquet_options *o, rths_floquet_estimate *e) {
    e->trustworthy = 0;
    if (!(e->relative_residual <= o->max_relative_residual))
        snprintf(e->note, sizeof e->note, "one-step residual %.3g of the output above %.3g",
                 e->relative_residual, o->max_relative_residual);
    else if (!(e->condition <= o->max_condition))
        snprintf(e->note, sizeof e->note, "regression condition %.3g above %.3g", e->condition,
                 o->max_condition);
    else if (!(e->closure_gain > 0.05))
        snprintf(e->note, sizeof e->note, "closure ill-posed (|1 - b0| = %.3g)", e->closure_gain);
    else if (!isfinite(e->max_abs_half[0]) || !isfinite(e->max_abs_half[1]))
        snprintf(e->note, sizeof e->note, "a half of the record is too short to fit");
    else if ((e->max_abs_half[0] < 1) != e->stable || (e->max_abs_half[1] < 1) != e->stable)
        snprintf(e->note, sizeof e->note, "the halves disagree (largest |mu| %.4f and %.4f)",
                 e->max_abs_half[0], e->max_abs_half[1]);
    else {
        e->trustworthy = 1;
        e->note[0] = 0;
    }
}

int rths_floquet_estimate_series(const double *u, const double *y, int samples_per_period,
                                 int periods, const rths_floquet_options *opt,
                                 rths_floquet_estimate *est, rths_error *err) {
    memset(est, 0, sizeof *est);
    const int p = samples_per_period;
    int rc = check_options(opt, p, periods, err);
    if (rc) return rc;
    const int nb = 2 * opt->phase_harmonics + 1;
    const int np_max = (2 * opt->max_order + 1) * nb;
    double *basis = malloc((size_t)p * nb * sizeof *basis);
    double *theta = malloc((size_t)np_max * sizeof *theta);
    double *best = malloc((size_t)np_max * sizeof *best);
    if (!basis || !theta || !best) {
        free(basis), free(theta), free(best);
        return rths_error_set(err, RTHS_EFAIL, "out of memory");
    }
    for (int j = 0; j < p; j++) {
        double phi = 2 * M_PI * j / p;
        basis[(size_t)j * nb] = 1;
        for (int q = 1; q <= opt->phase_harmonics; q++) {
            basis[(size_t)j * nb + 2 * q - 1] = cos(q * phi);
            basis[(size_t)j * nb + 2 * q] = sin(q * phi);
        }
    }
    arx_model m = {.u = u, .y = y, .p = p, .h = opt->phase_harmonics, .basis = basis};
    /* the order by the Bayesian information criterion, rows ln(rss / rows) + parameters ln rows:
     * a consistent order estimate, where a looser criterion adds noise-fitted near-cancelling
     * pole/zero pairs that the closure turns into spurious multipliers */
    double best_bic = INFINITY;
    arx_fit chosen = {0};
    for (int n = opt->min_order; n <= opt->max_order; n++) {
        m.n = n;
        arx_fit f = {.theta = theta};
        rths_error e;
        if (fit_arx(&m, 0, periods, &f, n == opt->min_order ? err : &e)) {
            if (n == opt->min_order) rc = err->code;
            break;
        }
        double bic = f.rows * log(fmax(f.rss, 1e-300) / f.rows) + parameter_count(&m) * log(f.rows);
        if (bic < best_bic) {
            best_bic = bic;
            chosen = f;
            est->order = n;
            memcpy(best, theta, sizeof(double) * (size_t)parameter_count(&m));
        }
    }
    double mult[2 * RTHS_FLOQUET_MAX_ORDER];
    if (!rc) {
        m.n = est->order;
        rc = close_and_multiply(&m, best, mult, &est->closure_gain, err);
    }
    if (!rc) {
        est->phase_harmonics = opt->phase_harmonics;
        est->parameters = parameter_count(&m);
        est->rows = (int)chosen.rows;
        est->n_multipliers = m.n;
        for (int i = 0; i < m.n; i++) {
            est->multiplier_re[i] = mult[2 * i];
            est->multiplier_im[i] = mult[2 * i + 1];
        }
        est->max_abs = hypot(mult[0], mult[1]);
        est->stable = est->max_abs < 1;
        est->relative_residual =
            chosen.y_square > 0 ? sqrt(chosen.rss / chosen.y_square) : INFINITY;
        est->condition = chosen.condition;
        est->max_abs_half[0] = max_abs_of(&m, 0, periods / 2, theta);
        est->max_abs_half[1] = max_abs_of(&m, periods / 2, periods, theta);
        judge(opt, est);
    }
    free(basis), free(theta), free(best);
    return rc;
}
