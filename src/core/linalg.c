/* Dense column-major linear algebra over LAPACKE / CBLAS (OpenBLAS). */
#include "rths/core.h"

#include <cblas.h>
#include <lapacke.h>
#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

double rths_monotonic_s(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int rths_error_set(rths_error *err, int code, const char *fmt, ...) {
    if (err) {
        va_list ap;
        va_start(ap, fmt);
        vsnprintf(err->msg, sizeof err->msg, fmt, ap);
        va_end(ap);
        err->code = code;
    }
    return code;
}

void rths_error_clear(rths_error *err) {
    if (err) {
        err->code = RTHS_OK;
        err->msg[0] = '\0';
    }
}

double *rths_mat_new(int rows, int cols) {
    size_t count = (size_t)(rows > 0 ? rows : 1) * (size_t)(cols > 0 ? cols : 1);
    return calloc(count, sizeof(double));
}

double *rths_mat_dup(const double *a, int rows, int cols) {
    double *c = rths_mat_new(rows, cols);
    if (c && a) memcpy(c, a, (size_t)rows * (size_t)cols * sizeof(double));
    return c;
}

void rths_mat_free(double *a) {
    free(a);
}

void rths_mat_identity(double *a, int n) {
    memset(a, 0, (size_t)n * (size_t)n * sizeof(double));
    for (int i = 0; i < n; i++)
        RTHS_AT(a, n, i, i) = 1.0;
}

void rths_mat_mul(int m, int n, int k, double alpha, const double *a, int trans_a, const double *b,
                  int trans_b, double beta, double *c) {
    cblas_dgemm(CblasColMajor, trans_a ? CblasTrans : CblasNoTrans,
                trans_b ? CblasTrans : CblasNoTrans, m, n, k, alpha, a, trans_a ? k : m, b,
                trans_b ? n : k, beta, c, m);
}

int rths_mat_solve(int n, int nrhs, double *a, double *b) {
    lapack_int *ipiv = malloc((size_t)n * sizeof *ipiv);
    if (!ipiv) return -1;
    lapack_int info = LAPACKE_dgesv(LAPACK_COL_MAJOR, n, nrhs, a, n, ipiv, b, n);
    free(ipiv);
    return (int)info;
}

int rths_mat_inverse(int n, const double *a, double *inv) {
    double *work = rths_mat_dup(a, n, n);
    if (!work) return -1;
    rths_mat_identity(inv, n);
    int info = rths_mat_solve(n, n, work, inv);
    free(work);
    return info;
}

double rths_mat_max_abs(const double *a, int rows, int cols) {
    double m = 0.0;
    for (size_t i = 0; i < (size_t)rows * (size_t)cols; i++)
        if (fabs(a[i]) > m) m = fabs(a[i]);
    return m;
}

double rths_mat_norm1(const double *a, int n) {
    double best = 0.0;
    for (int j = 0; j < n; j++) {
        double s = 0.0;
        for (int i = 0; i < n; i++)
            s += fabs(RTHS_AT(a, n, i, j));
        if (s > best) best = s;
    }
    return best;
}

int rths_mat_is_symmetric(const double *a, int n, double rel_tol) {
    double scale = rths_mat_max_abs(a, n, n);
    for (int i = 0; i < n; i++)
        for (int j = i + 1; j < n; j++)
            if (fabs(RTHS_AT(a, n, i, j) - RTHS_AT(a, n, j, i)) > rel_tol * scale) return 0;
    return 1;
}

int rths_mat_is_spd(const double *a, int n) {
    double *work = rths_mat_dup(a, n, n);
    if (!work) return 0;
    lapack_int info = LAPACKE_dpotrf(LAPACK_COL_MAJOR, 'L', n, work, n);
    free(work);
    return info == 0;
}

int rths_cmat_solve(int n, int nrhs, double complex *a, double complex *b) {
    lapack_int *ipiv = malloc((size_t)n * sizeof *ipiv);
    if (!ipiv) return -1;
    lapack_int info = LAPACKE_zgesv(LAPACK_COL_MAJOR, n, nrhs, (lapack_complex_double *)a, n, ipiv,
                                    (lapack_complex_double *)b, n);
    free(ipiv);
    return (int)info;
}

double rths_cmat_hermitian_eigen_ratio(int n, const double complex *a) {
    double complex *work = malloc((size_t)n * (size_t)n * sizeof *work);
    double *w = malloc((size_t)n * sizeof *w);
    double ratio = -1;
    if (work && w) {
        memcpy(work, a, (size_t)n * (size_t)n * sizeof *work);
        if (LAPACKE_zheev(LAPACK_COL_MAJOR, 'N', 'L', n, (lapack_complex_double *)work, n, w) ==
                0 &&
            w[n - 1] > 0)
            ratio = w[0] / w[n - 1]; /* ascending order */
    }
    free(work);
    free(w);
    return ratio;
}

/* Higham (2005), "The scaling and squaring method for the matrix exponential revisited":
 * Pade [13/13] with theta_13 = 5.37; lower orders for small norms. */
static const double pade13[] = {64764752532480000.0,
                                32382376266240000.0,
                                7771770303897600.0,
                                1187353796428800.0,
                                129060195264000.0,
                                10559470521600.0,
                                670442572800.0,
                                33522128640.0,
                                1323241920.0,
                                40840800.0,
                                960960.0,
                                16380.0,
                                182.0,
                                1.0};

int rths_expm(int n, const double *a, double *out) {
    size_t nn = (size_t)n * (size_t)n;
    double norm = rths_mat_norm1(a, n);
    int s = 0;
    const double theta13 = 5.371920351148152;
    if (norm > theta13) s = (int)ceil(log2(norm / theta13));
    double scale = ldexp(1.0, -s);

    double *buf = calloc(8 * nn, sizeof(double));
    if (!buf) return -1;
    double *A = buf, *A2 = buf + nn, *A4 = buf + 2 * nn, *A6 = buf + 3 * nn, *U = buf + 4 * nn,
           *V = buf + 5 * nn, *T = buf + 6 * nn, *Id = buf + 7 * nn;
    for (size_t i = 0; i < nn; i++)
        A[i] = a[i] * scale;
    rths_mat_identity(Id, n);
    rths_mat_mul(n, n, n, 1.0, A, 0, A, 0, 0.0, A2);
    rths_mat_mul(n, n, n, 1.0, A2, 0, A2, 0, 0.0, A4);
    rths_mat_mul(n, n, n, 1.0, A4, 0, A2, 0, 0.0, A6);
    const double *b = pade13;
    /* U = A [A6 (b13 A6 + b11 A4 + b9 A2) + b7 A6 + b5 A4 + b3 A2 + b1 I] */
    for (size_t i = 0; i < nn; i++)
        T[i] = b[13] * A6[i] + b[11] * A4[i] + b[9] * A2[i];
    rths_mat_mul(n, n, n, 1.0, A6, 0, T, 0, 0.0, U);
    for (size_t i = 0; i < nn; i++)
        U[i] += b[7] * A6[i] + b[5] * A4[i] + b[3] * A2[i] + b[1] * Id[i];
    memcpy(T, U, nn * sizeof(double));
    rths_mat_mul(n, n, n, 1.0, A, 0, T, 0, 0.0, U);
    /* V = A6 (b12 A6 + b10 A4 + b8 A2) + b6 A6 + b4 A4 + b2 A2 + b0 I */
    for (size_t i = 0; i < nn; i++)
        T[i] = b[12] * A6[i] + b[10] * A4[i] + b[8] * A2[i];
    rths_mat_mul(n, n, n, 1.0, A6, 0, T, 0, 0.0, V);
    for (size_t i = 0; i < nn; i++)
        V[i] += b[6] * A6[i] + b[4] * A4[i] + b[2] * A2[i] + b[0] * Id[i];
    /* Solve (V - U) R = (V + U) */
    for (size_t i = 0; i < nn; i++) {
        T[i] = V[i] - U[i];
        out[i] = V[i] + U[i];
    }
    int info = rths_mat_solve(n, n, T, out);
    for (int k = 0; k < s && info == 0; k++) {
        memcpy(T, out, nn * sizeof(double));
        rths_mat_mul(n, n, n, 1.0, T, 0, T, 0, 0.0, out);
    }
    free(buf);
    return info;
}

int rths_is_finite(double x) {
    return isfinite(x);
}

double rths_clamp(double x, double lo, double hi) {
    return x < lo ? lo : (x > hi ? hi : x);
}
