/* Rightmost characteristic roots by Chebyshev collocation of the infinitesimal generator
 * (Breda-Maset-Vermiglio style), on the DAE form of docs/method.md, "Delayed-feedback stability":
 *   q' = u,  w' = -C_0 u - K_0 q - K_tau q(t-tau),  0 = w - M_0 u - M_tau u(t-tau) - C_tau
 * q(t-tau). The state is y = (q, u, w) on nodes theta_k = tau (x_k - 1) / 2, x_k = cos(k pi / N), k
 * = 0..N. Rows k >= 1 say lambda y_k = (D y)_k (the history is an exponential); rows k = 0 are the
 * DAE with the delayed values taken at theta_N = -tau. The DAE form keeps the neutral term M_tau
 * u(t-tau) algebraic, so no differentiation of the history is needed at theta = 0. */
#include "rths/stability.h"

#include <lapacke.h>
#include <math.h>
#include <stdlib.h>
#include <string.h>

static void cheb_diff(int N, double *x, double *D) {
    int m = N + 1;
    for (int j = 0; j <= N; j++)
        x[j] = cos(M_PI * j / N);
    for (int i = 0; i <= N; i++) {
        double ci = (i == 0 || i == N) ? 2.0 : 1.0;
        double rs = 0;
        for (int j = 0; j <= N; j++) {
            if (i == j) continue;
            double cj = (j == 0 || j == N) ? 2.0 : 1.0;
            double sgn = ((i + j) % 2) ? -1.0 : 1.0;
            double v = ci / cj * sgn / (x[i] - x[j]);
            D[i + j * m] = v;
            rs += v;
        }
        D[i + i * m] = -rs; /* negative sum trick: exact derivative of constants */
    }
}

static int cmp_real_desc(const void *a, const void *b) {
    double ra = creal(*(const double complex *)a), rb = creal(*(const double complex *)b);
    return ra < rb ? 1 : ra > rb ? -1 : 0;
}

int rths_dde_spectral_roots(const rths_dde *d, double tau, int nodes, double accept_tol,
                            double complex **roots, int *n_roots, rths_error *err) {
    *roots = NULL;
    *n_roots = 0;
    if (!(tau > 0) || !isfinite(tau))
        return rths_error_set(err, RTHS_EINPUT, "spectral roots need a delay > 0, got %g", tau);
    if (nodes < 2 || nodes > 400)
        return rths_error_set(err, RTHS_EINPUT, "chebyshev nodes must be in [2, 400], got %d",
                              nodes);
    if (accept_tol <= 0) accept_tol = 1e-6;
    /* A first-order equation (no mass terms) uses the state (q, w), w = C_0 q + C_tau q(t-tau):
     * w' = -K_0 q - K_tau q(t-tau), 0 = w - C_0 q - C_tau q(t-tau). */
    int n = d->n, N = nodes;
    int first = rths_mat_max_abs(d->m0, n, n) == 0 && rths_mat_max_abs(d->mt, n, n) == 0;
    int s = (first ? 2 : 3) * n, dim = s * (N + 1);
    size_t dd = (size_t)dim * (size_t)dim;
    double *A = calloc(dd, sizeof(double)), *B = calloc(dd, sizeof(double));
    double *x = malloc((size_t)(N + 1) * sizeof(double));
    double *Dm = calloc((size_t)(N + 1) * (size_t)(N + 1), sizeof(double));
    double *ar = malloc((size_t)dim * 3 * sizeof(double));
    double complex *out = malloc((size_t)dim * sizeof(double complex));
    if (!A || !B || !x || !Dm || !ar || !out) {
        free(A), free(B), free(x), free(Dm), free(ar), free(out);
        return rths_error_set(err, RTHS_EFAIL, "out of memory (spectral discretisation, %d)", dim);
    }
    cheb_diff(N, x, Dm);
    int m = N + 1;
#define AA(i, j) A[(size_t)(i) + (size_t)(j) * (size_t)dim]
#define BB(i, j) B[(size_t)(i) + (size_t)(j) * (size_t)dim]
    int qN = N * s;
    if (first) {
        /* offsets in y_0: q at 0, w at n */
        for (int i = 0; i < n; i++) {
            BB(i, n + i) = 1.0;     /* lambda w = -K_0 q - K_tau q_N */
            AA(n + i, n + i) = 1.0; /* 0 = w - C_0 q - C_tau q_N */
            for (int j = 0; j < n; j++) {
                AA(i, j) = -RTHS_AT(d->k0, n, i, j);
                AA(i, qN + j) += -RTHS_AT(d->kt, n, i, j);
                AA(n + i, j) += -RTHS_AT(d->c0, n, i, j);
                AA(n + i, qN + j) += -RTHS_AT(d->ct, n, i, j);
            }
        }
    } else {
        /* offsets of q, u, w in y_0 are 0, n, 2n */
        int uN = N * s + n;
        for (int i = 0; i < n; i++) {
            BB(i, i) = 1.0; /* lambda q = u */
            AA(i, n + i) = 1.0;
            BB(n + i, 2 * n + i) = 1.0;     /* lambda w = -K_0 q - C_0 u - K_tau q_N */
            AA(2 * n + i, 2 * n + i) = 1.0; /* 0 = w - M_0 u - M_tau u_N - C_tau q_N */
            for (int j = 0; j < n; j++) {
                AA(n + i, j) = -RTHS_AT(d->k0, n, i, j);
                AA(n + i, n + j) = -RTHS_AT(d->c0, n, i, j);
                AA(n + i, qN + j) += -RTHS_AT(d->kt, n, i, j);
                AA(2 * n + i, n + j) += -RTHS_AT(d->m0, n, i, j);
                AA(2 * n + i, uN + j) += -RTHS_AT(d->mt, n, i, j);
                AA(2 * n + i, qN + j) += -RTHS_AT(d->ct, n, i, j);
            }
        }
    }
    double sc = 2.0 / tau;
    for (int k = 1; k <= N; k++)
        for (int r = 0; r < s; r++) {
            BB(k * s + r, k * s + r) = 1.0;
            for (int j = 0; j <= N; j++)
                AA(k * s + r, j * s + r) = sc * Dm[k + j * m];
        }
#undef AA
#undef BB
    double *ai = ar + dim, *be = ar + 2 * dim;
    lapack_int info = LAPACKE_dggev3(LAPACK_COL_MAJOR, 'N', 'N', dim, A, dim, B, dim, ar, ai, be,
                                     NULL, 1, NULL, 1);
    free(A), free(B), free(x), free(Dm);
    if (info != 0) {
        free(ar), free(out);
        return rths_error_set(err, RTHS_EFAIL, "spectral eigenproblem failed (dggev3 info %d)",
                              (int)info);
    }
    int cnt = 0;
    for (int k = 0; k < dim; k++) {
        if (be[k] == 0.0) continue;
        double complex l = (ar[k] + I * ai[k]) / be[k];
        if (!isfinite(creal(l)) || !isfinite(cimag(l)) || cimag(l) < -1e-9 * (1 + cabs(l)))
            continue;
        if (rths_dde_residual(d, tau, l) > accept_tol) continue;
        double complex lp = l;
        if (rths_dde_newton(d, tau, &lp) != 0) continue;
        /* Newton must stay with its eigenvalue, or the root belongs to another seed */
        if (cabs(lp - l) > 1e-3 * (1.0 + cabs(l))) continue;
        if (cimag(lp) < 0) lp = conj(lp);
        if (fabs(cimag(lp)) < 1e-10 * (1.0 + cabs(lp))) lp = creal(lp);
        int dup = 0;
        for (int j = 0; j < cnt && !dup; j++)
            dup = cabs(out[j] - lp) <= 1e-8 * (1.0 + cabs(lp));
        if (!dup) out[cnt++] = lp;
    }
    free(ar);
    qsort(out, (size_t)cnt, sizeof *out, cmp_real_desc);
    *roots = out;
    *n_roots = cnt;
    return RTHS_OK;
}

int rths_dde_label_at(const rths_dde *d, double tau, int nodes, rths_dde_label *out,
                      rths_error *err) {
    double rt;
    int rc = rths_dde_essential(d, &rt, NULL, NULL, err);
    if (rc) return rc;
    double complex *r;
    int nr;
    rc = rths_dde_spectral_roots(d, tau, nodes, 0, &r, &nr, err);
    if (rc) return rc;
    out->essential_per_s = rt / tau;
    out->rightmost_real = nr ? creal(r[0]) : -INFINITY;
    out->rightmost_imag = nr ? cimag(r[0]) : NAN;
    out->max_real_per_s = fmax(out->rightmost_real, out->essential_per_s);
    out->stable = out->rightmost_real < 0 && out->essential_per_s < 0;
    free(r);
    return RTHS_OK;
}
