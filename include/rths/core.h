/* rths core: errors, dense column-major linear algebra over LAPACKE, matrix exponential, RNG. */
#ifndef RTHS_CORE_H
#define RTHS_CORE_H

#include <complex.h>
#include <stddef.h>
#include <stdint.h>

/* Exit-status classes shared by the library and the CLI. */
enum {
    RTHS_OK = 0,
    RTHS_EFAIL = 1,  /* the work could not be done (numerics, I/O, rig fault) */
    RTHS_EINPUT = 2, /* bad usage or input: config, CLI, out-of-range numbers */
};

/* Room for two paths of PATH_MAX (4096) bytes and the reason after them. */
#define RTHS_ERROR_MSG_LEN 8192

typedef struct rths_error {
    int code;
    char msg[RTHS_ERROR_MSG_LEN];
} rths_error;

/* Fills err (may be NULL) and returns code, so callers can `return rths_error_set(...)`. */
int rths_error_set(rths_error *err, int code, const char *fmt, ...)
    __attribute__((format(printf, 3, 4)));
void rths_error_clear(rths_error *err);

/* Seconds on the monotonic clock (CLOCK_MONOTONIC): for intervals, timeouts and benchmarks. */
double rths_monotonic_s(void);

/* ---- dense matrices: column-major double arrays, element (i, j) at a[i + j*ld] ---- */

#define RTHS_AT(a, ld, i, j) ((a)[(size_t)(i) + (size_t)(j) * (size_t)(ld)])

double *rths_mat_new(int rows, int cols); /* zero-filled; NULL on allocation failure */
double *rths_mat_dup(const double *a, int rows, int cols);
void rths_mat_free(double *a);
void rths_mat_identity(double *a, int n);
/* c = alpha * op(a) * op(b) + beta * c with op = transpose when the flag is set (BLAS dgemm). */
void rths_mat_mul(int m, int n, int k, double alpha, const double *a, int trans_a, const double *b,
                  int trans_b, double beta, double *c);
/* Solves A X = B in place (B holds X on return); A is overwritten. Returns 0 or LAPACK info. */
int rths_mat_solve(int n, int nrhs, double *a, double *b);
/* Inverse of a square matrix into inv (a is left unchanged). Returns 0 or LAPACK info. */
int rths_mat_inverse(int n, const double *a, double *inv);
double rths_mat_max_abs(const double *a, int rows, int cols);
double rths_mat_norm1(const double *a, int n); /* induced 1-norm of a square matrix */
int rths_mat_is_symmetric(const double *a, int n, double rel_tol);
/* Symmetric positive definite test via Cholesky (dpotrf). */
int rths_mat_is_spd(const double *a, int n);
/* Complex solve A x = b (zgesv) with A column-major n x n; a and b overwritten. */
int rths_cmat_solve(int n, int nrhs, double complex *a, double complex *b);
/* Ratio of the smallest to the largest eigenvalue of a Hermitian n x n matrix (zheev, lower
 * triangle read; a is left unchanged): a normal matrix's conditioning. -1 on failure. */
double rths_cmat_hermitian_eigen_ratio(int n, const double complex *a);

/* Matrix exponential e^A of a real n x n matrix: scaling and squaring with a [13/13] Pade
 * approximant (Higham 2005), linear solves through LAPACK. out may not alias a. */
int rths_expm(int n, const double *a, double *out);

/* ---- deterministic random numbers (xoshiro256**), seeded by splitmix64 ---- */

typedef struct rths_rng {
    uint64_t s[4];
} rths_rng;

void rths_rng_seed(rths_rng *rng, uint64_t seed);
uint64_t rths_rng_next(rths_rng *rng);
double rths_rng_uniform(rths_rng *rng); /* [0, 1) */
double rths_rng_normal(rths_rng *rng);  /* standard normal, ziggurat (rng.c) */
/* n draws of rths_rng_normal into out, the same numbers in the same order: one call for a block
 * (the per-sample sensors draw from a pool refilled this way) */
void rths_rng_normals(rths_rng *rng, double *out, int n);

/* ---- small numeric helpers ---- */
int rths_is_finite(double x);
double rths_clamp(double x, double lo, double hi);

#endif
