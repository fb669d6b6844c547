/* The steady state from the transient: shared-pole fit of per-period coefficient series
 * (transient_fit.h; docs/method.md, "One evaluation"). Host side only: it allocates and calls
 * LAPACK, and never runs in the per-sample step. */
#include "iterate/transient_fit.h"

#include "rths/core.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

enum { NMAX = TRANSIENT_FIT_MAX_ORDER, GMAX = TRANSIENT_FIT_MAX_ORDER + 1 };

/* The decaying terms' basis: column j (0..n-1) is the solution of the recurrence
 * x_q = -sum_l alpha_l x_{q-l} started from the unit vector e_j. It spans {z_j^q} for distinct
 * roots and stays smooth in alpha where roots collide (a complex pair turning into two real
 * poles), which a basis of powers of the roots does not. */
static void decay_basis(int n, const double *alpha, int K, double *B) {
    for (int j = 0; j < n; j++)
        for (int q = 0; q < K; q++) {
            double x;
            if (q < n) {
                x = q == j ? 1.0 : 0.0;
            } else {
                x = 0;
                for (int l = 1; l <= n; l++)
                    x -= alpha[l - 1] * B[(q - l) + (size_t)j * K];
            }
            B[q + (size_t)j * K] = x;
        }
}

/* G = [1, B] (K x (1 + n)) and the inverse of its normal matrix; 0, or -1 when singular. The
 * columns are scaled to unit norm before the inverse (a slow pole's column and the constant
 * are nearly parallel) and the scaling is undone in the inverse. */
static int normal_inverse(int n, int K, const double *B, double *Ainv) {
    int g = 1 + n;
    double A[GMAX * GMAX] = {0}, s[GMAX];
    for (int c = 0; c < g; c++) {
        double ss = 0;
        for (int q = 0; q < K; q++) {
            double v = c ? B[q + (size_t)(c - 1) * K] : 1.0;
            ss += v * v;
        }
        s[c] = ss > 0 ? 1.0 / sqrt(ss) : 1.0;
    }
    for (int r = 0; r < g; r++)
        for (int c = 0; c < g; c++) {
            double acc = 0;
            for (int q = 0; q < K; q++) {
                double vr = r ? B[q + (size_t)(r - 1) * K] : 1.0;
                double vc = c ? B[q + (size_t)(c - 1) * K] : 1.0;
                acc += vr * vc;
            }
            A[r + c * g] = acc * s[r] * s[c];
        }
    if (rths_mat_inverse(g, A, Ainv)) return -1;
    for (int r = 0; r < g; r++)
        for (int c = 0; c < g; c++) {
            Ainv[r + c * g] *= s[r] * s[c];
            if (!isfinite(Ainv[r + c * g])) return -1;
        }
    return 0;
}

/* theta = Ainv G^T y for one series; returns its residual sum of squares, residuals into r
 * (may be NULL). */
static double series_fit(int n, int K, const double *B, const double *Ainv, const double *y,
                         double *theta, double *r) {
    int g = 1 + n;
    double gy[GMAX];
    for (int c = 0; c < g; c++) {
        double acc = 0;
        for (int q = 0; q < K; q++)
            acc += (c ? B[q + (size_t)(c - 1) * K] : 1.0) * y[q];
        gy[c] = acc;
    }
    for (int r0 = 0; r0 < g; r0++) {
        double acc = 0;
        for (int c = 0; c < g; c++)
            acc += Ainv[r0 + c * g] * gy[c];
        theta[r0] = acc;
    }
    double rss = 0;
    for (int q = 0; q < K; q++) {
        double model = theta[0];
        for (int j = 0; j < n; j++)
            model += theta[1 + j] * B[q + (size_t)j * K];
        double e = y[q] - model;
        if (r) r[q] = e;
        rss += e * e;
    }
    return rss;
}

typedef struct workspace {
    int m, K;
    const double *y;
    const double *w; /* per-series weight 1 / sigma^2 */
    double *B, *r;
} workspace;

/* Weighted residual sum of squares of the variable-projection problem at alpha (r: the weighted
 * residual vector, m K; may be NULL). HUGE_VAL when the basis is singular. */
static double projected_rss(workspace *ws, int n, const double *alpha, double *r) {
    double Ainv[GMAX * GMAX], theta[GMAX];
    decay_basis(n, alpha, ws->K, ws->B);
    if (normal_inverse(n, ws->K, ws->B, Ainv)) return HUGE_VAL;
    double total = 0;
    for (int i = 0; i < ws->m; i++) {
        double *ri = r ? r + (size_t)i * ws->K : NULL;
        total += ws->w[i] * series_fit(n, ws->K, ws->B, Ainv, ws->y + (size_t)i * ws->K, theta, ri);
        if (ri) {
            double sw = sqrt(ws->w[i]);
            for (int q = 0; q < ws->K; q++)
                ri[q] *= sw;
        }
    }
    return isfinite(total) ? total : HUGE_VAL;
}

/* Prony on the periods' differences (the constant drops out of them), all series sharing alpha:
 * d_{q+n} + sum_l alpha_l d_{q+n-l} = 0 in weighted least squares. */
static int prony(workspace *ws, int n, double *alpha) {
    double N[NMAX * NMAX] = {0}, rhs[NMAX] = {0};
    int K = ws->K;
    for (int i = 0; i < ws->m; i++) {
        const double *y = ws->y + (size_t)i * K;
        for (int q = 0; q + n + 1 < K; q++) {
            double row[NMAX], target = -(y[q + n + 1] - y[q + n]);
            for (int l = 1; l <= n; l++)
                row[l - 1] = y[q + n + 1 - l] - y[q + n - l];
            for (int a = 0; a < n; a++) {
                rhs[a] += ws->w[i] * row[a] * target;
                for (int b = 0; b < n; b++)
                    N[a + b * n] += ws->w[i] * row[a] * row[b];
            }
        }
    }
    double trace = 0;
    for (int a = 0; a < n; a++)
        trace += N[a + a * n];
    for (int a = 0; a < n; a++)
        N[a + a * n] += 1e-12 * trace + 1e-300;
    if (rths_mat_solve(n, 1, N, rhs)) return -1;
    memcpy(alpha, rhs, sizeof(double) * (size_t)n);
    return 0;
}

/* Levenberg-Marquardt on alpha with the linear parameters projected out (variable projection),
 * Jacobian by central differences. Returns the final weighted RSS. */
static double refine(workspace *ws, int n, double *alpha) {
    size_t mk = (size_t)ws->m * ws->K;
    double *r0 = malloc(sizeof(double) * mk), *rp = malloc(sizeof(double) * mk),
           *rm = malloc(sizeof(double) * mk), *J = malloc(sizeof(double) * mk * NMAX);
    double f = projected_rss(ws, n, alpha, r0), lambda = 1e-3;
    if (!r0 || !rp || !rm || !J || !isfinite(f)) goto done;
    for (int it = 0; it < 40; it++) {
        for (int l = 0; l < n; l++) {
            double a[NMAX], h = 1e-6 * (1.0 + fabs(alpha[l]));
            memcpy(a, alpha, sizeof a);
            a[l] = alpha[l] + h;
            double fp = projected_rss(ws, n, a, rp);
            a[l] = alpha[l] - h;
            double fm = projected_rss(ws, n, a, rm);
            if (!isfinite(fp) || !isfinite(fm)) goto done;
            for (size_t k = 0; k < mk; k++)
                J[k + l * mk] = (rp[k] - rm[k]) / (2 * h);
        }
        double JtJ[NMAX * NMAX], Jtr[NMAX];
        for (int a = 0; a < n; a++) {
            double acc = 0;
            for (size_t k = 0; k < mk; k++)
                acc += J[k + a * mk] * r0[k];
            Jtr[a] = acc;
            for (int b = 0; b < n; b++) {
                double s = 0;
                for (size_t k = 0; k < mk; k++)
                    s += J[k + a * mk] * J[k + b * mk];
                JtJ[a + b * n] = s;
            }
        }
        int improved = 0;
        for (int tries = 0; tries < 12 && !improved; tries++) {
            double M[NMAX * NMAX], step[NMAX], trial[NMAX];
            memcpy(M, JtJ, sizeof M);
            for (int a = 0; a < n; a++) {
                M[a + a * n] += lambda * (JtJ[a + a * n] + 1e-300);
                step[a] = -Jtr[a];
            }
            if (rths_mat_solve(n, 1, M, step)) {
                lambda *= 10;
                continue;
            }
            for (int a = 0; a < n; a++)
                trial[a] = alpha[a] + step[a];
            double ft = projected_rss(ws, n, trial, rp);
            if (ft < f) {
                double gain = f - ft;
                memcpy(alpha, trial, sizeof(double) * (size_t)n);
                memcpy(r0, rp, sizeof(double) * mk);
                f = ft;
                lambda = fmax(lambda / 10, 1e-12);
                improved = 1;
                if (gain <= 1e-12 * f) it = 1000; /* converged */
            } else {
                lambda *= 10;
            }
        }
        if (!improved) break;
    }
done:
    free(r0), free(rp), free(rm), free(J);
    return f;
}

/* Roots of z^n + alpha_1 z^(n-1) + ... + alpha_n (companion matrix eigenvalues). */
static void poles(int n, const double *alpha, double complex *z) {
    if (n == 0) return;
    double C[NMAX * NMAX] = {0}, wr[NMAX], wi[NMAX];
    for (int c = 0; c < n; c++)
        C[0 + c * n] = -alpha[c];
    for (int r = 1; r < n; r++)
        C[r + (r - 1) * n] = 1.0;
    if (LAPACKE_dhseqr(LAPACK_COL_MAJOR, 'E', 'N', n, 1, n, C, n, wr, wi, NULL, 1) != 0) {
        for (int j = 0; j < n; j++)
            z[j] = INFINITY;
        return;
    }
    for (int j = 0; j < n; j++)
        z[j] = wr[j] + I * wi[j];
}

/* d(B theta_decay)/d alpha (K x n) for one series' decay coefficients c, by central differences
 * of the basis (smooth in alpha: decay_basis). dB: n blocks of K x n, block l = dB/d alpha_l. */
static void basis_derivative(int n, const double *alpha, int K, double *dB, double *tmp) {
    for (int l = 0; l < n; l++) {
        double a[NMAX], h = 1e-6 * (1.0 + fabs(alpha[l]));
        double *block = dB + (size_t)l * K * n;
        memcpy(a, alpha, sizeof(double) * (size_t)n);
        a[l] = alpha[l] + h;
        decay_basis(n, a, K, block);
        a[l] = alpha[l] - h;
        decay_basis(n, a, K, tmp);
        for (size_t k = 0; k < (size_t)K * n; k++)
            block[k] = (block[k] - tmp[k]) / (2 * h);
    }
}

/* D = d(B c)/d alpha for decay coefficients c (K x n, column l). */
static void series_derivative(int n, int K, const double *dB, const double *c, double *D) {
    for (int l = 0; l < n; l++)
        for (int q = 0; q < K; q++) {
            double acc = 0;
            for (int j = 0; j < n; j++)
                acc += dB[(size_t)l * K * n + q + (size_t)j * K] * c[j];
            D[q + (size_t)l * K] = acc;
        }
}

/* u = Ainv G^T D (g x n) and D^T D - D^T G Ainv G^T D (n x n, added to S). */
static void schur_terms(int n, int K, const double *B, const double *Ainv, const double *D,
                        double *u, double *S, double weight) {
    int g = 1 + n;
    double GtD[GMAX * NMAX];
    for (int c = 0; c < g; c++)
        for (int l = 0; l < n; l++) {
            double acc = 0;
            for (int q = 0; q < K; q++)
                acc += (c ? B[q + (size_t)(c - 1) * K] : 1.0) * D[q + (size_t)l * K];
            GtD[c + l * g] = acc;
        }
    for (int r = 0; r < g; r++)
        for (int l = 0; l < n; l++) {
            double acc = 0;
            for (int c = 0; c < g; c++)
                acc += Ainv[r + c * g] * GtD[c + l * g];
            u[r + l * g] = acc;
        }
    if (!S) return;
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++) {
            double dd = 0, proj = 0;
            for (int q = 0; q < K; q++)
                dd += D[q + (size_t)a * K] * D[q + (size_t)b * K];
            for (int c = 0; c < g; c++)
                proj += GtD[c + a * g] * u[c + b * g];
            S[a + b * n] += weight * (dd - proj);
        }
}

/* Variance of a_inf from the pole uncertainty: u's row 0 through shared_cov. */
static double pole_variance(int n, const double *u, const double *shared_cov) {
    int g = 1 + n;
    double v = 0;
    for (int a = 0; a < n; a++)
        for (int b = 0; b < n; b++)
            v += u[0 + a * g] * shared_cov[a + b * n] * u[0 + b * g];
    return fmax(v, 0.0);
}

int transient_fit_series(int m, int K, const double *y, int max_order, const double *prior_var,
                         double prior_dof, transient_fit *fit, double *a_inf, double *se,
                         double *noise_var) {
    return transient_fit_series_margin(m, K, y, max_order, TRANSIENT_FIT_RESIDUAL_MARGIN, prior_var,
                                       prior_dof, fit, a_inf, se, noise_var);
}

int transient_fit_series_margin(int m, int K, const double *y, int max_order, int margin,
                                const double *prior_var, double prior_dof, transient_fit *fit,
                                double *a_inf, double *se, double *noise_var) {
    memset(fit, 0, sizeof *fit);
    if (m < 1 || K < 3) return -1;
    if (max_order > NMAX) max_order = NMAX;
    if (margin < 0) margin = 0;
    /* every series keeps at least as many degrees of freedom of its own as the decaying terms
     * take, and `margin` more (3 by default): a fit that nearly interpolates its record can
     * follow a misfit exactly and report a small residual for it */
    while (max_order > 0 && K - 1 - max_order < max_order + margin)
        max_order--;
    double *w = malloc(sizeof(double) * (size_t)m), *B = malloc(sizeof(double) * (size_t)K * NMAX),
           *r = malloc(sizeof(double) * (size_t)m * K);
    double *dB = malloc(sizeof(double) * (size_t)K * NMAX * NMAX),
           *tmp = malloc(sizeof(double) * (size_t)K * NMAX),
           *D = malloc(sizeof(double) * (size_t)K * NMAX),
           *u = malloc(sizeof(double) * (size_t)m * GMAX * NMAX);
    int rc = -1;
    if (!w || !B || !r || !dB || !tmp || !D || !u) goto done;
    /* weights: each series' second-difference scatter (its noise if steady, its transient's
     * curvature if not; only the series' relative weights matter, and its unit: m or rad) */
    for (int i = 0; i < m; i++) {
        const double *yi = y + (size_t)i * K;
        double ss = 0, scale = 0;
        for (int q = 0; q < K; q++)
            scale += yi[q] * yi[q];
        for (int q = 1; q + 1 < K; q++) {
            double dd = yi[q + 1] - 2 * yi[q] + yi[q - 1];
            ss += dd * dd / 6.0;
        }
        double v = ss / (K - 2);
        double floor_v = 1e-24 * scale / K + 1e-300;
        w[i] = 1.0 / fmax(v, floor_v);
    }
    workspace ws = {.m = m, .K = K, .y = y, .w = w, .B = B, .r = r};
    double best_bic = HUGE_VAL, best_alpha[NMAX] = {0};
    int best_n = -1;
    double N = (double)m * K;
    for (int n = 0; n <= max_order; n++) {
        double alpha[NMAX] = {0};
        if (n > 0 && prony(&ws, n, alpha)) continue;
        double f = n > 0 ? refine(&ws, n, alpha) : projected_rss(&ws, 0, alpha, NULL);
        if (!isfinite(f)) continue;
        double P = (double)m * (1 + n) + n;
        double bic = N * log(fmax(f, 1e-300) / N) + P * log(N);
        if (bic < best_bic) {
            best_bic = bic;
            best_n = n;
            memcpy(best_alpha, alpha, sizeof alpha);
        }
    }
    if (best_n < 0) goto done;
    int n = best_n, g = 1 + n;
    fit->order = n;
    fit->periods = K;
    memcpy(fit->alpha, best_alpha, sizeof best_alpha);
    poles(n, best_alpha, fit->z);
    fit->max_abs_z = 0;
    for (int j = 0; j < n; j++)
        fit->max_abs_z = fmax(fit->max_abs_z, cabs(fit->z[j]));
    double Ainv[GMAX * GMAX];
    decay_basis(n, best_alpha, K, B);
    if (normal_inverse(n, K, B, Ainv)) goto done;
    if (n > 0) basis_derivative(n, best_alpha, K, dB, tmp);
    double S[NMAX * NMAX] = {0}, rss_total = 0, lag_num = 0, lag_den = 0;
    double dof_own = K - 1 - n - (double)n / m;
    for (int i = 0; i < m; i++) {
        double theta[GMAX];
        const double *yi = y + (size_t)i * K;
        double *ri = r + (size_t)i * K;
        double rss = series_fit(n, K, B, Ainv, yi, theta, ri);
        rss_total += rss;
        double pv = prior_var && prior_dof > 0 ? prior_var[i] * prior_dof : 0.0;
        double pd = prior_var && prior_dof > 0 ? prior_dof : 0.0;
        double var = (rss + pv) / (dof_own + pd);
        a_inf[i] = theta[0];
        if (noise_var) noise_var[i] = var;
        se[i] = var * Ainv[0]; /* variance for now; the poles' part added below */
        w[i] = var > 0 ? 1.0 / var : 0.0;
        if (var > 0) {
            for (int q = 0; q < K; q++) {
                lag_den += ri[q] * ri[q] / var;
                if (q + 1 < K) lag_num += ri[q] * ri[q + 1] / var;
            }
        }
        if (n > 0) {
            series_derivative(n, K, dB, theta + 1, D);
            schur_terms(n, K, B, Ainv, D, u + (size_t)i * g * n, S, w[i]);
        }
    }
    fit->lag1 = lag_den > 0 ? lag_num / lag_den : 0.0;
    fit->rms_residual = sqrt(rss_total / K);
    if (n > 0) {
        /* the shared parameters' covariance, (S - sum C^T A^-1 C)^-1 */
        if (rths_mat_inverse(n, S, fit->shared_cov)) {
            /* S is singular only when no series carries the poles (every residual or decay
             * coefficient zero): then their uncertainty moves no a_inf either */
            for (int k = 0; k < n * n; k++)
                fit->shared_cov[k] = 0;
        }
        for (int i = 0; i < m; i++)
            se[i] += pole_variance(n, u + (size_t)i * g * n, fit->shared_cov);
    }
    for (int i = 0; i < m; i++)
        se[i] = sqrt(se[i]);
    fit->ok = 1;
    rc = 0;
done:
    free(w), free(B), free(r), free(dB), free(tmp), free(D), free(u);
    return rc;
}

void transient_fit_apply(const transient_fit *fit, const double *y, double *a_inf, double *se) {
    int n = fit->order, K = fit->periods;
    *a_inf = NAN;
    *se = INFINITY;
    if (!fit->ok) return;
    double *B = malloc(sizeof(double) * (size_t)K * NMAX),
           *dB = malloc(sizeof(double) * (size_t)K * NMAX * NMAX),
           *tmp = malloc(sizeof(double) * (size_t)K * NMAX),
           *D = malloc(sizeof(double) * (size_t)K * NMAX);
    double Ainv[GMAX * GMAX], theta[GMAX], u[GMAX * NMAX];
    if (!B || !dB || !tmp || !D) goto done;
    decay_basis(n, fit->alpha, K, B);
    if (normal_inverse(n, K, B, Ainv)) goto done;
    double rss = series_fit(n, K, B, Ainv, y, theta, NULL);
    double var = rss / (K - 1 - n);
    double v = var * Ainv[0];
    if (n > 0) {
        basis_derivative(n, fit->alpha, K, dB, tmp);
        series_derivative(n, K, dB, theta + 1, D);
        schur_terms(n, K, B, Ainv, D, u, NULL, 0);
        v += pole_variance(n, u, fit->shared_cov);
    }
    *a_inf = theta[0];
    *se = sqrt(v);
done:
    free(B), free(dB), free(tmp), free(D);
}
