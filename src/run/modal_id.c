/* Modal identification from a measured receptance (see modal_id.h; docs/method.md, "Complex FRF
 * and modal identification"). */
#include "run/modal_id.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { MAX_COLUMNS = 4 * FRF_MODAL_MAX_MODES + 4 };

typedef struct fit_data {
    int n;
    const double *w;         /* rad/s */
    const double complex *h; /* receptance */
    const double *sigma;     /* standard error of each part of h */
} fit_data;

/* Least squares A x = b (rows x cols, column-major, both overwritten) with the columns scaled to
 * unit norm first, so powers of s and poles of different sizes weigh alike. */
static int least_squares(int rows, int cols, double *a, double *b, double *x) {
    double scale[MAX_COLUMNS];
    for (int c = 0; c < cols; c++) {
        double norm = 0;
        for (int r = 0; r < rows; r++)
            norm += a[r + (size_t)rows * c] * a[r + (size_t)rows * c];
        scale[c] = norm > 0 ? sqrt(norm) : 1;
        for (int r = 0; r < rows; r++)
            a[r + (size_t)rows * c] /= scale[c];
    }
    if (LAPACKE_dgels(LAPACK_COL_MAJOR, 'N', rows, cols, 1, a, rows, b, rows) != 0) return -1;
    for (int c = 0; c < cols; c++) {
        x[c] = b[c] / scale[c];
        if (!isfinite(x[c])) return -1;
    }
    return 0;
}

static int compare_imag(const void *a, const void *b) {
    double x = cimag(*(const double complex *)a), y = cimag(*(const double complex *)b);
    return (x > y) - (x < y);
}

/* The poles: H = N(s) / D(s) in s = i w / w0 (w0 the largest w), D monic of degree 2m, N of
 * degree 2m + 2: the modes outside the band add to H a real, slowly varying term, c0 + c2 s^2
 * over the band (upper and lower residuals); with degree 2m + 1 alone the seed's second mode came
 * out 1.4e-5 high in frequency without noise, with 2m + 2 3e-7 (tests/test_modal_id.c). Fitted by
 * the linearised error N - H D weighted by 1 / (sigma |D_previous|) (Sanathanan-Koerner: at
 * convergence the weighted error of H itself); the m roots of D with positive imaginary part,
 * ascending. */
static int rfp_poles(const fit_data *d, int m, int iterations, double *a, double *b, double *weight,
                     double complex *poles) {
    int nb = 2 * m, p = 2 * m + 2, cols = p + 1 + nb, rows = 2 * d->n;
    double w0 = 0, hs = 0, x[MAX_COLUMNS];
    for (int k = 0; k < d->n; k++) {
        w0 = fmax(w0, d->w[k]);
        hs = fmax(hs, cabs(d->h[k]));
        weight[k] = 1;
    }
    if (!(w0 > 0) || !(hs > 0)) return -1;
    double prev[2 * FRF_MODAL_MAX_MODES] = {0};
    for (int it = 0; it < iterations; it++) {
        for (int k = 0; k < d->n; k++) {
            double complex s = I * d->w[k] / w0, hk = d->h[k] / hs, sp = 1;
            double g = hs / (d->sigma[k] * weight[k]);
            for (int j = 0; j <= p; j++, sp *= s) {
                a[2 * k + (size_t)rows * j] = g * creal(sp);
                a[2 * k + 1 + (size_t)rows * j] = g * cimag(sp);
            }
            sp = 1;
            for (int j = 0; j < nb; j++, sp *= s) {
                double complex v = -g * hk * sp;
                a[2 * k + (size_t)rows * (p + 1 + j)] = creal(v);
                a[2 * k + 1 + (size_t)rows * (p + 1 + j)] = cimag(v);
            }
            double complex rhs = g * hk * sp; /* sp = s^{2m} */
            b[2 * k] = creal(rhs);
            b[2 * k + 1] = cimag(rhs);
        }
        if (least_squares(rows, cols, a, b, x)) return -1;
        double change = 0, size = 0;
        for (int j = 0; j < nb; j++) {
            change = fmax(change, fabs(x[p + 1 + j] - prev[j]));
            size = fmax(size, fabs(x[p + 1 + j]));
            prev[j] = x[p + 1 + j];
        }
        for (int k = 0; k < d->n; k++) {
            double complex s = I * d->w[k] / w0, sp = 1, den = 0;
            for (int j = 0; j < nb; j++, sp *= s)
                den += x[p + 1 + j] * sp;
            weight[k] = cabs(den + sp);
            if (!(weight[k] > 0)) return -1;
        }
        if (it > 0 && change <= 1e-12 * size) break;
    }
    /* the roots of the monic D: eigenvalues of its companion matrix */
    double comp[4 * FRF_MODAL_MAX_MODES * FRF_MODAL_MAX_MODES] = {0};
    double wr[2 * FRF_MODAL_MAX_MODES], wi[2 * FRF_MODAL_MAX_MODES];
    for (int j = 0; j < nb; j++)
        comp[(size_t)nb * j] = -prev[nb - 1 - j]; /* first row: -b_{nb-1} ... -b_0 */
    for (int j = 1; j < nb; j++)
        comp[j + (size_t)nb * (j - 1)] = 1;
    if (LAPACKE_dgeev(LAPACK_COL_MAJOR, 'N', 'N', nb, comp, nb, wr, wi, NULL, 1, NULL, 1) != 0)
        return -1;
    int found = 0;
    for (int j = 0; j < nb; j++)
        if (wi[j] > 0 && wr[j] < 0 && found < m) poles[found++] = w0 * (wr[j] + I * wi[j]);
    if (found < m) return -1;
    qsort(poles, (size_t)m, sizeof *poles, compare_imag);
    return 0;
}

/* The residues with the poles fixed (least-squares frequency domain): H = sum_r R_r / (i w -
 * lambda_r) + conj(R_r) / (i w - conj(lambda_r)) + U - L / w^2, U and L real (the modes above
 * and below the band), weighted by 1 / sigma; the model at the points into model (may be NULL). */
static int lsfd_residues(const fit_data *d, int m, const double complex *poles, double *a,
                         double *b, double complex *residues, double complex *model) {
    int cols = 2 * m + 2, rows = 2 * d->n;
    double x[MAX_COLUMNS], hs = 0;
    for (int k = 0; k < d->n; k++)
        hs = fmax(hs, cabs(d->h[k]));
    for (int k = 0; k < d->n; k++) {
        double complex s = I * d->w[k], col[MAX_COLUMNS];
        for (int r = 0; r < m; r++) {
            double complex u = 1 / (s - poles[r]), v = 1 / (s - conj(poles[r]));
            col[2 * r] = u + v;
            col[2 * r + 1] = I * u - I * v;
        }
        col[2 * m] = 1;
        col[2 * m + 1] = -1 / (d->w[k] * d->w[k]);
        double g = 1 / d->sigma[k];
        for (int c = 0; c < cols; c++) {
            a[2 * k + (size_t)rows * c] = g * creal(col[c]);
            a[2 * k + 1 + (size_t)rows * c] = g * cimag(col[c]);
        }
        b[2 * k] = g * creal(d->h[k]) / hs;
        b[2 * k + 1] = g * cimag(d->h[k]) / hs;
    }
    if (least_squares(rows, cols, a, b, x)) return -1;
    for (int r = 0; r < m; r++)
        residues[r] = hs * (x[2 * r] + I * x[2 * r + 1]);
    for (int k = 0; model && k < d->n; k++) {
        double complex s = I * d->w[k], sum = hs * (x[2 * m] - x[2 * m + 1] / (d->w[k] * d->w[k]));
        for (int r = 0; r < m; r++)
            sum += residues[r] / (s - poles[r]) + conj(residues[r]) / (s - conj(poles[r]));
        model[k] = sum;
    }
    return 0;
}

/* Scratch for one fit: the least-squares matrix and right-hand side, the SK weights. */
typedef struct fit_work {
    double *a, *b, *weight;
} fit_work;

static int fit_once(const fit_data *d, int m, int iterations, fit_work *w, frf_mode_estimate *est,
                    double complex *model) {
    double complex poles[FRF_MODAL_MAX_MODES], residues[FRF_MODAL_MAX_MODES];
    if (rfp_poles(d, m, iterations, w->a, w->b, w->weight, poles) ||
        lsfd_residues(d, m, poles, w->a, w->b, residues, model))
        return -1;
    for (int r = 0; r < m; r++) {
        double wn = cabs(poles[r]);
        est[r].frequency_hz = wn / (2 * M_PI);
        est[r].damping_ratio = -creal(poles[r]) / wn;
        /* R = A / (2 i w_d) for the modal constant A of A / (w_n^2 - w^2 + 2 i zeta w_n w) */
        est[r].modal_constant = 2 * I * cimag(poles[r]) * residues[r];
    }
    return 0;
}

int frf_modal_fit(int n, const double *f_hz, const double complex *h, const double *se,
                  const frf_modal_fit_options *opt, frf_mode_estimate *out, int *replicates_used,
                  rths_error *err) {
    int m = opt->modes, iterations = opt->sk_iterations > 0 ? opt->sk_iterations : 30;
    if (replicates_used) *replicates_used = 0;
    if (m < 1 || m > FRF_MODAL_MAX_MODES)
        return rths_error_set(err, RTHS_EINPUT, "modal fit: %d modes (1..%d)", m,
                              FRF_MODAL_MAX_MODES);
    double *w = malloc((size_t)(n > 0 ? n : 1) * sizeof *w),
           *sigma = malloc((size_t)(n > 0 ? n : 1) * sizeof *sigma);
    double complex *hh = malloc((size_t)(n > 0 ? n : 1) * sizeof *hh),
                   *model = malloc((size_t)(n > 0 ? n : 1) * sizeof *model),
                   *star = malloc((size_t)(n > 0 ? n : 1) * sizeof *star);
    int used = 0;
    for (int k = 0; w && sigma && hh && k < n; k++)
        if (f_hz[k] > 0 && isfinite(creal(h[k])) && isfinite(cimag(h[k])) && se[k] > 0 &&
            isfinite(se[k])) {
            w[used] = 2 * M_PI * f_hz[k];
            hh[used] = h[k];
            sigma[used++] = se[k];
        }
    fit_work work = {malloc((size_t)(2 * used + 1) * MAX_COLUMNS * sizeof(double)),
                     malloc((size_t)(2 * used + 1) * sizeof(double)),
                     malloc((size_t)(used + 1) * sizeof(double))};
    int rc = 0;
    if (!w || !sigma || !hh || !model || !star || !work.a || !work.b || !work.weight)
        rc = rths_error_set(err, RTHS_EFAIL, "out of memory");
    else if (2 * used < 4 * m + 2 + 2)
        rc = rths_error_set(err, RTHS_EINPUT,
                            "modal fit: %d usable points for %d mode(s); at least %d needed", used,
                            m, 2 * m + 2);
    fit_data d = {used, w, hh, sigma};
    if (!rc && fit_once(&d, m, iterations, &work, out, model))
        rc = rths_error_set(err, RTHS_EFAIL,
                            "modal fit: the rational fraction fit found fewer than %d stable "
                            "oscillating poles in %d points",
                            m, used);
    for (int r = 0; r < m && !rc; r++)
        out[r].frequency_se_hz = out[r].damping_ratio_se = out[r].modal_constant_se_real =
            out[r].modal_constant_se_imag = NAN;
    /* parametric bootstrap: the fitted model plus circular noise of each point's SE, refitted;
     * the standard deviations of the replicates' estimates (Welford) */
    double mean[FRF_MODAL_MAX_MODES][4] = {{0}}, m2[FRF_MODAL_MAX_MODES][4] = {{0}};
    int good = 0;
    rths_rng rng;
    rths_rng_seed(&rng, opt->seed);
    for (int rep = 0; rep < opt->bootstrap && !rc; rep++) {
        for (int k = 0; k < used; k++) {
            double e1 = rths_rng_normal(&rng), e2 = rths_rng_normal(&rng);
            star[k] = model[k] + sigma[k] * (e1 + I * e2);
        }
        fit_data ds = {used, w, star, sigma};
        frf_mode_estimate est[FRF_MODAL_MAX_MODES];
        if (fit_once(&ds, m, iterations, &work, est, NULL)) continue;
        good++;
        for (int r = 0; r < m; r++) {
            double v[4] = {est[r].frequency_hz, est[r].damping_ratio, creal(est[r].modal_constant),
                           cimag(est[r].modal_constant)};
            for (int q = 0; q < 4; q++) {
                double delta = v[q] - mean[r][q];
                mean[r][q] += delta / good;
                m2[r][q] += delta * (v[q] - mean[r][q]);
            }
        }
    }
    /* too few replicates fitted: no standard error rather than a misleading one */
    if (!rc && good >= 2 && 2 * good >= opt->bootstrap)
        for (int r = 0; r < m; r++) {
            out[r].frequency_se_hz = sqrt(m2[r][0] / (good - 1));
            out[r].damping_ratio_se = sqrt(m2[r][1] / (good - 1));
            out[r].modal_constant_se_real = sqrt(m2[r][2] / (good - 1));
            out[r].modal_constant_se_imag = sqrt(m2[r][3] / (good - 1));
        }
    if (replicates_used) *replicates_used = good;
    free(w);
    free(sigma);
    free(hh);
    free(model);
    free(star);
    free(work.a);
    free(work.b);
    free(work.weight);
    return rc;
}
